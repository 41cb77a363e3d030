//! A design request from named settings: the one place where a value given for the design
//! (the accuracies, a parameter by its FMU name) is checked and applied to the defaults of its
//! form. The command line ([`crate::cli`]) reads its flags into settings; the Python binding
//! passes keyword arguments as settings. Both speak of a setting by their own label (`--jm`,
//! `J_m`), which the reasons quote.

use backlash_physics::chain::Coulomb;
use backlash_physics::{ContactLaw, Geometry, PiGains, PlantParams};

use crate::{default_params, speed, study, two_stage, web, Form};

/// What can be set, by name: the accuracies and the parameters by their FMU names
/// (docs/model.md §4, §8), each with the forms it belongs to (every form when empty) and the
/// range it must lie in.
pub const SETTINGS: [(&str, &[Form], Range); 38] = [
    ("accuracy", &[], Range::Positive),
    ("tension_accuracy", &[Form::Web], Range::Positive),
    ("Delta", SINGLE_GAP, Range::Positive),
    ("k", &[Form::Shaft], Range::Positive),
    ("K_b", &[Form::Belt, Form::Web], Range::Positive),
    ("Kp", &[], Range::Any),
    ("Ki", &[], Range::Any),
    ("J_m", &[], Range::Positive),
    ("J_L", &[], Range::Positive),
    ("b_m", &[], Range::NonNegative),
    ("b_L", &[], Range::NonNegative),
    ("R_1", &[Form::Belt, Form::Web], Range::Positive),
    ("R_2", &[Form::Belt, Form::Web], Range::Positive),
    ("R_g1", &[Form::Belt, Form::Web], Range::Positive),
    ("R_g2", &[Form::Belt, Form::Web], Range::Positive),
    ("Kp_T", &[Form::Web], Range::Any),
    ("Ki_T", &[Form::Web], Range::Any),
    ("R_w", &[Form::Web], Range::Positive),
    ("L_w", &[Form::Web], Range::Positive),
    ("EA", &[Form::Web], Range::Positive),
    ("v_ref", &[Form::Web], Range::Positive),
    ("d", &[Form::Shaft], Range::NonNegative),
    ("D_b", &[Form::Belt, Form::Web], Range::NonNegative),
    ("contact_law", &[], Range::Law),
    ("J_i", &[Form::TwoStage], Range::Positive),
    ("b_i", &[Form::TwoStage], Range::NonNegative),
    ("n_1", &[Form::TwoStage], Range::Positive),
    ("n_2", &[Form::TwoStage], Range::Positive),
    ("k_1", &[Form::TwoStage], Range::Positive),
    ("k_2", &[Form::TwoStage], Range::Positive),
    ("Delta_1", &[Form::TwoStage], Range::Positive),
    ("Delta_2", &[Form::TwoStage], Range::Positive),
    ("d_1", &[Form::TwoStage], Range::NonNegative),
    ("d_2", &[Form::TwoStage], Range::NonNegative),
    ("tau_c_m", SPEED_SINGLE_GAP, Range::NonNegative),
    ("tau_c_L", SPEED_SINGLE_GAP, Range::NonNegative),
    ("peak_m", SPEED_SINGLE_GAP, Range::AtLeastOne),
    ("peak_L", SPEED_SINGLE_GAP, Range::AtLeastOne),
];

/// The forms with one gap (docs/model.md §1, §8).
const SINGLE_GAP: &[Form] = &[Form::Shaft, Form::Belt, Form::Web];

/// The forms whose speed design takes bearing friction (docs/model.md §10, §12): the web line's
/// bounds with friction are +∞, and the two-stage design shares the accuracy among the gaps.
const SPEED_SINGLE_GAP: &[Form] = &[Form::Shaft, Form::Belt];

