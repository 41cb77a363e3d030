//! `backlash identify` and `backlash excite`: command lines read into an identification or an
//! excitation, the answers as strings. Unlike the rest of the library these read the data file
//! and write the schedule file the command line names; the computations stay pure.

use super::{build, excite, identify as identify_run, to_json, to_text};
use crate::cli::{model_choice, CliError};
use crate::request::{Setting, Vocabulary};

/// The identify command's usage.
pub fn identify_usage(command: &str) -> String {
    format!(
        "usage: {command} --model shaft|belt|web FILE [--fit NAME,NAME...] [--set NAME=VALUE ...]
       [--accuracy EPS] [--tension-accuracy EPS_T] [--json]

Fits the exact model (docs/model.md §1, §11) to the measured run in FILE and prints each fitted
parameter with its 95% interval, or `not identifiable` with the reason when the data do not
determine it.

FILE: CSV with a header of FMU variable names: time (s, uniform step), tau_m (required), tau_L
(0 if absent), and measured outputs, any of theta_m, omega_m, theta_L, omega_L (web: also v_in,
T_in, T). Inputs are held from their row's time to the next; the run starts at rest, angles
measured from the start.

options:
  --model M         shaft (default), belt or web
  --fit NAMES       the parameters to estimate, comma-separated, from J_m, J_L, b_m, b_L, k
                    (belt, web: K_b), Delta, u0 (default: Delta, the stiffness, J_L, b_L, u0)
  --set NAME=VALUE  a known parameter by its FMU name (docs/model.md §4), or the start of a
                    fitted one; every other takes the model's default
  --accuracy EPS    also report bound_sup at the estimate and at the worst corner of the
                    confidence box, and whether the drive meets EPS [rad/s]
  --tension-accuracy EPS_T
                    web: the same for bound_T_sup and EPS_T [N]
  --json            print one JSON object (docs/model.md §11) instead of text
  --help            this text"
    )
}

/// The excite command's usage.
pub fn excite_usage(command: &str) -> String {
    format!(
        "usage: {command} --model shaft|belt|web [--set NAME=VALUE ...] [--duration S] [--step H]
       [--torque-limit TAU] [--out FILE]

Writes a motor-torque schedule (CSV: time,tau_m) for the drive: the torque reverses at
pseudo-random instants, each dwell half to one and a half periods of the contact resonance,
alternating between the full and half torque limit, so that the teeth cross the gap at every
reversal. `backlash identify` needs ten reversals at least: a run of ten resonance periods
(about 5 s for the paper's rig; docs/model.md §11).

options:
  --model M           shaft (default), belt or web
  --set NAME=VALUE    a drive parameter by its FMU name
  --duration S        run length [s] (default: 10 s, or ten resonance periods if longer)
  --step H            sample step [s] (default 1e-3)
  --torque-limit TAU  largest |tau_m| [N.m] (default: 5 r_m K g)
  --out FILE          write the CSV there (default: print it)
  --help              this text"
    )
}

/// Flags shared by both commands, read in one pass: (positional arguments, settings, other
/// flags with their values).
struct Parsed {
    positional: Vec<String>,
    settings: Vec<(String, String)>,
    flags: Vec<(String, String)>,
    json: bool,
    help: bool,
}

fn parse(command: &str, args: &[String], valued: &[&str], usage: &dyn Fn() -> String) -> Result<Parsed, CliError> {
    let mut p = Parsed {
        positional: Vec::new(),
        settings: Vec::new(),
        flags: Vec::new(),
        json: false,
        help: false,
    };
    let mut it = args.iter();
    while let Some(arg) = it.next() {
        let (flag, inline) = match arg.split_once('=') {
            Some((f, v)) if f.starts_with("--") => (f, Some(v.to_string())),
            _ => (arg.as_str(), None),
        };
        match flag {
            "--help" | "-h" => p.help = true,
            "--json" if valued.contains(&"--fit") => p.json = true,
            f if f == "--model" || f == "--set" || valued.contains(&f) => {
                let value = match inline {
                    Some(v) => v,
                    None => it
                        .next()
                        .cloned()
                        .ok_or_else(|| CliError::new(command, format!("{f} needs a value")))?,
                };
                match f {
                    "--model" => {}
                    "--set" => {
                        let (name, v) = value
                            .split_once('=')
                            .ok_or_else(|| CliError::new(command, format!("--set {value}: write NAME=VALUE")))?;
                        p.settings.push((name.trim().to_string(), v.trim().to_string()));
                    }
                    _ => {
                        if p.flags.iter().any(|(g, _)| g == f) {
                            return Err(CliError::new(command, format!("{f} given twice")));
                        }
                        p.flags.push((f.to_string(), value));
                    }
                }
            }
            f if f.starts_with('-') && f.len() > 1 => {
                return Err(CliError::with_usage(
                    command,
                    format!("unknown argument `{arg}`"),
                    usage(),
                ))
            }
            _ => p.positional.push(arg.clone()),
        }
    }
    Ok(p)
}

fn number(command: &str, flag: &str, text: &str) -> Result<f64, CliError> {
    text.trim()
        .parse()
        .map_err(|_| CliError::new(command, format!("{flag}: `{text}` is not a number")))
}

/// Settings from `--set` pairs and numeric flags (named `accuracy`, `tension_accuracy`).
fn settings<'a>(
    command: &str,
    parsed: &'a Parsed,
    extra: &'a [(&'a str, &'a str, String)],
) -> Result<Vec<Setting<'a>>, CliError> {
    let mut out = Vec::new();
    for (name, text) in &parsed.settings {
        out.push(Setting {
            name,
            label: name,
            text: text.clone(),
            value: number(command, &format!("--set {name}"), text)?,
        });
    }
    for (name, label, text) in extra {
        out.push(Setting {
            name,
            label,
            text: text.clone(),
            value: number(command, label, text)?,
        });
    }
    Ok(out)
}

