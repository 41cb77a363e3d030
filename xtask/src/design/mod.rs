//! `cargo xtask design`: the paper's open question ("permissible values of compliance and
//! backlash to yield a given accuracy") answered for one plant, shaft or belt form: the
//! computations are in [`study`], this module parses and prints.

pub mod study;
pub mod web;

use std::io;

use serde::Serialize;
use serde_json::ser::Formatter;
use serde_json::{json, Value};

use backlash_fmu::fmu::adapter;
use backlash_fmu::physics::{closed_loop, Geometry, PiGains, Plant, PlantParams};
use study::{Crossing, GainDesign, StiffnessStudy};

const USAGE: &str = "\
usage: cargo xtask design --accuracy EPS [--model shaft|belt] [options] [--json]
       cargo xtask design --model web --tension-accuracy EPS_T [--accuracy EPS] [options] [--json]

For a required load-speed accuracy EPS (the bound on |omega_L with backlash - omega_L without|,
docs/model.md §3 bound_sup) and a PI loop on the motor speed, prints
  delta_max  the largest half gap Delta with bound_sup <= EPS at the nominal stiffness
             (bound_sup is linear in Delta: delta_max = EPS / bound_sup(Delta = 1));
  k_min      the smallest stiffness reachable from the nominal one by softening while
             bound_sup <= EPS at the given Delta (log scan, then a bracketing root
             finder), and k_max, the largest by stiffening: with fixed gains bound_sup
             is not monotone in k.

--model shaft (default): the shaft form of docs/model.md §1 with the paper's rectilinear rig
as defaults (SI units, metres as the angle unit); the stiffness is k [N.m/rad], Delta in rad.
--model belt: the belt-pulley + gear form with BacklashBelt.fmu's parameter values as
defaults; the stiffness is the belt's K_b [N/m], Delta in m on the gears' pitch circle.
--model web: that belt drive pulling one web span (docs/model.md §8); requires
--tension-accuracy EPS_T [N], the bound on |T with backlash - T without|, and takes --accuracy
as an optional second requirement. delta_max and the K_b window then meet every accuracy given.

options:
  --accuracy EPS  required speed accuracy [rad/s], finite and > 0 (required, except for web)
  --model M       shaft, belt or web (default shaft)
  --delta D       half gap Delta for the stiffness search (default: shaft 0.775e-3 rad, the
                  paper's 1.55 mm gap read as 2 Delta; belt 5e-5 m)
  --k K           nominal stiffness: shaft k [N.m/rad] (default 200), belt K_b [N/m]
                  (default 2e5)
  --r1 --r2 --rg1 --rg2
                  belt and web: pulley radii R_1, R_2 and gear pitch radii R_g1, R_g2 [m]
                  (defaults 0.02, 0.04, 0.015, 0.045)
  --tension-accuracy EPS_T
                  web: required tension accuracy [N], finite and > 0
  --rw --lw --ea --vref
                  web: roller radius R_w [m], span length L_w [m], web stiffness EA [N] and
                  transport speed v_ref [m/s] (defaults 0.05, 1, 1e5, 2)
  --kp-t --ki-t   web: outer tension PI trimming the speed reference [rad/s per N,
                  rad/s^2 per N] (default 0 0: no tension loop)
  --kp KP --ki KI PI gains [N.m.s/rad, N.m/rad] (default: the best-damped rule: the gains that
                  maximise the smallest damping ratio of the backlash-free closed-loop poles)
  --jm --jl       inertias [kg.m2] (defaults: shaft 2.28, 2.55; belt 1e-4, 5e-3)
  --bm --bl       viscous friction [N.m.s/rad] (defaults: shaft 0.05, 0.05; belt 1e-4, 1e-3)
  --json          print one JSON object instead of text
  --help          this text";

/// The inputs of one design run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    pub accuracy: f64,
    pub params: PlantParams,
    /// Gains given by the user; `None` means the best-damped rule.
    pub gains: Option<PiGains>,
}

/// The answer, with everything needed to print it or write it as JSON.
pub struct Answer {
    pub request: Request,
    pub gains: PiGains,
    /// Set when the gains came from the rule.
    pub rule: Option<GainDesign>,
    /// Smallest damping ratio of the backlash-free loop at `gains`.
    pub min_damping: f64,
    /// bound_sup at Δ = 1 and the nominal stiffness [rad/s per unit Δ].
    pub bound_sup_per_delta: f64,
    /// bound_sup at the requested Δ and the nominal stiffness.
    pub bound_sup_nominal: f64,
    pub delta_max: f64,
    pub study: StiffnessStudy,
}

