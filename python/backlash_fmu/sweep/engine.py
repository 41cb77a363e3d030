"""Running the samples: in this process (serial), or in tasks of several samples each on a Dask
LocalCluster or on an existing cluster. The rows are the same whichever runs them: a sample's
row depends only on its index, its drawn parameters, the settings and the archive.

On Dask:
- the workers import this package (`pip install` it on every worker host): the task function,
  `run_chunk`, travels by reference, a few bytes per task;
- the FMU archive travels once per worker, in a worker plugin (`ArchivePlugin`) that unpacks it
  and loads its library when the worker registers it, also on a worker that joins mid-sweep;
  tasks name the archive by its digest;
- a task runs a chunk of samples; the first tasks hold PROBE samples each and measure the time
  per sample on the workers, from which the later chunks are sized (`Chunker`: a task lasts
  about TASK_SECONDS, at least MIN_TASK_SECONDS, and there are at least TASKS_PER_WORKER tasks
  per worker thread still to hand out, so that the last ones finish together); `--chunk N`
  fixes the size instead;
- the client keeps WINDOW tasks per worker thread in flight, drawing the samples of a task only
  when it is submitted, and hands each chunk's rows to `on_rows` as it completes
  (as_completed): neither the draws nor the rows of the whole sweep are ever held, and Dask's
  debugging logs, which would keep every task's message, are cut to LOG_LENGTH entries (in this
  process, and in a LocalCluster's workers);
- every process that runs samples holds the model's library open (`_hold_library`), so that
  fmpy's load and unload of it with each instance does not grow the process.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import sys
import time
from dataclasses import dataclass, field
from itertools import islice
from typing import Any, Callable, Iterable, Iterator, Sequence

from distributed.diagnostics.plugin import WorkerPlugin
from tqdm import tqdm

from .. import fmu, twin

Sample = tuple[int, dict[str, float]]

# Samples in each of the first tasks, which measure the time of a sample on the workers.
PROBE = 2
# The duration a task is sized for, and the least one (unless fewer samples are left) [s].
TASK_SECONDS = 1.0
MIN_TASK_SECONDS = 0.2
# Tasks per worker thread among the samples still to hand out (guided: the chunks shrink as the
# sweep nears its end, so that the workers finish together).
TASKS_PER_WORKER = 4
# Tasks in flight per worker thread: one running and one waiting, so a worker never idles while
# its next task travels.
WINDOW = 2
# How often the client asks the scheduler how many worker threads there are [s].
WORKERS_POLL = 1.0
# Dask's debugging logs of recent messages and transitions (distributed.admin.low-level-log-length,
# 100 000 entries by default) keep every task's message, and with it the task's samples: the
# client's (and the LocalCluster's scheduler's, which runs in the client) memory would grow with
# the sweep. A short log keeps it flat.
LOG_LENGTH = 10


@dataclass
class Outcome:
    # The rows in sample order when no `on_rows` was given, else None.
    rows: list[dict] | None
    engine: str
    # Wall time from the first task handed out to the last row received [s].
    elapsed: float
    # Starting the LocalCluster or connecting to the scheduler, sending the archive and
    # preparing the workers (imports, unpacking) [s].
    startup: float = 0.0
    scheduler: str | None = None
    # Samples run by each worker (its address, or "local").
    samples_per_worker: dict[str, int] = field(default_factory=dict)
    # Tasks run by each worker.
    tasks_per_worker: dict[str, int] = field(default_factory=dict)
    # Samples run in this call.
    samples: int = 0
    # The first chunk sized from the measured time of a sample (or --chunk), the largest one, and
    # that time [s] (compute only, on the workers: the mean over the samples measured then).
    chunk: int | None = None
    largest_chunk: int | None = None
    sample_seconds: float | None = None

    @property
    def tasks(self) -> int:
        return sum(self.tasks_per_worker.values())


class SchedulerError(RuntimeError):
    """The scheduler cannot be reached, or its workers cannot take the sweep; the message is one
    line."""


def _progress(total: int, show: bool) -> tqdm:
    return tqdm(total=total, desc="sweep", unit="sample", file=sys.stderr, disable=not show, dynamic_ncols=True)


def samples_of(draws: Sequence[dict] | Iterable[Sample]) -> Iterator[Sample]:
    """(index, parameters) pairs: a list of parameter dicts is numbered from 0; an iterable of
    pairs (what the command line gives: the samples still to run, drawn lazily) is taken as is."""
    if isinstance(draws, Sequence):
        return ((i, params) for i, params in enumerate(draws))
    return iter(draws)


def compute_rows(archive: fmu.Archive, samples: list[Sample], settings: dict) -> list[dict]:
    """The rows of these samples, in order (backlash_fmu.twin's sample_rows, or its sample_row
    one by one)."""
    many = getattr(twin, "sample_rows", None)
    if many is not None:
        return many(archive, samples, settings)
    return [twin.sample_row(archive, index, params, settings) for index, params in samples]


def draw(config: Any, samples: int, seed: int, done: Sequence[tuple[int, int]] = ()) -> Iterator[Sample]:
    """The samples of `config.draw(samples, seed)` one at a time, as (index, parameters), leaving
    out those in the sorted, disjoint intervals [start, stop) of `done` (the samples already in a
    resumed table): drawn lazily from the
    one generator, sample after sample, so that sample i has the same values as in
    `config.draw` whatever is skipped, and the client never holds every draw. The config's own
    `iter_draws(samples, seed)` when it has one; otherwise Config.draw's loop (the parameters in
    the config's order, a uniform drawn by `rng.uniform`, a fixed one drawing nothing)."""
    own = getattr(config, "iter_draws", None)
    if own is not None:
        source = own(samples, seed)
    else:
        # Config.draw's loop again, lazily: checked against it on the first samples.
        first = min(samples, 8)
        if list(_draws(config, first, seed)) != config.draw(first, seed):
            raise RuntimeError("the sweep's lazy draws differ from Config.draw: give the config an iter_draws")
        source = _draws(config, samples, seed)
    intervals = iter(done)
    skip = next(intervals, None)
    for i, params in enumerate(source):
        while skip is not None and skip[1] <= i:
            skip = next(intervals, None)
        if skip is not None and skip[0] <= i:
            continue
        yield i, params


