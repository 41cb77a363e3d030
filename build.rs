//! Writes the value-reference tables of both models into OUT_DIR (included by
//! `src/fmu/variables.rs`) from the single source of truth `modelDescription/generate.rs`,
//! together with each model's `modelDescription.xml` for the tests that cross-check them.

#[path = "modelDescription/generate.rs"]
mod generate;

use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-changed=modelDescription/generate.rs");
    println!("cargo:rerun-if-changed=build.rs");
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    write(&out.join("model_variables.rs"), &generate::rust_variable_tables());
    for identifier in generate::model_identifiers() {
        write(
            &out.join(format!("{identifier}.xml")),
            &generate::model_description_xml(identifier),
        );
    }
}

/// Writes only when the content changed, so dependants are not rebuilt needlessly.
fn write(path: &std::path::Path, content: &str) {
    if std::fs::read_to_string(path).ok().as_deref() != Some(content) {
        std::fs::write(path, content).unwrap_or_else(|e| panic!("cannot write {}: {e}", path.display()));
    }
}
