//! Writes the library's generated tables into OUT_DIR from the interface description
//! (the `model-description` crate in modelDescription/): the variable tables and `Symbol`
//! (included by `src/fmu/variables.rs`) and the log categories (`src/fmu/logging.rs`).

use std::path::{Path, PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    // The library stays loaded once loaded (ELF's NODELETE flag): an importer that closes it while
    // an instance lives and opens it again (ecos does, when two components of a system use the
    // same FMU file) finds its table of live instances as it left it, rather than an empty one
    // that hands the next instance the live one's handle (tests/python/test_reload.py).
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        println!("cargo:rustc-cdylib-link-arg=-Wl,-z,nodelete");
    }
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    write(
        &out.join("model_variables.rs"),
        &model_description::rust::variable_tables(),
    );
    write(
        &out.join("log_categories.rs"),
        &model_description::rust::log_categories(),
    );
}

/// Writes only when the content changed, so dependants are not rebuilt needlessly.
fn write(path: &Path, content: &str) {
    if std::fs::read_to_string(path).ok().as_deref() != Some(content) {
        std::fs::write(path, content).unwrap_or_else(|e| panic!("cannot write {}: {e}", path.display()));
    }
}
