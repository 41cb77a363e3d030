"""The identification step of the demo: the paper's rig measured, then identified.

BacklashShaft at its defaults (the paper's rig: J_m = 2.28, J_L = 2.55 kg, b = 0.05 N.s/m,
k = 200 N/m, Δ = 0.775 mm) is driven through fmpy by reversing torque steps with a multisine on
top, from rest with the teeth off centre in the gap (u0 = 0.3 Δ: the load's start angle set to
−u0, the angles logged from the start); the motor and load speeds are logged at 200 Hz with
Gaussian noise (σ = 1 mm/s) and a resolution of 0.1 mm/s, as a speed sensor gives them. Then
`backlash_fmu.identify` estimates Δ, k, J_L, b_L and u0 from that noisy run (J_m and b_m known),
and `backlash identify --accuracy` answers whether the identified drive meets the design
accuracy (0.02 m/s, as the design step).

    python -m backlash_fmu.demo.identify_rig [--out results] [--short]

Writes DIR/identify_run.csv (the measured run), DIR/identify.csv (parameter, true, estimate,
ci95_lo, ci95_hi, identifiable, inside) and DIR/identify.json (the answer of `backlash identify
--accuracy ... --json` with the true values beside it).
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from .. import fmu

H = 0.005  # logging step [s]
DURATION_FULL, DURATION_SHORT = 10.0, 4.0  # [s]
TORQUE = 2.0  # square-wave amplitude [N]
PERIOD = 1.0  # its period [s]
MULTISINE = 1.0  # total multisine amplitude [N]
SPEED_SIGMA, SPEED_RESOLUTION = 1e-3, 1e-4  # [m/s]
U0_FRACTION = 0.3
ACCURACY = 0.02  # [m/s], the design step's
SEED = 2026
FITTED = ("Delta", "k", "J_L", "b_L", "u0")


def schedule(n: int, h: float, seed: int = SEED) -> np.ndarray:
    """n torques: ±TORQUE reversing every half PERIOD (a quarter period first, so that the mean
    speed stays near 0) plus a multisine of five frequencies (0.5 to 4 Hz, random phases)."""
    t = np.arange(n) * h
    half = PERIOD / 2
    tau = TORQUE * np.where(np.floor((t + half / 2) / half) % 2 == 0, 1.0, -1.0)
    freqs = np.array([0.5, 1.1, 1.7, 2.6, 4.0])
    phases = np.random.default_rng(seed).uniform(0, 2 * np.pi, freqs.size)
    return tau + MULTISINE / freqs.size * np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None]).sum(axis=0)


def defaults(archive: fmu.Archive) -> dict[str, float]:
    """The real parameters' start values of the model description."""
    return {name: float(v.start) for name, v in archive.variables.items()
            if v.causality == "parameter" and v.type in ("Real", "Float64")}


