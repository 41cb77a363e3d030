//! Builds the cdylib for a platform other than this machine's.
//!
//! Two routes to the target's standard library, tried in order:
//! 1. the toolchain running this command has it (`rustup target add <target>`): plain
//!    `cargo build --target`;
//! 2. Debian's own Rust (`rustc-web`, `cargo-web` and its sources `rust-web-src`, installed
//!    together so that the sources are the compiler's): cargo builds the standard library from
//!    those sources (`-Zbuild-std`, allowed on a stable compiler by `RUSTC_BOOTSTRAP=1`).
//!
//! Either way the platform's C compiler links, and the output goes to `target/cross/<target>/`.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use crate::platform::{Built, Platform, Tool};
use crate::util::{self, step};

/// Debian's Rust (packages rustc-web, cargo-web; on Debian 13 and later rustc, cargo).
const DEBIAN_RUSTC: &str = "/usr/bin/rustc";
const DEBIAN_CARGO: &str = "/usr/bin/cargo";
/// The Debian 12 packages of a Rust recent enough for this workspace (bookworm-security carries
/// rustc-web 1.96), in one command so that the standard library's sources match the compiler.
pub const DEBIAN_RUST_PACKAGES: &str = "rustc-web cargo-web rust-web-src";

/// Where the standard library of `platform` comes from.
enum Route {
    /// The running toolchain ships the target's standard library.
    Installed,
    /// Debian's compiler, building the standard library from its sources.
    DebianBuildStd,
}

/// The cross-built library's path (whether or not it exists yet).
pub fn library_path(platform: &Platform) -> PathBuf {
    cross_target_dir()
        .join(platform.rust_target)
        .join("release")
        .join(platform.library_file)
}

/// Separate from the host build: another compiler's artifacts never invalidate the host's.
fn cross_target_dir() -> PathBuf {
    util::target_dir().join("cross")
}

/// Builds the release cdylib for `platform`; its one-line error names what to install.
pub fn build(platform: &'static Platform) -> Result<Built, String> {
    let route = route(platform)?;
    let missing = missing_tools(&[platform.c_compiler]);
    if !missing.is_empty() {
        return Err(install_line(platform.name, &missing));
    }
    let how = match route {
        Route::Installed => "the running toolchain's standard library",
        Route::DebianBuildStd => "Debian's rustc, standard library built from its sources",
    };
    step(&format!(
        "building the FMU library for {} ({}; {how})",
        platform.name, platform.rust_target
    ));
    let started = Instant::now();
    let linker_variable = format!(
        "CARGO_TARGET_{}_LINKER",
        platform.rust_target.to_uppercase().replace('-', "_")
    );
    let mut cmd = match route {
        Route::Installed => util::cargo(),
        Route::DebianBuildStd => {
            let mut cmd = Command::new(DEBIAN_CARGO);
            cmd.current_dir(util::repo_root())
                .env("RUSTC", DEBIAN_RUSTC)
                .env("RUSTC_BOOTSTRAP", "1")
                // The rustup proxies' choice of toolchain must not leak into Debian's cargo.
                .env_remove("RUSTUP_TOOLCHAIN")
                .env_remove("RUSTDOC");
            cmd
        }
    };
    cmd.env("CARGO_TARGET_DIR", cross_target_dir())
        .env(linker_variable, platform.c_compiler.command)
        .args([
            "build",
            "--release",
            "--locked",
            "--package",
            "backlash-fmu",
            "--lib",
            "--target",
        ])
        .arg(platform.rust_target);
    if let Route::DebianBuildStd = route {
        // panic_abort beside std: the profile's panic = "unwind" uses std's panic_unwind, but
        // build-std wants both runtimes available.
        cmd.arg("-Zbuild-std=std,panic_abort");
    }
    util::run(&mut cmd)?;
    let path = library_path(platform);
    if !path.is_file() {
        return Err(format!("cargo build succeeded but {} is missing", path.display()));
    }
    println!(
        "{}: built {} in {:.1} min",
        platform.name,
        util::shown(&path),
        started.elapsed().as_secs_f64() / 60.0
    );
    Ok(Built { platform, path })
}