def _draws(config: Any, samples: int, seed: int) -> Iterator[dict[str, float]]:
    import numpy as np

    from .config import PARAMETERS, Uniform

    names = tuple(getattr(config, "parameters", PARAMETERS))
    rng = np.random.default_rng(seed)
    for _ in range(samples):
        values = {}
        for name in names:
            d = config.distributions[name]
            values[name] = float(rng.uniform(d.low, d.high)) if isinstance(d, Uniform) else float(d.value)
        yield values


class _Sink:
    """Where rows go: `on_rows`, or a list sorted at the end."""

    def __init__(self, on_rows: Callable[[list[dict]], None] | None) -> None:
        self.on_rows = on_rows
        self.rows: list[dict] | None = [] if on_rows is None else None

    def __call__(self, rows: list[dict]) -> None:
        if self.on_rows is not None:
            self.on_rows(rows)
        else:
            self.rows.extend(rows)

    def result(self) -> list[dict] | None:
        if self.rows is not None:
            self.rows.sort(key=lambda r: r["sample"])
        return self.rows


def run_serial(fmu_bytes: bytes, draws: Sequence[dict] | Iterable[Sample], settings: dict, progress: bool = True,
               *, on_rows: Callable[[list[dict]], None] | None = None, total: int | None = None) -> Outcome:
    """The reference: the same rows as the Dask workers compute, in this process, handed to
    `on_rows` one by one (or returned in sample order)."""
    archive = twin.archive_from_bytes(fmu_bytes)
    _hold_library(archive)
    twin.prepare(fmu_bytes)
    total = len(draws) if total is None else total
    sink = _Sink(on_rows)
    started = time.perf_counter()
    n = 0
    with _progress(total, progress) as bar:
        for sample in samples_of(draws):
            sink(compute_rows(archive, [sample], settings))
            n += 1
            bar.update(1)
    return Outcome(sink.result(), "serial", time.perf_counter() - started, samples_per_worker={"local": n},
                   tasks_per_worker={"local": n}, samples=n, chunk=1, largest_chunk=1)


