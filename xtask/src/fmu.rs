//! `cargo xtask fmu`: builds the cdylib once per platform and packages one archive per model and
//! standard (Model Exchange and Co-Simulation in one description): FMI 2.0 in `target/fmu/`,
//! FMI 3.0 in `target/fmu/fmi3/` ([`STANDARDS`]).
//!
//! Layout of each archive (FMI 2.0 §2.3, FMI 3.0 §2.5): `modelDescription.xml`,
//! `binaries/<platform>/<id>.<ext>` (the same library under each model's identifier: FMI 2.0
//! `linux64/<id>.so`, with `--all-platforms` also `win64/<id>.dll`; FMI 3.0 `x86_64-linux/<id>.so`,
//! with `--all-platforms` also `x86_64-windows/<id>.dll` and `aarch64-linux/<id>.so`),
//! and the files of [`kit::entries`] (the documentation page, ...). FMI 2.0 has no folder for
//! aarch64-linux.
//!
//! Beside the archives of each standard, in every folder it fills, the manifest [`MANIFEST`]:
//! the model identifiers, one a line, in the order of `model_identifiers()` (the Python tests
//! take their list of models from it).

use std::fs;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use zip::write::SimpleFileOptions;
use zip::CompressionMethod;

use crate::platform::{self, Built, Platform};
use crate::util::{self, step};
use crate::{cross, kit, systems};

/// Name of the cdylib that cargo writes for the `backlash_fmu` library.
pub const LIBRARY_FILE: &str = platform::LINUX64.library_file;

/// What the archives of one FMI standard differ in.
pub struct Standard {
    /// The `fmiVersion` of its descriptions.
    pub fmi_version: &'static str,
    /// Its folder under `target/fmu/`; "" for FMI 2.0, whose archives the tests read there.
    pub subdir: &'static str,
    /// A platform's folder under `binaries/`, if the standard has one for it.
    pub folder_of: fn(&Platform) -> Option<&'static str>,
    /// The model description of a model identifier.
    pub description: fn(&str) -> String,
    /// The root attribute an importer passes back at instantiation: `guid` (FMI 2.0) or
    /// `instantiationToken` (FMI 3.0).
    pub token_attribute: &'static str,
}

impl Standard {
    /// The guid or instantiation token of a parsed description of this standard.
    pub fn token<'a>(&self, doc: &'a roxmltree::Document) -> Result<&'a str, String> {
        doc.root_element().attribute(self.token_attribute).ok_or_else(|| {
            format!(
                "the FMI {} modelDescription.xml has no {}",
                self.fmi_version, self.token_attribute
            )
        })
    }

    /// The folder its archives are written to.
    pub fn out_dir(&self) -> PathBuf {
        self.out_dir_in(&util::fmu_dir())
    }

    /// Its folder under `base`, a folder laid out as `target/fmu`.
    pub fn out_dir_in(&self, base: &Path) -> PathBuf {
        base.join(self.subdir)
    }
}

/// FMI 2.0 (§2.3: `linux64`, `win64`).
pub const FMI2: Standard = Standard {
    fmi_version: "2.0",
    subdir: "",
    folder_of: |p| p.fmi2_folder,
    description: model_description::xml::model_description,
    token_attribute: "guid",
};

/// FMI 3.0 (§2.5.1.4: platform tuples), beside the FMI 2.0 archives.
pub const FMI3: Standard = Standard {
    fmi_version: "3.0",
    subdir: "fmi3",
    folder_of: |p| Some(p.fmi3_folder),
    description: model_description::xml3::model_description,
    token_attribute: "instantiationToken",
};

/// The archives `cargo xtask fmu` writes for every model, in this order.
pub const STANDARDS: [&Standard; 2] = [&FMI2, &FMI3];

/// The manifest written beside each standard's archives: every plant's identifier, one a line,
/// in the order of `model_identifiers()`.
pub const MANIFEST: &str = "models.txt";

/// Its counterpart for the controllers (`controller_identifiers()`), whose archives lie beside
/// the plants'.
pub const CONTROLLER_MANIFEST: &str = "controllers.txt";

/// The release cdylib, as built by [`build_library`].
pub fn library_path() -> PathBuf {
    util::target_dir().join("release").join(LIBRARY_FILE)
}

const USAGE: &str = "usage: cargo xtask fmu [--all-platforms] [--out DIR]

  --out DIR   write the archives to DIR (FMI 3.0 in DIR/fmi3) instead of target/fmu; the
              Python package's build packs its own copies this way";

