//! What the FMI 2.0 ([`crate::xml`]) and the FMI 3.0 ([`crate::xml3`]) descriptions share, written
//! once: the names of the kinds of variables, the type attributes of a variable, the unit
//! definitions, log categories and default experiment (the same XML in both standards), the
//! dependency lists of the model structure, escaping, and the hash that names a description (the
//! FMI 2.0 guid, the FMI 3.0 instantiation token).

use std::fmt::Write as _;

use crate::{Causality, DefaultExperiment, Initial, Model, Range, Type, Var, Variability, LOG_CATEGORIES, UNITS};

/// `text` as XML (or HTML) attribute value or text.
pub fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The `causality` attribute (the same words in FMI 2.0 and 3.0).
pub(crate) fn causality_name(causality: Causality) -> &'static str {
    match causality {
        Causality::Input => "input",
        Causality::Output => "output",
        Causality::Parameter => "parameter",
        Causality::CalculatedParameter => "calculatedParameter",
        Causality::Local => "local",
    }
}

/// The `variability` attribute (the same words in FMI 2.0 and 3.0).
pub(crate) fn variability_name(variability: Variability) -> &'static str {
    match variability {
        Variability::Fixed => "fixed",
        Variability::Discrete => "discrete",
        Variability::Continuous => "continuous",
    }
}

/// The `initial` attribute with its leading space, "" where it is not written.
pub(crate) fn initial_attribute(initial: Initial) -> &'static str {
    match initial {
        Initial::Unset => "",
        Initial::Exact => " initial=\"exact\"",
        Initial::Calculated => " initial=\"calculated\"",
    }
}

/// The value reference of the variable `name` of `model`; panics if there is none.
pub(crate) fn vr_of(model: &Model, name: &str) -> u32 {
    model
        .variables
        .iter()
        .find(|v| v.name == name)
        .unwrap_or_else(|| panic!("{} has no variable {name}", model.identifier))
        .vr
}

/// The type attributes of `v`, each with its leading space, in the order both standards write
/// them: quantity, unit, min, max, nominal, derivative, start. `state_reference` turns the value
/// reference of the state a derivative belongs to into what the standard's `derivative`
/// attribute holds (FMI 2.0: the state's index; FMI 3.0: its value reference).
pub(crate) fn write_type_attributes(x: &mut String, v: &Var, state_reference: impl Fn(u32) -> String) {
    if !v.quantity.is_empty() {
        let _ = write!(x, " quantity=\"{}\"", v.quantity);
    }
    if !v.unit.is_empty() {
        let _ = write!(x, " unit=\"{}\"", v.unit);
    }
    match v.range {
        Range::NonNegative => x.push_str(" min=\"0.0\""),
        Range::AtLeastOne => x.push_str(" min=\"1.0\""),
        Range::Integers { min, max } => {
            let _ = write!(x, " min=\"{min}\" max=\"{max}\"");
        }
        Range::Finite | Range::Positive => {}
    }
    if let Some(nominal) = v.nominal {
        let _ = write!(x, " nominal=\"{nominal:?}\"");
    }
    if let Some(state) = v.derivative_of {
        let _ = write!(x, " derivative=\"{}\"", state_reference(state));
    }
    if let Some(s) = v.start {
        match v.ty {
            Type::Real => {
                let _ = write!(x, " start=\"{s:?}\"");
            }
            Type::Integer => {
                let _ = write!(x, " start=\"{}\"", s as i64);
            }
        }
    }
}

/// `<UnitDefinitions>` (the units `model` uses, in order of first use, so that the text is
/// deterministic), `<LogCategories>` and `<DefaultExperiment>`: the same elements and attributes
/// in FMI 2.0 and 3.0, two spaces in.
pub(crate) fn write_units_categories_and_experiment(x: &mut String, model: &Model) {
    let mut used: Vec<&str> = Vec::new();
    for v in &model.variables {
        if !v.unit.is_empty() && !used.contains(&v.unit) {
            used.push(v.unit);
        }
    }
    x.push_str("  <UnitDefinitions>\n");
    for name in &used {
        let (_, exps, displays) = UNITS
            .iter()
            .find(|(n, _, _)| n == name)
            .expect("every unit is in UNITS");
        let _ = write!(x, "    <Unit name=\"{}\">\n      <BaseUnit", name);
        for (attr, e) in ["kg", "m", "s", "rad"].iter().zip(exps) {
            if *e != 0 {
                let _ = write!(x, " {attr}=\"{e}\"");
            }
        }
        x.push_str("/>\n");
        for (display, factor) in displays.iter() {
            let _ = writeln!(x, "      <DisplayUnit name=\"{display}\" factor=\"{factor:?}\"/>");
        }
        x.push_str("    </Unit>\n");
    }
    x.push_str("  </UnitDefinitions>\n");

    x.push_str("  <LogCategories>\n");
    for category in LOG_CATEGORIES {
        let _ = writeln!(
            x,
            "    <Category name=\"{}\" description=\"{}\"/>",
            category.name,
            escape(category.description)
        );
    }
    x.push_str("  </LogCategories>\n");

    let DefaultExperiment {
        start_time: start,
        stop_time: stop,
        step_size: step,
    } = model.default_experiment;
    let _ = writeln!(
        x,
        "  <DefaultExperiment startTime=\"{start:?}\" stopTime=\"{stop:?}\" stepSize=\"{step:?}\"/>"
    );
}

