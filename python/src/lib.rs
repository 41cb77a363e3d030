//! `backlash_fmu._native`: the design library ([`backlash_design`]) for Python. The package's
//! `backlash_fmu.design()` and the `backlash` command installed with it call these
//! functions; everything they compute, check and refuse is the design library's.

use backlash_design::cli;
use backlash_design::identify;
use backlash_design::request::{self, Setting};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// The design answer as the JSON text `backlash design --json` prints, for `model` ("shaft",
/// "belt", "web"), the accuracies and `parameters` as (FMU name, value) pairs. Bad input raises
/// ValueError with the library's reason.
#[pyfunction]
#[pyo3(signature = (model, accuracy, tension_accuracy, parameters))]
fn design_json(
    py: Python<'_>,
    model: &str,
    accuracy: Option<f64>,
    tension_accuracy: Option<f64>,
    parameters: Vec<(String, f64)>,
) -> PyResult<String> {
    let accuracies = [("accuracy", accuracy), ("tension_accuracy", tension_accuracy)];
    let mut settings: Vec<Setting> = accuracies
        .iter()
        .filter_map(|&(name, value)| value.map(|value| setting(name, value)))
        .collect();
    settings.extend(parameters.iter().map(|(name, value)| setting(name, *value)));
    // The study runs for a fraction of a second to seconds: other Python threads go on.
    py.detach(|| request::design_json(model, &settings))
        .map_err(PyValueError::new_err)
}

/// The identification as the JSON text `backlash identify --json` prints, for `model`, the run
/// from the CSV file `path` or as `columns` (name, values), the names to `fit` (None: the
/// default) and the known `parameters` (and `accuracy`, `tension_accuracy`) as (name, value)
/// pairs. Bad data or input raises ValueError with the library's one-line reason.
#[pyfunction]
#[pyo3(signature = (model, path, columns, fit, parameters))]
fn identify_json(
    py: Python<'_>,
    model: &str,
    path: Option<String>,
    columns: Option<Vec<(String, Vec<f64>)>>,
    fit: Option<Vec<String>>,
    parameters: Vec<(String, f64)>,
) -> PyResult<String> {
    let settings: Vec<Setting> = parameters.iter().map(|(name, value)| setting(name, *value)).collect();
    // A fit takes about a second: other Python threads go on.
    py.detach(|| {
        let columns = match (path, columns) {
            (Some(path), _) => identify::data::read_csv(&path)?,
            (None, Some(columns)) => columns,
            (None, None) => return Err("data: give a CSV path or a table".to_string()),
        };
        identify::identify_json(model, &columns, fit.as_deref(), &settings)
    })
    .map_err(PyValueError::new_err)
}

/// A value given by keyword: its name is its label, its value written as Rust writes it.
fn setting(name: &str, value: f64) -> Setting<'_> {
    Setting {
        name,
        label: name,
        text: format!("{value}"),
        value,
    }
}

/// The `backlash` command line `args` (without the program name): (exit status, text for
/// stdout, text for stderr), each text with its final newline.
#[pyfunction]
fn command(py: Python<'_>, args: Vec<String>) -> (i32, String, String) {
    py.detach(|| cli::command(&args))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(design_json, m)?)?;
    m.add_function(wrap_pyfunction!(identify_json, m)?)?;
    m.add_function(wrap_pyfunction!(command, m)?)?;
    Ok(())
}
