//! The cross test's host program (tests/cross/host.c), compiled for a platform and run on this
//! machine: natively, under Wine, or under qemu-user.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::abi::HeaderDirs;
use crate::platform::{BinaryFormat, Platform, Runner};
use crate::util;

/// The host built for one platform, ready to run.
pub struct Host {
    pub platform: &'static Platform,
    program: PathBuf,
    /// Wine's configuration directory, made on the first run (Windows only).
    wine_prefix: PathBuf,
}

fn source(name: &str) -> PathBuf {
    util::repo_root().join("tests").join("cross").join(name)
}

/// Compiles the host for `platform` into `dir/<platform>/`, with the official FMI 2.0 and FMI 3.0
/// headers of `headers`. For Windows also the test-only stand-in of bcryptprimitives.dll beside it
/// (see tests/cross/bcryptprimitives.c), so that Wine loads Rust's DLL as Windows 10 would.
pub fn compile(platform: &'static Platform, headers: &HeaderDirs, dir: &Path) -> Result<Host, String> {
    let out = dir.join(platform.name);
    fs::create_dir_all(&out).map_err(|e| format!("creating {}: {e}", out.display()))?;
    let program = out.join(match platform.format {
        BinaryFormat::Pe => "host.exe",
        BinaryFormat::Elf => "host",
    });
    let mut cc = Command::new(platform.c_compiler.command);
    // -ffp-contract=off: no fused multiply-add in the host's own arithmetic (GCC fuses by default
    // on aarch64), so that every platform computes the same inputs for the FMU.
    cc.args([
        "-std=c99",
        "-O2",
        "-Wall",
        "-Wextra",
        "-Werror",
        "-ffp-contract=off",
        "-I",
    ])
    .arg(&headers.fmi2)
    .arg("-I")
    .arg(&headers.fmi3)
    .arg(source("host.c"))
    .arg("-o")
    .arg(&program);
    if platform.format == BinaryFormat::Elf {
        cc.arg("-ldl");
    }
    util::run(&mut cc)?;
    if platform.format == BinaryFormat::Pe {
        util::run(
            Command::new(platform.c_compiler.command)
                .args(["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-shared"])
                .arg(source("bcryptprimitives.c"))
                .arg("-o")
                .arg(out.join("bcryptprimitives.dll"))
                .arg("-lbcrypt"),
        )?;
    }
    Ok(Host {
        platform,
        program,
        wine_prefix: dir.join("wine-prefix"),
    })
}

impl Host {
    /// A path as the host program sees it: Wine maps the Unix root to drive Z:.
    pub fn path_argument(&self, path: &Path) -> String {
        match self.platform.runner {
            Runner::Wine(_) => format!("Z:{}", path.display()).replace('/', "\\"),
            _ => path.display().to_string(),
        }
    }

    /// Runs the host with `args`; its standard output, or an error with its standard error.
    ///
    /// The output goes through files rather than pipes: Wine's server, started by the first
    /// Windows program and lingering a few seconds after the last, inherits the program's
    /// descriptors, and reading a pipe to its end would wait for the server too.
    pub fn run(&self, args: &[String]) -> Result<String, String> {
        let mut cmd = match self.platform.runner {
            Runner::Native => Command::new(&self.program),
            Runner::Wine(wine) => {
                let mut cmd = Command::new(wine.command);
                cmd.arg(&self.program)
                    .env("WINEPREFIX", &self.wine_prefix)
                    .env("WINEDEBUG", "-all")
                    // No Mono or Gecko installer when the prefix is made: the host needs neither.
                    .env("WINEDLLOVERRIDES", "mscoree,mshtml=");
                cmd
            }
            Runner::QemuUser { qemu, sysroot } => {
                let mut cmd = Command::new(qemu.command);
                cmd.args(["-L", sysroot]).arg(&self.program);
                cmd
            }
        };
        let dir = self.program.parent().expect("the host is in a folder");
        let (stdout_path, stderr_path) = (dir.join("stdout.txt"), dir.join("stderr.txt"));
        let open = |path: &Path| fs::File::create(path).map_err(|e| format!("creating {}: {e}", path.display()));
        cmd.args(args).stdout(open(&stdout_path)?).stderr(open(&stderr_path)?);
        let status = cmd.status().map_err(|e| {
            format!(
                "{} host: could not start {:?}: {e}",
                self.platform.name,
                cmd.get_program()
            )
        })?;
        let read = |path: &Path| fs::read_to_string(path).map_err(|e| format!("reading {}: {e}", path.display()));
        if !status.success() {
            return Err(format!(
                "{} host `{}` failed ({status}):\n{}",
                self.platform.name,
                args.join(" "),
                read(&stderr_path)?.trim_end()
            ));
        }
        read(&stdout_path)
    }
}
