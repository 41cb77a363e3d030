//! `cargo xtask demo [--short]`: the paper's experiments (Figs. 11–13) reproduced with the
//! packaged FMUs, and its open design question answered. Builds the FMUs, makes sure the Python
//! environment exists, writes the design answer to results/design.json, then runs
//! demo/paper_experiments.py, which writes CSV and PNG files under results/.

use std::fs;
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

use backlash_fmu::physics::PlantParams;

use crate::design::{self as design_cmd, Request};
use crate::util::{self, step};
use crate::{fmu, python};

const USAGE: &str = "\
usage: cargo xtask demo [--short]

Reproduces the paper's closed-loop experiments (Figs. 11-13) with BacklashShaft.fmu: twin
instances (with and without backlash) under a PI speed loop closed through fmpy, for the three
gaps read as Delta = gap/2 and Delta = gap, with a step and a reversing reference; prints a table
of max deviation against bound_paper and bound; answers the design question for
eps = 0.02 m/s. Writes results/*.csv, results/*.png and results/design.json.

  --short   shorter horizons (also when the environment has CI=true)";

/// Required load-speed accuracy of the design question [m/s on the rectilinear rig].
pub const DEMO_ACCURACY: f64 = 0.02;
/// Half gap for the stiffness search: the paper's smallest gap, 1.55 mm, read as 2Δ.
pub const DEMO_DELTA: f64 = 0.775e-3;

pub fn run(args: &[String]) -> Result<(), String> {
    let mut short = std::env::var("CI").is_ok_and(|v| v == "true" || v == "1");
    for arg in args {
        match arg.as_str() {
            "--short" => short = true,
            "--help" | "-h" => {
                println!("{USAGE}");
                return Ok(());
            }
            other => return Err(format!("unknown argument `{other}`\n\n{USAGE}")),
        }
    }

    step("building the FMUs");
    fmu::package_all()?;
    python::ensure_venv()?;
    let started = Instant::now();

    step("design: gains by the best-damped rule, delta_max and k_min");
    let results = util::repo_root().join("results");
    fs::create_dir_all(&results).map_err(|e| format!("creating {}: {e}", results.display()))?;
    let request = Request {
        accuracy: DEMO_ACCURACY,
        params: PlantParams::paper_rig(DEMO_DELTA),
        gains: None,
    };
    let answer = design_cmd::solve(request)?;
    println!(
        "PI gains (best-damped rule): Kp = {:.6} N.s/m, Ki = {:.6} N/m; smallest damping ratio {:.4}",
        answer.gains.kp, answer.gains.ki, answer.min_damping
    );
    let design_json = results.join("design.json");
    fs::write(&design_json, design_cmd::to_json(&answer))
        .map_err(|e| format!("writing {}: {e}", design_json.display()))?;
    println!(
        "wrote {} ({:.2} s)",
        util::shown(&design_json),
        started.elapsed().as_secs_f64()
    );

    step("paper experiments through fmpy");
    let python = python::venv_python();
    let script: PathBuf = util::repo_root().join("demo").join("paper_experiments.py");
    let mut cmd = Command::new(python);
    cmd.current_dir(util::repo_root())
        .arg(&script)
        .arg("--fmu")
        .arg(util::fmu_dir().join("BacklashShaft.fmu"))
        .arg("--design")
        .arg(&design_json)
        .arg("--out")
        .arg(&results);
    if short {
        cmd.arg("--short");
    }
    util::run(&mut cmd)?;
    println!(
        "\ndemo finished in {:.1} s after the build",
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
