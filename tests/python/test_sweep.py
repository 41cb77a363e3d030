"""The tolerance sweep (backlash_fmu.sweep, `python -m backlash_fmu.sweep`): the same table
serially, on a LocalCluster, on a real `dask scheduler` with two `dask worker` processes, after
a worker is killed mid-run, and after the client itself is killed and the sweep resumed; a
worker that joins mid-sweep gets tasks; bad configs, an unreachable scheduler and a table of
another seed refused in one line before any work, also by the check that runs with the standard
library only; the defaults are the design answer's; the pieces (the chunk sizes, the lazy draws,
the table put in order) on their own.

Every server binds to 127.0.0.1. The workers run from an empty directory: they import
backlash_fmu as installed (the interpreter's, as on a worker host where it is pip-installed;
PYTHONPATH passed on when set) and get the FMU archive from the client, once each.
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
from backlash_fmu import design, twin
from backlash_fmu.fmu import fmu_path
from backlash_fmu.sweep import config as sweep_config
from backlash_fmu.sweep import engine, report, table

from archives import REPO

# The check that `cargo xtask sweep` runs by path with the base python3 before building.
CHECK = REPO / "python" / "backlash_fmu" / "sweep" / "check.py"

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


def sweep_args(out: Path, config: Path, *extra: str, samples: int = SAMPLES) -> list[str]:
    return [sys.executable, "-m", "backlash_fmu.sweep", "--fmu", str(fmu_path("BacklashShaft")), "--samples",
            str(samples), "--seed", str(SEED), "--config", str(config), "--out", str(out), "--no-progress", *extra]


def sweep(out: Path, config: Path, *extra: str, timeout: float = 120, samples: int = SAMPLES
          ) -> subprocess.CompletedProcess:
    """`python -m backlash_fmu.sweep` in a session of its own, so that a timeout also ends its
    LocalCluster."""
    args = sweep_args(out, config, *extra, samples=samples)
    with subprocess.Popen(args, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
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
    """A `dask scheduler` and `workers` `dask worker` processes (no nanny: a killed worker stays
    dead), all on 127.0.0.1; every process is killed on teardown."""

    def __init__(self, workdir: Path, workers: int = 2):
        self.address = f"tcp://127.0.0.1:{free_port()}"
        self.procs: list[subprocess.Popen] = []
        # TMPDIR: what the workers unpack stays under the test's directory, also when they are killed.
        env = dict(os.environ, TMPDIR=str(workdir))
        self.common = dict(cwd=workdir, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port = self.address.rsplit(":", 1)[1]
        self.procs.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", port,
             "--no-dashboard", "--dashboard-address", "127.0.0.1:0"], **self.common))
        self.workers: list[subprocess.Popen] = []
        for i in range(workers):
            self.add_worker(f"w{i}")

    def add_worker(self, name: str) -> subprocess.Popen:
        """One more `dask worker` process, named `name`."""
        worker = subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", self.address, "--host", "127.0.0.1",
             "--nthreads", "1", "--no-nanny", "--no-dashboard",
             "--dashboard-address", "127.0.0.1:0", "--name", name], **self.common)
        self.workers.append(worker)
        self.procs.append(worker)
        return worker

    def client(self):
        from distributed import Client

        return Client(self.address, timeout=30)

    def wait_ready(self, timeout: float = 60.0) -> dict:
        """The scheduler's view of its workers once all have joined."""
        from distributed import Client

        deadline = time.monotonic() + timeout
        while True:
            try:
                with Client(self.address, timeout=5) as c:
                    c.wait_for_workers(len(self.workers), timeout=max(1.0, deadline - time.monotonic()))
                    return c.scheduler_info(n_workers=-1)["workers"]
            except (OSError, TimeoutError):
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.5)

    def close(self):
        # The workers first, while the scheduler is there to take their goodbye (a worker whose
        # scheduler closes under it as it stops may linger for seconds), then the scheduler.
        for group in (self.workers, self.procs[:1]):
            for p in group:
                if p.poll() is None:
                    p.terminate()
            for p in group:
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
    # Both workers of this cluster ran samples, and the scheduler counted every task.
    execution = json.loads((tmp_path / "out" / "summary.json").read_text())["execution"]
    ran, tasks = execution["samples_per_worker"], execution["tasks_per_worker"]
    assert set(ran) == set(workers) and all(n >= 1 for n in ran.values()) and sum(ran.values()) == SAMPLES
    assert set(tasks) == set(workers) and sum(tasks.values()) < SAMPLES, tasks  # several samples a task
    with cluster.client() as c:
        counts = c.run_on_scheduler(lambda dask_scheduler: dict(dask_scheduler.task_prefixes["sweep"].state_counts))
    assert sum(counts.values()) >= sum(tasks.values()), counts


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
    fmu_bytes = fmu_path("BacklashShaft").read_bytes()
    outcome = engine.run_dask(fmu_bytes, draws, cfg.settings(), scheduler=cluster.address, progress=False,
                              after_first=kill)
    assert killed and victim.poll() is not None
    # Only the first task's rows had arrived when the worker died: whatever else it had computed
    # was lost with it and computed again by the survivor.
    assert outcome.samples_per_worker.get(victim_address, 0) <= engine.PROBE, outcome.samples_per_worker
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


