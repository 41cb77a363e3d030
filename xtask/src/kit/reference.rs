//! Reference results in every archive, as the layered standard FMI-LS-REF places them (and as the
//! Reference FMUs ship them): under `extra/org.fmi-standard.fmi-ls-ref/`, the manifest
//! `fmi-ls-manifest.xml` naming `<id>_in.csv` (the inputs) and `<id>_out.csv` (the outputs) of
//! the model's reference experiment. That experiment is the default one (start, stop, step) at
//! the parameters' start values, Co-Simulation with the inputs held over each step: the square
//! waves of the model's `reference_inputs` (its module in the description), the other inputs at
//! their start values.
//!
//! The outputs are computed here by the library itself (its Rust API, the code behind the C
//! functions) on an importer's grid, t_k = start + k h, each step from t_k to t_k+1, and written
//! at 1001 points or fewer (every step if there are fewer), read at every one. The inputs' file has a row at every
//! communication point, so that an importer that interpolates between rows, as fmpy does
//! (w0 v0 + w1 v1, exact only at a row's own time), reads exactly the held values; each flip is
//! a pair of rows at the communication point where the new value starts (a time event, as fmpy
//! reads such a pair: the value after it holds over the step that starts there).
//! tests/python/test_reference_results.py replays both files in fmpy and checks the outputs
//! against the independent reference solvers.

use backlash_fmu::fmu::{model_by_identifier, Instance};
use model_description::{Causality, SquareWave, Type};

use super::Entry;

/// The directory FMI-LS-REF gives its files.
pub const DIR: &str = "extra/org.fmi-standard.fmi-ls-ref";

/// Most output rows (besides the first, at the start time).
const OUTPUT_POINTS: u64 = 1000;

/// The manifest and the two CSV files of model `id`.
pub fn entries(id: &str) -> Result<Vec<Entry>, String> {
    let description = model_description::model(id);
    let run = Run::of(id, &description)?;
    let inputs = run.inputs_csv();
    let outputs = run.outputs_csv()?;
    let manifest = manifest(id, &run);
    Ok(vec![
        Entry {
            name: format!("{DIR}/fmi-ls-manifest.xml"),
            bytes: manifest.into_bytes(),
        },
        Entry {
            name: format!("{DIR}/{id}_in.csv"),
            bytes: inputs.into_bytes(),
        },
        Entry {
            name: format!("{DIR}/{id}_out.csv"),
            bytes: outputs.into_bytes(),
        },
    ])
}

/// The reference experiment of one model.
struct Run {
    id: String,
    start: f64,
    step: f64,
    steps: u64,
    /// Output rows every this many steps.
    every: u64,
    waves: Vec<SquareWave>,
}

impl Run {
    fn of(id: &str, description: &model_description::Model) -> Result<Run, String> {
        let e = &description.default_experiment;
        let steps = ((e.stop_time - e.start_time) / e.step_size).round();
        if !(steps >= 1.0
            && (e.start_time + steps * e.step_size - e.stop_time).abs() <= 1e-9 * e.stop_time.abs().max(1.0))
        {
            return Err(format!(
                "{id}: the default experiment's step {} does not divide {} to {}",
                e.step_size, e.start_time, e.stop_time
            ));
        }
        let steps = steps as u64;
        for wave in description.reference_inputs {
            let input = description.variables.iter().find(|v| v.name == wave.input);
            if !matches!(input, Some(v) if v.causality == Causality::Input) || wave.half_period == 0 {
                return Err(format!(
                    "{id}: reference input {wave:?} is not an input of the model with a half period"
                ));
            }
        }
        Ok(Run {
            id: id.to_string(),
            start: e.start_time,
            step: e.step_size,
            steps,
            every: steps.div_ceil(OUTPUT_POINTS),
            waves: description.reference_inputs.to_vec(),
        })
    }

    /// The time of communication point `k`: as the FMU counts it (start + k h).
    fn time(&self, k: u64) -> f64 {
        self.start + k as f64 * self.step
    }

    /// `time,<input>...`: a row at every communication point (the value held over the step that
    /// starts there), and at each flip a pair (the old value, then the new), the last row at
    /// the stop time.
    fn inputs_csv(&self) -> String {
        let names: Vec<&str> = self.waves.iter().map(|w| w.input).collect();
        let row = |t: f64, k: u64| {
            let values: Vec<String> = self.waves.iter().map(|w| number(w.at(k))).collect();
            format!("{},{}\n", number(t), values.join(","))
        };
        let mut text = format!("time,{}\n", names.join(","));
        text += &row(self.time(0), 0);
        for k in 1..self.steps {
            if self.waves.iter().any(|w| w.at(k) != w.at(k - 1)) {
                text += &row(self.time(k), k - 1);
            }
            text += &row(self.time(k), k);
        }
        text + &row(self.time(self.steps), self.steps - 1)
    }

