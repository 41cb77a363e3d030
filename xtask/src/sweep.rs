//! `cargo xtask sweep`: the tolerance sweep. Has the flags, the config and the output directory
//! checked first, so that a bad config is refused in a second rather than after minutes of
//! building: the base `python3` runs python/backlash_fmu/sweep/check.py by its path, which loads
//! the sweep's own parser and config validation with the standard library only (neither the venv
//! nor the package need exist yet; the same as `python -m backlash_fmu.sweep --check`). Then it
//! builds the FMUs, makes sure the Python environment exists, installs the package
//! `backlash_fmu` into it, and runs `python -m backlash_fmu.sweep` from the repository root with
//! the flags given here, on the installed package's archive of the model (`BACKLASH_FMU_DIR` is
//! removed from its environment) and with its defaults (the model's design answer).

use std::path::PathBuf;
use std::process::Command;

use crate::util::{self, step};
use crate::{fmu, python};

const USAGE: &str = "\
usage: cargo xtask sweep --samples N --seed S [--model shaft|belt|web]
                         [--scheduler tcp://HOST:PORT] [--workers N] [--chunk N]
                         [--config FILE] [--out DIR] [--resume] [--accuracy EPS] [--serial]

Tolerance sweep of a drive (default: the shaft): for each of N drives, Delta, the stiffness and
the load drawn from the config's distributions (default: the drive, the gains and the
reversing reference's frequency of the model's design answer; for the shaft at eps = 0.02,
Delta uniform over a wear range, k +-10 %, J_L +-5 %), a twin closed-loop run through fmpy
(with and without backlash) recording the max deviation, bound_sup and whether the accuracy is
met.
Runs on a Dask LocalCluster (one worker per core) or an existing cluster (--scheduler), in tasks
of several samples sized from the measured time of a sample. Writes results/sweep/samples.csv
(row by row as they arrive, in sample order at the end), manifest.json, summary.json and the
plots; --resume continues an interrupted sweep from the rows already written.

  --samples N       number of drives (required)
  --seed S          seed of the draws: the same seed gives the same table (required)
  --model M         shaft, belt or web (default: the config's, else shaft)
  --scheduler ADDR  a running Dask scheduler (`dask scheduler`, `dask worker ADDR`; every
                    worker needs the package: pip install it there)
  --workers N       LocalCluster worker processes (default: one per core); with
                    --scheduler, how many workers to wait for (default 1)
  --chunk N         samples per task (default: about a second of work a task)
  --config FILE     TOML distributions and settings (format: docs/sweep-tolerances.md,
                    python/backlash_fmu/sweep/config.py)
  --out DIR         output directory (default: results/sweep)
  --resume          continue the sweep interrupted in --out (same seed, model and config)
  --accuracy EPS    required load-speed accuracy (default: the config's)
  --serial          no Dask: every sample in one process
  --connect-timeout seconds to reach the scheduler (default 10)
  --no-progress     no progress bar";

/// Flags forwarded to `python -m backlash_fmu.sweep` with their value, and those without one.
const WITH_VALUE: [&str; 10] = [
    "--samples",
    "--seed",
    "--model",
    "--scheduler",
    "--workers",
    "--chunk",
    "--config",
    "--out",
    "--accuracy",
    "--connect-timeout",
];
const WITHOUT_VALUE: [&str; 3] = ["--serial", "--no-progress", "--resume"];

pub fn run(args: &[String]) -> Result<(), String> {
    let mut forwarded = Vec::new();
    let mut rest = args.iter();
    while let Some(arg) = rest.next() {
        let flag = arg.split('=').next().unwrap_or(arg);
        if arg == "--help" || arg == "-h" {
            println!("{USAGE}");
            return Ok(());
        } else if WITHOUT_VALUE.contains(&arg.as_str()) {
            forwarded.push(arg.clone());
        } else if let (true, Some((_, value))) = (WITH_VALUE.contains(&flag), arg.split_once('=')) {
            forwarded.extend([flag.to_string(), in_callers_directory(flag, value)]);
        } else if WITH_VALUE.contains(&flag) {
            let value = rest.next().ok_or(format!("{arg} needs a value\n\n{USAGE}"))?;
            forwarded.extend([arg.clone(), in_callers_directory(flag, value)]);
        } else {
            return Err(format!("unknown argument `{arg}`\n\n{USAGE}"));
        }
    }
    for required in ["--samples", "--seed"] {
        if !forwarded.iter().any(|a| a.split('=').next() == Some(required)) {
            return Err(format!("{required} is required\n\n{USAGE}"));
        }
    }

    step("checking the sweep's flags and config (python3 python/backlash_fmu/sweep/check.py)");
    let mut check = Command::new(python::base_python());
    check
        .current_dir(util::repo_root())
        .arg(check_script())
        .args(&forwarded);
    sweep_status(&mut check)?;

    step("building the FMUs");
    fmu::package_all()?;
    python::venv_with_package()?;

    step("tolerance sweep (python -m backlash_fmu.sweep)");
    let mut cmd = Command::new(python::venv_python());
    cmd.current_dir(util::repo_root())
        .env_remove("BACKLASH_FMU_DIR")
        .args(["-m", "backlash_fmu.sweep"])
        .args(&forwarded);
    sweep_status(&mut cmd)
}

/// The sweep's check run by its path: the arguments, the config and the output directory, with
/// the standard library only (python/backlash_fmu/sweep/check.py).
fn check_script() -> PathBuf {
    util::repo_root()
        .join("python")
        .join("backlash_fmu")
        .join("sweep")
        .join("check.py")
}

/// Runs the sweep (or its check); it says what went wrong in one line, so its exit code is
/// passed on.
fn sweep_status(cmd: &mut Command) -> Result<(), String> {
    let status = util::status(cmd)?;
    match status.code() {
        Some(0) => Ok(()),
        Some(code) => std::process::exit(code),
        None => Err(format!("the sweep was stopped ({status})")),
    }
}

/// A relative `--config` or `--out` names a path from where the command was run; the sweep runs
/// from the repository root, so it gets the path made absolute.
fn in_callers_directory(flag: &str, value: &str) -> String {
    match (flag, std::env::current_dir()) {
        ("--config" | "--out", Ok(here)) => here.join(value).to_string_lossy().into_owned(),
        _ => value.to_string(),
    }
}