/// The drive a request is for: one gap, or the two stages of docs/model.md §10 (as
/// `BacklashTwoStage`'s parameter values by name, mapped to the chain by its description).
enum Drive {
    Plant(PlantParams),
    TwoStage(Vec<(&'static str, f64)>),
}

impl Drive {
    /// Sets the drive-train parameter `name` (a name of [`SETTINGS`] of this drive's form).
    fn set(&mut self, name: &str, value: f64) {
        match self {
            Drive::Plant(params) => set_plant(params, name, value),
            Drive::TwoStage(values) => {
                let slot = values
                    .iter_mut()
                    .find(|(n, _)| *n == name)
                    .unwrap_or_else(|| unreachable!("setting `{name}` is no parameter of {}", two_stage::MODEL));
                slot.1 = value;
            }
        }
    }
}

/// Sets the drive-train parameter `name` of a single-gap drive.
fn set_plant(params: &mut PlantParams, name: &str, value: f64) {
    match name {
        "Delta" => *params = params.with_half_gap(value),
        "k" | "K_b" => *params = study::with_stiffness(params, value),
        "J_m" => params.j_m = value,
        "J_L" => params.j_l = value,
        "b_m" => params.b_m = value,
        "b_L" => params.b_l = value,
        "d" | "D_b" => params.damping.d = value,
        "contact_law" => params.damping.law = ContactLaw::from_code(value as i32).expect("checked by its range"),
        "R_1" | "R_2" | "R_g1" | "R_g2" => {
            let Geometry::Belt {
                r_1, r_2, r_g1, r_g2, ..
            } = &mut params.geometry
            else {
                unreachable!("belt settings are refused for the shaft form");
            };
            let slot = match name {
                "R_1" => r_1,
                "R_2" => r_2,
                "R_g1" => r_g1,
                _ => r_g2,
            };
            *slot = value;
        }
        other => unreachable!("setting `{other}` listed without its effect"),
    }
}

/// The values a setting may take (all of them finite).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Range {
    Positive,
    NonNegative,
    Any,
    /// `contact_law`: 1 (Modelica's ElastoBacklash) or 2 (ElastoBacklash2).
    Law,
    /// `peak_*`: breakaway over sliding friction, ≥ 1.
    AtLeastOne,
}

/// One value given for a design.
#[derive(Clone, Debug, PartialEq)]
pub struct Setting<'a> {
    /// Its name in [`SETTINGS`].
    pub name: &'a str,
    /// How the user wrote its name (`--jm`, `J_m`), quoted in a reason.
    pub label: &'a str,
    /// How the user wrote its value, quoted in a reason.
    pub text: String,
    pub value: f64,
}

/// How the reasons speak: of flags (`--model belt`) or of arguments (`model = "belt"`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Vocabulary {
    Flags,
    Arguments,
}

/// Why the settings make no request.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Refusal {
    pub message: String,
    /// A requirement is missing: the usage explains it.
    pub missing: bool,
}

impl Refusal {
    fn new(message: String) -> Refusal {
        Refusal {
            message,
            missing: false,
        }
    }
}

impl Vocabulary {
    fn forms(self, forms: &[Form]) -> String {
        let names: Vec<&str> = forms.iter().map(|f| f.name()).collect();
        match self {
            Vocabulary::Flags => format!("--model {}", names.join(" or ")),
            Vocabulary::Arguments => format!("model {}", names.join(" or ")),
        }
    }

    fn required(self, name: &str, form: Form) -> String {
        match (self, name, form) {
            (Vocabulary::Flags, "accuracy", _) => "--accuracy EPS is required".into(),
            (Vocabulary::Flags, _, _) => "--tension-accuracy EPS_T is required with --model web".into(),
            (Vocabulary::Arguments, _, form) => format!("{name} is required for model {}", form.name()),
        }
    }

    fn gains_together(self) -> String {
        match self {
            Vocabulary::Flags => "--kp and --ki go together (or neither, for the best-damped rule)".into(),
            Vocabulary::Arguments => "Kp and Ki go together (or neither, for the best-damped rule)".into(),
        }
    }
}

/// The form a model name stands for (`shaft`, `belt`, `web`, `two-stage`).
pub fn form_named(name: &str) -> Option<Form> {
    [Form::Shaft, Form::Belt, Form::Web, Form::TwoStage]
        .into_iter()
        .find(|f| f.name() == name)
}

