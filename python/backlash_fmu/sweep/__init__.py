"""Tolerance sweep of a drive: N drives with backlash, stiffness and load inertia drawn from
distributions, each run as a twin closed loop (with and without backlash) through fmpy.

    python -m backlash_fmu.sweep --samples 1000 --seed 1 [--model shaft|belt|web]
                                 [--scheduler tcp://HOST:PORT] [--workers N] [--chunk N]
                                 [--config FILE] [--out DIR] [--resume] [--fmu PATH] [--serial]
                                 [--accuracy EPS]

or `backlash_fmu.sweep.main([...])` with the same arguments. The defaults (config.py) are the
design answer for the model, `backlash_fmu.design(model, ...)`: its drive as the nominal one, its
gains and the frequency of its poles; the archive is the model's (BacklashShaft.fmu,
BacklashBelt.fmu, BacklashWeb.fmu) of $BACKLASH_FMU_DIR when that is set, else the package's own
(`backlash_fmu.fmu_path`).

Writes DIR/samples.csv (one row per sample, appended as the rows arrive and put in sample order
at the end), DIR/manifest.json (what wrote the rows: seed, model, config, archive),
DIR/summary.json, DIR/histogram.png and DIR/deviation_vs_delta.png. `--resume` continues a sweep
interrupted in DIR from the rows already there. Exit status: 0 done, 1 a sample's max deviation
exceeded its bound_sup (the bound would be wrong), 2 bad usage, config, unreadable archive,
output directory, table to resume or scheduler (refused before any sample runs), 3 any other
failure (its reason on one line).

Modules: config (defaults, the TOML config, the draws), engine (serial or Dask runs of
backlash_fmu.twin's samples, in tasks sized to the work), table (the table written as the rows
arrive, put in order, resumed), report (the summary, the plots), check (the arguments and the
config checked with the standard library only, run by path before anything is built).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Callable, NoReturn

from .config import ARCHIVES

__all__ = ["main", "parse", "UsageError"]


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
    ap.add_argument("--model", choices=tuple(ARCHIVES),
                    help="the drive swept (default: the config's `model`, else shaft)")
    ap.add_argument("--scheduler", help="tcp://HOST:PORT of a running Dask scheduler (default: a LocalCluster)")
    ap.add_argument("--workers", type=_positive_int,
                    help="LocalCluster worker processes (default: one per core); with --scheduler: wait for this many")
    ap.add_argument("--chunk", type=_positive_int,
                    help="samples per Dask task (default: sized from the measured time of a sample, "
                         "about a second a task)")
    ap.add_argument("--config", type=Path, help="TOML config (format: backlash_fmu/sweep/config.py, docs/sweep-tolerances.md)")
    ap.add_argument("--out", type=Path, default=Path("results/sweep"), help="output directory")
    ap.add_argument("--resume", action="store_true",
                    help="continue the sweep interrupted in --out: the samples already in its samples.csv are "
                         "not run again (refused if they come from another seed, model, config or archive)")
    ap.add_argument("--fmu", type=Path,
                    help="the model's archive (default: $BACKLASH_FMU_DIR's if set, else the package's own)")
    ap.add_argument("--serial", action="store_true", help="no Dask: every sample in this process")
    ap.add_argument("--accuracy", type=float, help="required load-speed accuracy [m/s] (overrides the config)")
    ap.add_argument("--connect-timeout", type=float, default=10.0, help="seconds to reach the scheduler")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    ap.add_argument("--check", action="store_true",
                    help="check the arguments, the config and the output directory, then stop (needs only the "
                         "standard library, also as `python3 backlash_fmu/sweep/check.py ARGS` without the package "
                         "installed: `cargo xtask sweep` runs it before building anything)")
    args = ap.parse_args(argv)
    if args.serial and (args.scheduler or args.workers or args.chunk):
        raise UsageError("--serial runs without Dask: it takes neither --scheduler, --workers nor --chunk")
    if args.scheduler is not None and not args.scheduler.startswith(("tcp://", "tls://")):
        raise UsageError(f"--scheduler: expected tcp://HOST:PORT, got {args.scheduler!r}")
    if args.accuracy is not None and not args.accuracy > 0:
        raise UsageError(f"--accuracy: must be > 0, got {args.accuracy!r}")
    return args


def default_archive(model: str = "shaft") -> Path:
    """The archive of `model` ("shaft", "belt", "web": BacklashShaft.fmu, ...) of
    $BACKLASH_FMU_DIR when that is set (backlash_fmu.fmu.fmu_path), else the package's own
    (backlash_fmu.fmu_path). Raises UsageError when the package has none."""
    from .. import fmu, fmu_path

    name = ARCHIVES[model]
    if os.environ.get("BACKLASH_FMU_DIR"):
        return fmu.fmu_path(name)
    try:
        return fmu_path(name)
    except (ValueError, FileNotFoundError) as e:
        raise UsageError(f"no FMU archive given and none in the package: {e} (give --fmu PATH)") from None


def _read_archive(path: Path | None, model: str) -> bytes:
    path = default_archive(model) if path is None else path
    try:
        return path.read_bytes()
    except OSError as e:
        raise UsageError(f"cannot read the FMU archive {path}: {e.strerror} "
                         "(build it with `cargo xtask fmu`)") from None


def _config_identity(config: object, settings: dict) -> dict:
    """What the rows depend on in a built config: every distribution (exact text) and the
    settings of the runs."""
    distributions = getattr(config, "distributions", {})
    return {"distributions": {name: d.describe() for name, d in distributions.items()}, "settings": settings}


def main(argv: list[str] | None = None) -> int:
    """The sweep's command line (`python -m backlash_fmu.sweep --help`); returns the exit status."""
    from . import config as config_mod
    from . import table

    try:
        args = parse(argv)
        config_mod.load_checked(args.config, model=args.model)
        _check_writable(args.out)
        if args.resume:
            # What the standard library can compare: the table's seed, model and config file.
            doc, _ = config_mod.read(args.config)
            table.check_manifest(args.out, {"seed": args.seed, "model": config_mod.model_of(doc, args.model),
                                            "config_file": table.digest(doc)})
    except (UsageError, config_mod.ConfigError, table.TableError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if args.check:
        return 0

    from . import engine, report

    out = args.out
    try:
        try:
            config = config_mod.load(args.config, model=args.model)
        except config_mod.ConfigError as e:
            raise UsageError(str(e)) from None
        if args.accuracy is not None:
            config.accuracy = args.accuracy
        model = config.model
        fmu_bytes = _read_archive(args.fmu, model)
        settings = config.settings()  # with its "model"
        doc, _ = config_mod.read(args.config)
        manifest = table.manifest(seed=args.seed, model=model, config=_config_identity(config, settings),
                                  config_file=doc, archive=fmu_bytes)
        resumed = table.resume_state(out, manifest, args.samples) if args.resume else None
        done = resumed.done if resumed is not None else []
        remaining = args.samples - table.count(done)
        samples = engine.draw(config, args.samples, args.seed, done)
        writer = table.Writer(out, manifest, resumed, config.columns())
        try:
            if remaining == 0:
                outcome = engine.Outcome(None, "none (every sample was in the table already)", 0.0)
            elif args.serial:
                outcome = engine.run_serial(fmu_bytes, samples, settings, progress=not args.no_progress,
                                            on_rows=writer.write, total=remaining)
            else:
                outcome = engine.run_dask(fmu_bytes, samples, settings, scheduler=args.scheduler,
                                          workers=args.workers, timeout=args.connect_timeout,
                                          progress=not args.no_progress, chunk=args.chunk, on_rows=writer.write,
                                          total=remaining)
        finally:
            writer.close()
    except (UsageError, engine.SchedulerError, table.TableError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except Exception as e:  # noqa: BLE001 - one line for the user, not a traceback; 1 is reserved
        reason = str(e).splitlines()[0] if str(e) else ""
        print(f"error: {type(e).__name__}: {reason}", file=sys.stderr)
        return 3

    try:
        table.finish(out, args.samples)
    except (OSError, table.TableError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 3
    rows = table.Rows(out / table.TABLE)
    summary = report.summarize(rows, config, args.seed)
    summary["execution"] = {
        "engine": outcome.engine,
        "scheduler": outcome.scheduler,
        # Where the samples ran: samples and tasks per worker (those of this run, not resumed).
        "samples_per_worker": outcome.samples_per_worker,
        "tasks_per_worker": outcome.tasks_per_worker,
        "samples_run": outcome.samples,
        "samples_resumed": args.samples - remaining,
        "chunk": outcome.chunk,
        "largest_chunk": outcome.largest_chunk,
        "sample_seconds": outcome.sample_seconds,
        "seconds": outcome.elapsed,
        "startup_seconds": outcome.startup,
    }
    report.write_summary(out / "summary.json", summary)
    plots = report.plot(out, rows, config)

    n = summary["samples"]
    ran = outcome.samples
    rate = f"{ran / outcome.elapsed:.2f} samples/s" if outcome.elapsed > 0 else "no sample run"
    tasks = (f", tasks of {outcome.chunk} sample(s)" if outcome.engine == "dask" and outcome.chunk else "")
    print(f"{n} samples (seed {args.seed}) on {outcome.engine}"
          f"{' at ' + outcome.scheduler if outcome.scheduler else ''}: {outcome.elapsed:.1f} s, "
          f"{rate}, {len(outcome.samples_per_worker)} worker(s){tasks}")
    if args.samples != remaining:
        print(f"resumed: {args.samples - remaining} samples were in {out / table.TABLE}, {ran} run now")
    for text in report.describe(summary):
        print(text)
    print(f"wrote {out / table.TABLE}, {out / 'summary.json'}, "
          + ", ".join(str(p) for p in plots))
    violation = report.violation(summary)
    if violation is not None:
        print(f"error: {violation}", file=sys.stderr)
        return 1
    return 0
