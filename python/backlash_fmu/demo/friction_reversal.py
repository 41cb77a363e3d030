"""The friction step of the demo: a low-speed reversal on the paper's rig, with bearing friction
and without.

BacklashShaft at its defaults (the paper's rig) with Coulomb friction with stiction in both
bearings (docs/model.md §12: tau_c_m = 0.05, tau_c_L = 0.3 N.m, peak 1.5 on the load), under the
demo's PI speed loop (the design step's gains, sampled every H) following a slow sine speed
reference that reverses every half period. At each reversal the load sticks while the motor
takes up the gap and winds the shaft up, then breaks away: the lost motion, θ_m − θ_L, swings
across the gap and beyond. The same run without friction beside it.

    python -m backlash_fmu.demo.friction_reversal [--out results] [--short]

Writes DIR/friction_reversal.csv (time, the reference, both runs' motor and load speeds, lost
motion, and the friction run's sliding_m, sliding_L) and DIR/friction_reversal.png.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .. import fmu  # noqa: E402

H = 0.001  # sample and communication step [s]
PERIOD = 4.0  # of the speed reference [s]
SPEED = 0.05  # its amplitude [rad/s]
FRICTION = {"tau_c_m": 0.05, "tau_c_L": 0.3, "peak_L": 1.5}
DURATION_FULL, DURATION_SHORT = 2 * PERIOD, PERIOD


def run_loop(archive: fmu.Archive, params: dict[str, float], kp: float, ki: float, n: int) -> dict[str, np.ndarray]:
    """The sampled PI on ω_m (τ_m = Kp e + Ki ∫e, e = ω_ref − ω_m, held over each step) for n
    steps from rest."""
    inst = archive.co_simulation("reversal", params)
    rows = []
    integral = 0.0
    try:
        for k in range(n):
            t = k * H
            theta_m, omega_m, theta_l, omega_l = inst.get("theta_m", "omega_m", "theta_L", "omega_L")
            sliding = inst.integers("sliding_m", "sliding_L")
            ref = SPEED * np.sin(2 * np.pi * t / PERIOD)
            error = ref - omega_m
            rows.append((t, ref, omega_m, omega_l, theta_m - theta_l, *sliding))
            tau = kp * error + ki * integral
            integral += H * error
            inst.step(t, H, tau_m=tau)
    finally:
        inst.free()
    a = np.array(rows)
    keys = ("time", "omega_ref", "omega_m", "omega_L", "lost_motion", "sliding_m", "sliding_L")
    return {key: a[:, i] for i, key in enumerate(keys)}


def stuck_spans(t: np.ndarray, sliding: np.ndarray) -> list[tuple[float, float]]:
    """The intervals (start, end) in which a body reads stuck (sliding 0), from the samples."""
    spans, start = [], None
    for ti, s in zip(t, sliding):
        if s == 0 and start is None:
            start = ti
        elif s != 0 and start is not None:
            spans.append((start, ti))
            start = None
    if start is not None:
        spans.append((start, t[-1]))
    return spans


def run(answer: dict, out: Path, short: bool, archive: Path | None = None) -> int:
    """Both runs, the table and the figure; returns the exit status."""
    started = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    n = int(round((DURATION_SHORT if short else DURATION_FULL) / H))
    kp, ki = answer["Kp"], answer["Ki"]
    with fmu.Archive(fmu.fmu_path("BacklashShaft") if archive is None else archive) as shaft:
        delta = float(shaft.variables["Delta"].start)
        with_friction = run_loop(shaft, dict(FRICTION), kp, ki, n)
        without = run_loop(shaft, {}, kp, ki, n)
    t = with_friction["time"]
    print(f"paper's rig, PI Kp = {kp:.4f}, Ki = {ki:.4f} sampled every {H * 1e3:g} ms; reference "
          f"{SPEED:g} sin(2 pi t / {PERIOD:g} s) rad/s; friction " + ", ".join(f"{k} = {v:g}" for k, v in FRICTION.items()))
    for name, r in (("with friction", with_friction), ("without", without)):
        tracking = np.max(np.abs(r["omega_L"] - r["omega_ref"]))
        print(f"  {name:<14} max |omega_L - omega_ref| = {tracking:.4g} rad/s, lost motion from "
              f"{r['lost_motion'].min() / delta:+.3f} to {r['lost_motion'].max() / delta:+.3f} Delta")
    for body, output in (("motor", "sliding_m"), ("load", "sliding_L")):
        spans = [(a, b) for a, b in stuck_spans(t, with_friction[output]) if b - a >= H]
        text = ", ".join(f"{a:.3f}-{b:.3f} s" for a, b in spans) or "never"
        print(f"  {body} stuck: {text}")

    csv_path = out / "friction_reversal.csv"
    with csv_path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["time", "omega_ref", "omega_m", "omega_L", "lost_motion", "sliding_m", "sliding_L",
                    "omega_m_frictionless", "omega_L_frictionless", "lost_motion_frictionless"])
        for i in range(n):
            w.writerow([repr(float(x)) for x in (
                t[i], with_friction["omega_ref"][i], with_friction["omega_m"][i], with_friction["omega_L"][i],
                with_friction["lost_motion"][i])] + [int(with_friction["sliding_m"][i]),
                                                     int(with_friction["sliding_L"][i])]
                       + [repr(float(x)) for x in (without["omega_m"][i], without["omega_L"][i],
                                                   without["lost_motion"][i])])

    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    ax = axes[0]
    ax.plot(t, with_friction["omega_ref"], "k:", label="reference")
    ax.plot(t, with_friction["omega_m"], label="motor, friction")
    ax.plot(t, with_friction["omega_L"], label="load, friction")
    ax.plot(t, without["omega_L"], "--", label="load, no friction")
    ax.set_ylabel("speed [rad/s]")
    ax.legend(loc="upper right", fontsize=8)
    ax = axes[1]
    ax.step(t, with_friction["sliding_m"] + 0.05, where="post", label="sliding_m")
    ax.step(t, with_friction["sliding_L"] - 0.05, where="post", label="sliding_L")
    ax.set_yticks([-1, 0, 1], ["backward", "stuck", "forward"])
    ax.legend(loc="upper right", fontsize=8)
    ax = axes[2]
    ax.plot(t, with_friction["lost_motion"] / delta, label="friction")
    ax.plot(t, without["lost_motion"] / delta, "--", label="no friction")
    ax.axhline(1.0, color="grey", lw=0.5)
    ax.axhline(-1.0, color="grey", lw=0.5)
    ax.set_ylabel("lost motion (theta_m - theta_L) / Delta")
    ax.set_xlabel("time [s]")
    ax.legend(loc="upper right", fontsize=8)
    fig.suptitle("Low-speed reversal on the paper's rig: bearing friction with stiction")
    fig.tight_layout()
    png = out / "friction_reversal.png"
    fig.savefig(png, dpi=120)
    plt.close(fig)
    print(f"wrote {csv_path}, {png} in {time.perf_counter() - started:.1f} s")
    return 0


def main(argv: list[str] | None = None) -> int:
    from . import shaft_design, short_mode
    import json

    ap = argparse.ArgumentParser(prog="python -m backlash_fmu.demo.friction_reversal",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("results"), help="output directory (default: results)")
    ap.add_argument("--short", action="store_true", help="a shorter run (also when the environment has CI=true)")
    ap.add_argument("--fmu", type=Path, help="the BacklashShaft archive (default: the package's)")
    args = ap.parse_args(argv)
    return run(json.loads(shaft_design()), args.out, short_mode(args.short), args.fmu)


if __name__ == "__main__":
    raise SystemExit(main())
