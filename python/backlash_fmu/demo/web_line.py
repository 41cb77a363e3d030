"""The web line (docs/model.md §8) through BacklashWeb.fmu: twin closed-loop runs against the
tension bound, and the tension design answer read back through the FMU.

Line: BacklashBelt's belt drive whose load roller (radius R_w) pulls one span of a film web
(length L_w, stiffness EA, transport speed v_ref). Its parameters and the speed PI gains are
those of the web-tension design answer (`backlash_fmu.design("web", tension_accuracy=20)`,
backlash_fmu.demo.web_design; written to design_web.json by `python -m backlash_fmu.demo`).

Loops (docs/model.md §8; backlash_fmu.twin.twin_web_run), closed OUTSIDE the FMU through fmpy and
sampled at every communication point (step h, zero-order hold on the motor torque):
    tension PI:  e_T,n = T_ref - T(t_n),  w_ref,n = w_ref0(t_n) + Kp_T e_T,n + Ki_T x_T,n,
                 x_T,n+1 = x_T,n + h e_T,n
    speed PI:    e_n = w_ref,n - omega_m(t_n),  tau_m = Kp e_n + Ki x_c,n,  x_c,n+1 = x_c,n + h e_n
The reference w_ref0 reverses (a sine on the motor speed) and the upstream web is held
(v_in = 0, T_in = 0), so that the load roller turns both ways and the gear crosses its gap twice
per period: the case in which the backlash acts.

Two instances run side by side from the same state (rest, T = 0): one with the FMU's Delta and
its twin with Delta = 0, both given the loops' gains (Kp, Ki, Kp_T, Ki_T), which enter only their
bounds. The tension deviation |T^b - T^0| is compared with the FMU's `bound_T` and `bound_T_sup`,
the load-speed deviation |omega_L^b - omega_L^0| with `bound`. The bounds belong to the
continuous-time loops; a rerun at h/2 shows how little the sampling changes the deviation.

The design answer (Delta_max and the K_b window for the tension accuracy eps_T, with the design's
gains) is checked through the FMU: its `bound_T_sup` there is eps_T.

Run by `python -m backlash_fmu.demo` (and `cargo xtask demo [--short]`) after the paper's
experiments; alone:
    python -m backlash_fmu.demo.web_line [--out results] [--short] [--design FILE] [--fmu PATH]
with the design answer computed (web_design) unless a JSON answer is given, and the archive
BacklashWeb.fmu of $BACKLASH_FMU_DIR, else the package's own, unless --fmu names one.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .. import fmu  # noqa: E402
from ..twin import (  # noqa: E402
    KI_T,
    KP_T,
    SPEED_AMPLITUDE,
    SPEED_FREQUENCY,
    T_IN,
    T_REF,
    V_IN,
    WebRun,
    bound_t_sup,
    twin_web_run,
)

# Communication step [s]: h times the belt drive's contact natural frequency
# (sqrt(K_b (R_1²/J_m + α_1²/J_L)) ≈ 1170 rad/s, docs/model.md §1) is 0.12; the rerun at h/2
# measures what the sampling changes.
H = 1e-4
HORIZON_FULL = 1.0
HORIZON_SHORT = 0.5
# Pointwise comparisons allow for round-off only (both sides start at exactly 0).
TOL = 1e-12


def holds(dev: np.ndarray, bound: np.ndarray) -> bool:
    """The deviation is within the bound at every communication point, up to round-off."""
    return bool(np.all(dev <= bound * (1 + 1e-9) + TOL))


def worst_ratio(dev: np.ndarray, bound: np.ndarray) -> float:
    """max dev/bound over the points where the bound is positive."""
    positive = bound > 0
    return float(np.max(dev[positive] / bound[positive]))


# ------------------------------------------------------------------------------------------
# Outputs
# ------------------------------------------------------------------------------------------


def write_csv(path: Path, run: WebRun) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", "T_b", "T_0", "dT", "bound_T", "bound_T_sup",
                    "omega_L_b", "omega_L_0", "d_omega_L", "bound", "bound_sup", "contact"])
        for i in range(len(run.t)):
            w.writerow(
                [f"{run.t[i]:.6g}", f"{run.T_b[i]:.12g}", f"{run.T_0[i]:.12g}", f"{run.dT[i]:.9g}",
                 f"{run.bound_T[i]:.9g}", f"{run.bound_T_sup:.9g}", f"{run.omega_L_b[i]:.12g}",
                 f"{run.omega_L_0[i]:.12g}", f"{run.d_omega_L[i]:.9g}", f"{run.bound[i]:.9g}",
                 f"{run.bound_sup:.9g}", int(run.contact[i])]
            )


def plot(path: Path, run: WebRun, delta: float) -> None:
    """Tension deviation against bound_T and bound_T_sup; load-speed deviation against bound."""
    fig, (ax_t, ax_w) = plt.subplots(2, 1, figsize=(10, 7.5), sharex=True)
    panels = (
        (ax_t, run.dT, run.bound_T, run.bound_T_sup, r"$|T^b - T^0|$", "bound_T", "bound_T_sup",
         "tension deviation [N]"),
        (ax_w, run.d_omega_L, run.bound, run.bound_sup, r"$|\omega_L^b - \omega_L^0|$", "bound", "bound_sup",
         "load-speed deviation [rad/s]"),
    )
    for ax, dev, bound, sup, dev_label, bound_label, sup_label, ylabel in panels:
        ax.fill_between(run.t, 0, 1, where=run.contact == 0, transform=ax.get_xaxis_transform(), color="grey",
                        alpha=0.15, lw=0, label="gear inside its gap (Δ run)")
        ax.plot(run.t, dev, color="C0", lw=1.2, label=f"{dev_label} (FMU twins)")
        ax.plot(run.t, bound, color="C2", lw=1.6, label=f"{bound_label} (rigorous, §8)")
        ax.axhline(sup, color="k", lw=0.9, ls=":", label=f"{sup_label} = {sup:.4g}")
        ax.set_ylim(0, 1.4 * max(sup, dev.max()))
        ax.set_ylabel(ylabel)
        ax.set_title(f"max {dev_label} / {bound_label} = {worst_ratio(dev, bound):.3f}", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper center", ncol=4, framealpha=0.85)
    ax_w.set_xlabel("time [s]")
    fig.suptitle(f"Web line (BacklashWeb.fmu), Δ = {delta * 1e3:g} mm against Δ = 0: speed PI and tension PI "
                 f"closed through fmpy (h = {H * 1e3:g} ms)\nmotor-speed reference {SPEED_AMPLITUDE:g} rad/s sine at "
                 f"{SPEED_FREQUENCY:g} Hz, T_ref = {T_REF:g} N, Kp_T = {KP_T:g}, Ki_T = {KI_T:g}", fontsize=10.5)
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ------------------------------------------------------------------------------------------
# Main
# ------------------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    """The web line alone (see the module's docstring); returns the exit status."""
    from . import short_mode, web_design

    ap = argparse.ArgumentParser(prog="python -m backlash_fmu.demo.web_line", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("results"), help="output directory (default: results)")
    ap.add_argument("--short", action="store_true", help="short horizon (also when the environment has CI=true)")
    ap.add_argument("--design", type=Path,
                    help="a web design answer as JSON (`backlash design --model web --json`; default: computed)")
    ap.add_argument("--fmu", type=Path, help="BacklashWeb.fmu (default: $BACKLASH_FMU_DIR's, else the package's)")
    args = ap.parse_args(argv)
    if args.design is None:
        design, name = json.loads(web_design()), "computed"
    else:
        design, name = json.loads(args.design.read_text()), args.design.name
    return run(design, args.out, short_mode(args.short), args.fmu, design_name=name)


def run(design: dict[str, Any], out: Path, short: bool, archive: Path | None = None, *,
        design_name: str = "design_web.json") -> int:
    """The twin web lines with the line and the speed gains of the web design answer `design` (a
    dict as `backlash_fmu.design("web", ...)` returns), on the archive `archive` (default:
    BacklashWeb's, backlash_fmu.fmu.fmu_path), writing under `out`; `short`: the short horizon;
    `design_name` names the answer in what is printed. Prints the table and the design answer
    read back through the FMU; returns the exit status (0)."""
    horizon = HORIZON_SHORT if short else HORIZON_FULL
    started = time.perf_counter()

    params = {name: value for name, value in design["plant"].items() if name != "form"}
    kp, ki = design["Kp"], design["Ki"]
    delta = params["Delta"]
    out.mkdir(parents=True, exist_ok=True)
    with fmu.Archive(fmu.fmu_path("BacklashWeb") if archive is None else archive) as web:
        print(f"web line: BacklashBelt's drive, Δ = {delta * 1e3:g} mm, pulling a span with "
              f"R_w = {params['R_w']:g} m, L_w = {params['L_w']:g} m, EA = {params['EA']:g} N, "
              f"v_ref = {params['v_ref']:g} m/s")
        print(f"speed PI ({design['gain_rule']}): Kp = {kp:.6f} N.m.s/rad, Ki = {ki:.6f} N.m/rad; "
              f"tension PI: Kp_T = {KP_T:g} rad/(s.N), Ki_T = {KI_T:g} rad/(s2.N), T_ref = {T_REF:g} N")
        print(f"loops closed through fmpy at every communication point, h = {H * 1e3:g} ms; horizon {horizon:g} s"
              f"{' (short)' if short else ''}; motor-speed reference {SPEED_AMPLITUDE:g} rad/s sine at "
              f"{SPEED_FREQUENCY:g} Hz, upstream web held (v_in = {V_IN:g} m/s, T_in = {T_IN:g} N)")

        run = twin_web_run(web, params, kp, ki, horizon, H)
        write_csv(out / "web_line.csv", run)
        plot(out / "web_line.png", run, delta)
        ratio_t, ratio_w = worst_ratio(run.dT, run.bound_T), worst_ratio(run.d_omega_L, run.bound)
        both_hold = holds(run.dT, run.bound_T) and holds(run.d_omega_L, run.bound)
        print()
        print("twin web lines (Δ and Δ = 0): tension deviation against bound_T [N], load speed against bound")
        header = f"{'max |ΔT|':>9s} {'bound_T':>9s} {'bound_T_sup':>11s} {'|ΔT|/bound_T':>12s} " \
                 f"{'|Δω_L|/bound':>12s} {'switches':>8s} {'holds':>5s}"
        print(header)
        print("-" * len(header))
        print(f"{run.dT.max():9.4f} {run.bound_T[-1]:9.4f} {run.bound_T_sup:11.4f} {ratio_t:12.3f} "
              f"{ratio_w:12.3f} {run.switches:8d} {'yes' if both_hold else 'NO':>5s}")
        print("(max |ΔT|/bound_T and max |Δω_L|/bound over the communication points; bound_T at the horizon; "
              "switches: contact changes between communication points)")
        half = twin_web_run(web, params, kp, ki, horizon, H / 2)
        print(f"sampling: halving h to {H / 2 * 1e3:g} ms changes max |ΔT| by "
              f"{(half.dT.max() / run.dT.max() - 1) * 100:+.2f} % (to {half.dT.max():.4f} N)")

        eps_t = design["tension_accuracy"]
        gains = dict(Kp=kp, Ki=ki, Kp_T=design["Kp_T"], Ki_T=design["Ki_T"])
        loop = "no tension loop" if gains["Kp_T"] == gains["Ki_T"] == 0 else \
            f"tension PI Kp_T = {gains['Kp_T']:g}, Ki_T = {gains['Ki_T']:g}"
        print()
        print(f"design answer for tension accuracy ε_T = {eps_t:g} N ({design_name}; speed PI above, {loop}):")
        print(f"  bound_T_sup at Δ = {delta * 1e3:g} mm: {design['bound_T_sup_at_delta']:.4f} N; "
              f"Δ_max = {design['delta_max'] * 1e3:.6f} mm")
        at_max = bound_t_sup(web, dict(params, **gains, Delta=design["delta_max"]))
        print(f"  FMU bound_T_sup at Δ = Δ_max: {at_max:.12g} N (relative to ε_T {at_max / eps_t - 1:+.2e})")
        for key, side in (("k_min", "below"), ("k_max", "above")):
            if design[key] is None:
                print(f"  {key}: none within the scan (ε_T holds {side} the nominal K_b to the scan's edge)")
                continue
            at_k = bound_t_sup(web, dict(params, **gains, K_b=design[key]))
            print(f"  K_b {key[2:]} = {design[key]:.1f} N/m at Δ = {delta * 1e3:g} mm; FMU bound_T_sup there: "
                  f"{at_k:.12g} N (relative to ε_T {at_k / eps_t - 1:+.2e})")

    print(f"\nwrote {out / 'web_line.csv'} and {out / 'web_line.png'} "
          f"in {time.perf_counter() - started:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