pub fn run(args: &[String]) -> Result<(), String> {
    let Some((command, json)) = parse(args)? else {
        println!("{USAGE}");
        return Ok(());
    };
    let request = match command {
        Command::Speed(request) => request,
        Command::Web(request) => {
            let answer = web::solve(request)?;
            println!(
                "{}",
                if json {
                    laid_out(&web::to_json(&answer))
                } else {
                    web::to_text(&answer)
                }
            );
            return Ok(());
        }
    };
    let answer = solve(request)?;
    if json {
        println!("{}", to_json(&answer));
    } else {
        print_text(&answer);
    }
    Ok(())
}

/// What the command line asks for.
pub enum Command {
    /// The speed design of the shaft or belt form.
    Speed(Request),
    /// The tension design of the web line.
    Web(web::Request),
}

/// Flags that take a number, and the forms each belongs to (all forms when empty).
const NUMBER_FLAGS: [(&str, &[Form]); 20] = [
    ("--accuracy", &[]),
    ("--delta", &[]),
    ("--k", &[]),
    ("--kp", &[]),
    ("--ki", &[]),
    ("--jm", &[]),
    ("--jl", &[]),
    ("--bm", &[]),
    ("--bl", &[]),
    ("--r1", &[Form::Belt, Form::Web]),
    ("--r2", &[Form::Belt, Form::Web]),
    ("--rg1", &[Form::Belt, Form::Web]),
    ("--rg2", &[Form::Belt, Form::Web]),
    ("--tension-accuracy", &[Form::Web]),
    ("--kp-t", &[Form::Web]),
    ("--ki-t", &[Form::Web]),
    ("--rw", &[Form::Web]),
    ("--lw", &[Form::Web]),
    ("--ea", &[Form::Web]),
    ("--vref", &[Form::Web]),
];

/// Parses the command line; `Ok(None)` for `--help`.
pub fn parse(args: &[String]) -> Result<Option<(Command, bool)>, String> {
    let form = model_choice(args)?;
    let mut accuracy = None;
    let mut tension_accuracy = None;
    let mut params = default_params(form);
    let mut line = web::film_line();
    let (mut kp, mut ki) = (None, None);
    let mut tension_gains = PiGains::default();
    let mut json = false;
    let mut seen: Vec<String> = Vec::new();
    let mut it = args.iter();
    while let Some(arg) = it.next() {
        // Accept both `--flag value` and `--flag=value`.
        let (flag, inline) = match arg.split_once('=') {
            Some((f, v)) if f.starts_with("--") => (f, Some(v.to_string())),
            _ => (arg.as_str(), None),
        };
        match flag {
            "--help" | "-h" => return Ok(None),
            "--json" => {
                json = true;
                continue;
            }
            "--model" => {
                // Read by `model_choice`; skip its value.
                if inline.is_none() {
                    it.next();
                }
                continue;
            }
            _ => {}
        }
        let Some((_, forms)) = NUMBER_FLAGS.iter().find(|(f, _)| *f == flag) else {
            return Err(format!("unknown argument `{arg}`\n\n{USAGE}"));
        };
        if !forms.is_empty() && !forms.contains(&form) {
            let names: Vec<&str> = forms.iter().map(|f| f.name()).collect();
            return Err(format!("{flag} applies to --model {} only", names.join(" or ")));
        }
        if seen.iter().any(|s| s == flag) {
            return Err(format!("{flag} given twice"));
        }
        seen.push(flag.to_string());
        let text = match inline {
            Some(v) => v,
            None => it.next().cloned().ok_or_else(|| format!("{flag} needs a value"))?,
        };
        let value: f64 = text
            .trim()
            .parse()
            .map_err(|_| format!("{flag}: `{text}` is not a number"))?;
        if !value.is_finite() {
            return Err(format!("{flag} = {text} must be finite"));
        }
        let positive = |v: f64| {
            if v > 0.0 {
                Ok(v)
            } else {
                Err(format!("{flag} = {text} must be > 0"))
            }
        };
        let non_negative = |v: f64| {
            if v >= 0.0 {
                Ok(v)
            } else {
                Err(format!("{flag} = {text} must be >= 0"))
            }
        };
        match flag {
            "--accuracy" => accuracy = Some(positive(value)?),
            "--tension-accuracy" => tension_accuracy = Some(positive(value)?),
            "--delta" => params = params.with_half_gap(positive(value)?),
            "--k" => params = study::with_stiffness(&params, positive(value)?),
            "--kp" => kp = Some(value),
            "--ki" => ki = Some(value),
            "--kp-t" => tension_gains.kp = value,
            "--ki-t" => tension_gains.ki = value,
            "--jm" => params.j_m = positive(value)?,
            "--jl" => params.j_l = positive(value)?,
            "--bm" => params.b_m = non_negative(value)?,
            "--bl" => params.b_l = non_negative(value)?,
            "--rw" => line.r_w = positive(value)?,
            "--lw" => line.l_w = positive(value)?,
            "--ea" => line.ea = positive(value)?,
            "--vref" => line.v_ref = positive(value)?,
            "--r1" | "--r2" | "--rg1" | "--rg2" => {
                let Geometry::Belt {
                    r_1, r_2, r_g1, r_g2, ..
                } = &mut params.geometry
                else {
                    unreachable!("belt flags are refused for the shaft form above");
                };
                let slot = match flag {
                    "--r1" => r_1,
                    "--r2" => r_2,
                    "--rg1" => r_g1,
                    _ => r_g2,
                };
                *slot = positive(value)?;
            }
            _ => unreachable!("flag list checked above"),
        }
    }
    let gains = match (kp, ki) {
        (Some(kp), Some(ki)) => Some(PiGains { kp, ki }),
        (None, None) => None,
        _ => return Err("--kp and --ki go together (or neither, for the best-damped rule)".into()),
    };
    let command = match form {
        Form::Web => Command::Web(web::Request {
            tension_accuracy: tension_accuracy
                .ok_or_else(|| format!("--tension-accuracy EPS_T is required with --model web\n\n{USAGE}"))?,
            accuracy,
            drive: params,
            web: line,
            gains,
            tension_gains,
        }),
        Form::Shaft | Form::Belt => Command::Speed(Request {
            accuracy: accuracy.ok_or_else(|| format!("--accuracy EPS is required\n\n{USAGE}"))?,
            params,
            gains,
        }),
    };
    Ok(Some((command, json)))
}

