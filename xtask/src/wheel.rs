//! `cargo xtask wheel`: the Python package `backlash_fmu` as the two files a user installs
//! without this repository, in `dist/`:
//!
//! - `backlash_fmu-<version>-cp39-abi3-<manylinux>.whl`: the native module (abi3, one wheel for
//!   every CPython from 3.9), every model's archives (FMI 2.0 and 3.0, the controller's too) with
//!   the binaries of every platform built, their manifests and the packed systems. maturin tags it
//!   with the manylinux policy it meets; `auditwheel show` (PyPI auditwheel, pinned in
//!   tests/python/requirements.txt) must confirm it. The FMU libraries are zip members of the
//!   archives, not files of the wheel, so the audit sees the native module alone;
//! - `backlash_fmu-<version>.tar.gz`: the sdist, the whole workspace the wheel is built from
//!   (the build backend's `build_sdist`), which `pip install` builds where cargo is present.
//!
//! The version is the workspace's (Cargo.toml, `[workspace.package]`): maturin reads it from the
//! binding's crate, xtask from its own, both inheriting it.
//!
//! Also the two install tests of `cargo xtask test`: the wheel in a fresh venv whose PATH holds
//! no cargo or rustc ([`test_without_cargo`]), and the sdist installed where cargo is present
//! ([`test_sdist`]); both run tests/install/check_installed.py with the venv's interpreter.

use std::fs;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use crate::platform::{self, Platform};
use crate::util::{self, step};
use crate::{cross, fmu, python, systems};

/// The workspace's version, which the wheel and the sdist carry in their names.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
/// The distribution's name, as the file names spell it.
const NAME: &str = "backlash_fmu";

const USAGE: &str = "usage: cargo xtask wheel [--all-platforms | --linux64] [--test]

Writes dist/backlash_fmu-<version>-cp39-abi3-<manylinux>.whl and dist/backlash_fmu-<version>.tar.gz.
The wheel's archives carry the binaries of every platform when this machine has the cross tools
(README.md, \"Windows and ARM binaries\"), else linux64's only, and the command says so.
  --all-platforms   every platform or an error naming the missing tools
  --linux64         linux64 binaries only
  --test            then install each file into a fresh venv and check it there (as steps 9
                    and 10 of `cargo xtask test`): the wheel with no cargo or rustc on PATH, the
                    sdist built by pip where cargo is present";

/// The files `cargo xtask wheel` wrote.
pub struct Distribution {
    pub wheel: PathBuf,
    pub sdist: PathBuf,
}

pub fn run(args: &[String]) -> Result<(), String> {
    let mut test = false;
    let mut choice: Option<&str> = None;
    for arg in args {
        match arg.as_str() {
            "--test" => test = true,
            "--all-platforms" | "--linux64" if choice.is_none() => choice = Some(arg.as_str()),
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(());
            }
            other => return Err(format!("unexpected argument `{other}`\n{USAGE}")),
        }
    }
    let platforms = match choice {
        None => match cross::unavailable() {
            None => platform::ALL.to_vec(),
            Some(line) => {
                println!("the wheel's archives will carry linux64 binaries only ({line})");
                vec![&platform::LINUX64]
            }
        },
        Some("--all-platforms") => match cross::unavailable() {
            None => platform::ALL.to_vec(),
            Some(line) => return Err(format!("--all-platforms: {line}")),
        },
        Some(_) => vec![&platform::LINUX64],
    };
    python::ensure_venv()?;
    let built = build(&platforms)?;
    if test {
        step("the wheel in a fresh venv, no cargo or rustc on PATH");
        test_without_cargo(&built.wheel)?;
        step("the sdist installed with pip into a fresh venv, cargo present");
        test_sdist(&built.sdist)?;
    }
    step("cargo xtask wheel: done");
    println!(
        "{} (archives with the binaries of {})",
        util::shown(&built.wheel),
        names(&platforms)
    );
    println!("{}", util::shown(&built.sdist));
    Ok(())
}

/// The folder the distributions are written to.
pub fn dist_dir() -> PathBuf {
    util::repo_root().join("dist")
}

/// Where the package's build takes its archives from (ignored by git).
fn package_archives() -> PathBuf {
    util::repo_root().join("python").join("backlash_fmu").join("archives")
}

