//! The co-simulation systems of `systems/` (a plant or two under BacklashController), packed
//! beside the archives: for each system folder, `systems/<name>/` under the archives' folder with
//! its `SystemStructure.ssd` (SSP 1.0: ecos, fmpy's SSP runner, libcosim, which reads its step
//! from the SSD's annotation), its `OspSystemStructure.xml` (libcosim), the parameter sets it
//! binds (`parameters/*.ssv`) and the FMI 2.0 archives its components use (`resources/*.fmu`),
//! and the same SSP zipped as `systems/<name>.ssp` (`SystemStructure.ssd` first, then its
//! resources and parameter sets).
//!
//! What a system holds is read from its files: every `source` of the SSD (components and
//! parameter bindings) and of the OSP file (simulators), so that a new system is a folder and
//! nothing here.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

use crate::{fmu, util};

const SSD: &str = "SystemStructure.ssd";
const OSP: &str = "OspSystemStructure.xml";

fn source_dir() -> PathBuf {
    util::repo_root().join("systems")
}

/// Packs every system of `systems/` into `base/systems/`, its FMUs taken from the FMI 2.0
/// archives in `base`.
pub fn pack_into(base: &Path) -> Result<(), String> {
    let out = base.join("systems");
    for name in system_names()? {
        let folder = source_dir().join(&name);
        let ssd = read(&folder.join(SSD))?;
        let osp = read(&folder.join(OSP))?;
        let mut files: BTreeSet<String> = sources(&ssd, SSD, "source")?;
        let simulators = sources(&osp, OSP, "source")?;
        if !simulators.is_subset(&files) {
            return Err(format!(
                "systems/{name}: {OSP} uses {simulators:?}, which {SSD} does not all use ({files:?})"
            ));
        }
        files.extend(simulators);
        let target = out.join(&name);
        if target.exists() {
            fs::remove_dir_all(&target).map_err(|e| format!("removing {}: {e}", target.display()))?;
        }
        let mut entries: Vec<(String, Vec<u8>)> = vec![(SSD.to_string(), ssd.into_bytes())];
        for file in &files {
            let from = match file.strip_prefix("resources/") {
                Some(archive) if !archive.contains('/') => base.join(archive),
                _ if file.starts_with("parameters/") => source_dir().join(file),
                _ => {
                    return Err(format!(
                        "systems/{name}: source {file:?} is neither resources/<model>.fmu nor parameters/<set>.ssv"
                    ))
                }
            };
            let bytes = fs::read(&from).map_err(|e| format!("systems/{name}: reading {}: {e}", from.display()))?;
            entries.push((file.clone(), bytes));
        }
        for (file, bytes) in entries.iter().chain([&(OSP.to_string(), osp.into_bytes())]) {
            let path = target.join(file);
            fs::create_dir_all(path.parent().expect("a file in a folder"))
                .and_then(|()| fs::write(&path, bytes))
                .map_err(|e| format!("writing {}: {e}", path.display()))?;
        }
        let ssp = out.join(format!("{name}.ssp"));
        let zipped: Vec<(String, &[u8], _)> = entries
            .iter()
            .map(|(file, bytes)| (file.clone(), bytes.as_slice(), fmu::TEXT))
            .collect();
        fmu::write_zip(&ssp, &zipped)?;
        println!("wrote {} and {}", util::shown(&target), util::shown(&ssp));
    }
    Ok(())
}

/// The system folders of `systems/` (each with a `SystemStructure.ssd`), sorted.
pub fn system_names() -> Result<Vec<String>, String> {
    let dir = source_dir();
    let mut names = Vec::new();
    for entry in fs::read_dir(&dir).map_err(|e| format!("reading {}: {e}", dir.display()))? {
        let path = entry.map_err(|e| format!("reading {}: {e}", dir.display()))?.path();
        if path.join(SSD).is_file() {
            names.push(
                path.file_name()
                    .expect("a folder's name")
                    .to_string_lossy()
                    .into_owned(),
            );
        }
    }
    names.sort();
    Ok(names)
}

fn read(path: &Path) -> Result<String, String> {
    fs::read_to_string(path).map_err(|e| format!("reading {}: {e}", util::shown(path)))
}

/// Every value of the attribute `attribute` in the XML `text` (of the file `what`).
fn sources(text: &str, what: &str, attribute: &str) -> Result<BTreeSet<String>, String> {
    let doc = roxmltree::Document::parse(text).map_err(|e| format!("{what} is not XML: {e}"))?;
    Ok(doc
        .descendants()
        .filter_map(|n| n.attribute(attribute))
        .map(str::to_string)
        .collect())
}