/// The design request of `form` with `settings` applied to its defaults, each checked: a name of
/// [`SETTINGS`] that belongs to the form, given once, finite and in its range.
pub fn build(form: Form, settings: &[Setting], vocabulary: Vocabulary) -> Result<Request, Refusal> {
    let refuse = |message: String| Refusal::new(message);
    let mut drive = match form {
        Form::TwoStage => Drive::TwoStage(two_stage::default_values().map_err(|e| refuse(e.to_string()))?),
        _ => Drive::Plant(default_params(form).map_err(|e| refuse(e.to_string()))?),
    };
    let mut line = web::film_line().map_err(|e| refuse(e.to_string()))?;
    let (mut accuracy, mut tension_accuracy) = (None, None);
    let (mut kp, mut ki) = (None, None);
    let mut tension_gains = PiGains::default();
    // The motor's and the load's bearing friction.
    let mut friction = [Coulomb::NONE; 2];
    for (i, s) in settings.iter().enumerate() {
        let Some((_, forms, range)) = SETTINGS.iter().find(|(name, _, _)| *name == s.name) else {
            return Err(refuse(format!("unknown parameter `{}`", s.label)));
        };
        if !forms.is_empty() && !forms.contains(&form) {
            return Err(refuse(format!(
                "{} applies to {} only",
                s.label,
                vocabulary.forms(forms)
            )));
        }
        if settings[..i].iter().any(|earlier| earlier.name == s.name) {
            return Err(refuse(format!("{} given twice", s.label)));
        }
        let (label, text, value) = (s.label, &s.text, s.value);
        if !value.is_finite() {
            return Err(refuse(format!("{label} = {text} must be finite")));
        }
        match range {
            Range::Positive if value <= 0.0 => return Err(refuse(format!("{label} = {text} must be > 0"))),
            Range::NonNegative if value < 0.0 => return Err(refuse(format!("{label} = {text} must be >= 0"))),
            Range::AtLeastOne if value < 1.0 => return Err(refuse(format!("{label} = {text} must be >= 1"))),
            Range::Law if ContactLaw::from_code(value as i32).is_none() || value.fract() != 0.0 => {
                return Err(refuse(format!(
                    "{label} = {text} must be 1 (ElastoBacklash) or 2 (ElastoBacklash2)"
                )))
            }
            _ => {}
        }
        match s.name {
            "accuracy" => accuracy = Some(value),
            "tension_accuracy" => tension_accuracy = Some(value),
            "Kp" => kp = Some(value),
            "Ki" => ki = Some(value),
            "Kp_T" => tension_gains.kp = value,
            "Ki_T" => tension_gains.ki = value,
            "R_w" => line.r_w = value,
            "L_w" => line.l_w = value,
            "EA" => line.ea = value,
            "v_ref" => line.v_ref = value,
            "tau_c_m" => friction[0].tau_c = value,
            "tau_c_L" => friction[1].tau_c = value,
            "peak_m" => friction[0].peak = value,
            "peak_L" => friction[1].peak = value,
            drive_train => drive.set(drive_train, value),
        }
    }
    let gains = match (kp, ki) {
        (Some(kp), Some(ki)) => Some(PiGains { kp, ki }),
        (None, None) => None,
        _ => return Err(refuse(vocabulary.gains_together())),
    };
    let missing = |name: &str| Refusal {
        message: vocabulary.required(name, form),
        missing: true,
    };
    Ok(match (form, drive) {
        (Form::Web, Drive::Plant(params)) => Request::Web(web::Request {
            tension_accuracy: tension_accuracy.ok_or_else(|| missing("tension_accuracy"))?,
            accuracy,
            drive: params,
            web: line,
            gains,
            tension_gains,
        }),
        (_, Drive::Plant(params)) => Request::Speed(speed::Request {
            accuracy: accuracy.ok_or_else(|| missing("accuracy"))?,
            params,
            gains,
            friction,
        }),
        (_, Drive::TwoStage(values)) => Request::TwoStage(two_stage::Request {
            accuracy: accuracy.ok_or_else(|| missing("accuracy"))?,
            drive: two_stage::drive_of(&values).map_err(|e| refuse(e.to_string()))?,
            gains,
        }),
    })
}

/// What a design is asked for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Request {
    /// The speed design of the shaft or belt form.
    Speed(speed::Request),
    /// The tension design of the web line.
    Web(web::Request),
    /// The design of a two-stage gearbox.
    TwoStage(two_stage::Request),
}

impl Request {
    /// The answer as JSON (what `backlash design --json` prints).
    pub fn answer_json(self) -> Result<String, String> {
        Ok(match self {
            Request::Speed(r) => speed::to_json(&speed::solve(r)?),
            Request::Web(r) => web::to_json(&web::solve(r)?),
            Request::TwoStage(r) => two_stage::to_json(&two_stage::solve(r)?),
        })
    }

    /// The answer as text (what `backlash design` prints).
    pub fn answer_text(self) -> Result<String, String> {
        Ok(match self {
            Request::Speed(r) => speed::to_text(&speed::solve(r)?),
            Request::Web(r) => web::to_text(&web::solve(r)?),
            Request::TwoStage(r) => two_stage::to_text(&two_stage::solve(r)?),
        })
    }
}