pub fn run(args: &[String]) -> Result<(), String> {
    let (out, rest) = match args {
        [flag, dir, rest @ ..] if flag == "--out" => (Some(PathBuf::from(dir)), rest),
        [rest @ .., flag, dir] if flag == "--out" => (Some(PathBuf::from(dir)), rest),
        [.., flag] if flag == "--out" => return Err(format!("--out needs a folder\n{USAGE}")),
        _ => (None, args),
    };
    let platforms = platforms_from_arguments(rest, USAGE)?;
    let out = out.unwrap_or_else(util::fmu_dir);
    package_into(&platforms, &out).map(|_| ())
}

/// `[]` → linux64 only; `[--all-platforms]` → every platform of [`platform::ALL`].
pub fn platforms_from_arguments(args: &[String], usage: &str) -> Result<Vec<&'static Platform>, String> {
    match args {
        [] => Ok(vec![&platform::LINUX64]),
        [flag] if flag == "--all-platforms" => Ok(platform::ALL.to_vec()),
        [other, ..] => Err(format!("unexpected argument `{other}`\n{usage}")),
    }
}

/// The linux64 archives, as `cargo xtask fmu` writes them; returns their paths, those of
/// FMI 2.0 first.
pub fn package_all() -> Result<Vec<PathBuf>, String> {
    package(&[&platform::LINUX64])?;
    Ok(archive_paths())
}

fn archive_paths() -> Vec<PathBuf> {
    STANDARDS
        .iter()
        .flat_map(|standard| {
            model_description::model_identifiers()
                .iter()
                .map(|id| standard.out_dir().join(format!("{id}.fmu")))
        })
        .collect()
}

