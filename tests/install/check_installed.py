"""The package backlash_fmu as a user has it after `pip install` of the wheel or the sdist, run
with the interpreter of the venv it was installed into, from a folder outside the repository
(`cargo xtask test` runs it in two fresh venvs: the wheel's, with `--without-cargo` and a PATH
that holds no cargo or rustc, and the sdist's). Each check prints a line; the first that fails
ends the run with its reason and exit status 1.

    python tests/install/check_installed.py [--without-cargo]

What it checks:
- the package is the installed one (in this venv's site-packages), and with --without-cargo
  neither cargo nor rustc is on PATH;
- `backlash design --accuracy 0.02` answers (exit 0), and its JSON is the one design() returns;
- bad input to the command (`--accuracy nan`, an unknown command) gets exactly one `error:` line
  on stderr, nothing on stdout, and exit status 2;
- the package's own example (the indented block of its docstring) runs;
- the shipped BacklashShaft.fmu (fmu_path), simulated by fmpy's simulate_fmu with the motor inside
  the gap under a constant torque from rest, follows the closed form
  ω_m = τ/b_m·(1 − e^{−b_m t/J_m}), θ_m = τ/b_m·(t − J_m/b_m·(1 − e^{−b_m t/J_m})) to 1e-9
  relative, the load at rest (tests/importer checks the same through the `fmi` crate);
- `backlash excite` writes a reversing schedule within its limit; BacklashShaft (not at its
  defaults) driven by it with noisy speeds is identified by `backlash identify --json` and
  identify() alike, the true Delta and k within the intervals (widened to 99.9%);
- the shipped system `sine` (BacklashShaft under BacklashController), run from its .ssp by fmpy's
  SSP runner through the package's systems.run_fmpy: the load speed follows the controller's sine
  reference (its zero crossings at the reference's frequency, its peak of the amplitude's order
  over the last 4 s), and equals to the bit the
  loop closed here in Python (systems.python_loop, the PI law written a second time) on the
  runner's timing.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path


def check(what: str, condition: bool, detail: object = "") -> None:
    if not condition:
        print(f"FAILED: {what}" + (f": {detail}" if detail != "" else ""), file=sys.stderr)
        sys.exit(1)
    print(f"ok: {what}")


def command(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["backlash", *args], capture_output=True, text=True)


def installed(without_cargo: bool) -> None:
    import backlash_fmu

    where = Path(backlash_fmu.__file__).resolve()
    check("backlash_fmu is the copy installed in this venv", Path(sys.prefix).resolve() in where.parents, where)
    check("the `backlash` command is this venv's",
          Path(shutil.which("backlash") or "").resolve().parent == (Path(sys.prefix) / "bin").resolve(),
          shutil.which("backlash"))
    if without_cargo:
        check("no cargo or rustc on PATH", shutil.which("cargo") is None and shutil.which("rustc") is None,
              (shutil.which("cargo"), shutil.which("rustc")))


def design_command() -> None:
    import backlash_fmu

    out = command("design", "--accuracy", "0.02")
    check("`backlash design --accuracy 0.02` answers", out.returncode == 0 and "delta_max" in out.stdout
          and out.stderr == "", out)
    out = command("design", "--accuracy", "0.02", "--json")
    answer = json.loads(out.stdout)
    check("its JSON is design()'s", out.returncode == 0 and answer == backlash_fmu.design("shaft", accuracy=0.02))
    check("delta_max is positive and bound_sup meets the accuracy there",
          answer["delta_max"] > 0 and answer["bound_sup_per_unit_delta"] * answer["delta_max"] <= 0.02 * (1 + 1e-9),
          answer["delta_max"])
    for args in (["design", "--accuracy", "nan"], ["desing"]):
        out = command(*args)
        check(f"`backlash {' '.join(args)}`: one error line, exit status 2",
              out.returncode == 2 and out.stdout == "" and out.stderr.startswith("error: ")
              and out.stderr.count("\n") == 1, out)


def docstring_example() -> None:
    """The indented block of the package's docstring, run as written."""
    import backlash_fmu

    lines = backlash_fmu.__doc__.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("    ") and line.strip())
    block = []
    for line in lines[start:]:
        if line.strip() and not line.startswith("    "):
            break
        block.append(line)
    code = textwrap.dedent("\n".join(block))
    check("the package's docstring has an example", "backlash_fmu" in code, code)
    names: dict = {}
    exec(compile(code, "backlash_fmu.__doc__", "exec"), names)
    check("the package's docstring example runs", isinstance(names.get("answer"), dict)
          and names["answer"]["delta_max"] > 0 and Path(names["path"]).is_file(), code)


