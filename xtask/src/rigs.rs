//! The FMUs' test rigs, read from tests/fixtures/rigs.toml: the one Rust reader of the fixture,
//! for the cross-platform test and the bench (xtask) and for the integration tests, which include
//! this file as a module of theirs (std and the `toml` crate only). The Python tests read the same
//! file (tests/python/rigs.py).

use std::fs;
use std::path::Path;

/// The fixture, relative to the repository root.
const FIXTURE: &str = "tests/fixtures/rigs.toml";

/// The rig of the model `id` in the fixture of the repository at `root`, by FMU parameter name:
/// the parameter sets the rig lists under `sets` (`parameters`, or `cross_platform`, which a rig
/// that has none takes as its `parameters`), then its gains; applied in order, a later set's value
/// replacing an earlier one's (in the place of the first), as the Python tests merge them.
pub fn rig(root: &Path, id: &str, sets: &str) -> Result<Vec<(String, f64)>, String> {
    let bad = |what: &str| format!("{FIXTURE}: {what}");
    let path = root.join(FIXTURE);
    let text = fs::read_to_string(&path).map_err(|e| format!("reading {}: {e}", path.display()))?;
    let fixture: toml::Table = text.parse().map_err(|e| bad(&format!("{e}")))?;
    let rig = fixture
        .get("rigs")
        .and_then(|r| r.get(id))
        .ok_or_else(|| bad(&format!("no rig for {id}")))?;
    let names = |key: &str| -> Option<Vec<String>> {
        match rig.get(key)? {
            toml::Value::String(name) => Some(vec![name.clone()]),
            toml::Value::Array(names) => names.iter().map(|n| n.as_str().map(str::to_string)).collect(),
            _ => None,
        }
    };
    let parameters = names(sets)
        .or_else(|| names("parameters"))
        .ok_or_else(|| bad(&format!("rig {id} names no parameter sets")))?;
    let gains = names("gains").ok_or_else(|| bad(&format!("rig {id} names no gains")))?;
    let mut values: Vec<(String, f64)> = Vec::new();
    for set in parameters.iter().chain(&gains) {
        let table = fixture
            .get("sets")
            .and_then(|s| s.get(set))
            .and_then(|t| t.as_table())
            .ok_or_else(|| bad(&format!("no parameter set {set}")))?;
        for (name, value) in table {
            let value = match value {
                toml::Value::Float(x) if x.is_finite() => *x,
                toml::Value::Integer(n) => *n as f64,
                _ => return Err(bad(&format!("{set}.{name} is not a finite number"))),
            };
            match values.iter_mut().find(|(known, _)| known == name) {
                Some(earlier) => earlier.1 = value,
                None => values.push((name.clone(), value)),
            }
        }
    }
    Ok(values)
}