/// Packs the archives of `platforms` into the package, then writes the wheel (audited) and the
/// sdist into `dist/`, replacing those of this version.
pub fn build(platforms: &[&'static Platform]) -> Result<Distribution, String> {
    let archives = package_archives();
    step(&format!(
        "the package's archives ({}; {})",
        util::shown(&archives),
        names(platforms)
    ));
    if archives.exists() {
        fs::remove_dir_all(&archives).map_err(|e| format!("removing {}: {e}", archives.display()))?;
    }
    fmu::package_into(platforms, &archives)?;

    let dist = dist_dir();
    fs::create_dir_all(&dist).map_err(|e| format!("creating {}: {e}", dist.display()))?;
    for old in ours(&dist)? {
        fs::remove_file(&old).map_err(|e| format!("removing {}: {e}", old.display()))?;
    }

    step("the wheel (maturin build --release)");
    util::run(
        Command::new(python::venv_bin("maturin"))
            .env("PATH", python::path_with_venv()?)
            .current_dir(util::repo_root())
            .args(["build", "--release", "--locked", "--out"])
            .arg(&dist),
    )?;
    let wheel = only(&dist, ".whl")?;
    check_wheel(&wheel, platforms)?;

    step("the sdist (the build backend's build_sdist: the whole workspace)");
    util::run(
        Command::new(python::venv_python())
            .env("PATH", python::path_with_venv()?)
            .current_dir(util::repo_root())
            .args([
                "-c",
                "import sys; sys.path.insert(0, 'python/backend'); import backlash_backend; \
                 backlash_backend.build_sdist(sys.argv[1])",
            ])
            .arg(&dist),
    )?;
    let sdist = only(&dist, ".tar.gz")?;
    println!(
        "wrote {} ({} bytes)",
        util::shown(&sdist),
        fs::metadata(&sdist).map(|m| m.len()).unwrap_or(0)
    );
    Ok(Distribution { wheel, sdist })
}

fn names(platforms: &[&Platform]) -> String {
    platforms.iter().map(|p| p.name).collect::<Vec<_>>().join(", ")
}

/// The wheels and sdists of this version in `dist`.
fn ours(dist: &Path) -> Result<Vec<PathBuf>, String> {
    let prefix_wheel = format!("{NAME}-{VERSION}-");
    let sdist = format!("{NAME}-{VERSION}.tar.gz");
    let entries = fs::read_dir(dist).map_err(|e| format!("reading {}: {e}", dist.display()))?;
    Ok(entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            let name = p
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            (name.starts_with(&prefix_wheel) && name.ends_with(".whl")) || name == sdist
        })
        .collect())
}

/// The one file of this version in `dist` ending in `suffix`.
fn only(dist: &Path, suffix: &str) -> Result<PathBuf, String> {
    let found: Vec<PathBuf> = ours(dist)?
        .into_iter()
        .filter(|p| p.to_string_lossy().ends_with(suffix))
        .collect();
    match found.as_slice() {
        [one] => Ok(one.clone()),
        [] => Err(format!(
            "no {NAME}-{VERSION}*{suffix} in {}: the package's version is not the workspace's {VERSION}?",
            util::shown(dist)
        )),
        many => Err(format!(
            "several {suffix} of {VERSION} in {}: {many:?}",
            util::shown(dist)
        )),
    }
}

/// The wheel's platform tag is one `auditwheel show` says it meets, and the wheel carries every
/// archive of every standard, the manifests and the packed systems.
fn check_wheel(wheel: &Path, platforms: &[&Platform]) -> Result<(), String> {
    step("auditwheel show (the manylinux policy the wheel meets)");
    let shown = util::output(Command::new(python::venv_bin("auditwheel")).arg("show").arg(wheel))?;
    print!("{shown}");
    let met = audited_tag(&shown).ok_or_else(|| format!("auditwheel show: no platform tag in its answer:\n{shown}"))?;
    let name = wheel.file_name().unwrap_or_default().to_string_lossy().into_owned();
    let tags = name
        .strip_suffix(".whl")
        .and_then(|stem| stem.rsplit('-').next())
        .ok_or_else(|| format!("{name}: not a wheel's file name"))?;
    for tag in tags.split('.') {
        if !meets(tag, &met) {
            return Err(format!(
                "{name}: its platform tag {tag} is not one the wheel meets (auditwheel: {met})"
            ));
        }
    }
    println!("{name}: tag {tags}, auditwheel: consistent with {met}");

    let file = fs::File::open(wheel).map_err(|e| format!("{}: {e}", wheel.display()))?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| format!("{}: not a zip archive: {e}", wheel.display()))?;
    let members = entry_names(&zip).map_err(|e| format!("{name}: {e}"))?;
    let mut expected: Vec<String> = Vec::new();
    let ids = model_description::model_identifiers();
    let controllers = model_description::controller_identifiers();
    for standard in fmu::STANDARDS {
        let dir = Path::new(NAME).join("archives").join(standard.subdir);
        for id in ids.iter().chain(controllers) {
            expected.push(dir.join(format!("{id}.fmu")).to_string_lossy().into_owned());
        }
        expected.push(dir.join(fmu::MANIFEST).to_string_lossy().into_owned());
        expected.push(dir.join(fmu::CONTROLLER_MANIFEST).to_string_lossy().into_owned());
    }
    for system in systems::system_names()? {
        expected.push(format!("{NAME}/archives/systems/{system}.ssp"));
    }
    let missing: Vec<&String> = expected.iter().filter(|m| !members.contains(m)).collect();
    if !missing.is_empty() {
        return Err(format!("{name} lacks {missing:?}"));
    }
    // Each archive's binaries are the platforms packed (fmu::package_into checked each archive
    // as written; here the copy in the wheel).
    let mut shaft = Vec::new();
    zip.by_name(&format!("{NAME}/archives/fmi3/BacklashShaft.fmu"))
        .map_err(|e| format!("{name}: {e}"))?
        .read_to_end(&mut shaft)
        .map_err(|e| format!("{name}: {e}"))?;
    let inner = zip::ZipArchive::new(std::io::Cursor::new(shaft)).map_err(|e| format!("{name}: {e}"))?;
    for p in platforms {
        let entry = format!("binaries/{}/{}", p.fmi3_folder, p.archive_file("BacklashShaft"));
        if !entry_names(&inner)
            .map_err(|e| format!("{name}: {e}"))?
            .contains(&entry)
        {
            return Err(format!("{name}: the FMI 3.0 BacklashShaft.fmu lacks {entry}"));
        }
    }
    let loose: Vec<&String> = members
        .iter()
        .filter(|m| m.ends_with(".so") || m.contains(".so.") || m.ends_with(".dll"))
        .collect();
    println!(
        "{name}: {} archives and manifests, {} systems, binaries of {}; loose shared libraries: {loose:?}",
        expected.len(),
        systems::system_names()?.len(),
        names(platforms)
    );
    Ok(())
}

