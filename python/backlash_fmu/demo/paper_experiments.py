"""The paper's closed-loop experiments (Figs. 11-13) reproduced with BacklashShaft.fmu, and its
open design question answered.

Rig (paper, "Experiments"; docs/model.md §4): the rectilinear ECP system in shaft form,
M_1 = J_m = 2.28 kg, M_2 = J_L = 2.55 kg, k = 200 N/m, b_m = b_L = 0.05 N.s/m; metres play the
role of radians (docs/model.md §1, rectilinear analogue), so speeds are in m/s and "torques" in N.

Loop (paper Fig. 8, docs/model.md §3): a PI controller on the motor speed, closed OUTSIDE the FMU
through fmpy and sampled at every communication point (step h, zero-order hold on the force):
    e_n = w_ref(t_n) - omega_m(t_n),  tau_m = Kp e_n + Ki x_n,  x_{n+1} = x_n + h e_n.
Two instances run side by side from rest: one with the backlash (Delta > 0) and its twin without
(Delta = 0). The deviation |omega_L^b - omega_L^0| is compared with the FMU's outputs `bound`
(docs/model.md §3, rigorous) and `bound_paper` (eq. 37 as printed) and with `bound_sup` (the
horizontal line of the paper's figures). The gains are those of the design answer
(`backlash_fmu.design`, best-damped rule; backlash_fmu.demo.shaft_design), which is also checked
through the FMU.

The paper's gaps (1.55, 3.56, 5.38 mm) are ambiguous (docs/model.md §5): both readings are run,
Delta = gap/2 (the nomenclature: Delta is the half gap) and Delta = gap.

Run by `python -m backlash_fmu.demo` (and `cargo xtask demo [--short]`) with the web line;
alone:
    python -m backlash_fmu.demo.paper_experiments [--out results] [--short] [--design FILE] [--fmu PATH]
with the design answer computed (shaft_design) unless a JSON answer is given, and the archive
BacklashShaft.fmu of $BACKLASH_FMU_DIR, else the package's own, unless --fmu names one.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .. import fmu  # noqa: E402
from ..twin import SPEED, Run, bound_sup, reference_frequency, references, twin_run  # noqa: E402

GAPS_MM = (1.55, 3.56, 5.38)
READINGS = {"half": 0.5, "full": 1.0}  # Delta = factor * gap
READING_LABEL = {"half": "Δ = gap/2", "full": "Δ = gap"}
FIGURE_OF_GAP = {1.55: 11, 3.56: 12, 5.38: 13}
# Communication step [s]: 1 ms, a hundred times shorter than the closed loop's time constant
# (poles near |s| = 8.9 1/s); the sampling study below measures how much h matters.
H = 1e-3
HORIZON_FULL = 8.0
HORIZON_SHORT = 1.5


# ------------------------------------------------------------------------------------------
# Tables
# ------------------------------------------------------------------------------------------


def write_run_csv(path: Path, run: Run) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(
            ["t_s", "omega_ref", "omega_m_b", "omega_L_b", "omega_m_0", "omega_L_0", "tau_m_b", "tau_m_0",
             "deviation", "bound", "bound_paper", "bound_sup", "contact"]
        )
        for i in range(len(run.t)):
            w.writerow(
                [f"{run.t[i]:.6g}", f"{run.ref[i]:.9g}", f"{run.omega_m_b[i]:.12g}", f"{run.omega_L_b[i]:.12g}",
                 f"{run.omega_m_0[i]:.12g}", f"{run.omega_L_0[i]:.12g}", f"{run.tau_b[i]:.9g}", f"{run.tau_0[i]:.9g}",
                 f"{run.deviation[i]:.9g}", f"{run.bound[i]:.9g}", f"{run.bound_paper[i]:.9g}",
                 f"{run.bound_sup:.9g}", int(run.contact[i])]
            )


# Pointwise comparisons allow for round-off only (both sides start at exactly 0).
TOL = 1e-12


def holds(dev: np.ndarray, bound: np.ndarray) -> bool:
    return bool(np.all(dev <= bound * (1 + 1e-9) + TOL))


# ------------------------------------------------------------------------------------------
# Plots
# ------------------------------------------------------------------------------------------


def plot_gap(path: Path, gap: float, runs: dict[tuple[str, str], Run], f_ref: float) -> None:
    """One figure per gap, as the paper's Figs. 11-13: rows = reference, columns = reading."""
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex=True)
    for row, ref_name in enumerate(("step", "sine")):
        for col, reading in enumerate(("half", "full")):
            ax = axes[row][col]
            run = runs[(ref_name, reading)]
            mm = 1e3
            ax.plot(run.t, run.deviation * mm, color="C0", lw=1.2, label=r"$|\omega_L^b - \omega_L^0|$ (FMU twins)")
            ax.plot(run.t, run.bound * mm, color="C2", lw=1.6, label="bound (true, §3)")
            ax.plot(run.t, run.bound_paper * mm, color="C3", lw=1.4, ls="--", label="bound_paper (eq. 37 as printed)")
            ax.axhline(run.bound_sup * mm, color="k", lw=0.9, ls=":", label="bound_sup (data-sheet line)")
            over = run.deviation > run.bound_paper * (1 + 1e-9) + TOL
            if over.any():
                ax.fill_between(run.t, run.bound_paper * mm, run.deviation * mm, where=over, color="C3", alpha=0.25,
                                lw=0, label="eq. 37 violated")
            delta = READINGS[reading] * gap * 1e-3
            ratio = run.deviation.max() / max(run.bound_paper.max(), 1e-300)
            title = (f"{'step' if ref_name == 'step' else f'sine {f_ref:.2f} Hz'} reference, "
                     f"{READING_LABEL[reading]} = {delta * 1e3:.3f} mm\n"
                     f"max dev / sup bound_paper = {ratio:.2f}, max dev / sup bound = "
                     f"{run.deviation.max() / run.bound.max():.2f}")
            ax.set_title(title, fontsize=9.5)
            ax.set_ylim(0, 1.12 * max(run.bound.max(), run.deviation.max()) * mm)
            ax.grid(alpha=0.3)
            if row == 1:
                ax.set_xlabel("time [s]")
            if col == 0:
                ax.set_ylabel("load-speed deviation [mm/s]")
    handles, labels = [], []
    for ax in axes.flat:
        for hd, lb in zip(*ax.get_legend_handles_labels()):
            if lb not in labels:
                handles.append(hd)
                labels.append(lb)
    fig.legend(handles, labels, loc="lower center", ncol=5, fontsize=9, frameon=False)
    fig.suptitle(f"Paper Fig. {FIGURE_OF_GAP[gap]} reproduced: gap {gap} mm, PI on motor speed closed through fmpy "
                 f"(h = {H * 1e3:g} ms)", fontsize=11)
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_design(path: Path, design: dict[str, Any], fmu_checks: list[tuple[float, float, float]]) -> None:
    """bound_sup over (Delta, k): bound_sup = Delta * S(k), S from the design scan."""
    eps = design["accuracy"]
    scan = np.array([[k, s] for k, s in design["k_scan"] if s is not None])
    delta_scan = design["plant"]["Delta"]
    ks, per_delta = scan[:, 0], scan[:, 1] / delta_scan
    deltas = np.logspace(-5, -2, 200)
    K, D = np.meshgrid(ks, deltas)
    B = D * per_delta[None, :]
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12.5, 5.2))
    levels = np.logspace(-4, 0, 17)
    cs = ax.contourf(K, D * 1e3, B, levels=levels, norm=matplotlib.colors.LogNorm(), cmap="viridis", extend="both")
    fig.colorbar(cs, ax=ax, label="bound_sup [m/s]")
    ax.contour(K, D * 1e3, B, levels=[eps], colors="w", linewidths=2)
    ax.plot([], [], color="w", lw=2, label=f"bound_sup = ε = {eps:g} m/s")
    k0 = design["plant"]["k"]
    ax.plot(k0, design["delta_max"] * 1e3, "o", color="orange", ms=8,
            label=f"Δ_max = {design['delta_max'] * 1e3:.4f} mm at k = {k0:g}")
    for key, marker in (("k_min", "v"), ("k_max", "^")):
        if design[key] is not None:
            ax.plot(design[key], delta_scan * 1e3, marker, color="red", ms=8,
                    label=f"{key} = {design[key]:.2f} N/m at Δ = {delta_scan * 1e3:g} mm")
    ax.axhline(delta_scan * 1e3, color="red", lw=0.6, ls=":")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("stiffness k [N/m]")
    ax.set_ylabel("half gap Δ [mm]")
    ax.set_title("bound_sup over (Δ, k), fixed gains: feasible = below the white line", fontsize=10)
    ax.legend(fontsize=8, loc="lower left", framealpha=0.85)

    ax2.loglog(ks, scan[:, 1], color="C0", label=f"bound_sup(k) at Δ = {delta_scan * 1e3:g} mm (design scan)")
    ax2.axhline(eps, color="k", ls="--", lw=1, label=f"ε = {eps:g} m/s")
    for k, via_fmu, _ in fmu_checks:
        ax2.plot(k, via_fmu, "s", mfc="none", color="C1", ms=7)
    ax2.plot([], [], "s", mfc="none", color="C1", label="bound_sup read from the FMU")
    for key in ("k_min", "k_max"):
        if design[key] is not None:
            ax2.axvline(design[key], color="red", lw=0.8, ls=":")
    for tp in design["k_turning_points"]:
        ax2.axvline(tp, color="grey", lw=0.6, ls="-.")
    ax2.set_xlabel("stiffness k [N/m]")
    ax2.set_ylabel("bound_sup [m/s]")
    ax2.set_title("not monotone in k (fixed gains): feasible window [k_min, k_max]\n"
                  f"around the nominal k (Kp = {design['Kp']:.3f} N.s/m, Ki = {design['Ki']:.3f} N/m)", fontsize=10)
    ax2.grid(alpha=0.3, which="both")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ------------------------------------------------------------------------------------------
