//! The command line of the design study: `backlash design ...` (and its alias `cargo xtask
//! design ...`) read into a request, solved, and the answer written as text or JSON. Everything
//! here returns strings; the caller prints them.

pub use crate::request::Request;
use crate::request::{self, form_named, Setting, Vocabulary};
use crate::Form;

/// The `backlash` command's usage.
pub const USAGE: &str = "\
usage: backlash <command> [args]

commands:
  design    the design study: the backlash and stiffness that meet a load-speed accuracy, or a
            web line's tension accuracy (see `backlash design --help`)
  identify  a drive's half gap, stiffness and load from one measured run, with 95% intervals
            (see `backlash identify --help`)
  excite    a reversing motor-torque schedule that makes the gap identifiable (see
            `backlash excite --help`)
  help      this text

A command line without an answer (an unknown command or argument, a bad or missing value, a
plant and gains with no finite bound) gives one `error:` line on stderr and exit status 2.";

/// The design command's usage after its first two lines, which name the command.
const DESIGN_DETAILS: &str = "
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
--model two-stage: two gear stages in series (docs/model.md §10, BacklashTwoStage), defaults
the paper's rig with its compliance and gap split over two meshes; bound_sup = s_1 Delta_1 +
s_2 Delta_2 is linear in each half gap, so it prints each stage's s_j (bound_sup per unit of
its gap), the largest Delta_j with the other gap at its value and with it closed, and which
stage spends more of the bound.

options:
  --accuracy EPS  required speed accuracy [rad/s], finite and > 0 (required, except for web)
  --model M       shaft, belt, web or two-stage (default shaft)
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
  --damping D     damper in the compliant member: shaft d [N.m.s/rad], belt and web D_b [N.s/m]
                  (default 0); the backlash-free loop is then the spring-damper's, and
                  bound_sup answers for the gap only (docs/model.md §3)
  --contact-law L 1: Modelica's ElastoBacklash (default), 2: ElastoBacklash2
  --ji --bi       two-stage: the intermediate shaft's inertia J_i [kg.m2] and friction b_i
                  [N.m.s/rad] (defaults 0.1, 0.01; --jm --jl --bm --bl as the shaft's)
  --n1 --n2       two-stage: each stage's reduction ratio (defaults 1, 1)
  --k1 --k2       two-stage: each stage's stiffness [N.m/rad] (defaults 400, 400)
  --delta1 --delta2
                  two-stage: each stage's half gap [rad] (defaults 0.3875e-3, 0.3875e-3)
  --d1 --d2       two-stage: each stage's damper [N.m.s/rad] (default 0), under --contact-law;
                  bound_sup then answers for the gaps only, as with --damping
  --tau-c-m --tau-c-l --peak-m --peak-l
                  shaft and belt: Coulomb friction with stiction in the motor's and the load's
                  bearing (docs/model.md §12), tau_c [N.m] >= 0 and peak >= 1 (defaults 0, 1).
                  bound_sup then adds 2 peak tau_c int|h_b| per body, a part no gap shrinks
                  (docs/model.md §10): delta_max and the stiffness window include it, and when
                  friction alone spends the accuracy there is no delta_max
  --json          print one JSON object instead of text
  --help          this text";

/// The design command's usage, naming it `command` (`backlash design`, `cargo xtask design`).
pub fn design_usage(command: &str) -> String {
    format!(
        "usage: {command} --accuracy EPS [--model shaft|belt|two-stage] [options] [--json]\n       \
         {command} --model web --tension-accuracy EPS_T [--accuracy EPS] [options] [--json]\n{DESIGN_DETAILS}"
    )
}

/// Why a command line gives no answer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CliError {
    /// The reason, on one line.
    pub message: String,
    /// The command whose `--help` explains the command line (`backlash`, `backlash design`).
    pub command: String,
    /// The command's usage, when the reason is something it explains (an unknown argument, a
    /// missing requirement).
    pub usage: Option<String>,
}

impl CliError {
    /// The exit status of a command line without an answer.
    pub const EXIT_STATUS: i32 = 2;

    pub(crate) fn new(command: &str, message: impl Into<String>) -> CliError {
        CliError {
            message: message.into(),
            command: command.to_string(),
            usage: None,
        }
    }

    pub(crate) fn with_usage(command: &str, message: impl Into<String>, usage: String) -> CliError {
        CliError {
            usage: Some(usage),
            ..CliError::new(command, message)
        }
    }