fn entry_names<R: std::io::Read + std::io::Seek>(
    zip: &zip::ZipArchive<R>,
) -> Result<Vec<String>, zip::result::ZipError> {
    zip.file_names().map(|n| n.map(|n| n.into_owned())).collect()
}

/// The tag of auditwheel's "is consistent with the following platform tag: "<tag>"" (its text
/// wraps lines anywhere between words).
fn audited_tag(text: &str) -> Option<String> {
    let words: Vec<&str> = text.split_whitespace().collect();
    let joined = words.join(" ");
    let rest = joined.split("following platform tag: ").nth(1)?;
    let tag = rest.split_whitespace().next()?.trim_matches(|c| c == '"' || c == '.');
    Some(tag.to_string())
}

/// Whether a wheel audited as `met` (`manylinux_2_35_x86_64`) may carry the platform tag `tag`:
/// a manylinux tag of the same architecture and a glibc no older than the audited one.
fn meets(tag: &str, met: &str) -> bool {
    match (manylinux(tag), manylinux(met)) {
        (Some((glibc, arch)), Some((needed, met_arch))) => arch == met_arch && glibc >= needed,
        _ => false,
    }
}

/// (glibc (major, minor), architecture) of a manylinux tag, the legacy aliases included.
fn manylinux(tag: &str) -> Option<((u32, u32), &str)> {
    for (alias, glibc) in [
        ("manylinux2014_", (2, 17)),
        ("manylinux2010_", (2, 12)),
        ("manylinux1_", (2, 5)),
    ] {
        if let Some(arch) = tag.strip_prefix(alias) {
            return Some((glibc, arch));
        }
    }
    let rest = tag.strip_prefix("manylinux_")?;
    let mut parts = rest.splitn(3, '_');
    let major = parts.next()?.parse().ok()?;
    let minor = parts.next()?.parse().ok()?;
    Some(((major, minor), parts.next()?))
}

/// A fresh venv at `dir/venv` from the base Python (the one `.venv` is made from).
fn fresh_venv(dir: &Path) -> Result<PathBuf, String> {
    if dir.exists() {
        fs::remove_dir_all(dir).map_err(|e| format!("removing {}: {e}", dir.display()))?;
    }
    fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    let venv = dir.join("venv");
    util::run(Command::new(python::base_python()).args(["-m", "venv"]).arg(&venv))?;
    Ok(venv)
}

/// The pinned versions, as constraints: the fresh venvs resolve the package's dependencies from
/// its metadata, as a user's pip does, at the versions the project tests.
fn constraints() -> PathBuf {
    util::repo_root().join("tests").join("python").join("requirements.txt")
}

/// The check run in each fresh venv.
fn check_script() -> PathBuf {
    util::repo_root()
        .join("tests")
        .join("install")
        .join("check_installed.py")
}

