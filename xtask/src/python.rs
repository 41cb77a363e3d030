//! The Python side of the commands: a virtual environment at `.venv` with the pinned
//! requirements of tests/python (fmpy, maturin, the test, demo and sweep packages) and
//! tests/importer (the libclang wheel), the package `backlash_fmu` installed into it from this
//! repository, and the pytest run over the package's FMUs.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::platform::{self, Platform};
use crate::util::{self, step};

/// `cargo xtask pytest`: the venv, the package, the suite and the Python examples of README.md and
/// docs/.
pub fn run(args: &[String]) -> Result<(), String> {
    if let Some(arg) = args.first() {
        return Err(format!("`cargo xtask pytest` takes no arguments, got `{arg}`"));
    }
    venv_with_package()?;
    run_pytest()?;
    run_readme_example()
}

/// The venv ([`ensure_venv`]) with the package installed into it ([`install_package`]): what
/// every command that runs the package's Python needs.
pub fn venv_with_package() -> Result<(), String> {
    ensure_venv()?;
    install_package()
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
    let mut install = venv_pip_install();
    // maturin's build hooks run the `maturin` program the venv installed, found on PATH.
    install
        .env("PATH", path_with_venv()?)
        .args(["--no-build-isolation", "."]);
    if platforms.len() > 1 {
        install.args(["--config-settings", "platforms=all"]);
    }
    util::run(&mut install)
}

/// Installs the wheel `wheel` (`cargo xtask wheel`) into `.venv` in place of any installed
/// version; the venv's pinned packages are its dependencies (`--no-deps`).
pub fn install_wheel(wheel: &Path) -> Result<(), String> {
    step(&format!(
        "the Python package backlash_fmu (pip install {} into .venv)",
        util::shown(wheel)
    ));
    util::run(venv_pip_install().arg(wheel))
}

/// `pip install` into `.venv` from the repository root, replacing any installed version, with
/// the venv's pinned packages as the dependencies (`--no-deps`).
fn venv_pip_install() -> Command {
    let mut pip = Command::new(venv_python());
    pip.current_dir(util::repo_root()).args([
        "-m",
        "pip",
        "install",
        "--disable-pip-version-check",
        "--quiet",
        "--no-deps",
        "--force-reinstall",
    ]);
    pip
}

/// `PATH` with `.venv/bin` first, where the build finds the venv's `maturin`.
pub fn path_with_venv() -> Result<std::ffi::OsString, String> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    path_with_bin(&venv_dir(), std::env::split_paths(&path))
}

/// A `PATH` of `venv`'s `bin` in front of `dirs`.
pub fn path_with_bin(venv: &Path, dirs: impl Iterator<Item = PathBuf>) -> Result<std::ffi::OsString, String> {
    std::env::join_paths(std::iter::once(venv.join("bin")).chain(dirs))
        .map_err(|e| format!("PATH with {}: {e}", venv.join("bin").display()))
}

fn venv_dir() -> PathBuf {
    util::repo_root().join(".venv")
}

/// A program the venv installed (`maturin`, `auditwheel`).
pub fn venv_bin(program: &str) -> PathBuf {
    venv_dir().join("bin").join(program)
}

/// The venv's interpreter (made by [`ensure_venv`]).
pub fn venv_python() -> PathBuf {
    venv_bin("python")
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

/// The pages whose ```python blocks run: the README, then every page of docs/ (sorted), so that
/// what a user copies from the front page and the user guide is known to work.
pub fn example_pages() -> Result<Vec<PathBuf>, String> {
    let root = util::repo_root();
    let docs = root.join("docs");
    let mut pages: Vec<PathBuf> = fs::read_dir(&docs)
        .map_err(|e| format!("reading {}: {e}", util::shown(&docs)))?
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|path| path.extension().is_some_and(|x| x == "md"))
        .collect();
    pages.sort();
    pages.insert(0, root.join("README.md"));
    Ok(pages)
}

/// Runs every ```python block of README.md and of the pages of docs/ in the venv from the
/// repository root, each in a fresh interpreter. A block whose fence says ```python no-run is
/// shown only (kept rare: each says why). README.md must have at least one block.
pub fn run_readme_example() -> Result<(), String> {
    step("Python examples of README.md and docs/");
    let root = util::repo_root();
    for page in example_pages()? {
        let shown = page.strip_prefix(&root).unwrap_or(&page).display().to_string();
        let text = fs::read_to_string(&page).map_err(|e| format!("reading {shown}: {e}"))?;
        let blocks = python_blocks(&text);
        if blocks.is_empty() && shown == "README.md" {
            return Err("README.md has no ```python block".into());
        }
        for (n, code) in blocks.iter().enumerate() {
            println!("{shown}: Python block {} of {}", n + 1, blocks.len());
            util::run(Command::new(venv_python()).current_dir(&root).arg("-c").arg(code))
                .map_err(|e| format!("{shown}, Python block {}: {e}", n + 1))?;
        }
    }
    Ok(())
}

/// The bodies of the fenced blocks whose info string is exactly `python` (a fence of three
/// backticks at the start of a line; ```python no-run and other languages are skipped).
fn python_blocks(markdown: &str) -> Vec<String> {
    let mut blocks = Vec::new();
    let mut open: Option<(bool, String)> = None;
    for line in markdown.lines() {
        match &mut open {
            None => {
                if let Some(info) = line.strip_prefix("```") {
                    open = Some((info.trim() == "python", String::new()));
                }
            }
            Some((runs, body)) => {
                if line.trim_end() == "```" {
                    if *runs {
                        blocks.push(std::mem::take(body));
                    }
                    open = None;
                } else {
                    body.push_str(line);
                    body.push('\n');
                }
            }
        }
    }
    blocks
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn python_blocks_are_the_fences_that_say_python() {
        let page =
            "text\n```python\nprint(1)\n```\n```sh\nls\n```\n```python no-run\nx\n```\n```python\na = 2\nb = 3\n```\n";
        assert_eq!(
            python_blocks(page),
            vec!["print(1)\n".to_string(), "a = 2\nb = 3\n".to_string()]
        );
    }

    #[test]
    fn every_page_with_examples_is_found() {
        let pages = example_pages().unwrap();
        assert!(pages[0].ends_with("README.md"));
        assert!(pages.iter().any(|p| p.ends_with("docs/simulate-an-fmu.md")));
    }
}
