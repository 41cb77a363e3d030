"""The scripts of examples/, run as a user runs them (`python examples/<name>.py`), each with a
short horizon so that it takes seconds: what they print is checked, not only their exit status.

They run on the archives under test (the installed package's, or $BACKLASH_FMU_DIR's), in a fresh
interpreter from a scratch directory, so that an example that only works from the repository
root fails here.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys

from archives import REPO
from backlash_fmu.fmu import archive_dir

EXAMPLES = REPO / "examples"


def run(tmp_path, name: str, *args: str) -> str:
    # The archives under test, named absolutely: the script runs in another directory.
    env = dict(os.environ, BACKLASH_FMU_DIR=str(archive_dir().resolve())) if "BACKLASH_FMU_DIR" in os.environ \
        else None
    done = subprocess.run([sys.executable, str(EXAMPLES / name), *args], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600, env=env)
    assert done.returncode == 0, f"{name} failed ({done.returncode}):\n{done.stdout}\n{done.stderr}"
    return done.stdout


def number(pattern: str, text: str) -> float:
    found = re.search(pattern, text)
    assert found, f"no match for {pattern!r} in:\n{text}"
    return float(found.group(1))


def test_every_example_is_run_here():
    tested = {"design_then_simulate.py", "ecos_loop.py", "local_sweep.py"}
    assert {path.name for path in EXAMPLES.glob("*.py")} == tested


def test_design_then_simulate(tmp_path):
    import backlash_fmu

    out = run(tmp_path, "design_then_simulate.py", "--horizon", "1")
    delta = number(r"delta_max = (\S+) ", out)
    assert delta == float(f"{backlash_fmu.design('shaft', accuracy=0.02)['delta_max']:.4e}")
    worst = number(r"over 1\.0 s = (\S+) m/s", out)
    bound_sup = number(r"bound_sup = (\S+) m/s", out)
    # The designed drive deviates measurably (the reference reverses at the loop's own
    # frequency), yet within the guarantee, which equals the accuracy at delta_max.
    assert 0.5 * 0.02 < worst <= bound_sup
    assert abs(bound_sup - 0.02) < 1e-6
    assert out.rstrip().endswith("the designed drive meets the accuracy")


def test_ecos_loop(tmp_path):
    out = run(tmp_path, "ecos_loop.py", "--steps", "1500")
    assert "plant (BacklashShaft)" in out and "controller (BacklashController)" in out
    assert "h = 0.001 s from the SSD" in out
    assert "ecos: 1500 steps to t = 1.500 s" in out
    assert number(r"largest load speed (\S+) rad/s", out) > 0.01  # the loop drives the load
    assert out.rstrip().endswith("the loop closed in Python agrees with ecos to the bit")


def test_local_sweep(tmp_path):
    out = run(tmp_path, "local_sweep.py", "--samples", "8", "--workers", "2", "--horizon", "0.2",
              "--out", "sweep")
    found = re.search(r"(\d+) of (\d+) drives meet the accuracy .* worst deviation / bound_sup = (\S+) "
                      r"\(the bound holds: True\)", out)
    assert found, out
    meeting, samples, worst = int(found.group(1)), int(found.group(2)), float(found.group(3))
    assert samples == 8 and 0 <= meeting <= 8 and 0 < worst <= 1
    # Every sample ran on a worker of the LocalCluster.
    per_worker = re.search(r"samples per worker: \[(.*)\]", out).group(1)
    assert sum(int(n) for n in per_worker.split(",")) == 8
    assert (tmp_path / "sweep" / "samples.csv").read_text().count("\n") == 9