/// The design answer as JSON for `model` with settings by name: what the Python binding calls.
pub fn design_json(model: &str, settings: &[Setting]) -> Result<String, String> {
    let form = form_named(model)
        .ok_or_else(|| format!("model = {model:?}: choose \"shaft\", \"belt\", \"web\" or \"two-stage\""))?;
    build(form, settings, Vocabulary::Arguments)
        .map_err(|r| r.message)?
        .answer_json()
}

#[cfg(test)]
mod tests {
    use super::*;
    use model_description::Range as Admits;

    /// Values a design setting of `range` may take, at its edges and beyond.
    fn samples(range: Range) -> Vec<f64> {
        match range {
            Range::Positive => vec![f64::MIN_POSITIVE, 1e-9, 1.0, 1e9],
            Range::NonNegative => vec![0.0, 1e-9, 1.0, 1e9],
            Range::Any => vec![-1e9, -1.0, 0.0, 1.0, 1e9],
            Range::Law => vec![1.0, 2.0],
            Range::AtLeastOne => vec![1.0, 1.5, 1e9],
        }
    }

    /// The two-stage form's settings are BacklashTwoStage's parameters, each admitting no value
    /// the FMU refuses; the parameters it does not take are the bearings' friction (the
    /// two-stage design shares the accuracy among the gaps and refuses friction, docs/model.md
    /// §10).
    #[test]
    fn the_two_stage_settings_are_its_fmu_parameters() {
        let description = model_description::model(two_stage::MODEL);
        let mut taken = Vec::new();
        for (name, forms, range) in SETTINGS {
            if name == "accuracy" || !(forms.is_empty() || forms.contains(&Form::TwoStage)) {
                continue;
            }
            let v = description
                .variables
                .iter()
                .find(|v| v.name == name)
                .unwrap_or_else(|| panic!("{name} is no variable of {}", two_stage::MODEL));
            for x in samples(range) {
                assert!(
                    v.range.admits(x),
                    "{name} = {x}: the design takes it, the FMU refuses it"
                );
            }
            assert!(
                !matches!(v.range, Admits::Integers { .. }) || range == Range::Law,
                "{name}"
            );
            taken.push(name);
        }
        let mut untaken: Vec<&str> = two_stage::default_values()
            .unwrap()
            .iter()
            .map(|(n, _)| *n)
            .filter(|n| !taken.contains(n))
            .collect();
        untaken.sort_unstable();
        assert_eq!(untaken, ["peak_L", "peak_i", "peak_m", "tau_c_L", "tau_c_i", "tau_c_m"]);
    }

    /// A setting reaches the chain through the description's mapping, and `named` reads each
    /// back: the two are inverse on every drive-train parameter.
    #[test]
    fn settings_reach_the_drive_and_named_reads_them_back() {
        let given = [
            ("J_i", 0.3),
            ("n_2", 2.5),
            ("Delta_1", 1e-3),
            ("d_2", 4.0),
            ("contact_law", 2.0),
        ];
        let settings: Vec<Setting> = given
            .iter()
            .map(|(name, value)| Setting {
                name,
                label: name,
                text: value.to_string(),
                value: *value,
            })
            .chain([Setting {
                name: "accuracy",
                label: "accuracy",
                text: "0.1".into(),
                value: 0.1,
            }])
            .collect();
        let Ok(Request::TwoStage(request)) = build(Form::TwoStage, &settings, Vocabulary::Arguments) else {
            panic!("a two-stage request")
        };
        let named = two_stage::named(&request.drive);
        for (name, value) in given {
            assert_eq!(named.iter().find(|(n, _)| *n == name).unwrap().1, value, "{name}");
        }
        // Every other drive-train parameter keeps its start value.
        let defaults = two_stage::default_values().unwrap();
        for (name, value) in named {
            if given.iter().all(|(n, _)| *n != name) {
                let start = defaults.iter().find(|(n, _)| *n == name).unwrap().1;
                assert_eq!(value, start, "{name}");
            }
        }
        let mut values = defaults.clone();
        for (name, value) in named {
            values.iter_mut().find(|(n, _)| *n == name).unwrap().1 = value;
        }
        assert_eq!(two_stage::drive_of(&values).unwrap(), request.drive);
    }
}