/// A command of `venv` with the environment a user's shell gives it: `PATH` as given, without
/// what cargo sets for the programs it runs (`CARGO*`, `RUSTUP*`, the toolchain's
/// `LD_LIBRARY_PATH`).
fn in_venv(venv: &Path, program: &str, path: &std::ffi::OsStr, cwd: &Path) -> Command {
    let mut cmd = Command::new(venv.join("bin").join(program));
    for (key, _) in std::env::vars_os() {
        let key = key.to_string_lossy();
        if key.starts_with("CARGO") || key.starts_with("RUSTUP") || key.starts_with("RUSTC") || key == "LD_LIBRARY_PATH"
        {
            cmd.env_remove(key.as_ref());
        }
    }
    cmd.env("PATH", path)
        .env("PIP_DISABLE_PIP_VERSION_CHECK", "1")
        .current_dir(cwd);
    cmd
}

/// `PATH` without every folder that holds a `cargo` or `rustc`, behind the venv's `bin`.
fn path_without_cargo(venv: &Path) -> Result<std::ffi::OsString, String> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    let kept: Vec<PathBuf> = std::env::split_paths(&path)
        .filter(|dir| !["cargo", "rustc"].iter().any(|tool| dir.join(tool).exists()))
        .collect();
    let dropped: Vec<String> = std::env::split_paths(&path)
        .filter(|dir| !kept.contains(dir))
        .map(|dir| dir.display().to_string())
        .collect();
    println!(
        "PATH without the folders that hold cargo or rustc: {}",
        dropped.join(", ")
    );
    python::path_with_bin(venv, kept.into_iter())
}

/// The wheel installed into a fresh venv and run there with a `PATH` that holds no cargo or
/// rustc: pip resolves the dependencies from PyPI (pinned versions as constraints), then
/// tests/install/check_installed.py --without-cargo runs from a folder outside the repository.
pub fn test_without_cargo(wheel: &Path) -> Result<(), String> {
    let started = Instant::now();
    let dir = util::target_dir().join("install-test").join("wheel");
    let venv = fresh_venv(&dir)?;
    let path = path_without_cargo(&venv)?;
    util::run(
        in_venv(&venv, "python", &path, &dir)
            .args(["-m", "pip", "install", "--quiet", "-c"])
            .arg(constraints())
            .arg(wheel),
    )?;
    util::run(
        in_venv(&venv, "python", &path, &dir)
            .arg(check_script())
            .arg("--without-cargo"),
    )?;
    println!("the wheel without cargo: {:.0} s", started.elapsed().as_secs_f64());
    Ok(())
}

/// The sdist installed with pip into a fresh venv where cargo is present (build isolation:
/// pip fetches maturin), building in `target/sdist-build` (`CARGO_TARGET_DIR`), kept between
/// runs so that a rebuild is incremental and the main build's outputs are never touched; then
/// tests/install/check_installed.py on what it installed.
pub fn test_sdist(sdist: &Path) -> Result<(), String> {
    let started = Instant::now();
    let dir = util::target_dir().join("install-test").join("sdist");
    let venv = fresh_venv(&dir)?;
    let path = python::path_with_bin(
        &venv,
        std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default()),
    )?;
    println!("pip builds the workspace from the sdist: minutes while target/sdist-build is cold");
    util::run(
        in_venv(&venv, "python", &path, &dir)
            .env("CARGO_TARGET_DIR", util::target_dir().join("sdist-build"))
            .args(["-m", "pip", "install", "--quiet", "-c"])
            .arg(constraints())
            .arg(sdist),
    )?;
    util::run(in_venv(&venv, "python", &path, &dir).arg(check_script()))?;
    println!("the sdist with cargo: {:.0} s", started.elapsed().as_secs_f64());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_audited_tag_is_read_from_wrapped_text() {
        let text = "\nbacklash_fmu-0.1.0-cp39-abi3-linux_x86_64.whl is consistent with the\nfollowing platform tag: \"manylinux_2_35_x86_64\".\n\nThe wheel references ...";
        assert_eq!(audited_tag(text).as_deref(), Some("manylinux_2_35_x86_64"));
        assert_eq!(audited_tag("nothing"), None);
    }

    #[test]
    fn a_tag_is_met_by_the_audited_glibc_or_a_newer_one() {
        assert!(meets("manylinux_2_35_x86_64", "manylinux_2_35_x86_64"));
        assert!(meets("manylinux_2_36_x86_64", "manylinux_2_35_x86_64"));
        assert!(!meets("manylinux_2_17_x86_64", "manylinux_2_35_x86_64"));
        assert!(meets("manylinux2014_x86_64", "manylinux_2_17_x86_64"));
        assert!(!meets("manylinux_2_35_aarch64", "manylinux_2_35_x86_64"));
        assert!(!meets("linux_x86_64", "manylinux_2_35_x86_64"));
        assert!(!meets("manylinux_2_35_x86_64", "linux_x86_64"));
    }
}
