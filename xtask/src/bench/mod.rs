//! `cargo xtask bench [--smoke]`: every benchmark in one run, and BENCHMARKS.md generated from it.
//!
//! Builds the FMUs, unpacks BacklashShaft.fmu, BacklashBelt.fmu, BacklashWeb.fmu and
//! BacklashTwoStage.fmu, compiles the C host benches/native_host.c against the official FMI 2.0
//! headers (fmpy's copy in .venv) and the value references and start values of the archives'
//! modelDescription.xml, then runs: the native per-call costs and their floors, with the event-free
//! steps of the belt drive, the web line and the two-stage gearbox beside them, the growth with
//! steps and instances, the PI loop natively, through fmpy and in scipy
//! (benches/python_bench.py), and the criterion bench of the physics core. Each tool prints
//! `@ <key> <values>` lines (criterion writes estimates.json); run.rs collects them, report.rs
//! writes the report with the machine facts and the exact commands.

mod report;
mod run;

use std::fs;
use std::time::Instant;

use crate::util::{self, step};
use crate::{fmu, python};
use run::{Facts, Runner};

const USAGE: &str = "\
usage: cargo xtask bench [--smoke]

Runs every benchmark (native C host through the FMI C ABI, the PI loop through fmpy and in scipy,
growth with steps and instances, the tolerance sweep serially and on Dask, identification of
a 10 s run, criterion bench of the physics core) and rewrites BENCHMARKS.md
with the numbers, the machine facts and the exact commands. Takes a few minutes.

  --smoke   tiny sizes, no criterion: checks that the harness runs (seconds after the build);
            writes target/bench/BENCHMARKS.smoke.md and leaves BENCHMARKS.md alone";

/// The model of the native host's per-call costs, growth and PI loop, and of the Python benches.
const MODEL: &str = "BacklashShaft";

/// The belt drive and the web line that extends it, each from its own archive: their event-free
/// steps are taken in the same rounds of the native suite, so that the web's cost is measured
/// against the belt's in one run (target: within 1.5x of it).
const DRIVE_AND_WEB: [&str; 2] = ["BacklashBelt", "BacklashWeb"];

/// The two-stage gearbox, from its own archive: its event-free step is taken in the same rounds
/// of the native suite as the shaft's, at the shaft's step size, so that its cost is measured
/// against the shaft's in one run (target: within 2.5x of it).
const GEARBOX: &str = "BacklashTwoStage";

/// Sizes of one run; `--smoke` shrinks all of them.
struct Plan {
    smoke: bool,
    /// Rounds of the native per-call suite (section 1): one batch of every row per round.
    suite_rounds: u32,
    batches: u32,
    steps_per_batch: u64,
    scale_steps: Vec<u64>,
    instance_counts: Vec<u32>,
    instance_steps_per_batch: u64,
    loop_seconds: f64,
    loop_repeats: u32,
    sweep: &'static str,
    /// Samples of the tolerance-sweep benchmark (benches/sweep_bench.py) and its repeats.
    tolerance_samples: u32,
    tolerance_repeats: u32,
}

impl Plan {
    fn full() -> Plan {
        Plan {
            smoke: false,
            // ~10 s in all, longer than the spells of contention seen on shared machines.
            suite_rounds: 101,
            batches: 21,
            steps_per_batch: 20_000,
            scale_steps: vec![1_000, 10_000, 100_000, 1_000_000, 10_000_000],
            instance_counts: vec![1, 10, 100, 1000],
            instance_steps_per_batch: 20_000,
            loop_seconds: 10.0,
            loop_repeats: 7,
            sweep: "RK45:1e-3,RK45:1e-6,RK45:1e-9,RK45:1e-12,DOP853:1e-3,DOP853:1e-8,DOP853:1e-12",
            // At least 200 samples, so that the tasks sized to the work are several per worker.
            tolerance_samples: 240,
            tolerance_repeats: 3,
        }
    }

    fn smoke() -> Plan {
        Plan {
            smoke: true,
            suite_rounds: 3,
            batches: 3,
            steps_per_batch: 200,
            scale_steps: vec![1_000, 10_000],
            instance_counts: vec![1, 10],
            instance_steps_per_batch: 200,
            loop_seconds: 0.05,
            loop_repeats: 3,
            sweep: "RK45:1e-3",
            tolerance_samples: 4,
            tolerance_repeats: 1,
        }
    }
}

pub fn run(args: &[String]) -> Result<(), String> {
    let mut plan = Plan::full();
    for arg in args {
        match arg.as_str() {
            "--smoke" => plan = Plan::smoke(),
            "--help" | "-h" => {
                println!("{USAGE}");
                return Ok(());
            }
            other => return Err(format!("unknown argument `{other}`\n\n{USAGE}")),
        }
    }
    let started = Instant::now();
    let load_start = run::read_trimmed("/proc/loadavg");

    fmu::package_all()?;
    // The Python benches drive the archives through the package, installed as a user does.
    python::venv_with_package()?;

    step("compiling the native host (benches/native_host.c)");
    let work = util::target_dir().join("bench");
    let mut runner = Runner::prepare(&work)?;

    step("native host: per-call costs");
    runner.native_suite(&plan)?;
    step("native host: growth with the number of steps (one process each)");
    runner.native_scale(&plan)?;
    step("native host: many instances stepped round-robin (one process each)");
    runner.native_instances(&plan)?;
    step("native host: the PI loop");
    runner.native_piloop(&plan)?;

    step("the PI loop through fmpy and in scipy (benches/python_bench.py)");
    runner.python(&plan)?;

    step("the tolerance sweep: serial and on a Dask LocalCluster (benches/sweep_bench.py)");
    runner.sweep(&plan)?;

    step("identification of a 10 s run at 1 kHz (design/benches/identify.rs)");
    runner.identify()?;

    if !plan.smoke {
        step("criterion bench of the physics core (benches/physics.rs)");
        runner.criterion()?;
    }

    let measured = runner.finish();
    let facts = Facts::collect(load_start, started);
    let report = report::render(&plan, &measured, &facts)?;
    let path = if plan.smoke {
        work.join("BENCHMARKS.smoke.md")
    } else {
        util::repo_root().join("BENCHMARKS.md")
    };
    fs::write(&path, report).map_err(|e| format!("writing {}: {e}", path.display()))?;
    println!(
        "\nwrote {} ({:.0} s in all)",
        util::shown(&path),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
