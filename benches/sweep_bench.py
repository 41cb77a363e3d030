"""Tolerance sweep side of `cargo xtask bench`: samples per second of the same N samples run
serially (no Dask, one process), on a LocalCluster of 1 worker and of 2 workers.

Prints `@ <key> <value> ...` lines, collected by xtask/src/bench/run.rs:
    @ sweep_config <samples> <horizon s> <step s> <repeats>
    @ sweep_serial <samples/s> <s>
    @ sweep_dask1 <samples/s> <s> <start s>
    @ sweep_dask2 <samples/s> <s> <start s>
    @ sweep_scaling <dask1 s / dask2 s>
    @ sweep_overhead <1 - serial s / dask1 s, percent>
    @ sweep_paired <worker/serial compute of the same blocks> <blocks> <samples a block> <idle %> <overhead %>
    @ sweep_scaling_paired <2 x shared x (1 - idle2) / (1 - idle)> <shared: alone / together compute> <blocks> <samples a block> <idle2 %>
    @ sweep_chunk <chunk, 1 worker> <tasks, 1 worker> <chunk, 2 workers> <tasks, 2 workers> <ms per sample>
    @ sweep_identical <1 if every table of every run is the serial one, else 0>
    @ sweep_load <1-minute load average at the start> <at the end> <cores>
The time of a run is from the first task handed out to the last row received; the one-time work
before it is reported apart as the start: the cluster's start, the archive sent to each worker
(once, in a worker plugin), and on each worker the imports and the unpacking of the archive
(which the serial run also does before its clock starts). The Dask runs are the sweep's own
engine (backlash_fmu.sweep.engine.run_dask): tasks of several samples, sized from the time of a
sample measured on the workers (the chunk is the first size so chosen, the ms per sample that
measure, from the median 2-worker run). Each mode runs --repeats times, interleaved, and the
median counts (the scaling and the overhead are ratios of medians).

The machine's speed drifts by tens of percent from one 15-second window to the next, so the
ratio of a serial run and a Dask run timed minutes apart measures the drift as much as Dask.
The paired figure takes the two parts of Dask's overhead apart, each within one window:
- idle: the share of the median 1-worker run's wall time in which the worker was not computing
  samples (scheduling, transfers, waiting), 1 - sum of the tasks' compute times / wall time;
- compute: the same blocks of samples computed in a plain Python process (a child of this one,
  without Dask) and in a 1-worker cluster's worker (the sweep's own task, run_chunk),
  alternating which goes first, block after block; the ratio of the two sums says whether a
  sample computes slower in a worker. Both processes are pinned to one core: the host runs this
  machine's two cores at speeds some percent apart, so that two processes on different cores
  differ by that much whatever they run. (Not in this process either: its Dask client's threads
  share its interpreter.)
Then the 1-worker time per sample is the serial one times compute / (1 - idle), and the paired
overhead is 1 - (1 - idle) / compute.

The scaling from 1 to 2 workers is taken apart the same way. A run's time is the compute time
of its samples over its workers' busy share: T1 = C1 / (1 - idle), T2 = C2 / (2 (1 - idle2)),
idle2 the share of the median 2-worker run's worker time not spent computing samples (the tail
where one worker waits for the other included). C1 / C2, how much slower a sample computes when
two workers share the machine (the client's and scheduler's work beside them included), is
measured paired: blocks of samples computed on the worker of a 1-worker cluster and, at once, on
each worker of a 2-worker cluster, by turns (`shared`). The paired scaling is
2 x shared x (1 - idle2) / (1 - idle); the ratio of the median whole runs is reported beside it.

    python benches/sweep_bench.py [--samples 240] [--repeats 3] [--seed 1] [--block 8] [--chunk N] [--fmu PATH]

The sweep is the package's (backlash_fmu.sweep, its default config); the archive is
BacklashShaft.fmu of $BACKLASH_FMU_DIR when that is set, else the package's own, unless --fmu
names one. Dask's workers import backlash_fmu: run with the package installed (or PYTHONPATH
naming python/, which the LocalCluster's workers inherit).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import sys
from pathlib import Path
from typing import Callable

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402

from backlash_fmu import twin  # noqa: E402
from backlash_fmu.sweep import config, default_archive, engine  # noqa: E402


def emit(key: str, *values: object) -> None:
    print("@", key, *values, flush=True)


def median_run(runs: list[engine.Outcome]) -> engine.Outcome:
    """The run of median time (the lower median of an even count)."""
    ordered = sorted(runs, key=lambda r: r.elapsed)
    return ordered[(len(ordered) - 1) // 2]


# The plain process of the paired measure: the archive and settings, set up once.
_PLAIN: dict = {}


def _pin() -> None:
    """This process on the first core: the two processes of the paired measure then run on
    the same core, whose speed the host may set apart from the other's."""
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})


def _plain_setup(data: bytes, settings: dict) -> None:
    _pin()
    archive = twin.archive_from_bytes(data)
    engine._hold_library(archive)
    twin.prepare(data)
    _PLAIN.update(archive=archive, settings=settings)


def _plain_chunk(batch: list) -> float:
    """The compute time of `batch` in the plain process, as run_chunk measures it on a worker."""
    started = time.perf_counter()
    engine.compute_rows(_PLAIN["archive"], batch, _PLAIN["settings"])
    return time.perf_counter() - started