/// The states a single gap's output other than the states, `psi` and `contact` depends on in
/// Continuous-Time Mode (no output depends on an input: docs/model.md §1); the bounds depend on
/// time alone ([`depends_on_time`]). The others' are computed from the physics
/// (`crate::structure::output_dependencies`).
pub(crate) fn output_dependencies(name: &str) -> &'static [&'static str] {
    match name {
        // The friction mode: the sign of the speed sliding, the law of stiction at rest (the
        // torque on the body, from every state).
        "sliding_m" | "sliding_L" => &["theta_m", "omega_m", "theta_L", "omega_L"],
        "bound" | "bound_paper" | "bound_T" => &[],
        other => panic!("{other} is not an output whose dependencies are listed"),
    }
}

/// Whether the output `name` depends on time itself, beyond the states: the bounds, functions
/// of the time since the start time (docs/model.md §3, §6). Only FMI 3.0 has a variable to name
/// for it (the independent variable); FMI 2.0 lists none.
pub(crate) fn depends_on_time(name: &str) -> bool {
    matches!(name, "bound" | "bound_paper" | "bound_T")
}

/// The event indicators of every plant in the order of the description (value references 28,
/// 29, 44–47 and 54–57; FMI 2.0 counts them in `numberOfEventIndicators`, FMI 3.0 lists them):
/// the contact surfaces, in the order the physics computes them (`Plant::event_indicators`,
/// docs/model.md §6), then the bodies' friction surfaces (§12).
pub(crate) const EVENT_INDICATORS: [&str; CONTACT_INDICATORS + FRICTION_INDICATORS.len()] = [
    "u_minus_g",
    "u_plus_g",
    "force_upper",
    "force_lower",
    "cap_upper",
    "cap_lower",
    FRICTION_INDICATORS[0],
    FRICTION_INDICATORS[1],
    FRICTION_INDICATORS[2],
    FRICTION_INDICATORS[3],
];

/// The contact surfaces' event indicators (docs/model.md §6).
pub(crate) const CONTACT_INDICATORS: usize = backlash_physics::vector_field::EVENT_INDICATORS;

/// The friction surfaces' event indicators (docs/model.md §12): where the motor and the load
/// stop sliding, and break away.
pub(crate) const FRICTION_INDICATORS: [&str; 4] = ["stop_m", "breakaway_m", "stop_L", "breakaway_L"];

/// The event indicators of `model` in the order of its description (value-reference order):
/// its continuous locals that are no state derivative. On a single-gap plant they are
/// [`EVENT_INDICATORS`]; on a chain each stage's contact surfaces under its names with the
/// stage's number (`u_minus_g_1`, …), then every body's friction surfaces (`stop_i`, …).
pub(crate) fn event_indicators(model: &Model) -> Vec<&Var> {
    let mut vars: Vec<&Var> = model
        .variables
        .iter()
        .filter(|v| {
            v.causality == Causality::Local && v.variability == Variability::Continuous && v.derivative_of.is_none()
        })
        .collect();
    vars.sort_by_key(|v| v.vr);
    vars
}

/// Whether `v` is an unknown of Initialization Mode as FMI 2.0 §2.2.8 and FMI 3.0 §2.4.8 define
/// the list: outputs and state derivatives with initial = calculated (the states themselves are
/// initial = exact), and calculated parameters. Other locals (the event indicators) are not.
pub(crate) fn is_initial_unknown(v: &Var) -> bool {
    let output_or_derivative = v.causality == Causality::Output || v.derivative_of.is_some();
    (output_or_derivative && v.initial == Initial::Calculated) || v.causality == Causality::CalculatedParameter
}

/// FNV-1a with the 128-bit parameters (offset basis and prime from the FNV specification).
fn fnv1a_128(bytes: &[u8]) -> u128 {
    const OFFSET: u128 = 0x6c62272e07bb014262b821756295c58d;
    const PRIME: u128 = 0x0000000001000000000000000000013B;
    let mut hash = OFFSET;
    for b in bytes {
        hash ^= *b as u128;
        hash = hash.wrapping_mul(PRIME);
    }
    hash
}

/// `{8-4-4-4-12}` hex of the FNV-1a-128 hash of `text`: the guid (FMI 2.0) or instantiation
/// token (FMI 3.0) of a description, hashed with that attribute empty.
pub(crate) fn hash_name(text: &str) -> String {
    let h = format!("{:032x}", fnv1a_128(text.as_bytes()));
    format!(
        "{{{}-{}-{}-{}-{}}}",
        &h[0..8],
        &h[8..12],
        &h[12..16],
        &h[16..20],
        &h[20..32]
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hash_is_fnv1a_128_in_guid_form() {
        // FNV-1a-128 of "" is the offset basis.
        assert_eq!(hash_name(""), "{6c62272e-07bb-0142-62b8-21756295c58d}");
        assert_ne!(hash_name("a"), hash_name("b"));
    }

    #[test]
    fn event_indicators_are_locals_and_no_initial_unknown() {
        for id in crate::model_identifiers() {
            let model = crate::model(id);
            let found: Vec<&str> = event_indicators(&model).iter().map(|v| v.name).collect();
            if matches!(model.kind, crate::Kind::Plant(_)) {
                assert_eq!(found, EVENT_INDICATORS, "{id}");
            }
            for v in event_indicators(&model) {
                assert!(!is_initial_unknown(v), "{id} {}", v.name);
            }
        }
    }
}