# Main
# ------------------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    """The experiments alone (see the module's docstring); returns the exit status."""
    from . import shaft_design, short_mode

    ap = argparse.ArgumentParser(prog="python -m backlash_fmu.demo.paper_experiments",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("results"), help="output directory (default: results)")
    ap.add_argument("--short", action="store_true", help="short horizons (also when the environment has CI=true)")
    ap.add_argument("--design", type=Path,
                    help="a shaft design answer as JSON (`backlash design --json`; default: computed)")
    ap.add_argument("--fmu", type=Path, help="BacklashShaft.fmu (default: $BACKLASH_FMU_DIR's, else the package's)")
    args = ap.parse_args(argv)
    design = json.loads(shaft_design()) if args.design is None else json.loads(args.design.read_text())
    return run(design, args.out, short_mode(args.short), args.fmu)


def run(design: dict[str, Any], out: Path, short: bool, archive: Path | None = None) -> int:
    """The experiments with the gains and the rig of the shaft design answer `design` (a dict as
    `backlash_fmu.design("shaft", ...)` returns), on the archive `archive` (default:
    BacklashShaft's, backlash_fmu.fmu.fmu_path), writing under `out`; `short`: the short
    horizon. Prints the tables; returns the exit status (0)."""
    horizon = HORIZON_SHORT if short else HORIZON_FULL
    started = time.perf_counter()
    started_at = time.time() - 1.0  # files written by this run are newer (1 s for coarse clocks)
    out.mkdir(parents=True, exist_ok=True)
    with fmu.Archive(fmu.fmu_path("BacklashShaft") if archive is None else archive) as shaft:
        _experiments(design, out, horizon, short, shaft)

    def written(pattern: str) -> int:
        return sum(1 for path in out.glob(pattern) if path.stat().st_mtime >= started_at)

    print(f"\nwrote {written('*.csv')} CSV and {written('*.png')} PNG files "
          f"under {out} in {time.perf_counter() - started:.1f} s")
    return 0


