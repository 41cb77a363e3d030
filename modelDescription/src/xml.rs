//! `modelDescription.xml` (FMI 2.0 Model Exchange and Co-Simulation) of each model, and its guid.

use std::fmt::Write as _;

use crate::common::{
    causality_name, event_indicators, hash_name, initial_attribute, variability_name, vr_of, write_type_attributes,
    write_units_categories_and_experiment,
};
use crate::structure::{derivative_dependencies, initial_dependencies, output_dependencies};
use crate::{model, Causality, Kind, Model, Type};

/// `text` as XML (or HTML) attribute value or text (shared with the FMI 3.0 description).
pub use crate::common::escape;

/// The complete `modelDescription.xml` of `identifier`.
/// Panics on an identifier not in [`crate::model_identifiers`].
pub fn model_description(identifier: &str) -> String {
    let model = model(identifier);
    let body = xml_with_guid(&model, "");
    xml_with_guid(&model, &hash_name(&body))
}

/// The guid written into `identifier`'s description.
pub fn guid(identifier: &str) -> String {
    hash_name(&xml_with_guid(&model(identifier), ""))
}

fn xml_with_guid(model: &Model, guid: &str) -> String {
    let mut x = String::new();
    x.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(
        x,
        "<fmiModelDescription fmiVersion=\"2.0\" modelName=\"{}\" guid=\"{}\" description=\"{}\" generationTool=\"backlash-fmu (model-description crate)\" variableNamingConvention=\"flat\" numberOfEventIndicators=\"{}\">",
        model.identifier,
        guid,
        escape(model.description),
        match model.kind {
            Kind::Plant(_) | Kind::TwoStage(_) => event_indicators(model).len(),
            Kind::Controller => 0,
        }
    );
    match model.kind {
        Kind::Plant(_) | Kind::TwoStage(_) => {
            // Event indicators: the contact surfaces of docs/model.md §6; no event needs an iteration,
            // so completed integrator steps need not be reported.
            let _ = writeln!(
                x,
                "  <ModelExchange modelIdentifier=\"{}\" needsExecutionTool=\"false\" completedIntegratorStepNotNeeded=\"true\" canBeInstantiatedOnlyOncePerProcess=\"false\" canNotUseMemoryManagementFunctions=\"true\" canGetAndSetFMUstate=\"true\" canSerializeFMUstate=\"true\" providesDirectionalDerivative=\"true\"/>",
                model.identifier
            );
            let _ = writeln!(
                x,
                "  <CoSimulation modelIdentifier=\"{}\" needsExecutionTool=\"false\" canHandleVariableCommunicationStepSize=\"true\" canInterpolateInputs=\"true\" maxOutputDerivativeOrder=\"1\" canRunAsynchronuously=\"false\" canBeInstantiatedOnlyOncePerProcess=\"false\" canNotUseMemoryManagementFunctions=\"true\" canGetAndSetFMUstate=\"true\" canSerializeFMUstate=\"true\" providesDirectionalDerivative=\"false\"/>",
                model.identifier
            );
        }
        // A sampled controller: Co-Simulation only, one sample per step of its period, no input
        // or output derivatives, no FMU state.
        Kind::Controller => {
            let _ = writeln!(
                x,
                "  <CoSimulation modelIdentifier=\"{}\" needsExecutionTool=\"false\" canHandleVariableCommunicationStepSize=\"false\" canInterpolateInputs=\"false\" maxOutputDerivativeOrder=\"0\" canRunAsynchronuously=\"false\" canBeInstantiatedOnlyOncePerProcess=\"false\" canNotUseMemoryManagementFunctions=\"true\" canGetAndSetFMUstate=\"false\" canSerializeFMUstate=\"false\" providesDirectionalDerivative=\"false\"/>",
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

/// The index (from 1, FMI 2.0 §2.2.8) of the variable with value reference `vr`.
fn index_of(model: &Model, vr: u32) -> usize {
    model.variables.iter().position(|w| w.vr == vr).expect("known vr") + 1
}

/// `<ModelVariables>`, two spaces in.
fn write_variables(x: &mut String, model: &Model) {
    let index_of = |vr: u32| index_of(model, vr);
    x.push_str("  <ModelVariables>\n");
    for (i, v) in model.variables.iter().enumerate() {
        let causality = causality_name(v.causality);
        let variability = variability_name(v.variability);
        let _ = writeln!(x, "    <!-- index {} -->", i + 1);
        let _ = write!(
            x,
            "    <ScalarVariable name=\"{}\" valueReference=\"{}\" description=\"{}\" causality=\"{causality}\" variability=\"{variability}\"",
            v.name,
            v.vr,
            escape(v.description)
        );
        x.push_str(initial_attribute(v.initial));
        x.push_str(">\n");
        let element = match v.ty {
            Type::Real => "Real",
            Type::Integer => "Integer",
        };
        let _ = write!(x, "      <{element}");
        write_type_attributes(x, v, |state| index_of(state).to_string());
        x.push_str("/>\n    </ScalarVariable>\n");
    }
    x.push_str("  </ModelVariables>\n");
}

/// `<ModelStructure>`: outputs, derivatives and initial unknowns with their dependencies, by
/// index; two spaces in.
fn write_model_structure(x: &mut String, model: &Model) {
    if let Kind::Controller = model.kind {
        // Its one output is held from the last sample: no dependency at the same instant, no
        // derivative, and its start value is exact (no initial unknown).
        x.push_str("  <ModelStructure>\n    <Outputs>\n");
        for (i, v) in model.variables.iter().enumerate() {
            if v.causality == Causality::Output {
                let _ = writeln!(x, "      <Unknown index=\"{}\" dependencies=\"\"/>", i + 1);
            }
        }
        x.push_str("    </Outputs>\n  </ModelStructure>\n");
        return;
    }
    let index_of = |vr: u32| index_of(model, vr);
    let index_list = |names: &[&str]| -> String {
        let mut indices: Vec<usize> = names.iter().map(|n| index_of(vr_of(model, n))).collect();
        indices.sort_unstable();
        indices.iter().map(|i| i.to_string()).collect::<Vec<_>>().join(" ")
    };
    x.push_str("  <ModelStructure>\n    <Outputs>\n");
    for (i, v) in model.variables.iter().enumerate() {
        if v.causality == Causality::Output {
            // No direct feedthrough: every output is a function of the state (docs/model.md §1).
            let deps = index_list(&output_dependencies(model, v));
            let _ = writeln!(x, "      <Unknown index=\"{}\" dependencies=\"{deps}\"/>", i + 1);
        }
    }
    x.push_str("    </Outputs>\n    <Derivatives>\n");
    for (i, v) in model.variables.iter().enumerate() {
        if v.derivative_of.is_some() {
            let deps = index_list(&derivative_dependencies(model, v));
            let _ = writeln!(x, "      <Unknown index=\"{}\" dependencies=\"{deps}\"/>", i + 1);
        }
    }
    x.push_str("    </Derivatives>\n    <InitialUnknowns>\n");
    for (i, v) in model.variables.iter().enumerate() {
        if !crate::common::is_initial_unknown(v) {
            continue;
        }
        match initial_dependencies(model, v) {
            Some(deps) => {
                let list: Vec<String> = deps.iter().map(|vr| index_of(*vr).to_string()).collect();
                let _ = writeln!(
                    x,
                    "      <Unknown index=\"{}\" dependencies=\"{}\"/>",
                    i + 1,
                    list.join(" ")
                );
            }
            None => {
                let _ = writeln!(x, "      <Unknown index=\"{}\"/>", i + 1);
            }
        }
    }
    x.push_str("    </InitialUnknowns>\n  </ModelStructure>\n");
}