/// The drive train a design is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    Shaft,
    Belt,
    /// The belt drive pulling a web span (docs/model.md §8).
    Web,
}

impl Form {
    fn name(self) -> &'static str {
        match self {
            Form::Shaft => "shaft",
            Form::Belt => "belt",
            Form::Web => "web",
        }
    }
}

/// `--model`'s value (shaft when absent), read before the other flags, whose defaults it sets.
fn model_choice(args: &[String]) -> Result<Form, String> {
    let mut found = None;
    let mut it = args.iter();
    while let Some(arg) = it.next() {
        let value = match arg.split_once('=') {
            Some(("--model", v)) => v.to_string(),
            _ if arg == "--model" => it.next().cloned().ok_or("--model needs a value")?,
            _ => continue,
        };
        if found.is_some() {
            return Err("--model given twice".into());
        }
        found = Some(match value.as_str() {
            "shaft" => Form::Shaft,
            "belt" => Form::Belt,
            "web" => Form::Web,
            other => return Err(format!("--model = {other}: choose shaft, belt or web")),
        });
    }
    Ok(found.unwrap_or(Form::Shaft))
}

/// The default drive of each form: the paper's rig (shaft, Δ = 0.775 mm read as rad),
/// BacklashBelt.fmu's parameter start values (belt), and BacklashWeb.fmu's drive (the same belt
/// drive; its span is `web::film_line`).
pub(crate) fn default_params(form: Form) -> PlantParams {
    match form {
        Form::Shaft => PlantParams::paper_rig(0.775e-3),
        Form::Belt => adapter::default_plant_params("BacklashBelt"),
        Form::Web => PlantParams {
            web: None,
            ..adapter::default_plant_params("BacklashWeb")
        },
    }
}

fn form_of(params: &PlantParams) -> Form {
    match params.geometry {
        Geometry::Shaft { .. } => Form::Shaft,
        Geometry::Belt { .. } => Form::Belt,
    }
}

