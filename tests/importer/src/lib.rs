//! Where the importer tests find the packaged FMUs.
//!
//! The tests in `tests/` are `#[ignore]`d in a plain `cargo test --workspace` (which runs before
//! the archives exist) and run by `cargo xtask test` with `--include-ignored` after packaging.

use std::path::PathBuf;

/// `$BACKLASH_FMU_DIR/<identifier>.fmu`, or `target/fmu/<identifier>.fmu` of this workspace.
/// Panics with instructions if the archive is missing: a missing FMU is a failure, not a skip.
pub fn fmu_path(identifier: &str) -> PathBuf {
    let dir = std::env::var_os("BACKLASH_FMU_DIR").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/fmu"),
        PathBuf::from,
    );
    let path = dir.join(format!("{identifier}.fmu"));
    assert!(
        path.is_file(),
        "{} not found: run `cargo xtask fmu` first (or `cargo xtask test`, which packages and then runs this test)",
        path.display()
    );
    path
}
