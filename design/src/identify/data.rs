//! A measured run (docs/model.md §11): a CSV with a header of FMU variable names,
//! `time` on a uniform step, the inputs held from their row's time to the next, and at least one
//! measured output. Every refusal is one line naming the row or the column.

/// The columns a run may have: inputs (held per sample) and measured outputs (states).
pub const INPUTS: [&str; 4] = ["tau_m", "tau_L", "v_in", "T_in"];
/// Measured outputs, in the order of the simulated state `[θ_m, ω_m, θ_L, ω_L, T]`.
pub const OUTPUTS: [&str; 5] = ["theta_m", "omega_m", "theta_L", "omega_L", "T"];
/// Fewer samples than this cannot determine five parameters with any confidence.
pub const MIN_SAMPLES: usize = 20;

/// A run: the sample step, the inputs per sample, the measured outputs per sample.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// The uniform sample step h [s].
    pub step: f64,
    /// Sample count.
    pub samples: usize,
    /// [tau_m, tau_L, v_in, T_in] per sample (0 where the column is absent).
    pub inputs: Vec<[f64; 4]>,
    /// The measured outputs: (index into [`OUTPUTS`], values per sample).
    pub outputs: Vec<(usize, Vec<f64>)>,
}

/// A table by columns: what the CSV reader and a Python table both become.
pub type Columns = Vec<(String, Vec<f64>)>;

/// Reads a CSV text into columns: a header of names, then rows of numbers. `nan`, `inf`,
/// missing or extra cells are refused naming the row (1-based, the header is row 1).
pub fn parse_csv(text: &str) -> Result<Columns, String> {
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let Some((_, header)) = lines.next() else {
        return Err("the data are empty: no header row".into());
    };
    let names: Vec<String> = header
        .split(',')
        .map(|s| s.trim().trim_matches('"').to_string())
        .collect();
    let mut columns: Columns = names.iter().map(|n| (n.clone(), Vec::new())).collect();
    for (i, line) in lines {
        let row = i + 1;
        let cells: Vec<&str> = line.split(',').collect();
        if cells.len() != names.len() {
            return Err(format!(
                "row {row}: {} cells, the header has {}",
                cells.len(),
                names.len()
            ));
        }
        for (cell, (name, values)) in cells.iter().zip(columns.iter_mut()) {
            let value: f64 = cell
                .trim()
                .parse()
                .map_err(|_| format!("row {row}, column {name}: `{}` is not a number", cell.trim()))?;
            values.push(value);
        }
    }
    Ok(columns)
}

/// Reads the CSV file at `path` into columns; a refusal names the file.
pub fn read_csv(path: &str) -> Result<Columns, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    parse_csv(&text).map_err(|m| format!("{path}: {m}"))
}

/// The noise level of a measured signal from its sample-to-sample scatter: for white noise of
/// σ the second difference has variance 6σ², while a smooth signal's is h² x'' (small at the
/// sample rate); the median of |Δ²x| (× 1.4826, its ratio to σ for a normal law) keeps steps
/// and kinks out.
pub fn noise_level(values: &[f64]) -> f64 {
    let mut d2: Vec<f64> = values.windows(3).map(|w| (w[2] - 2.0 * w[1] + w[0]).abs()).collect();
    if d2.is_empty() {
        return 0.0;
    }
    let mid = d2.len() / 2;
    let (_, median, _) = d2.select_nth_unstable_by(mid, f64::total_cmp);
    1.4826 * *median / 6f64.sqrt()
}

