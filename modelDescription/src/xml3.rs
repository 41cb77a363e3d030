//! `modelDescription.xml` (FMI 3.0 Model Exchange and Co-Simulation) of each model, and its
//! instantiation token: the FMI 2.0 description of [`crate::xml`] in FMI 3.0 terms, from the same
//! variable tables (docs/model.md §7).
//!
//! What FMI 3.0 changes: `<Float64>` and `<Int32>` in place of `<ScalarVariable>` with `<Real>`
//! or `<Integer>`; `derivative` and the model structure name variables by value reference, not
//! by index; the event indicators are variables (`u_minus_g`, `u_plus_g`, `force_upper`,
//! `force_lower`, `cap_upper`, `cap_lower`), listed as `<EventIndicator>`s in the order
//! `fmi3GetEventIndicators` returns them; and a description has exactly one variable of causality `independent`
//! (FMI 3.0 §2.4.7.4), here `time` with value reference 0, which no table row uses, and without
//! unit (implicitly s).

use std::fmt::Write as _;

use crate::common::{
    causality_name, depends_on_time, escape, event_indicators, hash_name, initial_attribute, is_initial_unknown,
    variability_name, vr_of, write_type_attributes, write_units_categories_and_experiment,
};
use crate::structure::{
    derivative_dependencies, event_indicator_dependencies, initial_dependencies, output_dependencies,
};
use crate::{model, Causality, Kind, Model, Type};

/// The name and value reference of the independent variable (time), which only the FMI 3.0
/// description has.
pub const TIME: (&str, u32) = ("time", 0);

/// The complete FMI 3.0 `modelDescription.xml` of `identifier`.
/// Panics on an identifier not in [`crate::model_identifiers`].
pub fn model_description(identifier: &str) -> String {
    let model = model(identifier);
    let body = xml_with_token(&model, "");
    xml_with_token(&model, &hash_name(&body))
}

/// The `instantiationToken` written into `identifier`'s FMI 3.0 description: the hash of the
/// description written with an empty token, as the FMI 2.0 guid is.
pub fn instantiation_token(identifier: &str) -> String {
    hash_name(&xml_with_token(&model(identifier), ""))
}

fn xml_with_token(model: &Model, token: &str) -> String {
    let mut x = String::new();
    x.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(
        x,
        "<fmiModelDescription fmiVersion=\"3.0\" modelName=\"{}\" instantiationToken=\"{}\" description=\"{}\" generationTool=\"backlash-fmu (model-description crate)\" variableNamingConvention=\"flat\">",
        model.identifier,
        token,
        escape(model.description)
    );
    match model.kind {
        Kind::Plant(_) | Kind::TwoStage(_) => {
            // As FMI 2.0: no event needs an iteration, so completed integrator steps need not be
            // reported; the exact Jacobian for Model Exchange only. Co-Simulation may return early at a
            // contact switch and offers Event Mode there (docs/model.md §7); FMI 3.0 has no input
            // derivatives, so FMI 2.0's canInterpolateInputs has no counterpart.
            let _ = writeln!(
                x,
                "  <ModelExchange modelIdentifier=\"{}\" canGetAndSetFMUState=\"true\" canSerializeFMUState=\"true\" providesDirectionalDerivatives=\"true\" needsCompletedIntegratorStep=\"false\"/>",
                model.identifier
            );
            let _ = writeln!(
                x,
                "  <CoSimulation modelIdentifier=\"{}\" canGetAndSetFMUState=\"true\" canSerializeFMUState=\"true\" canHandleVariableCommunicationStepSize=\"true\" maxOutputDerivativeOrder=\"1\" hasEventMode=\"true\" mightReturnEarlyFromDoStep=\"true\" canReturnEarlyAfterIntermediateUpdate=\"false\" providesIntermediateUpdate=\"false\" providesDirectionalDerivatives=\"false\"/>",
                model.identifier
            );
        }
        // As FMI 2.0's: Co-Simulation only, a fixed step, no Event Mode (nothing happens between
        // samples), no FMU state.
        Kind::Controller => {
            let _ = writeln!(
                x,
                "  <CoSimulation modelIdentifier=\"{}\" canGetAndSetFMUState=\"false\" canSerializeFMUState=\"false\" canHandleVariableCommunicationStepSize=\"false\" maxOutputDerivativeOrder=\"0\" hasEventMode=\"false\" mightReturnEarlyFromDoStep=\"false\" canReturnEarlyAfterIntermediateUpdate=\"false\" providesIntermediateUpdate=\"false\" providesDirectionalDerivatives=\"false\"/>",
                model.identifier
            );
        }
    }

    write_units_categories_and_experiment(&mut x, model);
    write_variables(&mut x, model);
    write_model_structure(&mut x, model);
    x.push_str("</fmiModelDescription>\n");
    x
}