    /// One line: the reason, and where the usage is when it explains it.
    pub fn line(&self) -> String {
        match self.usage {
            Some(_) => format!("{}; see `{} --help`", self.message, self.command),
            None => self.message.clone(),
        }
    }

    /// The reason followed by the usage when it explains it, after an empty line.
    pub fn with_usage_text(&self) -> String {
        match &self.usage {
            Some(usage) => format!("{}\n\n{usage}", self.message),
            None => self.message.clone(),
        }
    }
}

/// The `backlash` command as a process runs it: (exit status, text for stdout, text for
/// stderr), each text with its final newline; a command line without an answer gives one
/// `error:` line and [`CliError::EXIT_STATUS`].
pub fn command(args: &[String]) -> (i32, String, String) {
    match run(args) {
        Ok(text) => (0, format!("{text}\n"), String::new()),
        Err(e) => (CliError::EXIT_STATUS, String::new(), format!("error: {}\n", e.line())),
    }
}

/// The `backlash` command: `args` without the program name. `Ok` holds the text to print (an
/// answer or a usage), without its final newline.
pub fn run(args: &[String]) -> Result<String, CliError> {
    match args.split_first() {
        None => Err(CliError::with_usage("backlash", "no command given", USAGE.to_string())),
        Some((command, _)) if matches!(command.as_str(), "help" | "--help" | "-h") => Ok(USAGE.to_string()),
        Some((command, rest)) if command == "design" => design("backlash design", rest),
        Some((command, rest)) if command == "identify" => crate::identify::command::identify("backlash identify", rest),
        Some((command, rest)) if command == "excite" => crate::identify::command::excite("backlash excite", rest),
        Some((other, _)) => Err(CliError::with_usage(
            "backlash",
            format!("unknown command `{other}`"),
            USAGE.to_string(),
        )),
    }
}

/// The design command, named `command` in its usage: `args` are its flags. `Ok` holds the text
/// to print (the answer as text or JSON, or the usage), without its final newline.
pub fn design(command: &str, args: &[String]) -> Result<String, CliError> {
    let Some((request, json)) = parse(command, args)? else {
        return Ok(design_usage(command));
    };
    let answer = if json {
        request.answer_json()
    } else {
        request.answer_text()
    };
    answer.map_err(|message| CliError::new(command, message))
}

/// The flags that take a number, and the setting each one gives ([`request::SETTINGS`]; `--k` is
/// the stiffness of the form: `k` or `K_b`).
const NUMBER_FLAGS: [(&str, &str); 36] = [
    ("--accuracy", "accuracy"),
    ("--delta", "Delta"),
    ("--k", STIFFNESS),
    ("--kp", "Kp"),
    ("--ki", "Ki"),
    ("--jm", "J_m"),
    ("--jl", "J_L"),
    ("--bm", "b_m"),
    ("--bl", "b_L"),
    ("--r1", "R_1"),
    ("--r2", "R_2"),
    ("--rg1", "R_g1"),
    ("--rg2", "R_g2"),
    ("--tension-accuracy", "tension_accuracy"),
    ("--kp-t", "Kp_T"),
    ("--ki-t", "Ki_T"),
    ("--rw", "R_w"),
    ("--lw", "L_w"),
    ("--ea", "EA"),
    ("--vref", "v_ref"),
    ("--damping", DAMPING),
    ("--contact-law", "contact_law"),
    ("--ji", "J_i"),
    ("--bi", "b_i"),
    ("--n1", "n_1"),
    ("--n2", "n_2"),
    ("--k1", "k_1"),
    ("--k2", "k_2"),
    ("--delta1", "Delta_1"),
    ("--delta2", "Delta_2"),
    ("--d1", "d_1"),
    ("--tau-c-m", "tau_c_m"),
    ("--tau-c-l", "tau_c_L"),
    ("--peak-m", "peak_m"),
    ("--peak-l", "peak_L"),
    ("--d2", "d_2"),
];

/// Stands for the form's stiffness in [`NUMBER_FLAGS`].
const STIFFNESS: &str = "";
/// Stands for the damper of the form's compliant member (`d` or `D_b`) in [`NUMBER_FLAGS`].
const DAMPING: &str = "damping";