    /// `time,<output>...` (every Real and Integer output, in value-reference order) at every
    /// `every`-th communication point, from a Co-Simulation run of the library.
    fn outputs_csv(&self) -> Result<String, String> {
        let model = model_by_identifier(&self.id).ok_or_else(|| format!("{}: not a model of the library", self.id))?;
        let fail = |what: &str, e: backlash_fmu::fmu::FmuError| format!("{}: reference run, {what}: {e}", self.id);
        let outputs: Vec<_> = model
            .variables
            .iter()
            .filter(|v| v.causality == Causality::Output)
            .collect();
        let reals: Vec<u32> = outputs.iter().filter(|v| v.ty == Type::Real).map(|v| v.vr).collect();
        let integers: Vec<u32> = outputs.iter().filter(|v| v.ty == Type::Integer).map(|v| v.vr).collect();
        let input_vrs: Vec<u32> = self.waves.iter().map(|w| model.vr(w.input)).collect();

        let mut instance = Instance::new(model, None, false);
        instance
            .setup_experiment(None, self.start, Some(self.time(self.steps)))
            .map_err(|e| fail("fmi2SetupExperiment", e))?;
        instance
            .enter_initialization_mode()
            .map_err(|e| fail("initialization", e))?;
        instance
            .exit_initialization_mode()
            .map_err(|e| fail("initialization", e))?;

        let names: Vec<&str> = outputs.iter().map(|v| v.name).collect();
        let mut text = format!("time,{}\n", names.join(","));
        let (mut real, mut integer) = (vec![0.0; reals.len()], vec![0; integers.len()]);
        // Read at every communication point, as an importer that records each step does: the
        // bounds are brought up to date when read (docs/model.md §3), and an update over two
        // steps at once may round differently from two over one.
        let mut sample = |instance: &mut Instance, text: Option<&mut String>| -> Result<(), String> {
            instance
                .get_real(&reals, &mut real)
                .map_err(|e| fail("fmi2GetReal", e))?;
            instance
                .get_integer(&integers, &mut integer)
                .map_err(|e| fail("fmi2GetInteger", e))?;
            let Some(text) = text else {
                return Ok(());
            };
            let mut by_vr = std::collections::BTreeMap::new();
            by_vr.extend(reals.iter().zip(&real).map(|(vr, v)| (*vr, number(*v))));
            by_vr.extend(integers.iter().zip(&integer).map(|(vr, v)| (*vr, v.to_string())));
            let cells: Vec<String> = outputs.iter().map(|v| by_vr[&v.vr].clone()).collect();
            *text += &format!("{},{}\n", number(instance.time()), cells.join(","));
            Ok(())
        };
        sample(&mut instance, Some(&mut text))?;
        for k in 0..self.steps {
            let values: Vec<f64> = self.waves.iter().map(|w| w.at(k)).collect();
            instance
                .set_real(&input_vrs, &values)
                .map_err(|e| fail("fmi2SetReal", e))?;
            let t = self.time(k);
            instance
                .do_step(t, self.time(k + 1) - t)
                .map_err(|e| fail("fmi2DoStep", e))?;
            let written = (k + 1) % self.every == 0 || k + 1 == self.steps;
            sample(&mut instance, written.then_some(&mut text))?;
        }
        Ok(text)
    }
}

/// A float as the shortest text that reads back to the same bits.
fn number(x: f64) -> String {
    format!("{x:?}")
}

/// The FMI-LS-REF manifest of model `id`.
fn manifest(id: &str, run: &Run) -> String {
    let held: Vec<String> = run
        .waves
        .iter()
        .map(|w| {
            if w.amplitude == 0.0 {
                format!("{} {} throughout", w.input, number(w.level))
            } else {
                format!(
                    "{} {} {} {} flipping every {} steps",
                    w.input,
                    number(w.level),
                    if w.amplitude < 0.0 { "-/+" } else { "+/-" },
                    number(w.amplitude.abs()),
                    w.half_period
                )
            }
        })
        .collect();
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiReferences
    xmlns:fmi-ls="http://fmi-standard.org/fmi-ls-manifest"
    fmi-ls:fmi-ls-name="org.fmi-standard.fmi-ls-ref"
    fmi-ls:fmi-ls-version="1.0.0-alpha.1"
    fmi-ls:fmi-ls-description="Layered Standard providing information on related files included in an FMU.">
  <Related type="text/csv" source="{id}_in.csv" role="testcase" description="Inputs of the reference experiment: the default experiment in Co-Simulation, each input held over each step of {step} s ({held}; the other inputs at their start values). A row at every communication point; each flip a pair of rows at the communication point where the new value starts (a time event: the value after it holds from there)"/>
  <Related type="text/csv" source="{id}_out.csv" role="result" description="Outputs of the reference experiment at the parameters' start values, every {every} communication points"/>
</fmiReferences>
"#,
        step = number(run.step),
        held = held.join("; "),
        every = run.every,
    )
}
