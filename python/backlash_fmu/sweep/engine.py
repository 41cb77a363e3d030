"""Running the samples: in this process (serial), or as one Dask task per sample on a LocalCluster
or on an existing cluster. The rows are the same whichever runs them: each task gets its drawn
parameters and the FMU archive as bytes, and the rows are sorted by sample index at the end.

A worker needs only Python, fmpy and numpy (not this package): the task code (backlash_fmu.twin
and the driver it runs on, backlash_fmu.fmu) is shipped by value, and the archive travels as a
scattered bytes object, unpacked once per worker process.
"""

from __future__ import annotations

import hashlib
import json
import logging
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable

from tqdm import tqdm

from .. import fmu, twin


@dataclass
class Outcome:
    rows: list[dict]
    engine: str
    # Wall time from the first task handed out to the last row received [s].
    elapsed: float
    # Starting the LocalCluster or connecting to the scheduler, sending the archive and
    # preparing the workers (imports, unpacking) [s].
    startup: float = 0.0
    scheduler: str | None = None
    tasks_per_worker: dict[str, int] = field(default_factory=dict)


class SchedulerError(RuntimeError):
    """The scheduler cannot be reached; the message is one line."""


def _progress(total: int, show: bool) -> tqdm:
    return tqdm(total=total, desc="sweep", unit="sample", file=sys.stderr, disable=not show, dynamic_ncols=True)


def run_serial(fmu_bytes: bytes, draws: list[dict], settings: dict, progress: bool = True) -> Outcome:
    """The reference: the same task function as the Dask workers run, in this process."""
    twin.prepare(fmu_bytes)
    started = time.perf_counter()
    rows = []
    with _progress(len(draws), progress) as bar:
        for i, params in enumerate(draws):
            row, _ = twin.sweep_task(fmu_bytes, i, params, settings)
            rows.append(row)
            bar.update(1)
    return Outcome(rows, "serial", time.perf_counter() - started, tasks_per_worker={"local": len(rows)})


def task_keys(fmu_bytes: bytes, draws: list[dict], settings: dict) -> list[str]:
    """Keys that name a task's inputs (archive, parameters, settings): a key always means the
    same result, so a task recomputed after a lost worker is interchangeable with the original."""
    base = hashlib.sha256(fmu_bytes)
    base.update(json.dumps(settings, sort_keys=True).encode())
    keys = []
    for i, params in enumerate(draws):
        h = base.copy()
        h.update(json.dumps([i, params], sort_keys=True).encode())
        keys.append(f"sweep-{i}-{h.hexdigest()[:20]}")
    return keys


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


class _Shipped:
    """A function of backlash_fmu.twin that travels by value even through plain pickle: the
    scheduler unpickles the graph with the standard library, and the workers of an existing
    cluster need not have this package. Unpickled, it is a small closure that carries the source
    of the modules the task runs on (backlash_fmu.fmu, then backlash_fmu.twin): when a worker first
    calls it, it executes them into a private package of that process (named by their digest;
    their own imports, fmpy and numpy, are the worker's) and calls the function of that name,
    once per process."""

    # The modules shipped, dependencies first: twin imports fmu (`from . import fmu`).
    MODULES = (fmu, twin)

    def __init__(self, fn: Callable) -> None:
        import inspect

        import cloudpickle

        if fn.__module__ != twin.__name__:
            raise ValueError(f"{fn.__qualname__} is not a function of {twin.__name__}")
        name = fn.__name__
        sources = tuple((module.__name__.rsplit(".", 1)[1], inspect.getsource(module)) for module in self.MODULES)
        digest = hashlib.sha256(repr(sources).encode()).hexdigest()[:20]

        def call(*args: Any) -> Any:
            import sys
            import threading
            import types

            package = f"_backlash_fmu_shipped_{digest}"
            store = sys.modules.setdefault("_backlash_sweep_code", types.ModuleType("_backlash_sweep_code"))
            lock = store.__dict__.setdefault("lock", threading.Lock())
            with lock:
                loaded = sys.modules.get(package)
                if loaded is None:
                    loaded = types.ModuleType(package)
                    loaded.__path__ = []
                    sys.modules[package] = loaded
                    try:
                        for module_name, source in sources:
                            module = types.ModuleType(f"{package}.{module_name}")
                            module.__package__ = package
                            module.__file__ = f"<{package}/{module_name}.py>"
                            sys.modules[module.__name__] = module
                            exec(compile(source, module.__file__, "exec"), module.__dict__)
                            setattr(loaded, module_name, module)
                    except BaseException:
                        for key in [k for k in sys.modules if k == package or k.startswith(package + ".")]:
                            del sys.modules[key]
                        raise
            return getattr(loaded.twin, name)(*args)

        self.call = call
        self.pickled = cloudpickle.dumps(call)

    def __call__(self, *args: Any) -> Any:
        return self.call(*args)

    def __reduce__(self) -> tuple[Callable, tuple[bytes]]:
        import cloudpickle

        return cloudpickle.loads, (self.pickled,)


def run_dask(fmu_bytes: bytes, draws: list[dict], settings: dict, *, scheduler: str | None = None,
             workers: int | None = None, timeout: float = 10.0, progress: bool = True,
             after_first: Callable[[], None] | None = None) -> Outcome:
    """One task per sample on a Dask cluster; `after_first` runs once the first row is in (the
    tests kill a worker there)."""
    from distributed import as_completed

    task = _Shipped(twin.sweep_task)
    t0 = time.perf_counter()
    client, cluster = connect(scheduler, workers, timeout)
    try:
        if scheduler is not None:
            # A cluster without workers would queue the tasks forever: wait for them, bounded.
            try:
                client.wait_for_workers(workers or 1, timeout=timeout)
            except (TimeoutError, OSError) as e:
                raise SchedulerError(f"the Dask scheduler at {scheduler} has fewer than {workers or 1} worker(s) "
                                     f"after {timeout:g} s: {str(e).splitlines()[0] if str(e) else type(e).__name__}"
                                     ) from None
        # Each worker present imports fmpy and unpacks the archive before the clock starts, as
        # the serial run does; a worker that joins later does it at its first task.
        archive = client.scatter(fmu_bytes, broadcast=True, hash=True)
        client.run(_Shipped(twin.prepare), fmu_bytes)
        startup = time.perf_counter() - t0
        started = time.perf_counter()
        keys = task_keys(fmu_bytes, draws, settings)
        # A worker lost mid-task is not an error of the task: the scheduler reruns it elsewhere
        # (up to distributed.scheduler.allowed-failures times); retries cover transient errors.
        # One map: the shipped task function is serialized once for the whole graph, not per sample.
        n = len(draws)
        futures = client.map(task, [archive] * n, range(n), draws, [settings] * n, key=keys, retries=2)
        rows, per_worker = [], {}
        with _progress(len(futures), progress) as bar:
            for future in as_completed(futures):
                row, where = future.result()
                rows.append(row)
                per_worker[where] = per_worker.get(where, 0) + 1
                bar.update(1)
                if after_first is not None and len(rows) == 1:
                    after_first()
        elapsed = time.perf_counter() - started
        address = client.scheduler.address
        del futures, archive
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    rows.sort(key=lambda r: r["sample"])
    return Outcome(rows, "dask", elapsed, startup, address, dict(sorted(per_worker.items())))
