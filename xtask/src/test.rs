//! `cargo xtask test`: every check of the project, in order, stopping at the first failure.

use std::process::Command;
use std::time::Instant;

use crate::platform::{self, Built};
use crate::util::{self, step};
use crate::{abi, fmu, python};

/// The package of tests/importer, and its integration test that loads the archives with the
/// `fmi` crate.
const IMPORTER_PACKAGE: &str = "importer-test";
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

    // 1. The venv first: it carries the libclang that step 5 builds with, and fmpy's copy of
    //    the official FMI headers for step 4.
    timed("python venv", &|| {
        step("1/7 Python venv");
        python::ensure_venv()
    })?;
    // 2. Unit and integration tests of every crate but the importer test, which needs the
    //    archives that step 3 writes and runs in step 5.
    timed("cargo test --workspace", &|| {
        step("2/7 cargo test --workspace");
        util::run(util::cargo().args(["test", "--workspace", "--exclude", IMPORTER_PACKAGE]))
    })?;
    // 3. The archives in target/fmu/.
    timed("cargo xtask fmu", &|| {
        step("3/7 cargo xtask fmu");
        fmu::package_all().map(|_| ())
    })?;
    // 4. The library's C ABI against the official headers, and its exported symbols.
    timed("ABI check", &|| {
        step("4/7 ABI check");
        abi::check(&[Built {
            platform: &platform::LINUX64,
            path: fmu::library_path(),
        }])
    })?;
    // 5. A Rust importer (the `fmi` crate) loads the packaged archive. --include-ignored runs
    //    the tests that a plain `cargo test` skips; they fail if an archive is missing.
    timed("importer test", &|| {
        step("5/7 importer test (fmi crate on target/fmu/*.fmu)");
        let mut test = util::cargo();
        bindgen_environment(&mut test)?;
        util::run(test.env("BACKLASH_FMU_DIR", util::fmu_dir()).args([
            "test",
            "--package",
            IMPORTER_PACKAGE,
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

/// The `fmi` crate's build runs bindgen, which loads libclang: the one the venv's wheel carries
/// (unless LIBCLANG_PATH names another), with the C compiler's own headers (stddef.h, which
/// the wheel lacks) unless BINDGEN_EXTRA_CLANG_ARGS is set.
fn bindgen_environment(cmd: &mut Command) -> Result<(), String> {
    if std::env::var_os("LIBCLANG_PATH").is_none() {
        let dir = python::libclang_dir()
            .ok_or("no libclang.so in .venv (the libclang wheel of tests/importer/requirements.txt)")?;
        cmd.env("LIBCLANG_PATH", dir);
    }
    if std::env::var_os("BINDGEN_EXTRA_CLANG_ARGS").is_none() {
        let include = util::output(Command::new("cc").args(["-print-file-name=include"]))?;
        cmd.env("BINDGEN_EXTRA_CLANG_ARGS", format!("-isystem {}", include.trim()));
    }
    Ok(())
}