/// Parses the design command's flags (`command` names it in errors); `Ok(None)` for `--help`,
/// else the request and whether the answer is wanted as JSON. The values are checked and
/// applied by [`request::build`].
pub fn parse(command: &str, args: &[String]) -> Result<Option<(Request, bool)>, CliError> {
    let refuse = |message: String| CliError::new(command, message);
    let refuse_with_usage = |message: String| CliError::with_usage(command, message, design_usage(command));
    let form = model_choice(args).map_err(refuse)?;
    let mut json = false;
    let mut settings: Vec<Setting> = Vec::new();
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
        let Some(&(flag, name)) = NUMBER_FLAGS.iter().find(|(f, _)| *f == flag) else {
            return Err(refuse_with_usage(format!("unknown argument `{arg}`")));
        };
        let name = match (name, form) {
            (STIFFNESS, Form::Shaft) => "k",
            (STIFFNESS, _) => "K_b",
            (DAMPING, Form::Shaft) => "d",
            (DAMPING, _) => "D_b",
            (name, _) => name,
        };
        let text = match inline {
            Some(v) => v,
            None => it
                .next()
                .cloned()
                .ok_or_else(|| refuse(format!("{flag} needs a value")))?,
        };
        let value: f64 = text
            .trim()
            .parse()
            .map_err(|_| refuse(format!("{flag}: `{text}` is not a number")))?;
        settings.push(Setting {
            name,
            label: flag,
            text,
            value,
        });
    }
    let request = request::build(form, &settings, Vocabulary::Flags).map_err(|r| match r.missing {
        true => refuse_with_usage(r.message),
        false => refuse(r.message),
    })?;
    Ok(Some((request, json)))
}