def measure(archive: fmu.Archive, tau: np.ndarray, u0: float, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """The FMU from rest with u(0) = u0 (θ_L(0) = −u0), each torque held over its row's step;
    the speeds at every row's time with noise and resolution."""
    inst = archive.co_simulation("identify", {"theta_L": -u0})
    try:
        speeds = [inst.get("omega_m", "omega_L")]
        for k, tm in enumerate(tau[:-1]):
            inst.step(k * H, H, tau_m=float(tm))
            speeds.append(inst.get("omega_m", "omega_L"))
    finally:
        inst.free()
    clean = np.array(speeds)
    noisy = clean + SPEED_SIGMA * rng.standard_normal(clean.shape)
    noisy = SPEED_RESOLUTION * np.round(noisy / SPEED_RESOLUTION)
    return {"time": np.arange(tau.size) * H, "tau_m": tau, "omega_m": noisy[:, 0], "omega_L": noisy[:, 1]}


def write_columns(path: Path, cols: dict[str, np.ndarray]) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(list(cols))
        for row in zip(*cols.values()):
            w.writerow([repr(float(v)) for v in row])


def run(out: Path, short: bool, archive: Path | None = None) -> int:
    """Measures, identifies and answers the accuracy question; prints the table; returns the exit
    status (0, or 1 when the command refuses)."""
    from .. import _native, identify

    started = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    duration = DURATION_SHORT if short else DURATION_FULL
    n = int(round(duration / H)) + 1
    tau = schedule(n, H)
    with fmu.Archive(fmu.fmu_path("BacklashShaft") if archive is None else archive) as shaft:
        rig = defaults(shaft)
        u0 = U0_FRACTION * rig["Delta"]
        cols = measure(shaft, tau, u0, np.random.default_rng(SEED))
    truth = {"Delta": rig["Delta"], "k": rig["k"], "J_L": rig["J_L"], "b_L": rig["b_L"], "u0": u0}
    run_csv = out / "identify_run.csv"
    write_columns(run_csv, cols)
    print(f"rig (BacklashShaft defaults): J_m = {rig['J_m']:g} kg, J_L = {rig['J_L']:g} kg, k = {rig['k']:g} N/m, "
          f"b_m = b_L = {rig['b_m']:g} N.s/m, Delta = {rig['Delta'] * 1e3:g} mm; u0 = {u0 * 1e3:g} mm")
    print(f"run: {duration:g} s at {H * 1e3:g} ms, ±{TORQUE:g} N reversing every {PERIOD / 2:g} s plus a multisine; "
          f"omega_m and omega_L with noise {SPEED_SIGMA * 1e3:g} mm/s, resolution {SPEED_RESOLUTION * 1e3:g} mm/s")

    known = {"J_m": rig["J_m"], "b_m": rig["b_m"]}
    answer = identify("shaft", run_csv, fit=list(FITTED), **known)
    sets = [a for name, value in known.items() for a in ("--set", f"{name}={value!r}")]
    status, text, err = _native.command(["identify", "--model", "shaft", str(run_csv), "--fit", ",".join(FITTED),
                                         *sets, "--accuracy", repr(ACCURACY), "--json"])
    if status != 0:
        print(err.strip())
        return 1
    with_accuracy: dict[str, Any] = json.loads(text)

    rows = []
    print(f"\n{'parameter':<10} {'true':>12} {'estimate':>12} {'ci95':>27}  identifiable  inside")
    for name in FITTED:
        est = answer["estimates"][name]
        ci = est["ci95"]
        inside = ci is not None and ci[0] <= truth[name] <= ci[1]
        ci_text = "-" if ci is None else f"[{ci[0]:.6g}, {ci[1]:.6g}]"
        print(f"{name:<10} {truth[name]:>12.6g} {est['value']:>12.6g} {ci_text:>27}  {str(est['identifiable']):<12}  "
              f"{'yes' if inside else 'NO'}")
        rows.append({"parameter": name, "true": truth[name], "estimate": est["value"],
                     "ci95_lo": None if ci is None else ci[0], "ci95_hi": None if ci is None else ci[1],
                     "identifiable": est["identifiable"], "inside": inside})
    print("inside: the true value within the 95% interval (expected of 19 parameters in 20, not of all)")
    print("residual rms: " + ", ".join(f"{k} {v:.3g}" for k, v in answer["residual_rms"].items())
          + f" (noise σ {SPEED_SIGMA:g} m/s)")
    for message in answer["messages"]:
        print(f"  note: {message}")
    acc = with_accuracy.get("accuracy", {})
    print(f"\naccuracy ε = {ACCURACY:g} m/s: " + ", ".join(f"{k} = {v}" for k, v in acc.items()))

    with (out / "identify.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    (out / "identify.json").write_text(json.dumps({**with_accuracy, "true": truth}, indent=2) + "\n")
    print(f"wrote {run_csv}, {out / 'identify.csv'}, {out / 'identify.json'} in {time.perf_counter() - started:.1f} s")
    return 0


def main(argv: list[str] | None = None) -> int:
    from . import short_mode

    ap = argparse.ArgumentParser(prog="python -m backlash_fmu.demo.identify_rig", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("results"), help="output directory (default: results)")
    ap.add_argument("--short", action="store_true", help="a shorter run (also when the environment has CI=true)")
    ap.add_argument("--fmu", type=Path, help="the BacklashShaft archive (default: the package's)")
    args = ap.parse_args(argv)
    return run(args.out, short_mode(args.short), args.fmu)


if __name__ == "__main__":
    raise SystemExit(main())
