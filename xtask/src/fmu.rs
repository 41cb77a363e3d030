//! `cargo xtask fmu`: builds the cdylib once and packages one archive per model and standard
//! (Model Exchange and Co-Simulation in one description, one binary): FMI 2.0 in `target/fmu/`,
//! FMI 3.0 in `target/fmu/fmi3/` ([`STANDARDS`]).
//!
//! Layout of each archive (FMI 2.0 §2.3, FMI 3.0 §2.5): `modelDescription.xml`,
//! `binaries/<platform>/<id>.so` (the same library under each model's identifier; `linux64` in
//! FMI 2.0, `x86_64-linux` in FMI 3.0), `documentation/index.html`.

use std::fs;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use zip::write::SimpleFileOptions;
use zip::CompressionMethod;

use crate::documentation;
use crate::util::{self, step};

/// Name of the cdylib that cargo writes for the `backlash_fmu` library.
pub const LIBRARY_FILE: &str = "libbacklash_fmu.so";

/// What the archives of one FMI standard differ in.
pub struct Standard {
    /// The `fmiVersion` of its descriptions.
    pub fmi_version: &'static str,
    /// Its folder under `target/fmu/`; "" for FMI 2.0, whose archives the tests read there.
    pub subdir: &'static str,
    /// Its folder under `binaries/` for 64-bit Linux on x86_64, the only platform this build
    /// produces.
    pub platform: &'static str,
    /// The model description of a model identifier.
    pub description: fn(&str) -> String,
}

impl Standard {
    /// The folder its archives are written to.
    pub fn out_dir(&self) -> PathBuf {
        util::fmu_dir().join(self.subdir)
    }
}

/// FMI 2.0 (§2.3: platform folder `linux64`).
pub const FMI2: Standard = Standard {
    fmi_version: "2.0",
    subdir: "",
    platform: "linux64",
    description: model_description::xml::model_description,
};

/// FMI 3.0 (§2.5.1.4: platform tuple `x86_64-linux`), beside the FMI 2.0 archives.
pub const FMI3: Standard = Standard {
    fmi_version: "3.0",
    subdir: "fmi3",
    platform: "x86_64-linux",
    description: model_description::xml3::model_description,
};

/// The archives `cargo xtask fmu` writes for every model, in this order.
pub const STANDARDS: [&Standard; 2] = [&FMI2, &FMI3];

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

/// Builds the library and writes every model's archive of every standard; returns the archive
/// paths, those of FMI 2.0 first.
pub fn package_all() -> Result<Vec<PathBuf>, String> {
    if !(cfg!(target_os = "linux") && cfg!(target_arch = "x86_64")) {
        return Err("packaging produces x86_64 Linux binaries only; build on x86_64 Linux".into());
    }
    build_library()?;
    let library = fs::read(library_path()).map_err(|e| format!("reading {}: {e}", library_path().display()))?;

    let mut written = Vec::new();
    for standard in STANDARDS {
        let out_dir = standard.out_dir();
        fs::create_dir_all(&out_dir).map_err(|e| format!("creating {}: {e}", out_dir.display()))?;
        for &id in model_description::model_identifiers() {
            let xml = (standard.description)(id);
            check_description(standard, id, &xml)?;
            let html = documentation::render(id, &xml)?;
            let path = out_dir.join(format!("{id}.fmu"));
            let binaries = [(format!("binaries/{}/{id}.so", standard.platform), library.as_slice())];
            write_archive(&path, &xml, &binaries, &html)?;
            verify_archive(&path, standard, id, &binaries)?;
            println!(
                "wrote {} ({} bytes)",
                util::shown(&path),
                fs::metadata(&path).map(|m| m.len()).unwrap_or(0)
            );
            written.push(path);
        }
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

/// The description must be a description of `standard` naming this model in its ModelExchange
/// and CoSimulation elements, or an importer would look for a library that is not in the archive.
fn check_description(standard: &Standard, id: &str, xml: &str) -> Result<(), String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("{id}: model description is not XML: {e}"))?;
    let root = doc.root_element();
    if !root.has_tag_name("fmiModelDescription") || root.attribute("fmiVersion") != Some(standard.fmi_version) {
        return Err(format!(
            "{id}: generated text is not an FMI {} model description",
            standard.fmi_version
        ));
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

/// Writes the archive `path`: the description, the `binaries` (archive name and bytes) and the
/// documentation page.
fn write_archive(path: &Path, xml: &str, binaries: &[(String, &[u8])], html: &str) -> Result<(), String> {
    // Write beside the target and rename, so that an interrupted run never leaves a truncated
    // archive where the tests look for one.
    let partial = path.with_extension("fmu.partial");
    let file = fs::File::create(&partial).map_err(|e| format!("creating {}: {e}", partial.display()))?;
    let mut zip = zip::ZipWriter::new(file);
    let text = SimpleFileOptions::default()
        .compression_method(CompressionMethod::Deflated)
        .unix_permissions(0o644);
    let binary = text.unix_permissions(0o755);
    let mut entries: Vec<(String, &[u8], SimpleFileOptions)> =
        vec![("modelDescription.xml".into(), xml.as_bytes(), text)];
    entries.extend(binaries.iter().map(|(name, bytes)| (name.clone(), *bytes, binary)));
    entries.push(("documentation/index.html".into(), html.as_bytes(), text));
    for (name, bytes, options) in entries {
        zip.start_file(name.as_str(), options)
            .and_then(|_| zip.write_all(bytes).map_err(Into::into))
            .map_err(|e| format!("{}: writing {name}: {e}", partial.display()))?;
    }
    zip.finish()
        .map_err(|e| format!("{}: finishing archive: {e}", partial.display()))?;
    fs::rename(&partial, path).map_err(|e| format!("renaming to {}: {e}", path.display()))
}

/// Reopens the archive and checks it holds exactly the expected entries, with forward slashes,
/// and a description of `standard` for this model.
fn verify_archive(path: &Path, standard: &Standard, id: &str, binaries: &[(String, &[u8])]) -> Result<(), String> {
    let file = fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut archive = zip::ZipArchive::new(file).map_err(|e| format!("{}: not a zip archive: {e}", path.display()))?;
    let mut names: Vec<String> = archive
        .file_names()
        .map(|n| n.map(|n| n.into_owned()))
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    names.sort();
    let mut expected: Vec<String> = binaries.iter().map(|(name, _)| name.clone()).collect();
    expected.extend([
        "documentation/index.html".to_string(),
        "modelDescription.xml".to_string(),
    ]);
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
    check_description(standard, id, &xml)
}
