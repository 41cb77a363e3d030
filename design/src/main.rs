//! `backlash`: the design study on the command line (`backlash design --help`). The command
//! line is read and answered by [`backlash_design::cli`]; this prints what it returns.

use std::process::ExitCode;

use backlash_design::cli::{self, CliError};

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, so printing into a pipe its reader has closed (`| head`) would
    // panic; with the default action the process ends quietly there, as other tools do.
    #[cfg(unix)]
    // SAFETY: sets a signal disposition to its default before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let args: Vec<String> = std::env::args().skip(1).collect();
    match cli::run(&args) {
        Ok(text) => {
            println!("{text}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {}", e.line());
            ExitCode::from(CliError::EXIT_STATUS as u8)
        }
    }
}