/// The plant's parameters by their FMU names, in the order of the text and JSON answers.
pub(crate) fn named_parameters(params: &PlantParams) -> Vec<(&'static str, f64)> {
    let mut named = vec![
        ("J_m", params.j_m),
        ("J_L", params.j_l),
        ("b_m", params.b_m),
        ("b_L", params.b_l),
    ];
    match params.geometry {
        Geometry::Shaft { k, delta } => named.extend([("k", k), ("Delta", delta)]),
        Geometry::Belt {
            k_b,
            r_1,
            r_2,
            r_g1,
            r_g2,
            delta,
        } => named.extend([
            ("K_b", k_b),
            ("R_1", r_1),
            ("R_2", r_2),
            ("R_g1", r_g1),
            ("R_g2", r_g2),
            ("Delta", delta),
        ]),
    }
    named
}

/// Units of the stiffness and the half gap in `form`.
fn units(form: Form) -> (&'static str, &'static str) {
    match form {
        Form::Shaft => ("N.m/rad", "rad"),
        Form::Belt | Form::Web => ("N/m", "m"),
    }
}

/// Runs the design computations of [`study`] for `request`.
pub fn solve(request: Request) -> Result<Answer, String> {
    let params = request.params;
    let plant = Plant::new(params.with_half_gap(0.0)).map_err(|e| e.to_string())?;
    let (gains, rule) = match request.gains {
        Some(g) => (g, None),
        None => {
            let d = study::best_damped_gains(&plant).map_err(|e| e.to_string())?;
            (d.gains, Some(d))
        }
    };
    let min_damping = study::min_damping_ratio(&plant, gains);
    let bound_sup_per_delta = study::bound_sup(&params.with_half_gap(1.0), gains).map_err(|e| e.to_string())?;
    let bound_sup_nominal = study::bound_sup(&params, gains).map_err(|e| e.to_string())?;
    let delta_max = study::delta_max(&params, gains, request.accuracy).map_err(|e| e.to_string())?;
    let study = study::stiffness_study(&params, gains, request.accuracy).map_err(|e| e.to_string())?;
    Ok(Answer {
        request,
        gains,
        rule,
        min_damping,
        bound_sup_per_delta,
        bound_sup_nominal,
        delta_max,
        study,
    })
}

fn describe_crossing(c: &Option<Crossing>, edge: &str) -> String {
    match c {
        Some(c) => format!(
            "{:.6} (bound_sup there {:.6e}; bracket [{:.4}, {:.4}], bound_sup {} on it: {})",
            c.k,
            c.bound_sup,
            c.bracket.0,
            c.bracket.1,
            if c.decreasing { "decreasing" } else { "increasing" },
            if c.monotone_in_bracket {
                "monotone, checked"
            } else {
                "NOT monotone"
            }
        ),
        None => format!("none within the scan (feasible to its {edge} edge)"),
    }
}

fn print_text(a: &Answer) {
    let p = &a.request.params;
    let form = form_of(p);
    let (k_unit, delta_unit) = units(form);
    let listed: Vec<String> = named_parameters(p).iter().map(|(n, v)| format!("{n} = {v}")).collect();
    println!("plant ({} form): {}", form.name(), listed.join(", "));
    match &a.rule {
        Some(_) => println!(
            "PI gains (best-damped rule): Kp = {:.6}, Ki = {:.6}; smallest closed-loop damping ratio {:.6}",
            a.gains.kp, a.gains.ki, a.min_damping
        ),
        None => println!(
            "PI gains (given): Kp = {}, Ki = {}; smallest closed-loop damping ratio {:.6}",
            a.gains.kp, a.gains.ki, a.min_damping
        ),
    }
    println!("required accuracy eps = {:e} rad/s", a.request.accuracy);
    println!(
        "bound_sup per unit Delta at k = {} {k_unit}: {:.9} (rad/s)/{delta_unit}",
        study::stiffness(p),
        a.bound_sup_per_delta
    );
    println!(
        "delta_max = {:.9e} {delta_unit} (gap 2*delta_max = {:.9e}); at Delta = {}: bound_sup = {:.6e}",
        a.delta_max,
        2.0 * a.delta_max,
        study::half_gap(p),
        a.bound_sup_nominal
    );
    let s = &a.study;
    println!(
        "stiffness at Delta = {} {delta_unit} (scan {} points, k in [{:.4}, {:.4}] {k_unit}): bound_sup is {}",
        s.delta,
        s.scan.len(),
        s.scan.first().map_or(0.0, |x| x.0),
        s.scan.last().map_or(0.0, |x| x.0),
        if s.monotone() {
            "monotone in k".to_string()
        } else {
            format!(
                "NOT monotone in k (turning points near k = {})",
                join(&s.turning_points)
            )
        }
    );
    match s.nominal_interval {
        Some(_) => {
            println!("  k_min = {}", describe_crossing(&s.k_min(), "lower"));
            println!("  k_max = {}", describe_crossing(&s.k_max(), "upper"));
        }
        None => println!(
            "  no: bound_sup > eps at the nominal k = {}; no k_min on its branch",
            s.k_nominal
        ),
    }
    for iv in &s.intervals {
        println!(
            "  feasible interval: [{}, {}]",
            iv.lo.map_or("<scan edge".to_string(), |c| format!("{:.6}", c.k)),
            iv.hi.map_or(">scan edge".to_string(), |c| format!("{:.6}", c.k))
        );
    }
}