/// `--model`'s value (shaft when absent), read before the other flags, whose defaults it sets.
pub(crate) fn model_choice(args: &[String]) -> Result<Form, String> {
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
        found =
            Some(form_named(&value).ok_or_else(|| format!("--model = {value}: choose shaft, belt, web or two-stage"))?);
    }
    Ok(found.unwrap_or(Form::Shaft))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study;
    use backlash_physics::{Geometry, PiGains};

    const COMMAND: &str = "backlash design";

    fn args(list: &[&str]) -> Vec<String> {
        list.iter().map(|s| s.to_string()).collect()
    }

    /// `--damping` is the damper of the form's member (`d` or `D_b`), `--contact-law` its law;
    /// both reach the plant of the request.
    #[test]
    fn damping_flags_reach_the_plant() {
        for (model, law) in [("shaft", 2.0), ("belt", 1.0), ("web", 2.0)] {
            let law_text = format!("{law}");
            let mut list = vec![
                "--model",
                model,
                "--damping",
                "12.5",
                "--contact-law",
                law_text.as_str(),
            ];
            list.extend(if model == "web" {
                ["--tension-accuracy", "20"]
            } else {
                ["--accuracy", "0.1"]
            });
            let Ok(Some((request, _))) = parse(COMMAND, &args(&list)) else {
                panic!("{list:?} refused")
            };
            let params = match request {
                Request::Speed(r) => r.params,
                Request::Web(r) => r.drive,
                Request::TwoStage(_) => panic!("{model} is a single-gap form"),
            };
            assert_eq!(params.damping.d, 12.5, "{model}");
            assert_eq!(params.damping.law.code() as f64, law, "{model}");
        }
    }

    /// The friction flags reach the speed design's request, checked by range; the web line and
    /// the two-stage form refuse them.
    #[test]
    fn friction_flags_reach_the_speed_design() {
        let list = [
            "--accuracy",
            "0.1",
            "--tau-c-m",
            "0.5",
            "--tau-c-l",
            "0.25",
            "--peak-m",
            "1.5",
            "--peak-l",
            "2",
        ];
        let Ok(Some((Request::Speed(r), false))) = parse(COMMAND, &args(&list)) else {
            panic!("{list:?} refused")
        };
        let [m, l] = r.friction;
        assert_eq!((m.tau_c, m.peak, l.tau_c, l.peak), (0.5, 1.5, 0.25, 2.0));
        for bad in [
            &["--accuracy", "0.1", "--tau-c-m", "-0.5"][..],
            &["--accuracy", "0.1", "--peak-l", "0.999"],
            &["--model", "web", "--tension-accuracy", "20", "--tau-c-m", "0.5"],
            &["--model", "two-stage", "--accuracy", "0.1", "--tau-c-l", "0.5"],
        ] {
            assert!(parse(COMMAND, &args(bad)).is_err(), "{bad:?}");
        }
    }

    /// With bearing friction, bound_sup = s Δ + F (docs/model.md §10): delta_max spends what F
    /// leaves of the accuracy, and F is linear in each body's peak·τ_c (the bound is 2 peak τ_c
    /// ∫|h_b| per body). Friction that alone spends the accuracy leaves no delta_max.
    #[test]
    fn friction_spends_part_of_the_accuracy() {
        let solve = |extra: &[&str]| {
            let mut list = vec!["--accuracy", "0.02", "--kp", "20", "--ki", "50"];
            list.extend_from_slice(extra);
            let Ok(Some((Request::Speed(r), false))) = parse(COMMAND, &args(&list)) else {
                panic!("{list:?} refused")
            };
            crate::speed::solve(r).unwrap()
        };
        let plain = solve(&[]);
        assert_eq!(plain.friction_sup, 0.0);
        let motor = solve(&["--tau-c-m", "0.01"]);
        let load = solve(&["--tau-c-l", "0.01", "--peak-l", "2"]);
        let both = solve(&["--tau-c-m", "0.01", "--tau-c-l", "0.01", "--peak-l", "2"]);
        assert!(motor.friction_sup > 0.0 && load.friction_sup > 0.0);
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
        // Each body's term apart, and the load's twice what peak 1 gives.
        assert!(close(both.friction_sup, motor.friction_sup + load.friction_sup));
        let load_peak1 = solve(&["--tau-c-l", "0.01"]);
        assert!(close(load.friction_sup, 2.0 * load_peak1.friction_sup));
        // delta_max: s Δ_max + F = ε, the same s as without friction.
        let d = both.delta_max.unwrap();
        assert!(close(both.bound_sup_per_delta * d + both.friction_sup, 0.02));
        assert_eq!(both.bound_sup_per_delta, plain.bound_sup_per_delta);
        assert!(d < plain.delta_max.unwrap());
        // Friction 0.02/F times that spends the whole accuracy: no delta_max.
        let heavy = format!("{}", 0.01 * 1.01 * 0.02 / motor.friction_sup);
        let none = solve(&["--tau-c-m", heavy.as_str()]);
        assert!(none.friction_sup > 0.02 && none.delta_max.is_none());
    }

    /// The two-stage flags reach their stage and body; a flag of another form is refused.
    #[test]
    fn two_stage_flags_reach_the_chain() {
        let list = [
            "--model",
            "two-stage",
            "--accuracy",
            "0.1",
            "--ji",
            "0.2",
            "--bi",
            "0.3",
            "--n1",
            "2",
            "--n2",
            "3",
            "--k1",
            "500",
            "--k2",
            "600",
            "--delta1",
            "1e-3",
            "--delta2",
            "2e-3",
            "--jl",
            "4",
        ];
        let Ok(Some((Request::TwoStage(r), false))) = parse(COMMAND, &args(&list)) else {
            panic!("{list:?} refused")
        };
        let [first, second] = r.drive.stages;
        assert_eq!(
            (r.drive.driven[0].j, r.drive.driven[0].b, r.drive.driven[1].j),
            (0.2, 0.3, 4.0)
        );
        assert_eq!((first.c, first.k, first.g), (2.0, 500.0, 1e-3));
        assert_eq!((second.c, second.k, second.g), (3.0, 600.0, 2e-3));
        assert_eq!((first.a, second.a), (1.0, 1.0));
        for bad in [
            &["--model", "two-stage", "--accuracy", "0.1", "--delta", "1e-3"][..],
            &["--model", "two-stage", "--accuracy", "0.1", "--k", "1e3"],
            &["--model", "two-stage", "--accuracy", "0.1", "--damping", "1"],
            &["--model", "shaft", "--accuracy", "0.1", "--n1", "2"],
            &["--model", "two-stage"],
        ] {
            assert!(parse(COMMAND, &args(bad)).is_err(), "{bad:?}");
        }
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
            &["--accuracy", "0.1", "--damping", "-1"],
            &["--accuracy", "0.1", "--damping", "NaN"],
            &["--accuracy", "0.1", "--contact-law", "3"],
            &["--accuracy", "0.1", "--contact-law", "0"],
            &["--accuracy", "0.1", "--contact-law", "1.5"],
        ] {
            let Err(e) = parse(COMMAND, &args(bad)) else {
                panic!("{bad:?} accepted")
            };
            // The binary prints `error: ` and this line: one line, whatever the reason.
            assert!(!e.line().contains('\n') && !e.line().is_empty(), "{bad:?}: {e:?}");
        }
    }

    #[test]
    fn the_usage_comes_with_an_unknown_argument_and_a_missing_requirement() {
        let unknown = parse(COMMAND, &args(&["--accuracy", "0.1", "--frobnicate"])).unwrap_err();
        assert_eq!(unknown.message, "unknown argument `--frobnicate`");
        assert_eq!(
            unknown.line(),
            "unknown argument `--frobnicate`; see `backlash design --help`"
        );
        assert_eq!(unknown.usage, Some(design_usage(COMMAND)));
        let missing = parse("cargo xtask design", &args(&["--model", "web"])).unwrap_err();
        assert_eq!(
            missing.with_usage_text(),
            format!(
                "--tension-accuracy EPS_T is required with --model web\n\n{}",
                design_usage("cargo xtask design")
            )
        );
        let negative = parse(COMMAND, &args(&["--accuracy", "-1"])).unwrap_err();
        assert_eq!(
            (negative.line(), negative.usage),
            ("--accuracy = -1 must be > 0".into(), None)
        );
    }

    #[test]
    fn the_usage_names_the_command() {
        let usage = design_usage("cargo xtask design");
        let mut lines = usage.lines();
        assert_eq!(
            lines.next(),
            Some("usage: cargo xtask design --accuracy EPS [--model shaft|belt|two-stage] [options] [--json]")
        );
        assert_eq!(
            lines.next(),
            Some("       cargo xtask design --model web --tension-accuracy EPS_T [--accuracy EPS] [options] [--json]")
        );
        assert_eq!(lines.next(), Some(""));
        assert_eq!(
            design("backlash design", &args(&["--help"])),
            Ok(design_usage("backlash design"))
        );
        assert_eq!(run(&args(&["design", "-h"])), Ok(design_usage("backlash design")));
    }

    #[test]
    fn the_command_takes_its_commands_and_help_only() {
        assert_eq!(run(&args(&["--help"])), Ok(USAGE.to_string()));
        assert_eq!(run(&args(&["help"])), Ok(USAGE.to_string()));
        let unknown = run(&args(&["desing", "--accuracy", "0.02"])).unwrap_err();
        assert_eq!(unknown.line(), "unknown command `desing`; see `backlash --help`");
        assert!(run(&[]).is_err());
    }

    #[test]
    fn the_belt_form_starts_from_the_belt_fmu_and_takes_its_flags() {
        let list = ["--model", "belt", "--accuracy", "0.5", "--rg1=0.02", "--k", "3e5"];
        let Some((Request::Speed(r), _)) = parse(COMMAND, &args(&list)).unwrap() else {
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
        let names: Vec<_> = r.params.named_drive_train().into_iter().map(|(n, _)| n).collect();
        assert_eq!(
            names,
            ["J_m", "J_L", "b_m", "b_L", "K_b", "R_1", "R_2", "R_g1", "R_g2", "Delta"]
        );
    }

    #[test]
    fn parses_both_flag_forms() {
        let (Request::Speed(r), json) = parse(COMMAND, &args(&["--accuracy=0.02", "--delta", "1e-3", "--json"]))
            .unwrap()
            .unwrap()
        else {
            panic!("not the speed design")
        };
        assert_eq!(r.accuracy, 0.02);
        assert_eq!(study::half_gap(&r.params), 1e-3);
        assert!(json && r.gains.is_none());
    }

    #[test]
    fn the_web_form_takes_the_film_line_and_its_flags() {
        let list = [
            "--model=web",
            "--tension-accuracy",
            "20",
            "--ea",
            "2e5",
            "--kp-t",
            "0.01",
        ];
        let Some((Request::Web(r), false)) = parse(COMMAND, &args(&list)).unwrap() else {
            panic!("not the web design")
        };
        // BacklashWeb.fmu's span (docs/model.md §8), EA overridden.
        assert_eq!((r.web.r_w, r.web.l_w, r.web.ea, r.web.v_ref), (0.05, 1.0, 2e5, 2.0));
        assert_eq!((r.tension_accuracy, r.accuracy), (20.0, None));
        assert_eq!(r.tension_gains, PiGains { kp: 0.01, ki: 0.0 });
        assert_eq!(r.drive.web, None);
    }
}
