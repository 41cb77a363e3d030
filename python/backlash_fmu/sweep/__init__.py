"""Tolerance sweep of the shaft drive: N drives with backlash, stiffness and load inertia drawn
from distributions, each run as a twin closed loop (with and without backlash) through fmpy.

    python -m backlash_fmu.sweep --samples 1000 --seed 1 [--scheduler tcp://HOST:PORT] [--workers N]
                                 [--config FILE] [--out DIR] [--fmu PATH] [--serial] [--accuracy EPS]

or `backlash_fmu.sweep.main([...])` with the same arguments. The defaults (config.py) are the
design answer for the shaft, `backlash_fmu.design("shaft", accuracy=0.02)`: its drive as the
nominal one, its gains and the frequency of its poles; the archive is BacklashShaft.fmu of
$BACKLASH_FMU_DIR when that is set, else the package's own (`backlash_fmu.fmu_path`).

Writes DIR/samples.csv (one row per sample), DIR/summary.json, DIR/histogram.png and
DIR/deviation_vs_delta.png. Exit status: 0 done, 1 a sample's max deviation exceeded its
bound_sup (the bound would be wrong), 2 bad usage, config, unreadable archive, output directory
or scheduler (refused before any sample runs), 3 any other failure (its reason on one line).

Modules: config (defaults, the TOML config, the draws), engine (serial or Dask runs of
backlash_fmu.twin's sample), report (the table, the summary, the plots), check (the arguments
and the config checked with the standard library only, run by path before anything is built).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Callable, NoReturn

__all__ = ["main", "parse", "UsageError"]

MODEL = "BacklashShaft"


class UsageError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise UsageError(message)


def _int_at_least(low: int) -> Callable[[str], int]:
    def convert(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {value}")
        return value

    return convert


_positive_int = _int_at_least(1)


def _check_writable(out: Path) -> None:
    """Refuses an output directory that could not be made, before the samples are computed
    (nothing is created yet: a refused run leaves no trace)."""
    probe = out.absolute()
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir() or not os.access(probe, os.W_OK | os.X_OK):
        raise UsageError(f"cannot write the output directory {out}: {probe} is not a writable directory")


def parse(argv: list[str] | None) -> argparse.Namespace:
    """The command line, validated; raises UsageError with a one-line reason."""
    ap = _Parser(prog="python -m backlash_fmu.sweep", description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=_positive_int, required=True, help="number of drives")
    ap.add_argument("--seed", type=_int_at_least(0), required=True, help="seed of the draws (same seed, same table)")
    ap.add_argument("--scheduler", help="tcp://HOST:PORT of a running Dask scheduler (default: a LocalCluster)")
    ap.add_argument("--workers", type=_positive_int,
                    help="LocalCluster worker processes (default: one per core); with --scheduler: wait for this many")
    ap.add_argument("--config", type=Path, help="TOML config (format: backlash_fmu/sweep/config.py, README.md)")
    ap.add_argument("--out", type=Path, default=Path("results/sweep"), help="output directory")
    ap.add_argument("--fmu", type=Path,
                    help="BacklashShaft.fmu (default: $BACKLASH_FMU_DIR's if set, else the package's own)")
    ap.add_argument("--serial", action="store_true", help="no Dask: every sample in this process")
    ap.add_argument("--accuracy", type=float, help="required load-speed accuracy [m/s] (overrides the config)")
    ap.add_argument("--connect-timeout", type=float, default=10.0, help="seconds to reach the scheduler")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    ap.add_argument("--check", action="store_true",
                    help="check the arguments, the config and the output directory, then stop (needs only the "
                         "standard library, also as `python3 backlash_fmu/sweep/check.py ARGS` without the package "
                         "installed: `cargo xtask sweep` runs it before building anything)")
    args = ap.parse_args(argv)
    if args.serial and (args.scheduler or args.workers):
        raise UsageError("--serial runs without Dask: it takes neither --scheduler nor --workers")
    if args.scheduler is not None and not args.scheduler.startswith(("tcp://", "tls://")):
        raise UsageError(f"--scheduler: expected tcp://HOST:PORT, got {args.scheduler!r}")
    if args.accuracy is not None and not args.accuracy > 0:
        raise UsageError(f"--accuracy: must be > 0, got {args.accuracy!r}")
    return args


def default_archive() -> Path:
    """BacklashShaft.fmu of $BACKLASH_FMU_DIR when that is set (backlash_fmu.fmu.fmu_path), else
    the package's own (backlash_fmu.fmu_path). Raises UsageError when the package has none."""
    from .. import fmu, fmu_path

    if os.environ.get("BACKLASH_FMU_DIR"):
        return fmu.fmu_path(MODEL)
    try:
        return fmu_path(MODEL)
    except (ValueError, FileNotFoundError) as e:
        raise UsageError(f"no FMU archive given and none in the package: {e} (give --fmu PATH)") from None


