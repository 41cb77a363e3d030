"""The tolerance sweep (sweep/, `python -m sweep`): the same table serially, on a LocalCluster, on
a real `dask scheduler` with two `dask worker` processes, and after a worker is killed mid-run;
bad configs and an unreachable scheduler refused in one line before any work.

Every server binds to 127.0.0.1. The workers run from an empty directory without this package on
their path: they get the task code and the FMU archive from the client.
"""

from __future__ import annotations

import math
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import fmu_driver

sys.path.insert(0, str(fmu_driver.REPO))

from sweep import config as sweep_config  # noqa: E402
from sweep import engine, report  # noqa: E402

SAMPLES = 8
SEED = 7
# Short runs keep the file well under a minute and a half; the defaults otherwise.
CONFIG = """\
[run]
horizon = 0.6
"""


@pytest.fixture(scope="module")
def config_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("sweep_config") / "sweep.toml"
    path.write_text(CONFIG)
    return path


def sweep(out: Path, config: Path, *extra: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """`python -m sweep` in a session of its own, so that a timeout also ends its LocalCluster."""
    args = [sys.executable, "-m", "sweep", "--fmu", str(fmu_driver.fmu_path("BacklashShaft")), "--samples",
            str(SAMPLES), "--seed", str(SEED), "--config", str(config), "--out", str(out), "--no-progress", *extra]
    with subprocess.Popen(args, cwd=fmu_driver.REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          start_new_session=True) as proc:
        try:
            stdout, stderr = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            raise
    return subprocess.CompletedProcess(args, proc.returncode, stdout, stderr)


@pytest.fixture(scope="module")
def serial_table(tmp_path_factory, config_file) -> bytes:
    out = tmp_path_factory.mktemp("sweep_serial")
    done = sweep(out, config_file, "--serial")
    assert done.returncode == 0, done.stderr
    table = (out / "samples.csv").read_bytes()
    lines = table.decode().splitlines()
    assert len(lines) == SAMPLES + 1
    header = lines[0].split(",")
    assert header[0] == "sample" and "max_dev" in header and "bound_sup" in header
    return table


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Cluster:
    """A `dask scheduler` and two `dask worker` processes (no nanny: a killed worker stays dead),
    all on 127.0.0.1; every process is killed on teardown."""

    def __init__(self, workdir: Path):
        self.address = f"tcp://127.0.0.1:{free_port()}"
        self.procs: list[subprocess.Popen] = []
        # TMPDIR: what the workers unpack stays under the test's directory, also when they are killed.
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        env["TMPDIR"] = str(workdir)
        common = dict(cwd=workdir, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port = self.address.rsplit(":", 1)[1]
        self.procs.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", port,
             "--no-dashboard", "--dashboard-address", "127.0.0.1:0"], **common))
        self.workers = [subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", self.address, "--host", "127.0.0.1",
             "--nthreads", "1", "--no-nanny", "--no-dashboard",
             "--dashboard-address", "127.0.0.1:0", "--name", f"w{i}"], **common) for i in range(2)]
        self.procs += self.workers

    def client(self):
        from distributed import Client

        return Client(self.address, timeout=30)

    def wait_ready(self, timeout: float = 60.0) -> dict:
        """The scheduler's view of its workers once both have joined."""
        from distributed import Client

        deadline = time.monotonic() + timeout
        while True:
            try:
                with Client(self.address, timeout=5) as c:
                    c.wait_for_workers(2, timeout=max(1.0, deadline - time.monotonic()))
                    return c.scheduler_info(n_workers=-1)["workers"]
            except (OSError, TimeoutError):
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.5)

    def close(self):
        for p in self.procs:
            if p.poll() is None:
                p.terminate()
        for p in self.procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=30)


@pytest.fixture
def cluster(tmp_path):
    workdir = tmp_path / "workers"
    workdir.mkdir()
    c = Cluster(workdir)
    try:
        yield c
    finally:
        c.close()


