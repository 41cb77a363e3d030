//! `cargo xtask demo [--short]`: the paper's experiments (Figs. 11–13) reproduced with the
//! packaged FMUs, and its open design questions answered. Builds the FMUs, makes sure the Python
//! environment exists, installs the package `backlash_fmu` into it, then runs
//! `python -m backlash_fmu.demo --out results [--short]` (python/backlash_fmu/demo/), which
//!
//! - computes the design answers with `backlash_fmu.design` and writes them to
//!   results/design.json (load speed, the paper's rig) and results/design_web.json (web tension,
//!   a film line on BacklashBelt's drive), in the layout of `backlash design ... --json`;
//! - runs the paper's experiments on BacklashShaft.fmu through fmpy: results/run_*.csv,
//!   results/summary.csv, results/sampling.csv, results/design_bound_sup.csv and the figures
//!   results/fig11–13_*.png, results/design_bound_sup.png;
//! - runs twin web lines (Δ and Δ = 0) on BacklashWeb.fmu under the speed and tension PI loops:
//!   results/web_line.csv (T^b, T^0, |ΔT| against bound_T; ω_L^b, ω_L^0, |Δω_L| against bound)
//!   and results/web_line.png, and reads design_web.json's answer back through the FMU's
//!   bound_T_sup;
//! - identifies the paper's rig from a noisy BacklashShaft run: results/identify*.{csv,json};
//! - runs a low-speed reversal on BacklashShaft with bearing friction with stiction and without,
//!   under the PI speed loop: results/friction_reversal.csv and results/friction_reversal.png;
//! - answers which mesh's backlash costs the accuracy of a two-stage gearbox, from its design
//!   answer (`backlash_fmu.design("two-stage", ...)`): results/two_stage.json and
//!   results/two_stage.png.
//!
//! The demo runs on the installed package's own archives (built from this tree by the install):
//! `BACKLASH_FMU_DIR` is removed from its environment.

use std::process::Command;

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
tension PI loops closed through fmpy and compares |T^b - T^0| with bound_T; identifies the
paper's rig from a noisy run; runs a low-speed reversal with bearing friction beside the same
run without; says which mesh's backlash costs the accuracy of a two-stage gearbox. Writes
results/*.csv, results/*.png, results/design.json, results/design_web.json and
results/two_stage.json.

The experiments are the package backlash_fmu's (python -m backlash_fmu.demo), installed into
.venv first.

  --short   shorter horizons (also when the environment has CI=true)";

pub fn run(args: &[String]) -> Result<(), String> {
    let mut short = false;
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
    python::venv_with_package()?;

    step("the demonstration (python -m backlash_fmu.demo)");
    let results = util::repo_root().join("results");
    let mut cmd = Command::new(python::venv_python());
    cmd.current_dir(util::repo_root())
        .env_remove("BACKLASH_FMU_DIR")
        .args(["-m", "backlash_fmu.demo", "--out"])
        .arg(&results);
    // The module also reads CI=true itself; --short is passed when asked for here.
    if short {
        cmd.arg("--short");
    }
    util::run(&mut cmd)
}
