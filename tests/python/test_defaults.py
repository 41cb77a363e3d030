"""An FMU used as shipped: instantiate, initialise with the start values, step.

Run in a child process with a time limit, so that a hang is reported as a failure instead of
stopping the suite (bad or default input never crashes or hangs: docs/model.md §4, refusals
and limits)."""

from __future__ import annotations

import json
import math
import subprocess
import sys

SCRIPT = r"""
import json, sys
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave
path, unzipdir = sys.argv[1:3]
md = read_model_description(path)
vr = {v.name: v.valueReference for v in md.modelVariables}
s = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier,
              instanceName="defaults")
s.instantiate()
s.setupExperiment(startTime=0.0)
s.enterInitializationMode()
s.exitInitializationMode()
names = ["theta_m", "omega_m", "theta_L", "omega_L", "psi", "bound", "bound_paper", "bound_sup"]
s.setReal([vr["tau_m"]], [1.0])
for k in range(10):
    s.doStep(k * 1e-3, 1e-3)
print(json.dumps(dict(zip(names, s.getReal([vr[n] for n in names])))))
s.terminate()
s.freeInstance()
"""
LIMIT_S = 30.0


def test_start_values_initialise_and_step_promptly(fmu):
    """The session's unpacked copy is reused (no temporary files left behind on a timeout)."""
    try:
        done = subprocess.run(
            [sys.executable, "-c", SCRIPT, str(fmu.path), fmu.unzipdir],
            capture_output=True,
            text=True,
            timeout=LIMIT_S,
        )
    except subprocess.TimeoutExpired:
        raise AssertionError(f"{fmu.model}: default initialisation + 10 steps took over {LIMIT_S} s") from None
    assert done.returncode == 0, done.stderr
    values = json.loads(done.stdout.strip().splitlines()[-1])
    finite = {k: v for k, v in values.items() if k != "bound_sup"}
    assert all(math.isfinite(v) for v in finite.values()), values
    assert values["omega_m"] > 0.0, "a positive motor torque must spin the motor up"
