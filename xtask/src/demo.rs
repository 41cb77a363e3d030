//! `cargo xtask demo [--short]`: the paper's experiments (Figs. 11–13) reproduced with the
//! packaged FMUs, and its open design questions answered. Builds the FMUs, makes sure the Python
//! environment exists, writes the design answers to results/design.json (load speed, the paper's
//! rig) and results/design_web.json (web tension, a film line on BacklashBelt's drive), then runs
//! through fmpy
//!
//! - demo/paper_experiments.py on BacklashShaft.fmu: results/run_*.csv, results/summary.csv,
//!   results/sampling.csv, results/design_bound_sup.csv and the figures results/fig11–13_*.png,
//!   results/design_bound_sup.png;
//! - demo/web_line.py on BacklashWeb.fmu: twin web lines (Δ and Δ = 0) under the speed and
//!   tension PI loops, results/web_line.csv (T^b, T^0, |ΔT| against bound_T; ω_L^b, ω_L^0,
//!   |Δω_L| against bound) and results/web_line.png, and design_web.json's answer read back
//!   through the FMU's bound_T_sup.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use backlash_design::{speed, web, Form, PiGains, PlantParams};

use crate::util::{self, step};
use crate::{fmu, python};

const USAGE: &str = "\
usage: cargo xtask demo [--short]

Reproduces the paper's closed-loop experiments (Figs. 11-13) with BacklashShaft.fmu: twin
instances (with and without backlash) under a PI speed loop closed through fmpy, for the three
gaps read as Delta = gap/2 and Delta = gap, with a step and a reversing reference; prints a table
of max deviation against bound_paper and bound; answers the design question for
eps = 0.02 m/s, and the web-tension question for a film line on BacklashBelt's drive for
eps_T = 20 N. Then runs twin BacklashWeb.fmu web lines (Delta and Delta = 0) under speed and
tension PI loops closed through fmpy and compares |T^b - T^0| with bound_T. Writes
results/*.csv, results/*.png, results/design.json and results/design_web.json.

  --short   shorter horizons (also when the environment has CI=true)";

/// Required load-speed accuracy of the design question [m/s on the rectilinear rig].
pub const DEMO_ACCURACY: f64 = 0.02;
/// Half gap for the stiffness search: the paper's smallest gap, 1.55 mm, read as 2Δ.
pub const DEMO_DELTA: f64 = 0.775e-3;
/// Required web-tension accuracy of the web line [N]: near what BacklashBelt's gap gives
/// (bound_T_sup 17.4 N at Δ = 50 µm), so that Δ_max and the stiffness window are both in view.
pub const DEMO_TENSION_ACCURACY: f64 = 20.0;

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
    let request = speed::Request {
        accuracy: DEMO_ACCURACY,
        params: PlantParams::paper_rig(DEMO_DELTA),
        gains: None,
    };
    let answer = speed::solve(request)?;
    println!(
        "PI gains (best-damped rule): Kp = {:.6} N.s/m, Ki = {:.6} N/m; smallest damping ratio {:.4}",
        answer.gains.kp, answer.gains.ki, answer.min_damping
    );
    let design_json = results.join("design.json");
    fs::write(&design_json, speed::to_json(&answer)).map_err(|e| format!("writing {}: {e}", design_json.display()))?;
    println!(
        "wrote {} ({:.2} s)",
        util::shown(&design_json),
        started.elapsed().as_secs_f64()
    );

    step("web line: delta_max and the K_b window for a tension accuracy");
    let web_answer = web::solve(web::Request {
        tension_accuracy: DEMO_TENSION_ACCURACY,
        accuracy: None,
        drive: backlash_design::default_params(Form::Web).map_err(|e| e.to_string())?,
        web: web::film_line().map_err(|e| e.to_string())?,
        gains: None,
        tension_gains: PiGains::default(),
    })?;
    println!("{}", web::to_text(&web_answer));
    let design_web_json = results.join("design_web.json");
    fs::write(&design_web_json, web::to_json(&web_answer) + "\n")
        .map_err(|e| format!("writing {}: {e}", design_web_json.display()))?;
    println!(
        "wrote {} ({:.2} s)",
        util::shown(&design_web_json),
        started.elapsed().as_secs_f64()
    );

    step("paper experiments through fmpy");
    run_script("paper_experiments.py", "BacklashShaft", &design_json, &results, short)?;
    step("web line through fmpy: twin runs against bound_T, the design answer through the FMU");
    run_script("web_line.py", "BacklashWeb", &design_web_json, &results, short)?;
    println!(
        "\ndemo finished in {:.1} s after the build",
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Runs demo/`script` in the project's venv on target/fmu/`model`.fmu with the design answer
/// `design`, writing under `out` (`--short`: shorter horizons).
fn run_script(script: &str, model: &str, design: &Path, out: &Path, short: bool) -> Result<(), String> {
    let script: PathBuf = util::repo_root().join("demo").join(script);
    let mut cmd = Command::new(python::venv_python());
    cmd.current_dir(util::repo_root())
        .arg(&script)
        .arg("--fmu")
        .arg(util::fmu_dir().join(format!("{model}.fmu")))
        .arg("--design")
        .arg(design)
        .arg("--out")
        .arg(out);
    if short {
        cmd.arg("--short");
    }
    util::run(&mut cmd)
}