/// `<ModelVariables>`: time, then the tables' variables; two spaces in.
fn write_variables(x: &mut String, model: &Model) {
    x.push_str("  <ModelVariables>\n");
    let _ = writeln!(
        x,
        "    <Float64 name=\"{}\" valueReference=\"{}\" description=\"Simulation time: the independent variable\" causality=\"independent\" variability=\"continuous\"/>",
        TIME.0, TIME.1
    );
    for v in &model.variables {
        let element = match v.ty {
            Type::Real => "Float64",
            Type::Integer => "Int32",
        };
        let _ = write!(
            x,
            "    <{element} name=\"{}\" valueReference=\"{}\" description=\"{}\" causality=\"{}\" variability=\"{}\"{}",
            escape(v.name),
            v.vr,
            escape(v.description),
            causality_name(v.causality),
            variability_name(v.variability),
            initial_attribute(v.initial)
        );
        write_type_attributes(x, v, |state| state.to_string());
        x.push_str("/>\n");
    }
    x.push_str("  </ModelVariables>\n");
}

/// `<ModelStructure>`: outputs, state derivatives, initial unknowns and event indicators with
/// their dependencies, by value reference; two spaces in.
fn write_model_structure(x: &mut String, model: &Model) {
    let vr_list = |vrs: &mut Vec<u32>| -> String {
        vrs.sort_unstable();
        vrs.iter().map(|vr| vr.to_string()).collect::<Vec<_>>().join(" ")
    };
    let name_list = |names: &[&str]| -> Vec<u32> { names.iter().map(|n| vr_of(model, n)).collect() };
    // FMI 3.0 §2.4.8: the elements in this order, each in the order of the variables.
    x.push_str("  <ModelStructure>\n");
    if let Kind::Controller = model.kind {
        // Its one output is held from the last sample (see the FMI 2.0 description).
        for v in model.variables.iter().filter(|v| v.causality == Causality::Output) {
            let _ = writeln!(x, "    <Output valueReference=\"{}\" dependencies=\"\"/>", v.vr);
        }
        x.push_str("  </ModelStructure>\n");
        return;
    }
    for v in &model.variables {
        if v.causality == Causality::Output {
            // No direct feedthrough: every output is a function of the state (docs/model.md §1),
            // and the bounds of the time since the start time.
            let mut deps = name_list(&output_dependencies(model, v));
            if depends_on_time(v.name) {
                deps.push(TIME.1);
            }
            let _ = writeln!(
                x,
                "    <Output valueReference=\"{}\" dependencies=\"{}\"/>",
                v.vr,
                vr_list(&mut deps)
            );
        }
    }
    for v in &model.variables {
        if v.derivative_of.is_some() {
            let mut deps = name_list(&derivative_dependencies(model, v));
            let _ = writeln!(
                x,
                "    <ContinuousStateDerivative valueReference=\"{}\" dependencies=\"{}\"/>",
                v.vr,
                vr_list(&mut deps)
            );
        }
    }
    for v in model.variables.iter().filter(|v| is_initial_unknown(v)) {
        match initial_dependencies(model, v) {
            Some(mut deps) => {
                let _ = writeln!(
                    x,
                    "    <InitialUnknown valueReference=\"{}\" dependencies=\"{}\"/>",
                    v.vr,
                    vr_list(&mut deps)
                );
            }
            None => {
                let _ = writeln!(x, "    <InitialUnknown valueReference=\"{}\"/>", v.vr);
            }
        }
    }
    for v in event_indicators(model) {
        let mut deps = name_list(&event_indicator_dependencies(model, v.name));
        let _ = writeln!(
            x,
            "    <EventIndicator valueReference=\"{}\" dependencies=\"{}\"/>",
            v.vr,
            vr_list(&mut deps)
        );
    }
    x.push_str("  </ModelStructure>\n");
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model_identifiers;

    #[test]
    fn the_token_is_the_hash_of_the_text_with_an_empty_token() {
        for id in model_identifiers() {
            let text = model_description(id);
            let token = instantiation_token(id);
            assert!(token.len() == 38 && token.starts_with('{') && token.ends_with('}'));
            assert_eq!(text.matches(&token).count(), 1, "{id}");
            assert_eq!(hash_name(&text.replacen(&token, "", 1)), token, "{id}");
            assert_ne!(token, crate::xml::guid(id), "{id}");
        }
        assert_ne!(
            instantiation_token("BacklashShaft"),
            instantiation_token("BacklashBelt")
        );
    }

    #[test]
    fn time_is_the_only_variable_the_tables_do_not_have() {
        for id in model_identifiers() {
            let model = model(id);
            assert!(model.variables.iter().all(|v| v.vr != TIME.1 && v.name != TIME.0));
            let text = model_description(id);
            assert_eq!(text.matches("causality=\"independent\"").count(), 1);
            let elements = text.matches("<Float64 ").count() + text.matches("<Int32 ").count();
            assert_eq!(elements, model.variables.len() + 1, "{id}");
        }
    }
}
