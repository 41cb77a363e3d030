"""Tolerance sweep side of `cargo xtask bench`: samples per second of the same N samples run
serially (no Dask, one process), on a LocalCluster of 1 worker and of 2 workers.

Prints `@ <key> <value> ...` lines, collected by xtask/src/bench/run.rs:
    @ sweep_config <samples> <horizon s> <step s> <repeats>
    @ sweep_serial <samples/s> <s>
    @ sweep_dask1 <samples/s> <s> <start s>
    @ sweep_dask2 <samples/s> <s> <start s>
    @ sweep_scaling <dask1 s / dask2 s>
    @ sweep_overhead <1 - serial s / dask1 s, percent>
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

    python benches/sweep_bench.py [--samples 240] [--repeats 3] [--seed 1] [--chunk N] [--fmu PATH]

The sweep is the package's (backlash_fmu.sweep, its default config); the archive is
BacklashShaft.fmu of $BACKLASH_FMU_DIR when that is set, else the package's own, unless --fmu
names one. Dask's workers import backlash_fmu: run with the package installed (or PYTHONPATH
naming python/, which the LocalCluster's workers inherit).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from backlash_fmu.sweep import config, default_archive, engine  # noqa: E402


def emit(key: str, *values: object) -> None:
    print("@", key, *values, flush=True)


def median_run(runs: list[engine.Outcome]) -> engine.Outcome:
    """The run of median time (the lower median of an even count)."""
    ordered = sorted(runs, key=lambda r: r.elapsed)
    return ordered[(len(ordered) - 1) // 2]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=240)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
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
    emit("sweep_chunk", med[1].chunk, med[1].tasks, med[2].chunk, med[2].tasks, med[2].sample_seconds * 1e3)
    reference = serial.rows
    emit("sweep_identical", int(all(r.rows == reference for out in runs.values() for r in out)))
    emit("sweep_load", load_start, os.getloadavg()[0], os.cpu_count())
    return 0


if __name__ == "__main__":
    sys.exit(main())
