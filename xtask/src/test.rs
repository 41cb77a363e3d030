//! `cargo xtask test`: every check of the project, in order, stopping at the first failure.

use std::time::Instant;

use crate::util::{self, step};
use crate::{abi, fmu, python};

/// The integration test of tests/importer that loads the archives with the `fmi` crate.
const IMPORTER_TEST: &str = "fmi_crate";

pub fn run(args: &[String]) -> Result<(), String> {
    if let Some(arg) = args.first() {
        return Err(format!("`cargo xtask test` takes no arguments, got `{arg}`"));
    }
    let started = Instant::now();
    let mut timings: Vec<(&str, f64)> = Vec::new();
    let mut timed = |name: &'static str, work: &dyn Fn() -> Result<(), String>| {
        let t0 = Instant::now();
        let result = work().map_err(|e| format!("{name}: {e}"));
        timings.push((name, t0.elapsed().as_secs_f64()));
        result
    };

    // 1. Unit and integration tests of every crate. The importer test is #[ignore]d here: it
    //    needs the archives that step 2 writes, and runs in step 5.
    timed("cargo test --workspace", &|| {
        step("1/7 cargo test --workspace");
        util::run(util::cargo().args(["test", "--workspace"]))
    })?;
    // 2. The archives in target/fmu/.
    timed("cargo xtask fmu", &|| {
        step("2/7 cargo xtask fmu");
        fmu::package_all().map(|_| ())
    })?;
    // 3. The venv comes before the ABI check because fmpy carries the official FMI headers.
    timed("python venv", &|| {
        step("3/7 Python venv");
        python::ensure_venv()
    })?;
    // 4. The library's C ABI against the official headers, and its exported symbols.
    timed("ABI check", &|| {
        step("4/7 ABI check");
        abi::check()
    })?;
    // 5. A Rust importer (the `fmi` crate) loads the packaged archive. --include-ignored runs
    //    the tests that step 1 skipped; they fail if an archive is missing. Selected with
    //    --workspace so that cargo reuses step 1's build (same feature unification).
    timed("importer test", &|| {
        step("5/7 importer test (fmi crate on target/fmu/*.fmu)");
        util::run(util::cargo().env("BACKLASH_FMU_DIR", util::fmu_dir()).args([
            "test",
            "--workspace",
            "--test",
            IMPORTER_TEST,
            "--",
            "--include-ignored",
        ]))
    })?;
    // 6. The pytest suite drives the packaged FMUs through fmpy.
    timed("pytest", &|| {
        step("6/7 pytest");
        python::run_pytest()
    })?;
    // 7. The usage example of README.md, so that what a new user copies works.
    timed("README example", &|| {
        step("7/7 README.md fmpy example");
        python::run_readme_example()
    })?;

    step("cargo xtask test: every step succeeded");
    for (name, seconds) in &timings {
        println!("  {seconds:>7.1} s  {name}");
    }
    println!("  {:>7.1} s  total", started.elapsed().as_secs_f64());
    Ok(())
}