/// `backlash identify`: `args` are its flags and the data file.
pub fn identify(command: &str, args: &[String]) -> Result<String, CliError> {
    let usage = || identify_usage(command);
    let parsed = parse(command, args, &["--fit", "--accuracy", "--tension-accuracy"], &usage)?;
    if parsed.help {
        return Ok(usage());
    }
    let form = model_choice(args).map_err(|m| CliError::new(command, m))?;
    let file = match parsed.positional.as_slice() {
        [file] => file,
        [] => return Err(CliError::with_usage(command, "no data FILE given", usage())),
        [_, extra, ..] => {
            return Err(CliError::with_usage(
                command,
                format!("unexpected argument `{extra}`"),
                usage(),
            ))
        }
    };
    let extra: Vec<(&str, &str, String)> = parsed
        .flags
        .iter()
        .filter_map(|(f, v)| match f.as_str() {
            "--accuracy" => Some(("accuracy", "--accuracy", v.clone())),
            "--tension-accuracy" => Some(("tension_accuracy", "--tension-accuracy", v.clone())),
            _ => None,
        })
        .collect();
    let settings = settings(command, &parsed, &extra)?;
    let fit: Option<Vec<String>> = parsed
        .flags
        .iter()
        .find(|(f, _)| f == "--fit")
        .map(|(_, v)| v.split(',').map(str::to_string).collect());
    let refuse = |m: String| CliError::new(command, m);
    let request = build(form, &settings, fit.as_deref(), Vocabulary::Flags).map_err(refuse)?;
    let columns = super::data::read_csv(file).map_err(refuse)?;
    let answer = identify_run(&request, &columns).map_err(|m| refuse(format!("{file}: {m}")))?;
    Ok(if parsed.json {
        to_json(&answer)
    } else {
        to_text(&answer)
    })
}

/// `backlash excite`: `args` are its flags.
pub fn excite(command: &str, args: &[String]) -> Result<String, CliError> {
    let usage = || excite_usage(command);
    let parsed = parse(
        command,
        args,
        &["--duration", "--step", "--torque-limit", "--out"],
        &usage,
    )?;
    if parsed.help {
        return Ok(usage());
    }
    if let Some(extra) = parsed.positional.first() {
        return Err(CliError::with_usage(
            command,
            format!("unexpected argument `{extra}`"),
            usage(),
        ));
    }
    let form = model_choice(args).map_err(|m| CliError::new(command, m))?;
    let refuse = |m: String| CliError::new(command, m);
    let settings = settings(command, &parsed, &[])?;
    let request = build(form, &settings, None, Vocabulary::Flags).map_err(refuse)?;
    let flag = |name: &str| parsed.flags.iter().find(|(f, _)| f == name).map(|(_, v)| v.clone());
    let value = |name: &str| flag(name).map(|v| number(command, name, &v)).transpose();
    let params = backlash_physics::PlantParams {
        web: None,
        ..request.params
    };
    let min = excite::min_duration(&params).map_err(refuse)?;
    let duration = value("--duration")?.unwrap_or(min.max(10.0));
    let step = value("--step")?.unwrap_or(1e-3);
    let schedule = excite::schedule(&params, duration, step, value("--torque-limit")?).map_err(refuse)?;
    let csv = excite::to_csv(&schedule);
    match flag("--out") {
        None => Ok(csv.trim_end().to_string()),
        Some(path) => {
            std::fs::write(&path, csv).map_err(|e| refuse(format!("{path}: {e}")))?;
            let reversals = schedule.windows(2).filter(|w| w[0].1 * w[1].1 < 0.0).count();
            let note = if duration < min {
                format!("; shorter than the {min:.3} s (ten resonance periods) that identification needs")
            } else {
                String::new()
            };
            Ok(format!(
                "wrote {path}: {} samples, {duration} s, {reversals} reversals{note}",
                schedule.len()
            ))
        }
    }
}
