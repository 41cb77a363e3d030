"""The two-stage step of the demo: which mesh's backlash costs the accuracy (docs/model.md §10).

A two-stage gearbox (GEARBOX: a fast motor-side mesh of ratio n_1 and a slow load-side mesh of
ratio n_2, each with its own stiffness, damper and half gap on its input side) under the PI speed
loop of the best-damped rule. `backlash_fmu.design("two-stage", accuracy=EPS, ...)` gives each stage's
bound_sup per unit of its half gap, s_j, from the rigorous bound of docs/model.md §10 (one
disturbance per stage, worst signs independent). bound_sup = s_1 Delta_1 + s_2 Delta_2 is linear in
each gap, so the gaps that meet the accuracy form the triangle s_1 Delta_1 + s_2 Delta_2 <= eps.
With dampers bound_sup is the gaps' part of the bound; a run's bound adds each damper's term along
its trajectory (docs/model.md §10, "With dampers"), which no choice of gap removes.

    python -m backlash_fmu.demo.two_stage [--out results]

Prints s_j, each stage's share of bound_sup at the gearbox's gaps, the largest Delta_j with the
other gap at its value, and the stage that dominates. Writes DIR/two_stage.json (the answer as
`backlash design --model two-stage --json` prints it) and DIR/two_stage.png: the triangle in the
(Delta_1, Delta_2) plane with lines of equal bound_sup and the gearbox's gaps, beside each stage's
share of bound_sup.

The answer is the bound's: this step runs no experiment (BacklashTwoStage.fmu simulates a
two-stage gearbox, docs/model.md §10; the gearbox's parameters here have its names).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

# A gearbox of two unequal meshes (SI units; angles in rad on each stage's input side), each
# mesh damped (d_j, the law of docs/model.md §1 by default): without, the light intermediate
# shaft rings on, and the best-damped rule's gains reach a smallest damping ratio of only 0.0018.
GEARBOX = {"J_m": 0.6, "J_i": 0.04, "J_L": 5.0, "b_m": 0.02, "b_i": 0.05, "b_L": 0.4,
           "n_1": 4.0, "n_2": 2.5, "k_1": 600.0, "k_2": 3000.0, "d_1": 1.0, "d_2": 5.0,
           "Delta_1": 1.0e-3, "Delta_2": 0.5e-3}
# Required load-speed accuracy [rad/s].
EPS = 0.1


def answer() -> dict:
    """The design answer for GEARBOX at EPS (gains by the best-damped rule)."""
    from .. import design

    return design("two-stage", accuracy=EPS, **GEARBOX)


def summary(a: dict) -> str:
    """The answer in a few lines: s_j, the shares, the largest gaps, the dominant stage."""
    lines = [f"gearbox: n_1 = {GEARBOX['n_1']:g}, n_2 = {GEARBOX['n_2']:g}, k_1 = {GEARBOX['k_1']:g} N.m/rad, "
             f"k_2 = {GEARBOX['k_2']:g} N.m/rad; PI ({a['gain_rule']}): Kp = {a['Kp']:.6f}, Ki = {a['Ki']:.6f}; "
             f"required accuracy eps = {a['accuracy']:g} rad/s"]
    for s in a["stages"]:
        largest = ("none (the other gap alone spends the accuracy)" if s["delta_max"] is None
                   else f"{s['delta_max'] * 1e3:.4f} mrad")
        lines.append(f"  stage {s['stage']}: bound_sup per unit gap {s['bound_sup_per_unit_delta']:.4f} (rad/s)/rad; "
                     f"at Delta_{s['stage']} = {s['delta'] * 1e3:g} mrad it spends {s['bound_sup_share']:.4g} rad/s "
                     f"({100 * s['bound_sup_share'] / a['bound_sup']:.0f}% of bound_sup); largest Delta_{s['stage']} "
                     f"with the other gap as it is: {largest}")
    verdict = "meets" if a["meets"] else "does not meet"
    lines.append(f"  bound_sup = {a['bound_sup']:.4g} rad/s: the gearbox {verdict} eps; stage "
                 f"{a['dominant_stage']}'s backlash costs the most")
    return "\n".join(lines)


def figure(a: dict, path: Path) -> None:
    """The admissible triangle with lines of equal bound_sup and the gearbox's gaps; the shares."""
    s1, s2 = (s["bound_sup_per_unit_delta"] for s in a["stages"])
    d1, d2 = (s["delta"] for s in a["stages"])
    eps = a["accuracy"]
    # The plane up to past both the triangle's corners and the gearbox's gaps [mrad].
    x_max = 1.2e3 * max(eps / s1, d1)
    y_max = 1.2e3 * max(eps / s2, d2)
    x, y = np.meshgrid(np.linspace(0.0, x_max, 200), np.linspace(0.0, y_max, 200))
    bound = (s1 * x + s2 * y) * 1e-3
    fig, (ax, bars) = plt.subplots(1, 2, figsize=(11, 4.6), gridspec_kw={"width_ratios": [3, 2]})
    levels = eps * np.array([0.25, 0.5, 0.75, 1.25, 1.5])
    lines = ax.contour(x, y, bound, levels=levels, colors="grey", linewidths=0.7)
    ax.clabel(lines, fmt=lambda v: f"{v:g}", fontsize=7)
    ax.fill([0.0, 1e3 * eps / s1, 0.0], [0.0, 0.0, 1e3 * eps / s2], color="tab:green", alpha=0.25,
            label=f"bound_sup <= eps = {eps:g} rad/s")
    ax.plot([1e3 * d1], [1e3 * d2], "ko", label=f"the gearbox: bound_sup = {a['bound_sup']:.3g} rad/s")
    for s, marker in zip(a["stages"], ("s", "^")):
        if s["delta_max"] is not None:
            point = (1e3 * s["delta_max"], 1e3 * d2) if s["stage"] == 1 else (1e3 * d1, 1e3 * s["delta_max"])
            ax.plot(*point, marker, color="tab:blue", label=f"largest Delta_{s['stage']}, the other as it is")
    ax.set_xlim(0.0, x_max)
    ax.set_ylim(0.0, y_max)
    ax.set_xlabel("Delta_1, motor-side mesh [mrad]")
    ax.set_ylabel("Delta_2, load-side mesh [mrad]")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("half gaps that meet the accuracy (lines: bound_sup [rad/s])", fontsize=10)
    shares = [s["bound_sup_share"] for s in a["stages"]]
    bars.bar(["stage 1\n(motor side)", "stage 2\n(load side)"], shares, color=["tab:orange", "tab:purple"])
    bars.axhline(eps, color="tab:green", lw=1.0, label="eps")
    bars.set_ylabel("share of bound_sup at the gearbox's gaps [rad/s]")
    bars.legend(fontsize=8)
    bars.set_title("which mesh's backlash costs the accuracy", fontsize=10)
    fig.suptitle(f"Two-stage gearbox (n_1 = {GEARBOX['n_1']:g}, n_2 = {GEARBOX['n_2']:g}) under the PI speed loop")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run(out: Path) -> int:
    """The answer, its summary, DIR/two_stage.json and DIR/two_stage.png; returns the exit status."""
    started = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    a = answer()
    print(summary(a))
    json_path, png = out / "two_stage.json", out / "two_stage.png"
    json_path.write_text(json.dumps(a, indent=1) + "\n", encoding="utf-8")
    figure(a, png)
    print(f"wrote {json_path}, {png} in {time.perf_counter() - started:.1f} s")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m backlash_fmu.demo.two_stage", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("results"), help="output directory (default: results)")
    return run(ap.parse_args(argv).out)


if __name__ == "__main__":
    raise SystemExit(main())
