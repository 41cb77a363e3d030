"""Tolerance sweep side of `cargo xtask bench`: samples per second of the same N samples run
serially (no Dask, one process), on a LocalCluster of 1 worker and of 2 workers.

Prints `@ <key> <value> ...` lines, collected by xtask/src/bench/run.rs:
    @ sweep_config <samples> <horizon s> <step s>
    @ sweep_serial <samples/s> <s>
    @ sweep_dask1 <samples/s> <s> <start s>
    @ sweep_dask2 <samples/s> <s> <start s>
    @ sweep_scaling <dask2 rate / dask1 rate>
    @ sweep_overhead <1 - serial s / dask1 s, percent>
    @ sweep_identical <1 if the three tables are the same, else 0>
The time of a run is from the first task handed out to the last row received. The one-time work
before it is reported apart as the start: the cluster's start, the archive's scatter, and on each
worker the imports and the unpacking of the archive (which the serial run also does before its
clock starts). Each
mode runs --repeats times, interleaved, and the fastest counts: on a shared machine the slower
runs measure the neighbours.

    python benches/sweep_bench.py [--samples 40] [--repeats 2] [--seed 1] [--fmu PATH]

The sweep is the package's (backlash_fmu.sweep, its default config); the archive is
BacklashShaft.fmu of $BACKLASH_FMU_DIR when that is set, else the package's own, unless --fmu
names one.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from backlash_fmu.sweep import config, default_archive, engine  # noqa: E402


def emit(key: str, *values: object) -> None:
    print("@", key, *values, flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=40)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--fmu", type=Path, help="BacklashShaft.fmu (default: $BACKLASH_FMU_DIR's, else the package's)")
    args = ap.parse_args(argv)

    cfg = config.load(None)
    draws, settings = cfg.draw(args.samples, args.seed), cfg.settings()
    data = (default_archive() if args.fmu is None else args.fmu).read_bytes()
    n = args.samples

    emit("sweep_config", n, settings["horizon"], settings["h"])
    # An untimed pass first: the first samples of a process run slower, and the serial figure
    # is the reference the overhead is measured against.
    engine.run_serial(data, draws[:4], settings, progress=False)
    best = {}
    for _ in range(args.repeats):
        runs = {0: engine.run_serial(data, draws, settings, progress=False)}
        for workers in (1, 2):
            runs[workers] = engine.run_dask(data, draws, settings, workers=workers, progress=False)
        for mode, out in runs.items():
            if mode not in best or out.elapsed < best[mode].elapsed:
                best[mode] = out
    serial, runs = best[0], best
    emit("sweep_serial", n / serial.elapsed, serial.elapsed)
    for workers in (1, 2):
        emit(f"sweep_dask{workers}", n / runs[workers].elapsed, runs[workers].elapsed, runs[workers].startup)
    emit("sweep_scaling", runs[1].elapsed / runs[2].elapsed)
    emit("sweep_overhead", (1 - serial.elapsed / runs[1].elapsed) * 100)
    emit("sweep_identical", int(serial.rows == runs[1].rows == runs[2].rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