# ------------------------------------------------------------------------------------------
# What runs on the workers
# ------------------------------------------------------------------------------------------

# The archives' shared libraries, held open once per process (_hold_library).
_LIBRARIES: dict[str, Any] = {}


def _hold_library(archive: fmu.Archive) -> None:
    """Keeps the archive's shared library loaded in this process. fmpy loads the library with
    each instance and unloads it when the instance is freed; each load of the Rust library after
    an unload leaves about 25 kB behind (its thread-local state), which over a sweep's 2 instances
    a sample would grow a worker by gigabytes. One more handle held open makes every later load
    and unload a reference count: the process stays flat."""
    import ctypes
    import glob
    import os

    key = str(archive.unzipdir)
    if key in _LIBRARIES:
        return
    for path in sorted(glob.glob(os.path.join(key, "binaries", "*", "*"))):
        if path.endswith((".so", ".dylib", ".dll")):
            try:
                _LIBRARIES[key] = ctypes.CDLL(path)
                return
            except OSError:
                continue  # another platform's binary


archive_digest = twin.archive_digest


class ArchivePlugin(WorkerPlugin):
    """The FMU archive, sent to each worker once: set up when registered (on the workers present)
    and when a worker joins later, it unpacks the archive and loads its library (twin.prepare),
    so that the tasks only name it by its digest."""

    def __init__(self, fmu_bytes: bytes) -> None:
        self.fmu_bytes = fmu_bytes
        self.digest = archive_digest(fmu_bytes)

    @property
    def name(self) -> str:
        return f"backlash-sweep-archive-{self.digest[:20]}"

    def setup(self, worker: Any = None) -> None:
        _hold_library(twin.archive_from_bytes(self.fmu_bytes))
        twin.prepare(self.fmu_bytes)


def run_chunk(digest: str, samples: list[Sample], settings: dict) -> tuple[list[dict], str, float]:
    """One task: the rows of `samples` on the archive of this digest (sent by ArchivePlugin),
    the address of the worker that ran them, and their compute time [s]."""
    archive = twin.unpacked(digest)
    if archive is None:
        raise RuntimeError(f"the archive {digest[:20]} was not sent to this worker (its ArchivePlugin did not run)")
    started = time.perf_counter()
    rows = compute_rows(archive, samples, settings)
    seconds = time.perf_counter() - started
    try:
        from distributed import get_worker

        where = get_worker().address
    except ValueError:
        where = "local"
    return rows, where, seconds


# ------------------------------------------------------------------------------------------
# The client
# ------------------------------------------------------------------------------------------


class Chunker:
    """The size of each task. With `fixed`, that size. Otherwise PROBE samples until a task has
    reported its compute time; then, from the mean time of a sample t measured so far, the
    remaining samples shared into TASKS_PER_WORKER tasks per worker thread, but no fewer than
    MIN_TASK_SECONDS / t and no more than TASK_SECONDS / t samples a task (and no more than are
    left)."""

    def __init__(self, fixed: int | None = None) -> None:
        self.fixed = fixed
        self.seconds = 0.0
        self.measured = 0
        self.first: int | None = None
        self.largest = 0

    def record(self, samples: int, seconds: float) -> None:
        self.seconds += seconds
        self.measured += samples

    @property
    def sample_seconds(self) -> float | None:
        return self.seconds / self.measured if self.measured else None

    def size(self, remaining: int, threads: int) -> int:
        if self.fixed is not None:
            n = self.fixed
        elif not self.measured:
            n = PROBE
        else:
            t = max(self.sample_seconds, 1e-6)
            low = max(1, math.ceil(MIN_TASK_SECONDS / t))
            high = max(low, math.floor(TASK_SECONDS / t))
            n = min(high, max(low, math.ceil(remaining / (TASKS_PER_WORKER * max(1, threads)))))
        n = max(1, min(n, remaining))
        if self.first is None and (self.fixed is not None or self.measured):
            self.first = n
        self.largest = max(self.largest, n)
        return n


