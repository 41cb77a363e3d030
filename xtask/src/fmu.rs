//! `cargo xtask fmu`: builds the cdylib once and packages one FMI 2.0 archive per model
//! (Model Exchange and Co-Simulation in one description, one binary).
//!
//! Layout of each archive (FMI 2.0 §2.3): `modelDescription.xml`, `binaries/linux64/<id>.so`
//! (the same library under each model's identifier), `documentation/index.html`.

use std::fs;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use zip::write::SimpleFileOptions;
use zip::CompressionMethod;

use crate::documentation;
use crate::util::{self, step};

/// Name of the cdylib that cargo writes for the `backlash_fmu` library.
pub const LIBRARY_FILE: &str = "libbacklash_fmu.so";

/// FMI 2.0 §2.3 platform folder for 64-bit Linux; the only platform this build produces.
const PLATFORM: &str = "linux64";

/// The release cdylib, as built by [`build_library`].
pub fn library_path() -> PathBuf {
    util::target_dir().join("release").join(LIBRARY_FILE)
}

pub fn run(args: &[String]) -> Result<(), String> {
    if let Some(arg) = args.first() {
        return Err(format!("`cargo xtask fmu` takes no arguments, got `{arg}`"));
    }
    package_all().map(|_| ())
}

/// Builds the library and writes every model's archive; returns the archive paths.
pub fn package_all() -> Result<Vec<PathBuf>, String> {
    if !(cfg!(target_os = "linux") && cfg!(target_arch = "x86_64")) {
        return Err(format!(
            "packaging produces binaries/{PLATFORM} only; build on x86_64 Linux"
        ));
    }
    build_library()?;
    let library = fs::read(library_path()).map_err(|e| format!("reading {}: {e}", library_path().display()))?;

    let out_dir = util::fmu_dir();
    fs::create_dir_all(&out_dir).map_err(|e| format!("creating {}: {e}", out_dir.display()))?;
    let mut written = Vec::new();
    for &id in model_description::model_identifiers() {
        let xml = model_description::xml::model_description(id);
        check_description(id, &xml)?;
        let html = documentation::render(id, &xml)?;
        let path = out_dir.join(format!("{id}.fmu"));
        write_archive(&path, id, &xml, &library, &html)?;
        verify_archive(&path, id)?;
        println!(
            "wrote {} ({} bytes)",
            util::shown(&path),
            fs::metadata(&path).map(|m| m.len()).unwrap_or(0)
        );
        written.push(path);
    }
    if written.is_empty() {
        return Err("the model-description crate lists no model identifiers".into());
    }
    Ok(written)
}

fn build_library() -> Result<(), String> {
    step("building the FMU library (release)");
    util::run(util::cargo().args(["build", "--release", "--package", "backlash-fmu", "--lib"]))?;
    if !library_path().is_file() {
        return Err(format!(
            "cargo build succeeded but {} is missing",
            library_path().display()
        ));
    }
    Ok(())
}

/// The description must be an FMI 2.0 description naming this model in its ModelExchange and
/// CoSimulation elements, or an importer would look for a library that is not in the archive.
fn check_description(id: &str, xml: &str) -> Result<(), String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("{id}: model description is not XML: {e}"))?;
    let root = doc.root_element();
    if !root.has_tag_name("fmiModelDescription") || root.attribute("fmiVersion") != Some("2.0") {
        return Err(format!("{id}: generated text is not an FMI 2.0 model description"));
    }
    for interface in ["ModelExchange", "CoSimulation"] {
        let element = root
            .children()
            .find(|n| n.has_tag_name(interface))
            .ok_or_else(|| format!("{id}: model description has no <{interface}> element"))?;
        if element.attribute("modelIdentifier") != Some(id) {
            return Err(format!("{id}: <{interface}> does not carry modelIdentifier=\"{id}\""));
        }
    }
    Ok(())
}

fn write_archive(path: &Path, id: &str, xml: &str, library: &[u8], html: &str) -> Result<(), String> {
    // Write beside the target and rename, so that an interrupted run never leaves a truncated
    // archive where the tests look for one.
    let partial = path.with_extension("fmu.partial");
    let file = fs::File::create(&partial).map_err(|e| format!("creating {}: {e}", partial.display()))?;
    let mut zip = zip::ZipWriter::new(file);
    let text = SimpleFileOptions::default()
        .compression_method(CompressionMethod::Deflated)
        .unix_permissions(0o644);
    let binary = text.unix_permissions(0o755);
    let entries: [(String, &[u8], SimpleFileOptions); 3] = [
        ("modelDescription.xml".into(), xml.as_bytes(), text),
        (format!("binaries/{PLATFORM}/{id}.so"), library, binary),
        ("documentation/index.html".into(), html.as_bytes(), text),
    ];
    for (name, bytes, options) in entries {
        zip.start_file(name.as_str(), options)
            .and_then(|_| zip.write_all(bytes).map_err(Into::into))
            .map_err(|e| format!("{}: writing {name}: {e}", partial.display()))?;
    }
    zip.finish()
        .map_err(|e| format!("{}: finishing archive: {e}", partial.display()))?;
    fs::rename(&partial, path).map_err(|e| format!("renaming to {}: {e}", path.display()))
}

/// Reopens the archive and checks it holds exactly the expected entries, with forward slashes.
fn verify_archive(path: &Path, id: &str) -> Result<(), String> {
    let file = fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut archive = zip::ZipArchive::new(file).map_err(|e| format!("{}: not a zip archive: {e}", path.display()))?;
    let mut names: Vec<String> = archive
        .file_names()
        .map(|n| n.map(|n| n.into_owned()))
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    names.sort();
    let mut expected = vec![
        format!("binaries/{PLATFORM}/{id}.so"),
        "documentation/index.html".to_string(),
        "modelDescription.xml".to_string(),
    ];
    expected.sort();
    if names != expected {
        return Err(format!("{}: entries {names:?}, expected {expected:?}", path.display()));
    }
    let mut xml = String::new();
    archive
        .by_name("modelDescription.xml")
        .map_err(|e| format!("{}: {e}", path.display()))?
        .read_to_string(&mut xml)
        .map_err(|e| format!("{}: modelDescription.xml: {e}", path.display()))?;
    check_description(id, &xml)
}