def test_local_cluster_gives_the_serial_table(tmp_path, config_file, serial_table):
    done = sweep(tmp_path, config_file, "--workers", "2")
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "samples.csv").read_bytes() == serial_table
    for name in ("summary.json", "histogram.png", "deviation_vs_delta.png"):
        assert (tmp_path / name).is_file()


def test_external_cluster_gives_the_serial_table_and_ran_the_tasks(tmp_path, config_file, serial_table, cluster):
    import json

    workers = cluster.wait_ready()
    done = sweep(tmp_path / "out", config_file, "--scheduler", cluster.address, "--workers", "2")
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "out" / "samples.csv").read_bytes() == serial_table
    # Both workers of this cluster ran samples, and the scheduler counted every sample's task.
    ran = json.loads((tmp_path / "out" / "summary.json").read_text())["execution"]["tasks_per_worker"]
    assert set(ran) == set(workers) and all(n >= 1 for n in ran.values()) and sum(ran.values()) == SAMPLES
    with cluster.client() as c:
        counts = c.run_on_scheduler(lambda dask_scheduler: dict(dask_scheduler.task_prefixes["sweep"].state_counts))
    assert sum(counts.values()) >= SAMPLES, counts


def test_killed_worker_loses_no_sample(tmp_path, config_file, serial_table, cluster):
    workers = cluster.wait_ready()
    victim = cluster.workers[1]
    victim_address = next(address for address, w in workers.items() if w["name"] == "w1")
    killed = []

    def kill():
        os.kill(victim.pid, signal.SIGKILL)
        victim.wait(timeout=30)
        killed.append(victim.pid)

    cfg = sweep_config.load(config_file)
    draws = cfg.draw(SAMPLES, SEED)
    fmu_bytes = fmu_driver.fmu_path("BacklashShaft").read_bytes()
    outcome = engine.run_dask(fmu_bytes, draws, cfg.settings(), scheduler=cluster.address, progress=False,
                              after_first=kill)
    assert killed and victim.poll() is not None
    # Only the first row had arrived when the worker died: whatever else it had computed was lost
    # with it and computed again by the survivor.
    assert outcome.tasks_per_worker.get(victim_address, 0) <= 1, outcome.tasks_per_worker
    assert [r["sample"] for r in outcome.rows] == list(range(SAMPLES))
    report.write_table(tmp_path / "samples.csv", outcome.rows)
    assert (tmp_path / "samples.csv").read_bytes() == serial_table


@pytest.mark.parametrize("text, says", [
    ("[parameters]\nbeta = 1.0\n", "unknown parameter 'beta'"),
    ("[parameters]\nDelta = { low = -1e-3, high = 2e-3 }\n", "negative range"),
    ("[parameters]\nk = { low = 220.0, high = 180.0 }\n", "inverted range"),
    ("[run]\nhorizon = 0.6\nspeed = 3\n", "unknown entry 'speed'"),
])
def test_bad_config_is_refused_in_one_line(tmp_path, text, says):
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    done = sweep(tmp_path / "out", bad, "--serial", timeout=60)
    assert done.returncode == 2
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and says in lines[0], done.stderr
    assert not (tmp_path / "out").exists()


def test_cargo_xtask_sweep_refuses_a_bad_config_before_building(tmp_path):
    """The config is checked by `python3 -m sweep --check` (standard library only) before the
    FMUs and the venv are built: the refusal is the sweep's one line, and no build step ran."""
    bad = tmp_path / "bad.toml"
    bad.write_text("[parameters]\nk = { low = 220.0, high = 180.0 }\n")
    cargo = os.environ.get("CARGO", "cargo")
    done = subprocess.run([cargo, "xtask", "sweep", "--samples", "2", "--seed", "1", "--config", str(bad),
                           "--out", str(tmp_path / "out")], cwd=fmu_driver.REPO, capture_output=True, text=True,
                          timeout=900)
    assert done.returncode == 2, done.stderr
    errors = [line for line in done.stderr.splitlines() if line.startswith("error")]
    assert len(errors) == 1 and "inverted range" in errors[0], done.stderr
    assert "building the FMUs" not in done.stdout + done.stderr
    assert not (tmp_path / "out").exists()