def _experiments(design: dict[str, Any], out: Path, horizon: float, short: bool, shaft: fmu.Archive) -> None:
    """The twelve cases, the sampling study and the design checks, on the unpacked `shaft`."""
    p = design["plant"]
    plant = {"J_m": p["J_m"], "J_L": p["J_L"], "b_m": p["b_m"], "b_L": p["b_L"], "k": p["k"]}
    kp, ki = design["Kp"], design["Ki"]
    f_ref = reference_frequency(design["poles"])
    omega_n = 2 * math.pi * f_ref

    print(f"rig: J_m = {p['J_m']} kg, J_L = {p['J_L']} kg, k = {p['k']} N/m, b_m = b_L = {p['b_m']} N.s/m")
    print(f"PI on motor speed, {design['gain_rule']}:")
    print(f"  Kp = {kp:.6f} N.s/m, Ki = {ki:.6f} N/m (smallest damping ratio {design['min_damping_ratio']:.4f}, "
          f"|poles| = {omega_n:.4f} 1/s)")
    print(f"loop closed through fmpy at every communication point, h = {H * 1e3:g} ms; horizon {horizon:g} s"
          f"{' (short)' if short else ''}; references: step {SPEED} m/s, sine {SPEED} m/s at {f_ref:.4f} Hz")

    rows = []
    for gap in GAPS_MM:
        runs = {}
        for reading, factor in READINGS.items():
            delta = factor * gap * 1e-3
            for ref_name, ref in references(f_ref).items():
                t0 = time.perf_counter()
                run = twin_run(shaft, plant, delta, kp, ki, ref, horizon, H)
                runs[(ref_name, reading)] = run
                case = f"gap{gap:.2f}mm_{reading}_{ref_name}"
                write_run_csv(out / f"run_{case}.csv", run)
                dev = run.deviation
                row = {
                    "case": case,
                    "gap_mm": gap,
                    "Delta_mm": delta * 1e3,
                    "reference": ref_name,
                    "max_deviation": float(dev.max()),
                    "sup_bound_paper": float(run.bound_paper.max()),
                    "sup_bound": float(run.bound.max()),
                    "bound_sup": run.bound_sup,
                    "paper_holds": holds(dev, run.bound_paper),
                    "bound_holds": holds(dev, run.bound),
                    "ratio_to_paper": float(dev.max() / run.bound_paper.max()),
                }
                rows.append(row)
                print(f"case {len(rows):2d}/12 {case:28s} max|dev| = {row['max_deviation']:.5f} m/s, "
                      f"sup bound_paper = {row['sup_bound_paper']:.5f}, sup bound = {row['sup_bound']:.5f} "
                      f"({time.perf_counter() - t0:.1f} s)", flush=True)
        plot_gap(out / f"fig{FIGURE_OF_GAP[gap]}_gap{gap:.2f}mm.png", gap, runs, f_ref)

    with (out / "summary.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)

    print()
    print("deviation |ω_L^b − ω_L^0| against the bounds (m/s); 'holds' = deviation <= bound at every sample")
    header = f"{'case':28s} {'max dev':>9s} {'sup b_paper':>11s} {'sup bound':>10s} {'bound_sup':>10s} " \
             f"{'dev/b_paper':>11s} {'paper holds':>11s} {'bound holds':>11s}"
    print(header)
    print("-" * len(header))
    for r in rows:
        print(f"{r['case']:28s} {r['max_deviation']:9.5f} {r['sup_bound_paper']:11.5f} {r['sup_bound']:10.5f} "
              f"{r['bound_sup']:10.5f} {r['ratio_to_paper']:11.2f} {'yes' if r['paper_holds'] else 'NO':>11s} "
              f"{'yes' if r['bound_holds'] else 'NO':>11s}")
    n_paper = sum(not r["paper_holds"] for r in rows)
    n_bound = sum(not r["bound_holds"] for r in rows)
    print(f"eq. (37) as printed fails in {n_paper}/{len(rows)} cases; the true bound fails in {n_bound}/{len(rows)}.")

    # Sampling: the bound is for a continuous PI; measure what the sampled loop changes.
    gap, reading = GAPS_MM[0], "half"
    delta = READINGS[reading] * gap * 1e-3
    sine = references(f_ref)["sine"]
    print()
    print(f"sampling study (sine, Δ = {delta * 1e3:.3f} mm): max|dev| as the communication step h grows")
    base = None
    with (out / "sampling.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["h_s", "max_deviation", "sup_bound", "relative_change"])
        for h in (H / 2, H, 5 * H, 20 * H):
            run = twin_run(shaft, plant, delta, kp, ki, sine, horizon, h)
            m = float(run.deviation.max())
            base = m if base is None else base
            w.writerow([h, m, float(run.bound.max()), m / base - 1])
            print(f"  h = {h * 1e3:5.1f} ms: max|dev| = {m:.6f} m/s "
                  f"({(m / base - 1) * 100:+.2f} % vs h = {H / 2 * 1e3:g} ms),"
                  f" sup bound = {run.bound.max():.6f}")

    # A damper in the shaft (docs/model.md §1 and §3, "With a damper"): the sine case of the
    # sampling study with d of contact damping ratio 0.5 (Modelica's ElastoBacklash, the
    # default law), beside the same case without; its twin is the spring-damper.
    zeta = 0.5
    d = 2 * zeta * math.sqrt(p["k"] / (1 / p["J_m"] + 1 / p["J_L"]))
    print()
    print(f"damper in the shaft (sine, Δ = {delta * 1e3:.3f} mm, d = {d:.4f} N.s/m, contact damping ratio "
          f"{zeta:g}, contact_law 1): against the spring-damper twin")
    with (out / "damped.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["d", "max_deviation", "sup_bound", "bound_sup", "bound_holds", "deviation_over_bound_sup"])
        for damping in (0.0, d):
            run = twin_run(shaft, dict(plant, d=damping), delta, kp, ki, sine, horizon, H)
            if damping > 0.0:
                write_run_csv(out / "run_damped_sine.csv", run)
            m = float(run.deviation.max())
            w.writerow([damping, m, float(run.bound.max()), run.bound_sup, holds(run.deviation, run.bound),
                        m / run.bound_sup])
            print(f"  d = {damping:7.4f}: max|dev| = {m:.6f} m/s, sup bound = {run.bound.max():.6f}, "
                  f"K g ∫|h| to ∞ (bound_sup) = {run.bound_sup:.6f}, bound holds: "
                  f"{'yes' if holds(run.deviation, run.bound) else 'NO'}")

    # The design question, checked through the FMU.
    eps = design["accuracy"]
    print()
    print(f"design (paper's open question) for accuracy ε = {eps:g} m/s, gains above:")
    print(f"  bound_sup per unit Δ at k = {p['k']:g}: {design['bound_sup_per_unit_delta']:.6f} (m/s)/m")
    print(f"  Δ_max = {design['delta_max'] * 1e3:.6f} mm (gap {2 * design['delta_max'] * 1e3:.6f} mm read as 2Δ)")
    via_fmu = bound_sup(shaft, dict(plant, Kp=kp, Ki=ki, Delta=design["delta_max"]))
    print(f"  FMU bound_sup at Δ = Δ_max: {via_fmu:.12g} (relative error {via_fmu / eps - 1:+.2e})")
    run = twin_run(shaft, plant, design["delta_max"], kp, ki, sine, horizon, H)
    print(f"  closed loop at Δ = Δ_max, sine reference: max|dev| = {run.deviation.max():.6f} m/s <= ε: "
          f"{run.deviation.max() <= eps}")
    mono = "monotone" if design["k_monotone"] else \
        f"NOT monotone (turning points near k = {', '.join(f'{k:.1f}' for k in design['k_turning_points'])})"
    print(f"  stiffness at Δ = {p['Delta'] * 1e3:g} mm: bound_sup(k) is {mono}")
    if design["k_min"] is not None:
        d = design["k_min_detail"]
        print(f"  k_min = {design['k_min']:.6f} N/m (root in the scan bracket "
              f"[{d['bracket'][0]:.3f}, {d['bracket'][1]:.3f}], bound_sup monotone there: {d['monotone_in_bracket']})")
    else:
        print("  k_min: none (ε is below bound_sup at the nominal k)")
    if design["k_max"] is not None:
        print(f"  k_max = {design['k_max']:.6f} N/m: a stiffer member with the same gains exceeds ε again")
    checks = []
    for k in [kk for kk in (design["k_min"], p["k"], design["k_max"], 10.0, 2000.0) if kk is not None]:
        b = bound_sup(shaft, dict(plant, k=k, Kp=kp, Ki=ki, Delta=p["Delta"]))
        idx = int(np.argmin([abs(math.log(s[0] / k)) for s in design["k_scan"]]))
        checks.append((k, b, design["k_scan"][idx][1]))
    print("  FMU bound_sup at k = " + ", ".join(f"{k:.2f}: {b:.6f}" for k, b, _ in checks))
    with (out / "design_bound_sup.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["k", "bound_sup_at_Delta", "bound_sup_per_unit_Delta"])
        for k, s in design["k_scan"]:
            w.writerow([k, s, None if s is None else s / p["Delta"]])
    plot_design(out / "design_bound_sup.png", design, checks)


if __name__ == "__main__":
    sys.exit(main())
