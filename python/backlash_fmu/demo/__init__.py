"""The demonstration: the paper's closed-loop experiments (Figs. 11-13) reproduced with
BacklashShaft.fmu and its open design question answered, then a web line on BacklashWeb.fmu
against its tension bound, the rig identified from a noisy run, and a low-speed reversal with
bearing friction.

    python -m backlash_fmu.demo [--out DIR] [--short]

In order (`main`):

1. the design answers, computed here with `backlash_fmu.design`: the load-speed answer for the
   paper's rig (`shaft_design`: accuracy 0.02 m/s, Delta = 0.775 mm) written to DIR/design.json,
   and the web-tension answer for a film line on BacklashBelt's drive (`web_design`: eps_T =
   20 N) written to DIR/design_web.json, as `backlash design ... --json` prints them;
2. `paper_experiments.run`: twin BacklashShaft instances (with and without backlash) under a PI
   speed loop closed through fmpy: DIR/run_*.csv, DIR/summary.csv, DIR/sampling.csv,
   DIR/design_bound_sup.csv and the figures DIR/fig11-13_*.png, DIR/design_bound_sup.png; and
   one case with a damper in the shaft beside the same case without, against the spring-damper
   twin (DIR/damped.csv, DIR/run_damped_sine.csv);
3. `master.run`: the sine experiment as the shipped system `sine` (BacklashShaft under
   BacklashController) in the co-simulation master ecos, against the loop closed here with
   ecos's timing and beside step 2's run: DIR/master_sine.csv, DIR/master_sine.png;
4. `web_line.run`: twin BacklashWeb lines (Delta and Delta = 0) under the speed and tension PI
   loops: DIR/web_line.csv, DIR/web_line.png, and the web answer read back through the FMU.
5. `identify_rig.run`: the paper's rig (BacklashShaft at its defaults) driven by reversing
   torque steps, its speeds logged with noise and quantisation, then identified with
   `backlash_fmu.identify` (Delta, k, J_L, b_L, u0 with 95% intervals, beside the true values)
   and the accuracy question answered by `backlash identify --accuracy`: DIR/identify_run.csv,
   DIR/identify.csv, DIR/identify.json.
6. `friction_reversal.run`: a low-speed reversal on the paper's rig under the PI speed loop, with
   bearing friction with stiction (docs/model.md §12) and without: motor and load speeds, the
   sliding modes, the lost motion: DIR/friction_reversal.csv, DIR/friction_reversal.png.
7. `two_stage.run`: a gearbox of two unequal meshes under the PI speed loop, and which mesh's
   backlash costs the accuracy: each stage's bound_sup per unit of its gap, its share, the
   admissible triangle of gaps (`backlash_fmu.design("two-stage", ...)`): DIR/two_stage.json,
   DIR/two_stage.png.

DIR defaults to results; `--short` (or CI=true in the environment) shortens the horizons. The
archives are those of $BACKLASH_FMU_DIR when it is set, else the package's own
(backlash_fmu.fmu.fmu_path). `cargo xtask demo [--short]` builds the FMUs, installs the package
and runs this.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import Any

__all__ = ["main", "shaft_design", "web_design", "short_mode",
           "DEMO_ACCURACY", "DEMO_DELTA", "DEMO_TENSION_ACCURACY"]

# Required load-speed accuracy of the design question [m/s on the rectilinear rig].
DEMO_ACCURACY = 0.02
# Half gap for the stiffness search: the paper's smallest gap, 1.55 mm, read as 2 Delta.
DEMO_DELTA = 0.775e-3
# Required web-tension accuracy of the web line [N]: near what BacklashBelt's gap gives
# (bound_T_sup 17.4 N at Delta = 50 um), so that Delta_max and the stiffness window are both in view.
DEMO_TENSION_ACCURACY = 20.0


def shaft_design() -> str:
    """The load-speed design answer for the paper's rig as JSON text: gains by the best-damped
    rule, delta_max and the stiffness window for DEMO_ACCURACY at Delta = DEMO_DELTA."""
    from .. import design_json

    return design_json("shaft", accuracy=DEMO_ACCURACY, Delta=DEMO_DELTA)


def web_design() -> str:
    """The web-tension design answer for the film line on BacklashBelt's drive (the defaults of
    BacklashWeb) as JSON text: delta_max and the K_b window for DEMO_TENSION_ACCURACY, no
    tension loop."""
    from .. import design_json

    return design_json("web", tension_accuracy=DEMO_TENSION_ACCURACY)


def short_mode(short: bool) -> bool:
    """`--short`, or CI=true (or 1) in the environment."""
    return short or os.environ.get("CI", "") in ("true", "1")


def web_summary(answer: dict[str, Any]) -> str:
    """The web answer in a few lines of text (the numbers of design_web.json a reader looks for)."""
    plant = {k: v for k, v in answer["plant"].items() if k != "form"}
    tension = ("none" if answer["Kp_T"] == answer["Ki_T"] == 0
               else f"Kp_T = {answer['Kp_T']!r}, Ki_T = {answer['Ki_T']!r}")
    speed = "" if answer["accuracy"] is None else f", speed accuracy eps = {answer['accuracy']:g} rad/s"
    lines = [
        "plant (web line: belt drive and one web span): " + ", ".join(f"{k} = {v!r}" for k, v in plant.items()),
        f"speed PI ({answer['gain_rule']}): Kp = {answer['Kp']:.6f}, Ki = {answer['Ki']:.6f}; tension PI: {tension}",
        f"required: tension accuracy eps_T = {answer['tension_accuracy']:g} N{speed}",
        f"per unit Delta: bound_T_sup {answer['bound_T_sup_per_unit_delta']:.9f} N/m, bound_sup "
        f"{answer['bound_sup_per_unit_delta']:.9f} (rad/s)/m; at Delta = {plant['Delta']!r} m: bound_T_sup = "
        f"{answer['bound_T_sup_at_delta']:.6e} N, bound_sup = {answer['bound_sup_at_delta']:.6e} rad/s",
    ]
    alone = f"tension alone {answer['delta_max_tension']:.9e} m"
    if answer["delta_max_speed"] is not None:
        alone += f", speed alone {answer['delta_max_speed']:.9e} m"
    lines.append(f"delta_max = {answer['delta_max']:.9e} m ({alone})")
    met = answer["bound_T_sup_at_delta"] <= answer["tension_accuracy"] and (
        answer["accuracy"] is None or answer["bound_sup_at_delta"] <= answer["accuracy"])
    if not met:
        lines.append(f"  no: an accuracy is not met at the nominal K_b = {plant['K_b']!r} N/m and Delta = "
                     f"{plant['Delta']!r} m")
    else:
        for key, name, side in (("k_min", "min", "lower"), ("k_max", "max", "upper")):
            edge = f"none within the scan (feasible to its {side} edge)" if answer[key] is None else \
                f"{answer[key]:.6f} N/m"
            lines.append(f"  K_b {name} = {edge}")
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------
# Main
# ------------------------------------------------------------------------------------------


def _step(message: str) -> None:
    print(f"\n==> {message}", flush=True)


def _shown(path: Path) -> str:
    """`path` relative to the working directory when it is below it."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def main(argv: list[str] | None = None) -> int:
    """`python -m backlash_fmu.demo [--out DIR] [--short]`: the design answers, then both
    experiments; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m backlash_fmu.demo", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("results"), help="output directory (default: results)")
    ap.add_argument("--short", action="store_true", help="shorter horizons (also when the environment has CI=true)")
    args = ap.parse_args(argv)
    short = short_mode(args.short)
    started = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)

    _step("design: gains by the best-damped rule, delta_max and k_min")
    answer_text = shaft_design()
    answer = json.loads(answer_text)
    print(f"PI gains (best-damped rule): Kp = {answer['Kp']:.6f} N.s/m, Ki = {answer['Ki']:.6f} N/m; "
          f"smallest damping ratio {answer['min_damping_ratio']:.4f}")
    design_json = args.out / "design.json"
    design_json.write_text(answer_text + "\n", encoding="utf-8")
    print(f"wrote {_shown(design_json)} ({time.perf_counter() - started:.2f} s)")

    _step("web line: delta_max and the K_b window for a tension accuracy")
    web_text = web_design()
    web_answer = json.loads(web_text)
    print(web_summary(web_answer))
    design_web_json = args.out / "design_web.json"
    design_web_json.write_text(web_text + "\n", encoding="utf-8")
    print(f"wrote {_shown(design_web_json)} ({time.perf_counter() - started:.2f} s)")

    from . import master, paper_experiments, web_line

    _step("paper experiments through fmpy")
    status = paper_experiments.run(answer, args.out, short)
    if status != 0:
        return status
    _step("the sine experiment in a co-simulation master: ecos runs the shipped system, beside the run above")
    status = master.run(args.out, short)
    if status != 0:
        return status
    _step("web line through fmpy: twin runs against bound_T, the design answer through the FMU")
    status = web_line.run(web_answer, args.out, short, design_name=design_web_json.name)
    if status != 0:
        return status
    from . import identify_rig

    _step("identification: the paper's rig from a noisy run, and the accuracy question")
    status = identify_rig.run(args.out, short)
    if status != 0:
        return status
    from . import friction_reversal

    _step("bearing friction: a low-speed reversal on the paper's rig, with stiction and without")
    status = friction_reversal.run(answer, args.out, short)
    if status != 0:
        return status
    from . import two_stage

    _step("two stages: which mesh's backlash costs the accuracy")
    status = two_stage.run(args.out)
    if status != 0:
        return status
    print(f"\ndemo finished in {time.perf_counter() - started:.1f} s")
    return 0