def alternated(first: Callable[[list], float], second: Callable[[list], float], draws: list[dict],
               block: int) -> tuple[float, float, int]:
    """The sums of first(batch) and second(batch) over the blocks of `block` samples of `draws`,
    the two taking turns to go first, after one untimed block of two samples each; and the
    number of blocks."""
    samples = list(enumerate(draws))
    first(samples[:2])
    second(samples[:2])
    sums = [0.0, 0.0]
    blocks = [samples[i:i + block] for i in range(0, len(samples), block)]
    for i, batch in enumerate(blocks):
        for j in (0, 1) if i % 2 == 0 else (1, 0):
            sums[j] += (first, second)[j](batch)
    return sums[0], sums[1], len(blocks)


def paired_compute(data: bytes, draws: list[dict], settings: dict, block: int) -> tuple[float, int]:
    """Worker compute time / plain-process compute time of the same blocks of `block` samples
    (the module's docstring), and the number of blocks. The plain process is a separate Python
    process without Dask, like the worker's a child of this one: this process, which holds the
    Dask client and its event loop, is not the reference."""
    client, cluster = engine.connect(None, 1, 10.0)
    try:
        plugin = engine.ArchivePlugin(data)
        client.register_plugin(plugin, name=plugin.name)
        client.run(_pin)
        with multiprocessing.get_context("spawn").Pool(1, _plain_setup, (data, settings)) as pool:

            def here(batch: list) -> float:
                return pool.apply(_plain_chunk, (batch,))

            def there(batch: list) -> float:
                return client.submit(engine.run_chunk, plugin.digest, batch, settings, pure=False).result()[2]

            local, worker, blocks = alternated(here, there, draws, block)
        return worker / local, blocks
    finally:
        client.close()
        cluster.close()


def paired_scaling(data: bytes, draws: list[dict], settings: dict, block: int) -> tuple[float, int]:
    """Compute time of a block of samples on the worker of a 1-worker cluster / its mean compute
    time on each worker of a 2-worker cluster running it at once (both clusters up, alternating
    which goes first, block after block), and the number of blocks: how much slower a sample
    computes when two workers share the machine, within one stretch of time (the module's
    docstring). Not pinned: the workers of the sweep are not."""
    one, one_cluster = engine.connect(None, 1, 10.0)
    two, two_cluster = engine.connect(None, 2, 10.0)
    try:
        plugin = engine.ArchivePlugin(data)
        for client in (one, two):
            client.register_plugin(plugin, name=plugin.name)
        pair = sorted(two.nthreads())

        def alone(batch: list) -> float:
            return one.submit(engine.run_chunk, plugin.digest, batch, settings, pure=False).result()[2]

        def together(batch: list) -> float:
            futures = [two.submit(engine.run_chunk, plugin.digest, batch, settings, pure=False, workers=[w])
                       for w in pair]
            return statistics.fmean(f.result()[2] for f in futures)

        single, shared, blocks = alternated(alone, together, draws, block)
        return single / shared, blocks
    finally:
        for client, cluster in ((one, one_cluster), (two, two_cluster)):
            client.close()
            cluster.close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=240)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--block", type=int, default=8, help="samples a block of the paired compute measure")
    ap.add_argument("--chunk", type=int, help="samples per task (default: the engine's, from a measured sample)")
    ap.add_argument("--fmu", type=Path, help="BacklashShaft.fmu (default: $BACKLASH_FMU_DIR's, else the package's)")
    args = ap.parse_args(argv)

    cfg = config.load(None)
    draws, settings = cfg.draw(args.samples, args.seed), cfg.settings()
    data = (default_archive() if args.fmu is None else args.fmu).read_bytes()
    n = args.samples

    load_start = os.getloadavg()[0]
    emit("sweep_config", n, settings["horizon"], settings["h"], args.repeats)
    # An untimed pass first: the first samples of a process run slower, and the serial figure
    # is the reference the overhead is measured against.
    engine.run_serial(data, draws[:4], settings, progress=False)
    runs: dict[int, list[engine.Outcome]] = {0: [], 1: [], 2: []}
    for _ in range(args.repeats):
        runs[0].append(engine.run_serial(data, draws, settings, progress=False))
        for workers in (1, 2):
            runs[workers].append(engine.run_dask(data, draws, settings, workers=workers, progress=False,
                                                 chunk=args.chunk))
    med = {mode: median_run(out) for mode, out in runs.items()}
    serial = med[0]
    emit("sweep_serial", n / serial.elapsed, serial.elapsed)
    for workers in (1, 2):
        emit(f"sweep_dask{workers}", n / med[workers].elapsed, med[workers].elapsed,
             statistics.median(r.startup for r in runs[workers]))
    emit("sweep_scaling", med[1].elapsed / med[2].elapsed)
    emit("sweep_overhead", (1 - serial.elapsed / med[1].elapsed) * 100)
    idle = statistics.median(1 - r.sample_seconds * r.samples / r.elapsed for r in runs[1])
    compute, blocks = paired_compute(data, draws, settings, args.block)
    emit("sweep_paired", compute, blocks, args.block, idle * 100, (1 - (1 - idle) / compute) * 100)
    busy2 = statistics.median(r.sample_seconds * r.samples / (2 * r.elapsed) for r in runs[2])
    shared, blocks = paired_scaling(data, draws, settings, args.block)
    emit("sweep_scaling_paired", 2 * shared * busy2 / (1 - idle), shared, blocks, args.block, (1 - busy2) * 100)
    emit("sweep_chunk", med[1].chunk, med[1].tasks, med[2].chunk, med[2].tasks, med[2].sample_seconds * 1e3)
    reference = serial.rows
    emit("sweep_identical", int(all(r.rows == reference for out in runs.values() for r in out)))
    emit("sweep_load", load_start, os.getloadavg()[0], os.cpu_count())
    return 0


if __name__ == "__main__":
    sys.exit(main())
