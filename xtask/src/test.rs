//! `cargo xtask test`: every check of the project, in order, stopping at the first failure.

use std::cell::RefCell;
use std::process::Command;
use std::time::Instant;

use crate::platform::{self, Built};
use crate::util::{self, step};
use crate::{abi, cross, fmu, python, wheel};

/// The package of tests/importer, and its integration test that loads the archives with the
/// `fmi` crate.
const IMPORTER_PACKAGE: &str = "importer-test";
/// The Python binding of the design crate: an extension module, built by maturin in step 6.
const PYTHON_BINDING: &str = "backlash-python";
const IMPORTER_TEST: &str = "fmi_crate";

const USAGE: &str = "usage: cargo xtask test [--cross | --no-cross]";

/// Whether step 11 (the win64 and aarch64-linux builds and their test) runs.
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
    // Decided up front, so that steps 3 and 6 build every platform when step 11 will test them.
    let cross_enabled = match (cross_mode, cross::unavailable()) {
        (Cross::Skipped, _) => false,
        (_, None) => true,
        (Cross::Required, Some(line)) => return Err(format!("--cross: {line}")),
        (Cross::IfAvailable, Some(line)) => {
            println!("step 11 (win64, aarch64-linux) will be skipped: {line}");
            false
        }
    };
    let platforms = if cross_enabled {
        platform::ALL.to_vec()
    } else {
        vec![&platform::LINUX64]
    };
    let built: RefCell<Vec<Built>> = RefCell::new(Vec::new());
    let distribution: RefCell<Option<wheel::Distribution>> = RefCell::new(None);
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
        step("1/11 Python venv");
        python::ensure_venv()
    })?;
    // 2. Unit and integration tests of every crate but the importer test, which needs the
    //    archives that step 3 writes and runs in step 5.
    timed("cargo test --workspace", &|| {
        step("2/11 cargo test --workspace");
        util::run(util::cargo().args([
            "test",
            "--workspace",
            "--exclude",
            IMPORTER_PACKAGE,
            "--exclude",
            PYTHON_BINDING,
        ]))
    })?;
    // 3. The archives in target/fmu/ (with the win64 DLL when step 11 runs).
    let fmu_command = if cross_enabled {
        "cargo xtask fmu --all-platforms"
    } else {
        "cargo xtask fmu"
    };
    timed(fmu_command, &|| {
        step(&format!("3/11 {fmu_command}"));
        *built.borrow_mut() = fmu::package(&platforms)?;
        Ok(())
    })?;
    // 4. The libraries' C ABI against the official headers, and their exported symbols; then
    //    the leak check's C driver, natively and briefly, so that the longer run in CI (with
    //    valgrind) finds a driver that still fits the models' interface.
    timed("ABI check", &|| {
        step("4/11 ABI check, and the leak check's driver (200 cycles, native)");
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
        step("5/11 importer test (fmi crate on target/fmu/*.fmu)");
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
    // 6. The Python package as a user gets it: `cargo xtask wheel` (the wheel, audited, and the
    //    sdist in dist/, the archives with the same platforms), the wheel installed into the
    //    venv; the suite runs against it, and steps 9 and 10 install the same files afresh.
    timed("wheel and sdist", &|| {
        step("6/11 Python package (cargo xtask wheel; the wheel installed into .venv)");
        let built = wheel::build(&platforms)?;
        python::install_wheel(&built.wheel)?;
        *distribution.borrow_mut() = Some(built);
        Ok(())
    })?;
    // 7. The pytest suite drives the package's FMUs through fmpy.
    timed("pytest", &|| {
        step("7/11 pytest");
        python::run_pytest()
    })?;
    // 8. The Python examples of README.md and of the user guide (docs/), so that what a new
    //    user copies works.
    timed("README and docs examples", &|| {
        step("8/11 Python examples of README.md and docs/");
        python::run_readme_example()
    })?;
    // 9. The wheel where no Rust toolchain is: a fresh venv, PATH without cargo or rustc; the
    //    command, the package's example, an FMU in fmpy, a shipped system in fmpy's SSP runner.
    timed("wheel without cargo", &|| {
        step("9/11 the wheel in a fresh venv, no cargo or rustc on PATH (tests/install/check_installed.py)");
        let distribution = distribution.borrow();
        let built = distribution.as_ref().ok_or("step 6 wrote no wheel")?;
        wheel::test_without_cargo(&built.wheel)
    })?;
    // 10. The sdist where cargo is: pip builds the whole workspace from it.
    timed("sdist with cargo", &|| {
        step("10/11 the sdist installed with pip into a fresh venv, cargo present");
        let distribution = distribution.borrow();
        let built = distribution.as_ref().ok_or("step 6 wrote no sdist")?;
        wheel::test_sdist(&built.sdist)
    })?;
    // 11. The win64 DLL under Wine and the aarch64 library under qemu against linux64.
    if cross_enabled {
        timed("cross-platform test", &|| {
            step("11/11 win64 and aarch64-linux against linux64 (cargo xtask cross-test)");
            cross::test(&built.borrow())
        })?;
    } else {
        step("11/11 cross-platform test skipped");
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