fn join(values: &[f64]) -> String {
    values.iter().map(|v| format!("{v:.4}")).collect::<Vec<_>>().join(", ")
}

/// A crossing's details, or null.
fn crossing_json(c: &Option<Crossing>) -> Value {
    match c {
        None => Value::Null,
        Some(c) => json!({
            "k": c.k,
            "bound_sup": c.bound_sup,
            "bracket": [c.bracket.0, c.bracket.1],
            "monotone_in_bracket": c.monotone_in_bracket,
            "decreasing": c.decreasing,
        }),
    }
}

/// The answer as one JSON object (keys documented in the README's design section). Numbers
/// are shortest round-trip; JSON has no infinity or NaN, so those become null.
pub fn to_json(a: &Answer) -> String {
    let p = &a.request.params;
    let s = &a.study;
    let poles = match &a.rule {
        Some(d) => d.poles.to_vec(),
        None => {
            let plant = Plant::new(p.with_half_gap(0.0)).expect("validated in solve");
            closed_loop::reduced_loop_poles(&plant, a.gains).to_vec()
        }
    };
    let gain_rule = if a.rule.is_some() {
        "best-damped: maximise the smallest damping ratio of the backlash-free closed-loop poles"
    } else {
        "given"
    };
    let mut plant = serde_json::Map::new();
    plant.insert("form".into(), json!(form_of(p).name()));
    for (name, value) in named_parameters(p) {
        plant.insert(name.into(), json!(value));
    }
    let value = json!({
        "plant": plant,
        "accuracy": a.request.accuracy,
        "gain_rule": gain_rule,
        "Kp": a.gains.kp,
        "Ki": a.gains.ki,
        "min_damping_ratio": a.min_damping,
        "poles": poles.iter().map(|z| json!([z.re, z.im])).collect::<Vec<_>>(),
        "bound_sup_per_unit_delta": a.bound_sup_per_delta,
        "bound_sup_at_delta": a.bound_sup_nominal,
        "delta_max": a.delta_max,
        "k_min": s.k_min().map(|c| c.k),
        "k_max": s.k_max().map(|c| c.k),
        "k_min_detail": crossing_json(&s.k_min()),
        "k_max_detail": crossing_json(&s.k_max()),
        "k_monotone": s.monotone(),
        "k_turning_points": s.turning_points,
        "k_intervals": s.intervals.iter().map(|iv| json!([iv.lo.map(|c| c.k), iv.hi.map(|c| c.k)])).collect::<Vec<_>>(),
        "k_scan": s.scan.iter().map(|(k, b)| json!([k, b])).collect::<Vec<_>>(),
    });
    laid_out(&value)
}

/// `value` as text in the [`Layout`].
pub(crate) fn laid_out(value: &Value) -> String {
    let mut out = Vec::new();
    let mut writer = serde_json::Serializer::with_formatter(&mut out, Layout { depth: 0 });
    value
        .serialize(&mut writer)
        .expect("a JSON value serializes into memory");
    String::from_utf8(out).expect("serde_json writes UTF-8")
}

/// The top-level object one key per line, everything inside it on one line with a space after
/// each `:` and `,`: one line per answer, and the scan stays a short block.
struct Layout {
    depth: usize,
}