/// The tools of `tools` that are not on PATH.
pub fn missing_tools(tools: &[Tool]) -> Vec<Tool> {
    tools.iter().copied().filter(|tool| !on_path(tool.command)).collect()
}

fn on_path(command: &str) -> bool {
    std::env::var_os("PATH")
        .map(|path| std::env::split_paths(&path).any(|dir| is_executable(&dir.join(command))))
        .unwrap_or(false)
}

fn is_executable(path: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    fs::metadata(path).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

/// One line: what is missing for what, and the apt command that brings it.
pub fn install_line(purpose: &str, missing: &[Tool]) -> String {
    let commands: Vec<&str> = missing.iter().map(|t| t.command).collect();
    let mut packages: Vec<&str> = Vec::new();
    for package in missing.iter().flat_map(|t| t.package.split(' ')) {
        if !packages.contains(&package) {
            packages.push(package);
        }
    }
    format!(
        "{purpose}: {} not found; install with `apt-get install {}`",
        commands.join(", "),
        packages.join(" ")
    )
}

/// Ok if this machine can get a standard library for each of `platforms`; else one line saying
/// what to install.
pub fn standard_libraries(platforms: &[&Platform]) -> Result<(), String> {
    let lacking: Vec<&str> = platforms
        .iter()
        .filter(|p| !running_toolchain_has(p.rust_target))
        .map(|p| p.rust_target)
        .collect();
    if lacking.is_empty() {
        return Ok(());
    }
    debian_rust_usable().map_err(|reason| no_standard_library(&lacking, &reason))
}

fn no_standard_library(targets: &[&str], reason: &str) -> String {
    format!(
        "no Rust standard library for {} ({reason}): install it with `rustup target add {}`, or without \
         rustup targets `apt-get install {DEBIAN_RUST_PACKAGES}`",
        targets.join(", "),
        targets.join(" ")
    )
}

/// Where the standard library for `platform` comes from; an error is the one line saying what
/// to install.
fn route(platform: &Platform) -> Result<Route, String> {
    if running_toolchain_has(platform.rust_target) {
        return Ok(Route::Installed);
    }
    debian_rust_usable()
        .map(|()| Route::DebianBuildStd)
        .map_err(|reason| no_standard_library(&[platform.rust_target], &reason))
}

/// True if the sysroot of the `rustc` that cargo runs holds a compiled standard library for
/// `target` (what `rustup target add` installs).
fn running_toolchain_has(target: &str) -> bool {
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    let Ok(sysroot) = util::output(Command::new(rustc).args(["--print", "sysroot"])) else {
        return false;
    };
    let lib = Path::new(sysroot.trim())
        .join("lib")
        .join("rustlib")
        .join(target)
        .join("lib");
    fs::read_dir(lib).is_ok_and(|entries| {
        entries
            .flatten()
            .any(|e| e.file_name().to_string_lossy().starts_with("libstd-"))
    })
}

/// Debian's compiler is usable if cargo, the compiler and the standard library's sources are
/// there, the compiler is at least the workspace's rust-version, and the sources are its own.
fn debian_rust_usable() -> Result<(), String> {
    for tool in [DEBIAN_RUSTC, DEBIAN_CARGO] {
        if !is_executable(Path::new(tool)) {
            return Err(format!("{tool} not found"));
        }
    }
    let version_line = util::output(Command::new(DEBIAN_RUSTC).arg("--version"))?;
    let version = parse_version(&version_line).ok_or_else(|| format!("cannot read `{}`", version_line.trim()))?;
    let required = workspace_rust_version()?;
    if version < required {
        return Err(format!(
            "{DEBIAN_RUSTC} is {}, older than the workspace's rust-version {}; Debian 12 has a newer \
             rustc-web in bookworm-security",
            show(version),
            show(required)
        ));
    }
    let sysroot = util::output(Command::new(DEBIAN_RUSTC).args(["--print", "sysroot"]))?;
    let sources = Path::new(sysroot.trim()).join("lib/rustlib/src/rust");
    if !sources.join("library/std/Cargo.toml").is_file() {
        return Err(format!("{} has no standard library sources", sources.display()));
    }
    // Debian installs the sources as /usr/src/rustc-<version>; other layouts are not checked.
    if let Some(source_version) = fs::canonicalize(&sources)
        .ok()
        .and_then(|dir| dir.file_name().map(|n| n.to_string_lossy().into_owned()))
        .and_then(|name| name.strip_prefix("rustc-").and_then(parse_version))
    {
        if source_version != version {
            return Err(format!(
                "the standard library sources are {} but {DEBIAN_RUSTC} is {}",
                show(source_version),
                show(version)
            ));
        }
    }
    Ok(())
}

type Version = (u32, u32, u32);

fn show((major, minor, patch): Version) -> String {
    format!("{major}.{minor}.{patch}")
}

/// The first `X.Y` or `X.Y.Z` in `text` ("rustc 1.96.0 (ac68faa20 2026-05-25)", "1.89").
fn parse_version(text: &str) -> Option<Version> {
    text.split(|c: char| c.is_whitespace() || c == '"').find_map(|word| {
        let mut numbers = word.split('.').map(|n| n.parse::<u32>().ok());
        let major = numbers.next()??;
        let minor = numbers.next()??;
        let patch = numbers.next().unwrap_or(Some(0))?;
        numbers.next().is_none().then_some((major, minor, patch))
    })
}

/// `rust-version` of the root Cargo.toml.
fn workspace_rust_version() -> Result<Version, String> {
    let manifest = util::repo_root().join("Cargo.toml");
    let text = fs::read_to_string(&manifest).map_err(|e| format!("reading {}: {e}", manifest.display()))?;
    text.lines()
        .find_map(|line| {
            let value = line
                .trim()
                .strip_prefix("rust-version")?
                .trim_start()
                .strip_prefix('=')?;
            parse_version(value.trim())
        })
        .ok_or_else(|| format!("{} declares no rust-version", manifest.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn versions_are_read_from_rustc_and_from_the_manifest() {
        assert_eq!(parse_version("rustc 1.96.0 (ac68faa20 2026-05-25)"), Some((1, 96, 0)));
        assert_eq!(parse_version("\"1.89\""), Some((1, 89, 0)));
        assert_eq!(
            parse_version("rustc-1.96.0".strip_prefix("rustc-").unwrap()),
            Some((1, 96, 0))
        );
        assert!((1, 85, 0) < (1, 89, 0) && (1, 96, 0) > (1, 89, 0));
        assert_eq!(workspace_rust_version().unwrap(), (1, 89, 0));
    }

    #[test]
    #[cfg(all(target_os = "linux", target_arch = "x86_64", target_env = "gnu"))]
    fn the_running_toolchain_has_its_own_target_and_no_made_up_one() {
        // The toolchain that builds this test has the host's standard library in its sysroot.
        assert!(running_toolchain_has(crate::platform::LINUX64.rust_target));
        assert!(!running_toolchain_has("x86_64-nowhere-none"));
    }

    #[test]
    fn a_missing_tool_is_one_line_with_the_apt_command() {
        let missing = [
            Tool {
                command: "x86_64-w64-mingw32-gcc",
                package: "gcc-mingw-w64-x86-64",
            },
            Tool {
                command: "wine",
                package: "wine wine64",
            },
        ];
        let line = install_line("win64", &missing);
        assert!(!line.contains('\n'));
        assert!(
            line.ends_with("`apt-get install gcc-mingw-w64-x86-64 wine wine64`"),
            "{line}"
        );
        assert!(
            missing_tools(&[Tool {
                command: "no-such-tool-anywhere",
                package: "x"
            }])
            .len()
                == 1
        );
    }
}
