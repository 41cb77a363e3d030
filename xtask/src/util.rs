//! Paths of the repository and a way to run a child process that reports what it runs and why it
//! failed.

use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus};

/// Top level of the repository (the directory holding the workspace `Cargo.toml`): the parent of
/// xtask's folder as `cargo run` names it to this process (`CARGO_MANIFEST_DIR`), else as it was
/// when this program was built. Cargo reuses a build of the same sources moved elsewhere that
/// share the target directory (pip unpacks each sdist into a folder of its own), and the folder
/// of that build may be gone.
pub fn repo_root() -> PathBuf {
    let built = Path::new(env!("CARGO_MANIFEST_DIR"));
    let given = std::env::var_os("CARGO_MANIFEST_DIR").map(PathBuf::from);
    let manifest = given
        .filter(|dir| dir.file_name() == built.file_name() && dir.join("Cargo.toml").is_file())
        .unwrap_or_else(|| built.to_path_buf());
    manifest
        .parent()
        .expect("xtask lives one level below the repository root")
        .to_path_buf()
}

/// Cargo's target directory: `CARGO_TARGET_DIR` when set, else `<repo>/target`.
pub fn target_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(dir) if !dir.is_empty() => {
            let dir = PathBuf::from(dir);
            if dir.is_absolute() {
                dir
            } else {
                repo_root().join(dir)
            }
        }
        _ => repo_root().join("target"),
    }
}

/// Where `cargo xtask fmu` writes the archives and the tests look for them.
pub fn fmu_dir() -> PathBuf {
    target_dir().join("fmu")
}

/// The cargo that runs this program (so that `cargo +toolchain xtask` keeps its toolchain).
pub fn cargo() -> Command {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.current_dir(repo_root());
    cmd
}

/// A progress line, so that a long `cargo xtask test` log shows where it is.
pub fn step(message: &str) {
    println!("\n==> {message}");
}

fn describe(cmd: &Command) -> String {
    let mut text = cmd.get_program().to_string_lossy().into_owned();
    for arg in cmd.get_args() {
        text.push(' ');
        text.push_str(&arg.to_string_lossy());
    }
    text
}

/// Runs `cmd` with inherited output; returns its exit status, or an error if it could not start.
pub fn status(cmd: &mut Command) -> Result<ExitStatus, String> {
    let text = describe(cmd);
    println!("$ {text}");
    cmd.status().map_err(|e| format!("could not start `{text}`: {e}"))
}

/// Runs `cmd` with inherited output; any non-zero exit is an error naming the command.
pub fn run(cmd: &mut Command) -> Result<(), String> {
    let text = describe(cmd);
    let status = status(cmd)?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("`{text}` failed ({status})"))
    }
}

/// Runs `cmd` and returns its standard output; a non-zero exit is an error carrying its stderr.
pub fn output(cmd: &mut Command) -> Result<String, String> {
    let text = describe(cmd);
    let out = cmd.output().map_err(|e| format!("could not start `{text}`: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "`{text}` failed ({}):\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    String::from_utf8(out.stdout).map_err(|_| format!("`{text}` printed non-UTF-8 output"))
}

/// Path relative to the repository root when possible, for messages.
pub fn shown(path: &Path) -> String {
    path.strip_prefix(repo_root()).unwrap_or(path).display().to_string()
}