def test_unreachable_scheduler_is_refused_in_one_line(tmp_path, config_file):
    done = sweep(tmp_path / "out", config_file, "--scheduler", "tcp://127.0.0.1:1", "--connect-timeout", "2",
                 timeout=60)
    assert done.returncode == 2
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: cannot reach the Dask scheduler"), done.stderr
    assert not (tmp_path / "out").exists()


def test_a_cluster_without_workers_is_refused_in_one_line(tmp_path, config_file, cluster):
    cluster.wait_ready()
    for w in cluster.workers:
        w.kill()
        w.wait(timeout=30)
    done = sweep(tmp_path / "out", config_file, "--scheduler", cluster.address, "--connect-timeout", "2", timeout=60)
    assert done.returncode == 2
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and "fewer than 1 worker" in lines[0], done.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("extra, says", [
    (("--seed", "-1"), "--seed: must be >= 0"),
    (("--out", "/dev/null/sweep"), "cannot write the output directory"),
])
def test_bad_arguments_are_refused_in_one_line_before_any_work(tmp_path, config_file, extra, says):
    done = sweep(tmp_path / "out", config_file, "--serial", *extra, timeout=60)
    assert done.returncode == 2
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and says in lines[0], done.stderr
    assert not (tmp_path / "out").exists()


def test_the_defaults_are_the_demos_rig_gains_and_reference():
    """The default config repeats numbers that `cargo xtask design` computes for the demo: they
    must not drift from it.

    The rig and the accuracy are decimal literals on both sides, read into the same doubles. The
    gains are not compared digit for digit: they maximise the smallest damping ratio, whose
    maximum lies on a ridge where two pole pairs meet (a near-double pole), so a fresh run on
    another machine (another libm) finds them only to about sqrt(eps) and may print other last
    digits. What the rule fixes is its value: the frozen gains must attain the fresh run's
    min_damping_ratio, and the frozen frequency must be the poles' mean natural frequency, both
    to the round-off of the poles, computed here independently (numpy's eig of A_cl, docs/model.md
    §3). Bauer-Fike: a computed pole lies within cond(V) eps |A| of an exact one; the design's own
    poles add as much again. (zeta* - zeta at gains sqrt(eps) off the ridge's top is O(eps).)"""
    from reference_bound import loop_matrices
    from rigs import plant_of
    from sweep import twin
    from test_design import design_json

    d = design_json(0.02)
    defaults = sweep_config.DEFAULT_PARAMETERS
    plant = d["plant"]
    assert (defaults["J_m"], defaults["b_m"], defaults["b_L"]) == (plant["J_m"], plant["b_m"], plant["b_L"])
    assert (defaults["k"]["nominal"], defaults["J_L"]["nominal"]) == (plant["k"], plant["J_L"])
    assert sweep_config.DEFAULT_RUN["accuracy"] == d["accuracy"]
    assert sweep_config.DEFAULT_REFERENCE["amplitude"] == twin.SPEED

    rig = {name: plant[name] for name in ("J_m", "J_L", "b_m", "b_L", "k", "Delta")}
    loop = sweep_config.DEFAULT_LOOP
    A, _, _ = loop_matrices(plant_of("BacklashShaft", rig), loop["Kp"], loop["Ki"])
    lam, V = np.linalg.eig(A)
    poles = np.delete(lam, np.argmin(np.abs(lam)))  # without the free position's 0
    pole_error = 2 * np.linalg.cond(V) * np.finfo(float).eps * np.linalg.norm(A, 2)
    # zeta = -Re p / |p| moves by at most 2 |dp| / |p|.
    zeta = float(np.min(-poles.real / np.abs(poles)))
    assert abs(zeta - d["min_damping_ratio"]) <= 2 * pole_error / np.min(np.abs(poles)), (zeta, d["min_damping_ratio"])
    frequency = twin.reference_frequency([(p.real, p.imag) for p in poles])
    assert abs(sweep_config.DEFAULT_REFERENCE["frequency"] - frequency) <= pole_error / (2 * math.pi)