/// Builds the library for each of `platforms` (linux64 first; it must be among them) and
/// writes every model's archive of every standard with the binaries the standard has a folder
/// for into target/fmu; returns every built library.
pub fn package(platforms: &[&'static Platform]) -> Result<Vec<Built>, String> {
    package_into(platforms, &util::fmu_dir())
}

/// [`package`] into the folder `base` (FMI 2.0 there, FMI 3.0 in its `fmi3/`).
pub fn package_into(platforms: &[&'static Platform], base: &Path) -> Result<Vec<Built>, String> {
    if !(cfg!(target_os = "linux") && cfg!(target_arch = "x86_64")) {
        return Err("packaging builds on x86_64 Linux only (linux64 natively, the others cross)".into());
    }
    if platforms.first() != Some(&&platform::LINUX64) {
        return Err("the linux64 library comes first in every archive's platform list".into());
    }
    // One line before any build when a tool is missing, rather than a linker's error later.
    if platforms.iter().any(|p| !p.is_host()) {
        if let Some(line) = cross::unavailable() {
            return Err(line);
        }
    }
    let mut built = Vec::new();
    for &platform in platforms {
        built.push(if platform.is_host() {
            build_library()?;
            Built {
                platform,
                path: library_path(),
            }
        } else {
            cross::toolchain::build(platform)?
        });
    }
    let mut libraries: Vec<(&Platform, Vec<u8>)> = Vec::new();
    for b in &built {
        let bytes = fs::read(&b.path).map_err(|e| format!("reading {}: {e}", b.path.display()))?;
        if b.platform.fmi2_folder.is_none() {
            println!(
                "{}: {} is built; FMI 2.0 has no binaries folder for it (FMI 3.0: {})",
                b.platform.name,
                util::shown(&b.path),
                b.platform.fmi3_folder
            );
        }
        libraries.push((b.platform, bytes));
    }

    let ids = model_description::model_identifiers();
    if ids.is_empty() {
        return Err("the model-description crate lists no model identifiers".into());
    }
    // The controllers' archives beside the plants'; the manifest lists the plants only.
    let controllers = model_description::controller_identifiers();
    for standard in STANDARDS {
        let out_dir = standard.out_dir_in(base);
        fs::create_dir_all(&out_dir).map_err(|e| format!("creating {}: {e}", out_dir.display()))?;
        for &id in ids.iter().chain(controllers) {
            let xml = (standard.description)(id);
            check_description(standard, id, &xml)?;
            let kit = kit::entries(standard, id, &xml)?;
            let path = out_dir.join(format!("{id}.fmu"));
            let entries = binary_entries(id, &libraries, standard.folder_of);
            write_archive(&path, &xml, &entries, &kit)?;
            verify_archive(&path, standard, id, &entries, &kit)?;
            println!(
                "wrote {} ({} bytes)",
                util::shown(&path),
                fs::metadata(&path).map(|m| m.len()).unwrap_or(0)
            );
        }
        write_manifest(&out_dir.join(MANIFEST), ids)?;
        write_manifest(&out_dir.join(CONTROLLER_MANIFEST), controllers)?;
    }
    // The systems use the FMI 2.0 archives, which every master here reads.
    systems::pack_into(&STANDARDS[0].out_dir_in(base))?;
    Ok(built)
}

/// Writes the manifest `path`: the identifiers `ids`, one a line, in their order.
fn write_manifest(path: &Path, ids: &[&str]) -> Result<(), String> {
    let text: String = ids.iter().map(|id| format!("{id}\n")).collect();
    // Beside the target and renamed, as the archives are.
    let partial = path.with_extension("txt.partial");
    fs::write(&partial, text).map_err(|e| format!("writing {}: {e}", partial.display()))?;
    fs::rename(&partial, path).map_err(|e| format!("renaming to {}: {e}", path.display()))?;
    println!("wrote {}", util::shown(path));
    Ok(())
}

/// The entries `binaries/<folder>/<id>.<ext>` of `libraries`, in the folder `folder_of` gives
/// each platform, skipping those it gives none (FMI 2.0 has no aarch64-linux folder).
fn binary_entries<'a>(
    id: &str,
    libraries: &'a [(&Platform, Vec<u8>)],
    folder_of: fn(&Platform) -> Option<&'static str>,
) -> Vec<(String, &'a [u8])> {
    libraries
        .iter()
        .filter_map(|(platform, bytes)| {
            let folder = folder_of(platform)?;
            Some((
                format!("binaries/{folder}/{}", platform.archive_file(id)),
                bytes.as_slice(),
            ))
        })
        .collect()
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
    // A controller is Co-Simulation only.
    let interfaces: &[&str] = match model_description::controller_identifiers().contains(&id) {
        true => &["CoSimulation"],
        false => &["ModelExchange", "CoSimulation"],
    };
    for &interface in interfaces {
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
/// files of the `kit` (the documentation page and the rest of [`kit::entries`]).
fn write_archive(path: &Path, xml: &str, binaries: &[(String, &[u8])], kit: &[kit::Entry]) -> Result<(), String> {
    let binary = TEXT.unix_permissions(0o755);
    let mut entries: Vec<(String, &[u8], SimpleFileOptions)> =
        vec![("modelDescription.xml".into(), xml.as_bytes(), TEXT)];
    entries.extend(binaries.iter().map(|(name, bytes)| (name.clone(), *bytes, binary)));
    entries.extend(kit.iter().map(|e| (e.name.clone(), e.bytes.as_slice(), TEXT)));
    write_zip(path, &entries)
}

/// A deflated file readable by all: every entry of an archive but its binaries.
pub const TEXT: SimpleFileOptions = SimpleFileOptions::DEFAULT
    .compression_method(CompressionMethod::Deflated)
    .unix_permissions(0o644);

/// Writes the zip archive `path` of `entries` (name, bytes, options), in their order: beside the
/// target and renamed, so that an interrupted run never leaves a truncated archive where the
/// tests look for one.
pub fn write_zip(path: &Path, entries: &[(String, &[u8], SimpleFileOptions)]) -> Result<(), String> {
    let extension = path
        .extension()
        .map_or(String::new(), |e| e.to_string_lossy().into_owned());
    let partial = path.with_extension(format!("{extension}.partial"));
    let file = fs::File::create(&partial).map_err(|e| format!("creating {}: {e}", partial.display()))?;
    let mut zip = zip::ZipWriter::new(file);
    for (name, bytes, options) in entries.iter().cloned() {
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
fn verify_archive(
    path: &Path,
    standard: &Standard,
    id: &str,
    binaries: &[(String, &[u8])],
    kit: &[kit::Entry],
) -> Result<(), String> {
    let file = fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut archive = zip::ZipArchive::new(file).map_err(|e| format!("{}: not a zip archive: {e}", path.display()))?;
    let mut names: Vec<String> = archive
        .file_names()
        .map(|n| n.map(|n| n.into_owned()))
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    names.sort();
    let mut expected: Vec<String> = binaries.iter().map(|(name, _)| name.clone()).collect();
    expected.extend(kit.iter().map(|e| e.name.clone()));
    expected.push("modelDescription.xml".to_string());
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
