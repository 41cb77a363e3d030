"""A closed loop in a co-simulation master: the shipped system `sine` run by ecos.

The system (docs/close-a-loop.md) is BacklashShaft under BacklashController, the paper's sine
experiment, as SSP 1.0 packed with its FMUs (`systems/sine.ssp`, shipped with the package). ecos
reads the connections and the parameter sets from the SSD; it is given the communication step h
that the SSD states (ecos reads none itself). The same loop closed in Python, with the plant
through fmpy and the controller's PI law written out, gives the same values to the bit.

    python examples/ecos_loop.py [--steps 8000]
"""

import argparse

import numpy as np
from backlash_fmu import systems

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--steps", type=int, default=None, help="communication steps (default: to the SSD's stop time)")
args = parser.parse_args()

# The system beside the package's archives: the folder (SystemStructure.ssd, its parameter sets,
# resources/ with the FMUs) and the same zipped as sine.ssp, the file a master is given.
folder = systems.system_dir("sine")
ssp = folder.with_suffix(".ssp")
system = systems.System.read(folder)
print(f"{ssp.name}: components {[c.name + ' (' + c.model + ')' for c in system.components]}, "
      f"h = {system.step_size} s from the SSD")

# ecos runs it (systems.run_ecos passes the SSD's h as ecos's step_size).
ecos = systems.run_ecos(ssp, steps=args.steps)
omega_L = ecos.record["plant", "omega_L"]
tau_m = ecos.record["controller", "tau_m"]
print(f"ecos: {len(ecos.times)} steps to t = {ecos.times[-1] + ecos.sizes[-1]:.3f} s; "
      f"omega_L = {omega_L[-1]:.6f} rad/s, tau_m = {tau_m[-1]:.4f} N.m")
print(f"largest load speed {np.max(np.abs(omega_L)):.4f} rad/s")

# The same loop closed here, under ecos's timing: equal to the bit.
here = systems.python_loop(system, ecos.times, ecos.sizes)
assert np.array_equal(here.record["plant", "omega_L"], omega_L)
assert np.array_equal(here.record["controller", "tau_m"], tau_m)
print("the loop closed in Python agrees with ecos to the bit")
