//! The Python side of the commands: a virtual environment at `.venv` with the pinned
//! requirements of tests/python (fmpy, maturin, the test, demo and sweep packages) and
//! tests/importer (the libclang wheel), the package `backlash_fmu` installed into it from this
//! repository, and the pytest run over the package's FMUs.

use std::fs;
use std::path::PathBuf;
use std::process::Command;

use crate::platform::{self, Platform};
use crate::util::{self, step};

/// `cargo xtask pytest`: the venv, the package, the suite and the README examples.
pub fn run(args: &[String]) -> Result<(), String> {
    if let Some(arg) = args.first() {
        return Err(format!("`cargo xtask pytest` takes no arguments, got `{arg}`"));
    }
    ensure_venv()?;
    install_package()?;
    run_pytest()?;
    run_readme_example()
}

/// [`install_package_for`] linux64.
pub fn install_package() -> Result<(), String> {
    install_package_for(&[&platform::LINUX64])
}

/// Installs the package `backlash_fmu` into `.venv` from this repository as a user does
/// (`pip install .`, pyproject.toml), its archives holding the libraries of `platforms`
/// (linux64, or every platform). Build isolation is off: the venv's pinned maturin builds it,
/// and the venv's pinned packages are its dependencies (`--no-deps`).
pub fn install_package_for(platforms: &[&'static Platform]) -> Result<(), String> {
    step("the Python package backlash_fmu (pip install . into .venv)");
    let mut install = Command::new(venv_python());
    // maturin's build hooks run the `maturin` program the venv installed, found on PATH.
    let path = std::env::var_os("PATH").unwrap_or_default();
    let dirs = std::iter::once(venv_dir().join("bin")).chain(std::env::split_paths(&path));
    let path = std::env::join_paths(dirs).map_err(|e| format!("PATH with .venv/bin: {e}"))?;
    install.env("PATH", path).current_dir(util::repo_root()).args([
        "-m",
        "pip",
        "install",
        "--disable-pip-version-check",
        "--quiet",
        "--no-deps",
        "--no-build-isolation",
        "--force-reinstall",
        ".",
    ]);
    if platforms.len() > 1 {
        install.args(["--config-settings", "platforms=all"]);
    }
    util::run(&mut install)
}

fn venv_dir() -> PathBuf {
    util::repo_root().join(".venv")
}

/// The venv's interpreter (made by [`ensure_venv`]).
pub fn venv_python() -> PathBuf {
    venv_dir().join("bin").join("python")
}

/// The pinned requirements installed into `.venv`: the pytest suite's, and the libclang that
/// the importer test's build needs.
fn requirements() -> [PathBuf; 2] {
    let tests = util::repo_root().join("tests");
    [
        tests.join("python").join("requirements.txt"),
        tests.join("importer").join("requirements.txt"),
    ]
}

/// The Python the venv is made from: `$PYTHON`, else `python3`.
pub fn base_python() -> String {
    std::env::var("PYTHON").unwrap_or_else(|_| "python3".into())
}

/// Records what the venv was installed from; pip runs again only when this text changes.
fn stamp_path() -> PathBuf {
    venv_dir().join("requirements.stamp")
}

/// Creates `.venv` if needed and installs the pinned requirements when they changed since the
/// last install.
pub fn ensure_venv() -> Result<(), String> {
    step("Python environment (.venv)");
    let requirements = requirements();
    let mut pinned = String::new();
    for path in &requirements {
        pinned += &fs::read_to_string(path).map_err(|e| format!("reading {}: {e}", util::shown(path)))?;
    }

    if !venv_python().is_file() {
        util::run(Command::new(base_python()).args(["-m", "venv"]).arg(venv_dir())).map_err(|e| {
            format!("{e}\ncreating the venv needs python3 with the venv module (Debian: apt-get install python3-venv)")
        })?;
    }
    // The stamp also names the interpreter, so a venv built by another Python is refreshed.
    let version = util::output(Command::new(venv_python()).arg("--version"))?;
    let wanted = format!("{}\n{pinned}", version.trim());
    if fs::read_to_string(stamp_path()).ok().as_deref() == Some(wanted.as_str()) {
        println!("requirements unchanged since the last install: reusing .venv");
        return Ok(());
    }
    let _ = fs::remove_file(stamp_path());
    let mut install = Command::new(venv_python());
    install.args(["-m", "pip", "install", "--disable-pip-version-check", "--quiet"]);
    for path in &requirements {
        install.arg("-r").arg(path);
    }
    util::run(&mut install)?;
    fs::write(stamp_path(), wanted).map_err(|e| format!("writing {}: {e}", stamp_path().display()))
}

/// Runs pytest on tests/python against the installed package and its archives (or those of
/// `$BACKLASH_FMU_DIR`, when set). "No tests collected" (exit 5) is a failure: a suite that
/// runs nothing proves nothing.
pub fn run_pytest() -> Result<(), String> {
    step("pytest tests/python (through fmpy, on the installed package's FMUs)");
    let status = util::status(Command::new(venv_python()).current_dir(util::repo_root()).args([
        "-m",
        "pytest",
        "tests/python",
        "-ra",
    ]))?;
    match status.code() {
        Some(0) => Ok(()),
        Some(5) => Err("pytest collected no tests in tests/python".into()),
        _ => Err(format!("pytest failed ({status})")),
    }
}

/// `relative` inside the venv's site-packages, where it holds `file`.
fn site_package_dir(relative: &[&str], file: &str) -> Option<PathBuf> {
    let lib = venv_dir().join("lib");
    let mut found: Vec<PathBuf> = fs::read_dir(&lib)
        .ok()?
        .filter_map(|entry| entry.ok())
        .filter(|entry| entry.file_name().to_string_lossy().starts_with("python3"))
        .map(|entry| {
            relative
                .iter()
                .fold(entry.path().join("site-packages"), |dir, part| dir.join(part))
        })
        .filter(|dir| dir.join(file).is_file())
        .collect();
    found.sort();
    found.pop()
}

/// fmpy's copy of the official FMI 2.0 headers, if the venv has fmpy.
pub fn fmpy_header_dir() -> Option<PathBuf> {
    site_package_dir(&["fmpy", "c-code"], "fmi2Functions.h")
}

/// The folder of the libclang shared library that the venv's `libclang` wheel carries.
pub fn libclang_dir() -> Option<PathBuf> {
    site_package_dir(&["clang", "native"], "libclang.so")
}

/// Runs every ```python block of README.md in the venv from the repository root, each in a
/// fresh interpreter, so the examples shown to users are known to work: the fmpy one on
/// target/fmu, and the package's.
pub fn run_readme_example() -> Result<(), String> {
    step("README.md Python examples");
    let readme_path = util::repo_root().join("README.md");
    let readme = fs::read_to_string(&readme_path).map_err(|e| format!("reading README.md: {e}"))?;
    let blocks = python_blocks(&readme);
    if blocks.is_empty() {
        return Err("README.md has no ```python block".into());
    }
    for code in blocks {
        util::run(
            Command::new(venv_python())
                .current_dir(util::repo_root())
                .arg("-c")
                .arg(code),
        )?;
    }
    Ok(())
}

fn python_blocks(markdown: &str) -> Vec<&str> {
    const OPEN: &str = "```python\n";
    let mut blocks = Vec::new();
    let mut rest = markdown;
    while let Some(start) = rest.find(OPEN) {
        let body = &rest[start + OPEN.len()..];
        let Some(end) = body.find("```") else { break };
        blocks.push(&body[..end]);
        rest = &body[end..];
    }
    blocks
}
