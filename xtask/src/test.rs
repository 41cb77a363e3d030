//! `cargo xtask test`: every check of the project, in order, stopping at the first failure.

use std::cell::RefCell;
use std::process::Command;
use std::time::Instant;

use crate::platform::{self, Built};
use crate::util::{self, step};
use crate::{abi, cross, fmu, python};

/// The package of tests/importer, and its integration test that loads the archives with the
/// `fmi` crate.
const IMPORTER_PACKAGE: &str = "importer-test";
/// The Python binding of the design crate: an extension module, built by maturin in step 6.
const PYTHON_BINDING: &str = "backlash-python";
const IMPORTER_TEST: &str = "fmi_crate";

const USAGE: &str = "usage: cargo xtask test [--cross | --no-cross]";

/// Whether step 9 (the win64 and aarch64-linux builds and their test) runs.
#[derive(Clone, Copy, PartialEq)]
enum Cross {
    /// When this machine has the tools (the default).
    IfAvailable,
    /// Always: a missing tool is an error (CI).
    Required,
    Skipped,
}

pub fn run(args: &[String]) -> Result<(), String> {
    let cross_mode = match args {
        [] => Cross::IfAvailable,
        [flag] if flag == "--cross" => Cross::Required,
        [flag] if flag == "--no-cross" => Cross::Skipped,
        [other, ..] => return Err(format!("unexpected argument `{other}`\n{USAGE}")),
    };
    // Decided up front, so that steps 3 and 6 build every platform when step 9 will test them.
    let cross_enabled = match (cross_mode, cross::unavailable()) {
        (Cross::Skipped, _) => false,
        (_, None) => true,
        (Cross::Required, Some(line)) => return Err(format!("--cross: {line}")),
        (Cross::IfAvailable, Some(line)) => {
            println!("step 9 (win64, aarch64-linux) will be skipped: {line}");
            false
        }
    };
    let platforms = if cross_enabled {
        platform::ALL.to_vec()
    } else {
        vec![&platform::LINUX64]
    };
    let built: RefCell<Vec<Built>> = RefCell::new(Vec::new());
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
        step("1/9 Python venv");
        python::ensure_venv()
    })?;
    // 2. Unit and integration tests of every crate but the importer test, which needs the
    //    archives that step 3 writes and runs in step 5.
    timed("cargo test --workspace", &|| {
        step("2/9 cargo test --workspace");
        util::run(util::cargo().args([
            "test",
            "--workspace",
            "--exclude",
            IMPORTER_PACKAGE,
            "--exclude",
            PYTHON_BINDING,
        ]))
    })?;
    // 3. The archives in target/fmu/ (with the win64 DLL when step 8 runs).
    let fmu_command = if cross_enabled {
        "cargo xtask fmu --all-platforms"
    } else {
        "cargo xtask fmu"
    };
    timed(fmu_command, &|| {
        step(&format!("3/9 {fmu_command}"));
        *built.borrow_mut() = fmu::package(&platforms)?;
        Ok(())
    })?;
    // 4. The libraries' C ABI against the official headers, and their exported symbols; then
    //    the leak check's C driver, natively and briefly, so that the longer run in CI (with
    //    valgrind) finds a driver that still fits the models' interface.
    timed("ABI check", &|| {
        step("4/9 ABI check, and the leak check's driver (200 cycles, native)");
        abi::check(&built.borrow())?;
        util::run(
            Command::new("bash")
                .arg("scripts/leak_check.sh")
                .args(["200", "--native"])
                .current_dir(util::repo_root()),
        )
    })?;
    // 5. A Rust importer (the `fmi` crate) loads the packaged archive. --include-ignored runs
    //    the tests that a plain `cargo test` skips; they fail if an archive is missing.
    timed("importer test", &|| {
        step("5/9 importer test (fmi crate on target/fmu/*.fmu)");
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
    // 6. The Python package, installed into the venv as a user installs it (`pip install .`),
    //    with the archives of the same platforms: the suite runs against it.
    timed("Python package", &|| {
        step("6/9 Python package (pip install . into .venv)");
        python::install_package_for(&platforms)
    })?;
    // 7. The pytest suite drives the package's FMUs through fmpy.
    timed("pytest", &|| {
        step("7/9 pytest");
        python::run_pytest()
    })?;
    // 8. The Python examples of README.md, so that what a new user copies works.
    timed("README examples", &|| {
        step("8/9 README.md Python examples");
        python::run_readme_example()
    })?;
    // 8. The win64 DLL under Wine and the aarch64 library under qemu against linux64.
    if cross_enabled {
        timed("cross-platform test", &|| {
            step("9/9 win64 and aarch64-linux against linux64 (cargo xtask cross-test)");
            cross::test(&built.borrow())
        })?;
    } else {
        step("9/9 cross-platform test skipped");
    }

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
