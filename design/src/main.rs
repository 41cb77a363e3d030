//! `backlash`: the design study on the command line (`backlash design --help`). The command
//! line is read and answered by [`backlash_design::cli`]; this prints what it returns.

use std::io::Write;
use std::process::ExitCode;

use backlash_design::cli;

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, so printing into a pipe its reader has closed (`| head`) would
    // panic; with the default action the process ends quietly there, as other tools do.
    #[cfg(unix)]
    // SAFETY: sets a signal disposition to its default before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (status, out, err) = cli::command(&args);
    // A failed write (a closed pipe without SIGPIPE) leaves nothing more to say.
    let _ = std::io::stdout().write_all(out.as_bytes());
    let _ = std::io::stderr().write_all(err.as_bytes());
    ExitCode::from(status as u8)
}
