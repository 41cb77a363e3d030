"""The paper's sine experiment in a co-simulation master: the shipped system `sine` (BacklashShaft
under BacklashController, systems/sine beside the archives) run by ecos from its files, beside the
same experiment closed through fmpy here.

- ecos's run against the loop closed here under ecos's timing (backlash_fmu.systems.python_loop):
  equal to the bit;
- against the Python-closed run of the paper experiments (twin.twin_run), where the torque of the
  sample at t_k acts over [t_k, t_k + h): in a master the controller's torque is out after its
  step, so it acts one sample later; the table shows what that moves, beside the deviation the
  backlash itself makes.

Writes DIR/master_sine.csv and DIR/master_sine.png.
"""

from __future__ import annotations

import csv
import importlib.util
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .. import fmu, systems  # noqa: E402
from ..twin import twin_run  # noqa: E402
from .paper_experiments import HORIZON_FULL, HORIZON_SHORT  # noqa: E402


def run(out: Path, short: bool) -> int:
    """The sine system in ecos for the paper experiments' horizon (`short`: the short one), its
    comparisons printed and written under `out`; returns the exit status (0)."""
    if importlib.util.find_spec("ecospy") is None:
        print("ecos (PyPI ecospy) is not installed here: the master run is skipped "
              "(`cargo xtask demo` runs in a venv that has it)")
        return 0
    folder = systems.system_dir("sine")
    system = systems.System.read(folder)
    h = system.step_size
    horizon = HORIZON_SHORT if short else HORIZON_FULL
    steps = int(round(horizon / h))
    params = {c.name: c.params for c in system.components}
    plant = params["plant"]
    controller = systems.controller_parameters(folder / "resources" / f"{systems.CONTROLLER}.fmu", params["controller"])
    print(f"system {_shown(folder)}: BacklashShaft (Delta = {plant['Delta'] * 1e3:g} mm) and BacklashController "
          f"(Kp = {controller['Kp']:.6f}, Ki = {controller['Ki']:.6f}, sine {controller['amplitude']:g} at "
          f"{controller['frequency']:.4f} Hz), h = {h * 1e3:g} ms, {horizon:g} s")

    ran = systems.run_ecos(folder, steps)
    here = systems.python_loop(system, ran.times, ran.sizes)
    same = all(np.array_equal(values, here.record[key]) for key, values in ran.record.items())
    ecos_w = ran.record["plant", "omega_L"]
    print(f"  ecos against the loop closed here with ecos's timing: "
          f"{'equal to the bit' if same else 'DIFFERENT'} ({len(ecos_w)} steps, every output)")

    with fmu.Archive(folder / "resources" / "BacklashShaft.fmu") as archive:
        closed = twin_run(archive, {}, plant["Delta"], controller["Kp"], controller["Ki"],
                          systems.controller_reference(controller), horizon, h)
    # After step k the master's omega_L is at t_(k+1).
    python_w = closed.omega_L_b[1:]
    delay = float(np.max(np.abs(ecos_w - python_w)))
    backlash = float(np.max(closed.deviation))
    print(f"  ecos against the Python-closed run above (the torque without the sample of delay): "
          f"max |d omega_L| = {delay:.3e}; the backlash's own max |omega_L^b - omega_L^0| = {backlash:.3e}")

    out.mkdir(parents=True, exist_ok=True)
    t = closed.t[1:]
    with (out / "master_sine.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", "omega_L_ecos", "omega_L_python_closed", "tau_m_ecos", "tau_m_python_closed"])
        tau = ran.record["controller", "tau_m"]
        for k in range(steps):
            w.writerow([f"{t[k]:.6g}", f"{ecos_w[k]:.12g}", f"{python_w[k]:.12g}", f"{tau[k]:.9g}",
                        f"{closed.tau_b[k + 1]:.9g}"])
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    top.plot(t, ecos_w, label="ecos (systems/sine)")
    top.plot(t, python_w, "--", label="closed through fmpy (twin run)")
    top.set_ylabel("omega_L")
    top.legend()
    bottom.plot(t, ecos_w - python_w, label="ecos - fmpy-closed: the sample of delay")
    bottom.plot(t, closed.omega_L_b[1:] - closed.omega_L_0[1:], label="with - without backlash")
    bottom.set_xlabel("t [s]")
    bottom.legend()
    fig.suptitle("The paper's sine experiment in a co-simulation master (ecos)")
    fig.tight_layout()
    fig.savefig(out / "master_sine.png", dpi=110)
    plt.close(fig)
    print(f"  wrote {_shown(out / 'master_sine.csv')}, {_shown(out / 'master_sine.png')}")
    return 0 if same else 1


def _shown(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)