def task_key(digest: str, samples: list[Sample], settings: dict) -> str:
    """A key that names a task's inputs (archive, samples, settings): a key always means the same
    result, so a task recomputed after a lost worker is interchangeable with the original."""
    h = hashlib.sha256(digest.encode())
    h.update(json.dumps([settings, samples], sort_keys=True).encode())
    return f"sweep-{samples[0][0]}-{h.hexdigest()[:20]}"


def connect(scheduler: str | None, workers: int | None, timeout: float) -> tuple[Any, Any]:
    """A Client on the given scheduler, or on a LocalCluster of `workers` single-threaded worker
    processes (default: one per core) bound to the loopback interface."""
    import dask
    from distributed import Client, LocalCluster

    if scheduler is None:
        n = workers or dask.system.CPU_COUNT
        # Every server on the loopback interface; the scheduler's HTTP server (health and
        # metrics, no dashboard) on a free port rather than 8787, which may be taken.
        # No statistical profiler: nobody looks at it, and it samples the task's stack every 10 ms.
        with dask.config.set({"distributed.worker.profile.enabled": False}):
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                                   dashboard_address=None, worker_dashboard_address=None,
                                   scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"},
                                   silence_logs=logging.ERROR)
        return Client(cluster), cluster
    # A refused connection is retried until the timeout; its log lines would repeat the error.
    quiet = logging.getLogger("distributed")
    level = quiet.level
    quiet.setLevel(logging.CRITICAL)
    try:
        client = Client(scheduler, timeout=timeout)
    except (OSError, TimeoutError, ValueError) as e:
        reason = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise SchedulerError(f"cannot reach the Dask scheduler at {scheduler}: {reason}") from None
    finally:
        quiet.setLevel(level)
    return client, None


def _send_archive(client: Any, plugin: ArchivePlugin, where: str) -> None:
    """Registers the archive's plugin; a worker that cannot take it (no backlash_fmu installed,
    another version, an archive its platform cannot load) is an error of the cluster."""
    try:
        client.register_plugin(plugin, name=plugin.name)
    except Exception as e:  # noqa: BLE001 - whatever the worker raised, one line
        reason = str(e).splitlines()[0] if str(e) else ""
        raise SchedulerError(f"a worker of {where} cannot take the sweep's archive: {type(e).__name__}: {reason} "
                             "(each worker needs this version of backlash_fmu installed: pip install it there)"
                             ) from None


def run_dask(fmu_bytes: bytes, draws: Sequence[dict] | Iterable[Sample], settings: dict, *,
             scheduler: str | None = None, workers: int | None = None, timeout: float = 10.0,
             progress: bool = True, after_first: Callable[[], None] | None = None, chunk: int | None = None,
             on_rows: Callable[[list[dict]], None] | None = None, total: int | None = None) -> Outcome:
    """The samples in tasks of several each on a Dask cluster (sized by `Chunker`, or `chunk`
    samples each); each task's rows are handed to `on_rows` as it completes (or returned in sample
    order). `total` is the number of samples (default: len(draws)); `after_first` runs once the
    first rows are in (the tests kill a worker there)."""
    import dask

    with dask.config.set({"distributed.admin.low-level-log-length": LOG_LENGTH}):
        return _run_dask(fmu_bytes, draws, settings, scheduler=scheduler, workers=workers, timeout=timeout,
                         progress=progress, after_first=after_first, chunk=chunk, on_rows=on_rows, total=total)