impl Formatter for Layout {
    fn begin_array<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.depth += 1;
        w.write_all(b"[")
    }

    fn end_array<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.depth -= 1;
        w.write_all(b"]")
    }

    fn begin_array_value<W: ?Sized + io::Write>(&mut self, w: &mut W, first: bool) -> io::Result<()> {
        w.write_all(if first { b"" } else { b", " })
    }

    fn begin_object<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.depth += 1;
        w.write_all(b"{")
    }

    fn end_object<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.depth -= 1;
        w.write_all(if self.depth == 0 { b"\n}" } else { b"}" })
    }

    fn begin_object_key<W: ?Sized + io::Write>(&mut self, w: &mut W, first: bool) -> io::Result<()> {
        let separator: &[u8] = match (self.depth, first) {
            (1, true) => b"\n  ",
            (1, false) => b",\n  ",
            (_, true) => b"",
            (_, false) => b", ",
        };
        w.write_all(separator)
    }

    fn begin_object_value<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        w.write_all(b": ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(list: &[&str]) -> Vec<String> {
        list.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn rejects_bad_arguments() {
        for bad in [
            &[][..],
            &["--accuracy"],
            &["--accuracy", "-0.1"],
            &["--accuracy", "0"],
            &["--accuracy", "NaN"],
            &["--accuracy", "inf"],
            &["--accuracy", "abc"],
            &["--accuracy", "0.1", "--frobnicate"],
            &["--accuracy", "0.1", "--kp", "3"],
            &["--accuracy", "0.1", "--k", "-200"],
            &["--accuracy", "0.1", "--accuracy", "0.2"],
            &["--accuracy", "0.1", "--model"],
            &["--accuracy", "0.1", "--model", "web"],
            &["--accuracy", "0.1", "--model", "wire"],
            &["--tension-accuracy", "1", "--model", "belt", "--accuracy", "0.1"],
            &["--model", "web", "--tension-accuracy", "0"],
            &["--model", "web", "--tension-accuracy", "1", "--rw", "0"],
            &["--accuracy", "0.1", "--model", "belt", "--model=belt"],
            &["--accuracy", "0.1", "--r1", "0.02"],
            &["--accuracy", "0.1", "--model", "belt", "--rg2", "0"],
        ] {
            assert!(parse(&args(bad)).is_err(), "{bad:?} accepted");
        }
    }

    #[test]
    fn the_layout_puts_each_top_level_key_on_its_line() {
        let value = json!({"a": {"x": 1.0, "y": [f64::INFINITY, 2.5e-7]}, "b": [], "c": "q\"uote"});
        let text = laid_out(&value);
        assert_eq!(
            text,
            "{\n  \"a\": {\"x\": 1.0, \"y\": [null, 2.5e-7]},\n  \"b\": [],\n  \"c\": \"q\\\"uote\"\n}"
        );
        assert_eq!(serde_json::from_str::<Value>(&text).unwrap()["c"], "q\"uote");
    }

    #[test]
    fn the_belt_form_starts_from_the_belt_fmu_and_takes_its_flags() {
        let list = ["--model", "belt", "--accuracy", "0.5", "--rg1=0.02", "--k", "3e5"];
        let Some((Command::Speed(r), _)) = parse(&args(&list)).unwrap() else {
            panic!("not the speed design")
        };
        let Geometry::Belt {
            k_b, r_1, r_g1, delta, ..
        } = r.params.geometry
        else {
            panic!("not the belt form: {:?}", r.params.geometry)
        };
        // BacklashBelt.fmu's start values (docs/model.md §4), two of them overridden.
        assert_eq!((k_b, r_1, r_g1, delta), (3e5, 0.02, 0.02, 5e-5));
        assert_eq!((r.params.j_m, r.params.j_l), (1e-4, 5e-3));
        let names: Vec<_> = named_parameters(&r.params).into_iter().map(|(n, _)| n).collect();
        assert_eq!(
            names,
            ["J_m", "J_L", "b_m", "b_L", "K_b", "R_1", "R_2", "R_g1", "R_g2", "Delta"]
        );
    }

    #[test]
    fn parses_both_flag_forms() {
        let (Command::Speed(r), json) = parse(&args(&["--accuracy=0.02", "--delta", "1e-3", "--json"]))
            .unwrap()
            .unwrap()
        else {
            panic!("not the speed design")
        };
        assert_eq!(r.accuracy, 0.02);
        assert_eq!(study::half_gap(&r.params), 1e-3);
        assert!(json && r.gains.is_none());
    }
}
