//! The platforms other than this machine's: their builds (`toolchain`).

pub mod toolchain;

use crate::platform::{self, Platform, Tool};

/// None when this machine can build and run every platform; otherwise one line saying what to
/// install.
pub fn unavailable() -> Option<String> {
    let mut missing: Vec<Tool> = Vec::new();
    for platform in platform::cross() {
        for tool in toolchain::missing_tools(&platform.tools()) {
            if !missing.contains(&tool) {
                missing.push(tool);
            }
        }
    }
    let mut problems = Vec::new();
    if !missing.is_empty() {
        problems.push(toolchain::install_line("win64 and aarch64-linux", &missing));
    }
    let platforms: Vec<&Platform> = platform::cross().collect();
    if let Err(line) = toolchain::standard_libraries(&platforms) {
        problems.push(line);
    }
    (!problems.is_empty()).then(|| problems.join("; "))
}