def _run_dask(fmu_bytes: bytes, draws: Sequence[dict] | Iterable[Sample], settings: dict, *,
              scheduler: str | None, workers: int | None, timeout: float, progress: bool,
              after_first: Callable[[], None] | None, chunk: int | None,
              on_rows: Callable[[list[dict]], None] | None, total: int | None) -> Outcome:
    from distributed import as_completed

    total = len(draws) if total is None else total
    samples = samples_of(draws)
    sink = _Sink(on_rows)
    plugin = ArchivePlugin(fmu_bytes)
    t0 = time.perf_counter()
    client, cluster = connect(scheduler, workers, timeout)
    where = scheduler or "the LocalCluster"
    try:
        if scheduler is not None:
            # A cluster without workers would queue the tasks forever: wait for them, bounded.
            try:
                client.wait_for_workers(workers or 1, timeout=timeout)
            except (TimeoutError, OSError) as e:
                raise SchedulerError(f"the Dask scheduler at {scheduler} has fewer than {workers or 1} worker(s) "
                                     f"after {timeout:g} s: {str(e).splitlines()[0] if str(e) else type(e).__name__}"
                                     ) from None
        # Each worker present takes the archive, imports fmpy and loads the library before the
        # clock starts, as the serial run does; a worker that joins later does it as it joins.
        _send_archive(client, plugin, where)
        startup = time.perf_counter() - t0
        started = time.perf_counter()

        chunker = Chunker(chunk)
        threads = max(1, sum(client.nthreads().values()))
        polled = time.monotonic()
        submitted = in_flight = done = 0
        per_worker: dict[str, int] = {}
        tasks_per_worker: dict[str, int] = {}
        pending = as_completed()

        def submit() -> bool:
            nonlocal submitted, in_flight
            size = chunker.size(total - submitted, threads)
            batch = list(islice(samples, size))
            if not batch:
                return False
            # A worker lost mid-task is not an error of the task: the scheduler reruns it elsewhere
            # (up to distributed.scheduler.allowed-failures times); retries cover transient errors.
            pending.add(client.submit(run_chunk, plugin.digest, batch, settings,
                                      key=task_key(plugin.digest, batch, settings), retries=2))
            submitted += len(batch)
            in_flight += 1
            return True

        with _progress(total, progress) as bar:
            while in_flight < WINDOW * threads and submit():
                pass
            for future in pending:
                rows, worker, seconds = future.result()
                del future
                in_flight -= 1
                chunker.record(len(rows), seconds)
                sink(rows)
                done += len(rows)
                per_worker[worker] = per_worker.get(worker, 0) + len(rows)
                tasks_per_worker[worker] = tasks_per_worker.get(worker, 0) + 1
                bar.update(len(rows))
                if after_first is not None and done == len(rows):
                    after_first()
                if time.monotonic() - polled >= WORKERS_POLL:
                    # Workers that joined (or left) since: the window and the chunks follow them.
                    threads = max(1, sum(client.nthreads().values()))
                    polled = time.monotonic()
                while in_flight < WINDOW * threads and submit():
                    pass
        elapsed = time.perf_counter() - started
        address = client.scheduler.address
        if cluster is None:
            # An existing cluster keeps no copy of the archive for the workers that join later.
            try:
                client.unregister_worker_plugin(plugin.name)
            except Exception:  # noqa: BLE001 - the rows are in; a worker gone since is no error
                pass
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return Outcome(sink.result(), "dask", elapsed, startup, address, dict(sorted(per_worker.items())),
                   dict(sorted(tasks_per_worker.items())), done, chunker.first, chunker.largest,
                   chunker.sample_seconds)