def _read_archive(path: Path | None) -> bytes:
    path = default_archive() if path is None else path
    try:
        return path.read_bytes()
    except OSError as e:
        raise UsageError(f"cannot read the FMU archive {path}: {e.strerror} "
                         "(build it with `cargo xtask fmu`)") from None


def main(argv: list[str] | None = None) -> int:
    """The sweep's command line (`python -m backlash_fmu.sweep --help`); returns the exit status."""
    from . import config as config_mod

    try:
        args = parse(argv)
        config_mod.load_checked(args.config)
        _check_writable(args.out)
    except (UsageError, config_mod.ConfigError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if args.check:
        return 0

    from . import engine, report

    try:
        try:
            config = config_mod.load(args.config)
        except config_mod.ConfigError as e:
            raise UsageError(str(e)) from None
        if args.accuracy is not None:
            config.accuracy = args.accuracy
        fmu_bytes = _read_archive(args.fmu)
        draws = config.draw(args.samples, args.seed)
        settings = config.settings()
        if args.serial:
            outcome = engine.run_serial(fmu_bytes, draws, settings, progress=not args.no_progress)
        else:
            outcome = engine.run_dask(fmu_bytes, draws, settings, scheduler=args.scheduler, workers=args.workers,
                                      timeout=args.connect_timeout, progress=not args.no_progress)
    except (UsageError, engine.SchedulerError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except Exception as e:  # noqa: BLE001 - one line for the user, not a traceback; 1 is reserved
        reason = str(e).splitlines()[0] if str(e) else ""
        print(f"error: {type(e).__name__}: {reason}", file=sys.stderr)
        return 3

    args.out.mkdir(parents=True, exist_ok=True)
    report.write_table(args.out / "samples.csv", outcome.rows)
    summary = report.summarize(outcome.rows, config, args.seed)
    summary["execution"] = {
        "engine": outcome.engine,
        "scheduler": outcome.scheduler,
        "tasks_per_worker": outcome.tasks_per_worker,
        "seconds": outcome.elapsed,
        "startup_seconds": outcome.startup,
    }
    report.write_summary(args.out / "summary.json", summary)
    plots = report.plot(args.out, outcome.rows, config)

    n = summary["samples"]
    print(f"{n} samples (seed {args.seed}) on {outcome.engine}"
          f"{' at ' + outcome.scheduler if outcome.scheduler else ''}: {outcome.elapsed:.1f} s, "
          f"{n / outcome.elapsed:.2f} samples/s, {len(outcome.tasks_per_worker)} worker(s)")
    print(f"accuracy ε = {config.accuracy:g} m/s met by {summary['meeting_accuracy']}/{n} "
          f"({summary['fraction_meeting_accuracy'] * 100:.1f} %)")
    print(f"largest max deviation {summary['largest_max_dev']:.6g} m/s (sample {summary['largest_max_dev_sample']}); "
          f"worst max_dev/bound_sup = {summary['worst_ratio']:.4f} (sample {summary['worst_ratio_sample']})")
    print(f"wrote {args.out / 'samples.csv'}, {args.out / 'summary.json'}, "
          + ", ".join(str(p) for p in plots))
    if not summary["bound_holds"]:
        print(f"error: max_dev/bound_sup = {summary['worst_ratio']!r} > 1 in sample {summary['worst_ratio_sample']}: "
              "the deviation exceeds the bound", file=sys.stderr)
        return 1
    return 0