/// Checks a table and makes it a run: `time` and `tau_m` present, every column known and given
/// once, of one length, finite; `time` increasing on a uniform step; one measured output at
/// least; `web` allows the web's `v_in`, `T_in` and `T`.
pub fn run_from_columns(columns: &Columns, web: bool) -> Result<Run, String> {
    for (i, (name, _)) in columns.iter().enumerate() {
        let known = name == "time"
            || INPUTS[..2].contains(&name.as_str())
            || OUTPUTS[..4].contains(&name.as_str())
            || (web && (INPUTS[2..].contains(&name.as_str()) || name == "T"));
        if !known {
            return Err(format!(
                "column {name:?} is unknown: expected time, tau_m, tau_L, theta_m, omega_m, theta_L, omega_L{}",
                if web { ", v_in, T_in, T" } else { "" }
            ));
        }
        if columns[..i].iter().any(|(n, _)| n == name) {
            return Err(format!("column {name} is given twice"));
        }
    }
    let column = |name: &str| columns.iter().find(|(n, _)| n == name).map(|(_, v)| v);
    let time = column("time").ok_or("column time is missing")?;
    column("tau_m").ok_or("column tau_m is missing")?;
    let samples = time.len();
    for (name, values) in columns {
        if values.len() != samples {
            return Err(format!("column {name} has {} values, time has {samples}", values.len()));
        }
        if let Some(row) = values.iter().position(|v| !v.is_finite()) {
            return Err(format!("row {}, column {name}: {} is not finite", row + 2, values[row]));
        }
    }
    if samples < MIN_SAMPLES {
        return Err(format!("{samples} samples: too few, at least {MIN_SAMPLES} are needed"));
    }
    for (i, w) in time.windows(2).enumerate() {
        if w[1] <= w[0] {
            return Err(format!("row {}, column time: {} does not increase", i + 3, w[1]));
        }
    }
    let step = time[1] - time[0];
    for (i, w) in time.windows(2).enumerate() {
        // Uniform to what a printed time column keeps: 1e-6 of the step and a few ulps of t.
        let dt = w[1] - w[0];
        if (dt - step).abs() > 1e-6 * step + 8.0 * f64::EPSILON * w[1].abs() {
            return Err(format!(
                "row {}, column time: step {dt} differs from the first step {step}: the time must be uniform",
                i + 3
            ));
        }
    }
    // The step from the whole run: the printed first step carries the rounding of two times.
    let step = (time[samples - 1] - time[0]) / (samples - 1) as f64;
    let mut inputs = vec![[0.0; 4]; samples];
    for (j, name) in INPUTS.iter().enumerate() {
        if let Some(values) = column(name) {
            for (row, v) in inputs.iter_mut().zip(values) {
                row[j] = *v;
            }
        }
    }
    let outputs: Vec<(usize, Vec<f64>)> = OUTPUTS
        .iter()
        .enumerate()
        .filter_map(|(j, name)| column(name).map(|v| (j, v.clone())))
        .collect();
    if outputs.is_empty() {
        return Err(format!(
            "no measured output column: give one of theta_m, omega_m, theta_L, omega_L{}",
            if web { ", T" } else { "" }
        ));
    }
    Ok(Run {
        step,
        samples,
        inputs,
        outputs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn csv(rows: usize, f: impl Fn(usize) -> String) -> String {
        let mut s = String::from("time,tau_m,omega_L\n");
        for i in 0..rows {
            s.push_str(&f(i));
            s.push('\n');
        }
        s
    }

    fn refusal(text: &str) -> String {
        parse_csv(text).and_then(|c| run_from_columns(&c, false)).unwrap_err()
    }

    #[test]
    fn a_good_run_is_read_with_its_step() {
        let text = csv(30, |i| format!("{},{},{}", i as f64 * 1e-3, 1.0, 0.5));
        let run = run_from_columns(&parse_csv(&text).unwrap(), false).unwrap();
        assert_eq!((run.samples, run.outputs.len(), run.outputs[0].0), (30, 1, 3));
        assert!((run.step - 1e-3).abs() < 1e-15);
        assert_eq!(run.inputs[3], [1.0, 0.0, 0.0, 0.0]);
    }

    #[test]
    fn bad_data_is_refused_naming_the_row_or_column() {
        let t = |i: usize| i as f64 * 1e-3;
        let cases: Vec<(String, &str)> = vec![
            (csv(30, |i| format!("{},1,nan", t(i))), "row 2, column omega_L"),
            (
                csv(30, |i| format!("{},1,{}", if i == 5 { t(4) } else { t(i) }, 0)),
                "row 7, column time",
            ),
            (
                csv(30, |i| format!("{},1,0", if i == 9 { t(i) + 3e-4 } else { t(i) })),
                "row 11, column time",
            ),
            (csv(5, |i| format!("{},1,0", t(i))), "too few"),
            (csv(30, |i| format!("{},1", t(i))), "row 2: 2 cells"),
            ("time,omega_L\n0,1\n".into(), "column tau_m is missing"),
            ("tau_m,omega_L\n0,1\n".into(), "column time is missing"),
            ("time,tau_m,speed\n0,1,2\n".into(), "column \"speed\" is unknown"),
            (csv(30, |i| format!("{},x,0", t(i))), "row 2, column tau_m"),
        ];
        for (text, expected) in cases {
            let e = refusal(&text);
            assert!(e.contains(expected) && !e.contains('\n'), "{expected}: {e}");
        }
        let no_output = "time,tau_m\n".to_string() + &(0..30).map(|i| format!("{},1\n", t(i))).collect::<String>();
        assert!(refusal(&no_output).starts_with("no measured output column"));
    }
}
