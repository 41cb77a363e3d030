"""An FMU used as shipped: instantiate, initialise with the start values, step.

Run in a child process with a time limit, so that a hang is reported as a failure instead of
stopping the suite (bad or default input never crashes or hangs: docs/model.md §4, refusals
and limits)."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import archives

SCRIPT = r"""
import json, sys
from backlash_fmu.fmu import Archive
path, unzipdir, names = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
s = Archive(path, unzipdir=unzipdir).co_simulation("defaults")
s.set_inputs(tau_m=1.0)
for k in range(10):
    s.do_step(k * 1e-3, 1e-3)
print(json.dumps(dict(zip(names, s.get(*names)))))
s.free()
"""
LIMIT_S = 30.0


def test_start_values_initialise_and_step_promptly(fmu):
    """The session's unpacked copy is reused (no temporary files left behind on a timeout)."""
    try:
        done = subprocess.run(
            [sys.executable, "-c", SCRIPT, str(fmu.path), fmu.unzipdir, json.dumps(archives.real_outputs(fmu.model))],
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