def shaft_closed_form() -> None:
    import numpy as np
    from fmpy import simulate_fmu

    import backlash_fmu

    j_m, b_m, tau, delta = 0.5, 1.0, 1.0, 10.0
    result = simulate_fmu(
        str(backlash_fmu.fmu_path("BacklashShaft")), stop_time=1.0, output_interval=1e-3,
        start_values={"J_m": j_m, "b_m": b_m, "J_L": 2.55, "b_L": 0.05, "k": 200.0, "Delta": delta,
                      "tau_m": tau, "tau_L": 0.0},
        output=["omega_m", "theta_m", "omega_L", "theta_L", "contact"])
    t = result["time"][1:]
    check("fmpy ran BacklashShaft.fmu to t = 1 s in steps of 1 ms", len(t) == 1000 and t[-1] == 1.0, t[-1:])
    decay = 1.0 - np.exp(-b_m * t / j_m)
    omega_m, theta_m = tau / b_m * decay, tau / b_m * (t - j_m / b_m * decay)
    error = max(np.max(np.abs(result["omega_m"][1:] / omega_m - 1)), np.max(np.abs(result["theta_m"][1:] / theta_m - 1)))
    check(f"omega_m and theta_m follow the closed form (largest relative deviation {error:.1e})",
          error < 1e-9 and theta_m[-1] < delta, error)
    check("the load rests and contact stays free inside the gap",
          not result["omega_L"].any() and not result["theta_L"].any() and not result["contact"].any())


def sine_system() -> None:
    import numpy as np

    from backlash_fmu import systems

    folder = systems.system_dir("sine")
    ssp = folder.parent / "sine.ssp"
    system = systems.System.read(folder)
    run = systems.run_fmpy(ssp)
    w = run.record["plant", "omega_L"]
    check(f"fmpy's SSP runner ran the shipped sine.ssp ({len(w)} steps of {system.step_size} s)",
          len(w) == system.steps and np.isfinite(w).all(), len(w))
    controller = next(c for c in system.components if c.model == systems.CONTROLLER)
    amplitude, frequency = controller.params["amplitude"], controller.params["frequency"]
    # The last 4 s: a sine at the reference's frequency crosses zero twice a period.
    tail = w[-int(round(4.0 / system.step_size)):]
    crossings = int(np.count_nonzero(np.signbit(tail[1:]) != np.signbit(tail[:-1])))
    expected = 2 * frequency * 4.0
    check(f"the load speed follows the sine reference ({crossings} zero crossings in the last 4 s at "
          f"{frequency:.4g} Hz, peak {np.max(np.abs(tail)):.3g} for an amplitude of {amplitude})",
          abs(crossings - expected) <= 1.5 and amplitude / 2 < np.max(np.abs(tail)) < 4 * amplitude, crossings)
    here = systems.python_loop(system, run.times, run.sizes)
    check("it equals to the bit the loop closed in Python on the runner's timing",
          all(np.array_equal(here.record[key], run.record[key]) for key in run.record))


def identify_command() -> None:
    """`backlash excite` writes a schedule; BacklashShaft (k = 160, Delta = 1.2e-3: not its
    defaults) driven by it through the package's driver, its speeds logged with noise, is
    identified by `backlash identify --json` and by identify() with the same answer, the true
    Delta and k within the intervals widened to 99.9% (3.29/1.96)."""
    import tempfile

    import numpy as np

    import backlash_fmu
    from backlash_fmu import fmu

    folder = Path(tempfile.mkdtemp())
    out = command("excite", "--model", "shaft", "--duration", "6", "--step", "0.005", "--torque-limit", "2",
                  "--out", str(folder / "schedule.csv"))
    check("`backlash excite` writes a schedule", out.returncode == 0, out.stderr)
    schedule = np.genfromtxt(folder / "schedule.csv", delimiter=",", names=True)
    t, tau = schedule["time"], schedule["tau_m"]
    check("it is time,tau_m within the limit and reverses", np.all(np.abs(tau) <= 2.0) and tau.min() < 0 < tau.max())
    truth = {"k": 160.0, "Delta": 1.2e-3}
    rng = np.random.default_rng(1)
    with fmu.Archive(backlash_fmu.fmu_path("BacklashShaft")) as shaft:
        inst = shaft.co_simulation("identify", {**truth, "theta_L": -0.5e-3})
        speeds = [inst.get("omega_m", "omega_L")]
        for i in range(len(t) - 1):
            inst.step(t[i], t[i + 1] - t[i], tau_m=float(tau[i]))
            speeds.append(inst.get("omega_m", "omega_L"))
        inst.free()
    speeds = np.array(speeds) + 1e-3 * rng.standard_normal((len(t), 2))
    np.savetxt(folder / "run.csv", np.column_stack([t, tau, speeds]), delimiter=",",
               header="time,tau_m,omega_m,omega_L", comments="", fmt="%.17g")
    out = command("identify", "--model", "shaft", str(folder / "run.csv"), "--json")
    check("`backlash identify --json` answers", out.returncode == 0, out.stderr)
    answer = json.loads(out.stdout)
    check("identify() gives the same answer", backlash_fmu.identify("shaft", folder / "run.csv") == answer)
    widen = 3.2905267314919255 / 1.959963984540054
    for name, true in truth.items():
        est = answer["estimates"][name]
        lo, hi = est["ci95"] or (math.nan, math.nan)
        v = est["value"]
        check(f"{name} = {v:.6g} [{lo:.6g}, {hi:.6g}] for {true:g}",
              est["identifiable"] and v - widen * (v - lo) <= true <= v + widen * (hi - v), est)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--without-cargo", action="store_true", help="also check that PATH holds no cargo or rustc")
    args = ap.parse_args()
    installed(args.without_cargo)
    design_command()
    docstring_example()
    shaft_closed_form()
    identify_command()
    sine_system()
    print("every check of the installed package passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
