//! Developer commands of the backlash-fmu workspace, run as `cargo xtask <command>`.

mod abi;
mod bench;
mod cross;
mod demo;
mod documentation;
mod fmu;
mod kit;
mod platform;
mod python;
mod reference;
mod rigs;
mod sweep;
mod systems;
mod test;
mod util;
mod wheel;

const USAGE: &str = "\
usage: cargo xtask <command> [args]

commands:
  fmu       build the cdylib (release) and write target/fmu/<model>.fmu for every model;
            --all-platforms: also build win64 (packed) and aarch64-linux; --out DIR: there
  test      run every check in order: Python venv, cargo test --workspace, fmu, ABI check,
            importer test (fmi crate), the wheel and sdist (as `wheel`) with the wheel installed
            into .venv, pytest, the Python examples of README.md and docs/, the wheel in a fresh
            venv without cargo or rustc on PATH, the sdist installed where cargo is, and the
            cross-platform test when the cross tools are present (--cross: required, --no-cross:
            skipped); stops at the first failure
  abi       check the cdylib's C ABI against the official FMI 2.0 headers and list its exports
            (--all-platforms: every platform's library)
  cross-test
            build every platform, then run the win64 DLL under Wine and the aarch64-linux
            library under qemu against linux64
  wheel     the Python package as dist/backlash_fmu-<version>-*.whl (the native module abi3,
            manylinux as auditwheel confirms, every archive with every platform's binaries the
            cross tools build, and the systems) and the sdist dist/backlash_fmu-<version>.tar.gz
            (see `cargo xtask wheel --help`)
  pytest    the Python part alone: .venv, the package installed, pytest on its archives, the
            Python examples of README.md and docs/
  demo      the main demonstration (see `cargo xtask demo --help`)
  design    the design study: `backlash design` of the design crate (see `cargo xtask design --help`)
  sweep     tolerance sweep on Dask: many drives drawn from tolerances (see `cargo xtask sweep --help`)
  bench     every benchmark, and BENCHMARKS.md generated from the run
  docs      write docs/fmu-reference.md from the model descriptions (--check: fail if the
            committed page differs)
  help      this text";

fn main() {
    // Rust ignores SIGPIPE, so printing into a pipe its reader has closed (`| head`) would
    // panic; with the default action the process ends quietly there, as other tools do.
    #[cfg(unix)]
    // SAFETY: sets a signal disposition to its default before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (command, rest) = match args.split_first() {
        Some((command, rest)) => (command.as_str(), rest),
        None => {
            eprintln!("{USAGE}");
            std::process::exit(2);
        }
    };
    let result = match command {
        "fmu" => fmu::run(rest),
        "test" => test::run(rest),
        "abi" => abi::run(rest),
        "cross-test" => cross::run(rest),
        "pytest" => python::run(rest),
        "wheel" => wheel::run(rest),
        "demo" => demo::run(rest),
        "design" => design(rest),
        "sweep" => sweep::run(rest),
        "bench" => bench::run(rest),
        "docs" => reference::run(rest),
        "help" | "-h" | "--help" => {
            println!("{USAGE}");
            Ok(())
        }
        other => Err(format!("unknown command `{other}`\n\n{USAGE}")),
    };
    if let Err(message) = result {
        eprintln!("\nerror: {message}");
        std::process::exit(1);
    }
}

/// `cargo xtask design`: the design crate's `backlash design` under this name, the same answers
/// and usage; a command line it refuses is reported as every command's error is here (its
/// reason, with the usage when that explains it; exit status 1).
fn design(args: &[String]) -> Result<(), String> {
    let text = backlash_design::cli::design("cargo xtask design", args).map_err(|e| e.with_usage_text())?;
    println!("{text}");
    Ok(())
}