# Run by path under a guard that refuses every import outside the standard library: the check
# needs neither the package's dependencies nor the package itself installed.
STDLIB_ONLY = """
import runpy, sys
class Guard:
    def find_spec(self, name, path=None, target=None):
        top = name.split(".")[0]
        if top not in sys.stdlib_module_names and not top.startswith("_backlash_fmu_sweep_check"):
            raise ImportError(f"not in the standard library: {name}")
sys.meta_path.insert(0, Guard())
sys.argv = sys.argv[1:]
runpy.run_path(sys.argv[0], run_name="__main__")
"""


def check(*args: str) -> subprocess.CompletedProcess:
    """check.py run by path as `cargo xtask sweep` runs it, in isolated mode (no PYTHONPATH, no
    user site) and with the standard library only."""
    return subprocess.run([sys.executable, "-I", "-c", STDLIB_ONLY, str(CHECK), *args], cwd=REPO,
                          capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize("text, says", [
    ("[parameters]\nk = { low = 220.0, high = 180.0 }\n", "inverted range"),
    ("[loop]\nKp = -1.0\n", "parameters.Kp: must be >= 0"),
    ("[reference]\nfrequency = -1.0\n", "reference.frequency: must be >= 0"),
    ("[run]\nh = 2.0\n", "run.h = 2.0 is longer than run.horizon = 1.5"),
])
def test_the_check_by_path_refuses_a_bad_config_with_the_standard_library_only(tmp_path, text, says):
    """The same one line and status 2 as the sweep itself, without the design's defaults."""
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    done = check("--samples", "2", "--seed", "1", "--config", str(bad), "--out", str(tmp_path / "out"))
    assert done.returncode == 2, done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: config {bad}: ") and says in lines[0], done.stderr
    itself = sweep(tmp_path / "out", bad, "--serial", timeout=60)
    assert itself.returncode == 2 and itself.stderr == done.stderr
    assert not (tmp_path / "out").exists()


def test_the_check_by_path_accepts_a_good_config_with_the_standard_library_only(tmp_path, config_file):
    done = check("--samples", "2", "--seed", "1", "--config", str(config_file), "--out", str(tmp_path / "out"))
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert not (tmp_path / "out").exists()


def test_cargo_xtask_sweep_refuses_a_bad_config_before_building(tmp_path):
    """The config is checked by python/backlash_fmu/sweep/check.py (run by path with the base
    python3, standard library only) before the FMUs, the venv and the package are built: the
    refusal is the sweep's one line, and no build step ran."""
    bad = tmp_path / "bad.toml"
    bad.write_text("[parameters]\nk = { low = 220.0, high = 180.0 }\n")
    cargo = os.environ.get("CARGO", "cargo")
    done = subprocess.run([cargo, "xtask", "sweep", "--samples", "2", "--seed", "1", "--config", str(bad),
                           "--out", str(tmp_path / "out")], cwd=REPO, capture_output=True, text=True,
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


def test_the_defaults_are_the_design_answers_rig_gains_and_reference():
    """The default config is the design answer for the shaft at the default accuracy,
    `backlash_fmu.design("shaft", accuracy=0.02)`: its plant as the nominal drive, its gains, and
    the mean natural frequency of its poles; the wear range, the tolerances, the amplitude and
    the run are the sweep's own.

    The design's gains and poles are then checked independently (numpy's eig of A_cl,
    docs/model.md §3): the gains attain the answer's min_damping_ratio, and the frequency is the
    poles' mean natural frequency, both to the round-off of the poles. Bauer-Fike: a computed
    pole lies within cond(V) eps |A| of an exact one; the design's own poles add as much again."""
    from reference_bound import loop_matrices
    from rigs import plant_of

    d = design("shaft", accuracy=sweep_config.DESIGN_ACCURACY)
    assert d["accuracy"] == 0.02
    cfg = sweep_config.load(None)
    plant = d["plant"]
    dist = cfg.distributions
    Fixed, Uniform = sweep_config.Fixed, sweep_config.Uniform
    assert (dist["J_m"], dist["b_m"], dist["b_L"]) == (Fixed(plant["J_m"]), Fixed(plant["b_m"]), Fixed(plant["b_L"]))
    assert dist["k"] == Uniform(plant["k"] * (1 - 0.10), plant["k"] * (1 + 0.10))
    assert dist["J_L"] == Uniform(plant["J_L"] * (1 - 0.05), plant["J_L"] * (1 + 0.05))
    assert dist["Delta"] == Uniform(0.5e-3, 3e-3)
    assert (dist["Kp"], dist["Ki"]) == (Fixed(d["Kp"]), Fixed(d["Ki"]))
    assert cfg.accuracy == d["accuracy"] and (cfg.horizon, cfg.h) == (1.5, 1e-3)
    assert cfg.amplitude == twin.SPEED
    assert cfg.frequency == twin.reference_frequency(d["poles"])

    rig = {name: plant[name] for name in ("J_m", "J_L", "b_m", "b_L", "k", "Delta")}
    A, _, _ = loop_matrices(plant_of("BacklashShaft", rig), d["Kp"], d["Ki"])
    lam, V = np.linalg.eig(A)
    poles = np.delete(lam, np.argmin(np.abs(lam)))  # without the free position's 0
    pole_error = 2 * np.linalg.cond(V) * np.finfo(float).eps * np.linalg.norm(A, 2)
    # zeta = -Re p / |p| moves by at most 2 |dp| / |p|.
    zeta = float(np.min(-poles.real / np.abs(poles)))
    assert abs(zeta - d["min_damping_ratio"]) <= 2 * pole_error / np.min(np.abs(poles)), (zeta, d["min_damping_ratio"])
    frequency = twin.reference_frequency([(p.real, p.imag) for p in poles])
    assert abs(cfg.frequency - frequency) <= pole_error / (2 * math.pi)


# ------------------------------------------------------------------------------------------
# Large sweeps: resuming after the client is killed, a worker joining mid-sweep, the pieces
# ------------------------------------------------------------------------------------------

# Enough samples of a short run that a sweep in tasks of 2 is still running when it is killed.
RESUME_SAMPLES = 120
SHORT_CONFIG = """\
[run]
horizon = 0.3
"""
# Enough samples that one worker is still busy when a second one has started and joined.
LATE_SAMPLES = 300


@pytest.fixture(scope="module")
def short_config(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("sweep_short") / "short.toml"
    path.write_text(SHORT_CONFIG)
    return path


def rows_in(path: Path) -> int:
    """The complete rows of a table being written (its lines but the header and a torn last one)."""
    try:
        return max(0, path.read_bytes().count(b"\n") - 1)
    except FileNotFoundError:
        return 0


def wait_for_rows(path: Path, proc: subprocess.Popen, rows: int, timeout: float = 120) -> None:
    deadline = time.monotonic() + timeout
    while rows_in(path) < rows:
        assert proc.poll() is None, f"the sweep ended before it wrote {rows} rows: {proc.stderr.read()}"
        assert time.monotonic() < deadline, f"no {rows} rows in {path} after {timeout} s"
        time.sleep(0.02)


def test_a_sweep_whose_client_is_killed_resumes_to_the_uninterrupted_table(tmp_path, short_config):
    """The client (and its LocalCluster) killed with SIGKILL once some rows are written: the rows
    are in samples.csv, and --resume runs only the others, to the very table of an
    uninterrupted run of the same seed, byte for byte."""
    import json

    whole = tmp_path / "whole"
    done = sweep(whole, short_config, "--serial", samples=RESUME_SAMPLES)
    assert done.returncode == 0, done.stderr

    out = tmp_path / "out"
    args = sweep_args(out, short_config, "--workers", "2", "--chunk", "2", samples=RESUME_SAMPLES)
    with subprocess.Popen(args, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          start_new_session=True) as proc:
        try:
            wait_for_rows(out / "samples.csv", proc, 10)
        finally:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)
    partial = rows_in(out / "samples.csv")
    assert 10 <= partial < RESUME_SAMPLES, partial

    resumed = sweep(out, short_config, "--workers", "2", "--resume", samples=RESUME_SAMPLES)
    assert resumed.returncode == 0, resumed.stderr
    assert f"resumed: {partial} samples were in" in resumed.stdout, resumed.stdout
    assert (out / "samples.csv").read_bytes() == (whole / "samples.csv").read_bytes()
    execution = json.loads((out / "summary.json").read_text())["execution"]
    assert (execution["samples_run"], execution["samples_resumed"]) == (RESUME_SAMPLES - partial, partial)


def test_resume_refuses_a_table_of_another_seed_or_config_in_one_line(tmp_path, short_config):
    out = tmp_path / "out"
    assert sweep(out, short_config, "--serial", samples=3).returncode == 0
    before = (out / "samples.csv").read_bytes()
    other = tmp_path / "other.toml"
    other.write_text("[run]\nhorizon = 0.2\n")
    for extra, says in ((("--seed", "8"), f"holds samples of seed {SEED}, not 8"),
                        (("--config", str(other)), "holds samples of another config file"),
                        (("--accuracy", "0.03"), "holds samples of another config (")):
        done = sweep(out, short_config, "--serial", "--resume", *extra, samples=3, timeout=60)
        assert done.returncode == 2, done.stderr
        lines = done.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: --resume: ") and says in lines[0], done.stderr
        assert (out / "samples.csv").read_bytes() == before
    # The pre-flight check (standard library only) refuses the seed as well.
    checked = check("--samples", "3", "--seed", "8", "--config", str(short_config), "--out", str(out), "--resume")
    assert checked.returncode == 2 and f"seed {SEED}, not 8" in checked.stderr, checked.stderr
    # The same seed and config resume: nothing is left to run.
    again = sweep(out, short_config, "--serial", "--resume", samples=3, timeout=60)
    assert again.returncode == 0 and "resumed: 3 samples" in again.stdout, again.stderr
    assert (out / "samples.csv").read_bytes() == before


def test_a_worker_that_joins_mid_sweep_gets_tasks(tmp_path, config_file):
    """A cluster of one worker; once the sweep's first rows are in, a second `dask worker` starts:
    it gets the archive as it joins and runs samples."""
    import json

    workdir = tmp_path / "workers"
    workdir.mkdir()
    cluster = Cluster(workdir, workers=1)
    try:
        cluster.wait_ready()
        out = tmp_path / "out"
        args = sweep_args(out, config_file, "--scheduler", cluster.address, samples=LATE_SAMPLES)
        with subprocess.Popen(args, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              start_new_session=True) as proc:
            try:
                wait_for_rows(out / "samples.csv", proc, 1)
                cluster.add_worker("late")
                stdout, stderr = proc.communicate(timeout=180)
            finally:
                if proc.poll() is None:
                    os.killpg(proc.pid, signal.SIGKILL)
        assert proc.returncode == 0, stderr
        with cluster.client() as c:
            workers = c.scheduler_info(n_workers=-1)["workers"]
        late = next(address for address, w in workers.items() if w["name"] == "late")
        ran = json.loads((out / "summary.json").read_text())["execution"]["samples_per_worker"]
        assert ran.get(late, 0) >= 1 and sum(ran.values()) == LATE_SAMPLES, ran
        assert [int(line.split(",", 1)[0]) for line in (out / "samples.csv").read_text().splitlines()[1:]] \
            == list(range(LATE_SAMPLES))
    finally:
        cluster.close()


def test_chunks_are_sized_from_the_measured_time_of_a_sample():
    c = engine.Chunker()
    assert c.size(10_000, 2) == engine.PROBE and c.first is None
    c.record(4, 0.125)  # 31.25 ms a sample
    # At most TASK_SECONDS (32 samples), at least MIN_TASK_SECONDS (7), else the samples left
    # over TASKS_PER_WORKER tasks per worker thread; never more than are left.
    assert (engine.TASK_SECONDS, engine.MIN_TASK_SECONDS, engine.TASKS_PER_WORKER) == (1.0, 0.2, 4)
    assert c.size(10_000, 2) == 32 and c.first == 32
    assert c.size(200, 2) == 25
    assert c.size(40, 2) == 7
    assert c.size(5, 2) == 5
    assert c.largest == 32
    fixed = engine.Chunker(7)
    assert (fixed.size(100, 2), fixed.size(3, 2), fixed.first) == (7, 3, 7)


@pytest.mark.parametrize("model", sweep_config.MODELS)
def test_the_lazy_draws_are_config_draws_less_the_samples_done(model):
    cfg = sweep_config.load(None, model=model)
    whole = cfg.draw(50, SEED)
    assert list(engine.draw(cfg, 50, SEED)) == list(enumerate(whole))
    done = [(0, 3), (10, 20), (45, 50)]
    assert list(engine.draw(cfg, 50, SEED, done)) == [
        (i, params) for i, params in enumerate(whole) if not any(a <= i < b for a, b in done)]


def test_the_table_is_put_in_order_from_its_runs_and_a_torn_line_is_cut(tmp_path):
    rows = [{"sample": i, "x": i * 0.1, "meets": i % 2 == 0} for i in range(10)]
    writer = table.Writer(tmp_path, {"format": table.FORMAT, "seed": 1})
    for group in ([4, 5, 6], [0, 1], [7, 8, 9], [2, 3], [5]):  # the last one a task's rows received twice
        writer.write([rows[i] for i in group])
    writer.close()
    with open(tmp_path / table.TABLE, "ab") as f:
        f.write(b"3,0.30000")  # a write cut short
    state = table.resume_state(tmp_path, {"seed": 1}, 10)
    assert (state.done, state.torn, state.rows) == ([(0, 10)], True, 10)
    with pytest.raises(table.TableError, match="seed 1, not 2"):
        table.resume_state(tmp_path, {"seed": 2}, 10)
    with pytest.raises(table.TableError, match="beyond --samples 9"):
        table.resume_state(tmp_path, {"seed": 1}, 9)
    table.finish(tmp_path, 10)
    expected = tmp_path / "expected.csv"
    table.write_table(expected, rows)
    assert (tmp_path / table.TABLE).read_bytes() == expected.read_bytes()
    assert list(table.Rows(tmp_path / table.TABLE)) == rows
    gap = tmp_path / "gap"
    writer = table.Writer(gap, {"format": table.FORMAT, "seed": 1})
    writer.write([rows[i] for i in (0, 1, 3)])
    writer.close()
    with pytest.raises(table.TableError, match="sample 2 is missing"):
        table.finish(gap, 4)
