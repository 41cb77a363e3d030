//! `modelDescription.xml` (FMI 2.0 Model Exchange and Co-Simulation) of each model, and its guid.

use std::fmt::Write as _;

use crate::{
    model, Causality, DefaultExperiment, DriveTrain, Initial, Model, Range, Type, Var, Variability, LOG_CATEGORIES,
    UNITS,
};

/// The complete `modelDescription.xml` of `identifier`.
/// Panics on an identifier not in [`crate::model_identifiers`].
pub fn model_description(identifier: &str) -> String {
    let model = model(identifier);
    let body = xml_with_guid(&model, "");
    xml_with_guid(&model, &guid_of(&body))
}

/// The guid written into `identifier`'s description.
pub fn guid(identifier: &str) -> String {
    guid_of(&xml_with_guid(&model(identifier), ""))
}

/// Variables (by value reference) whose start values and parameters the initial value of
/// `v` depends on (FMI 2.0 §2.2.8 InitialUnknowns); None means "all knowns".
fn initial_dependencies(model: &Model, v: &Var) -> Option<Vec<u32>> {
    let vr_of = |name: &str| model.variables.iter().find(|w| w.name == name).map(|w| w.vr);
    let geometry: &[&str] = match model.drive_train {
        DriveTrain::Shaft => &["Delta", "k"],
        DriveTrain::Belt => &["Delta", "K_b", "R_1", "R_2", "R_g1", "R_g2"],
    };
    let names: Vec<&str> = match v.name {
        // A state derivative: the state and inputs it depends on (`derivative_dependencies`),
        // and the inertia, friction and geometry of its equation.
        "der(theta_m)" | "der(theta_L)" => derivative_dependencies(v.name).to_vec(),
        "der(omega_m)" => derivative_dependencies(v.name)
            .iter()
            .chain(&["J_m", "b_m"])
            .chain(geometry)
            .copied()
            .collect(),
        "der(omega_L)" => derivative_dependencies(v.name)
            .iter()
            .chain(&["J_L", "b_L"])
            .chain(geometry)
            .copied()
            .collect(),
        // u -+ g: angles and geometry.
        "u_minus_g" | "u_plus_g" => ["theta_m", "theta_L"].iter().chain(geometry).copied().collect(),
        // psi = K dz(u, g): angles and geometry.
        "psi" => ["theta_m", "theta_L"].iter().chain(geometry).copied().collect(),
        // The mode exactly on +-g depends on the sign of u' as well (docs/model.md §4 `contact`).
        "contact" => ["theta_m", "omega_m", "theta_L", "omega_L"]
            .iter()
            .chain(geometry)
            .copied()
            .collect(),
        // Both bounds are 0 at the start time (docs/model.md §4: time measured from the start).
        "bound" | "bound_paper" => vec![],
        // bound_sup depends on everything that defines the loop of docs/model.md §3.
        "bound_sup" => ["J_m", "J_L", "b_m", "b_L", "Kp", "Ki"]
            .iter()
            .chain(geometry)
            .copied()
            .collect(),
        _ => return None,
    };
    let mut vrs: Vec<u32> = names
        .iter()
        .map(|n| vr_of(n).expect("dependency names a variable of the model"))
        .collect();
    vrs.sort_unstable();
    Some(vrs)
}

/// The states and inputs a state derivative depends on in Continuous-Time Mode (docs/model.md
/// §1): an angle's rate is its speed; an acceleration depends on its own torque, its own
/// speed and, through ψ = K dz(u, g), both angles.
fn derivative_dependencies(name: &str) -> &'static [&'static str] {
    match name {
        "der(theta_m)" => &["omega_m"],
        "der(omega_m)" => &["tau_m", "theta_m", "omega_m", "theta_L"],
        "der(theta_L)" => &["omega_L"],
        "der(omega_L)" => &["tau_L", "theta_m", "theta_L", "omega_L"],
        other => panic!("{other} is not a state derivative"),
    }
}

/// The states an output depends on in Continuous-Time Mode (no output depends on an input:
/// docs/model.md §1); `bound` and `bound_paper` depend on time alone.
fn output_dependencies(name: &str) -> &'static [&'static str] {
    match name {
        // A state output is the state itself.
        "theta_m" => &["theta_m"],
        "omega_m" => &["omega_m"],
        "theta_L" => &["theta_L"],
        "omega_L" => &["omega_L"],
        "psi" => &["theta_m", "theta_L"],
        // The mode exactly on +-g depends on the sign of u' as well.
        "contact" => &["theta_m", "omega_m", "theta_L", "omega_L"],
        "bound" | "bound_paper" => &[],
        other => panic!("{other} is not an output"),
    }
}

/// `text` as XML (or HTML) attribute value or text.
pub fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn xml_with_guid(model: &Model, guid: &str) -> String {
    let mut x = String::new();
    x.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(
        x,
        "<fmiModelDescription fmiVersion=\"2.0\" modelName=\"{}\" guid=\"{}\" description=\"{}\" generationTool=\"backlash-fmu (model-description crate)\" variableNamingConvention=\"flat\" numberOfEventIndicators=\"2\">",
        model.identifier,
        guid,
        escape(model.description)
    );
    // Event indicators u - g and u + g; no event needs an iteration, so completed integrator
    // steps need not be reported.
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

    // Units in order of first use, so the text is deterministic.
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

    let index_of = |vr: u32| model.variables.iter().position(|w| w.vr == vr).expect("known vr") + 1;
    let index_list = |names: &[&str]| -> String {
        let mut indices: Vec<usize> = names
            .iter()
            .map(|n| index_of(model.variables.iter().find(|w| w.name == *n).expect("a variable").vr))
            .collect();
        indices.sort_unstable();
        indices.iter().map(|i| i.to_string()).collect::<Vec<_>>().join(" ")
    };
    x.push_str("  <ModelVariables>\n");
    for (i, v) in model.variables.iter().enumerate() {
        let causality = match v.causality {
            Causality::Input => "input",
            Causality::Output => "output",
            Causality::Parameter => "parameter",
            Causality::CalculatedParameter => "calculatedParameter",
            Causality::Local => "local",
        };
        let variability = match v.variability {
            Variability::Fixed => "fixed",
            Variability::Discrete => "discrete",
            Variability::Continuous => "continuous",
        };
        let _ = writeln!(x, "    <!-- index {} -->", i + 1);
        let _ = write!(
            x,
            "    <ScalarVariable name=\"{}\" valueReference=\"{}\" description=\"{}\" causality=\"{causality}\" variability=\"{variability}\"",
            v.name,
            v.vr,
            escape(v.description)
        );
        match v.initial {
            Initial::Unset => {}
            Initial::Exact => x.push_str(" initial=\"exact\""),
            Initial::Calculated => x.push_str(" initial=\"calculated\""),
        }
        x.push_str(">\n");
        let element = match v.ty {
            Type::Real => "Real",
            Type::Integer => "Integer",
        };
        let _ = write!(x, "      <{element}");
        if !v.quantity.is_empty() {
            let _ = write!(x, " quantity=\"{}\"", v.quantity);
        }
        if !v.unit.is_empty() {
            let _ = write!(x, " unit=\"{}\"", v.unit);
        }
        if v.range == Range::NonNegative {
            x.push_str(" min=\"0.0\"");
        }
        if v.name == "contact" {
            x.push_str(" min=\"-1\" max=\"1\"");
        }
        if let Some(nominal) = v.nominal {
            let _ = write!(x, " nominal=\"{nominal:?}\"");
        }
        if let Some(state) = v.derivative_of {
            let _ = write!(x, " derivative=\"{}\"", index_of(state));
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
        x.push_str("/>\n    </ScalarVariable>\n");
    }
    x.push_str("  </ModelVariables>\n");

    x.push_str("  <ModelStructure>\n    <Outputs>\n");
    for (i, v) in model.variables.iter().enumerate() {
        if v.causality == Causality::Output {
            // No direct feedthrough: every output is a function of the state (docs/model.md §1).
            let deps = index_list(output_dependencies(v.name));
            let _ = writeln!(x, "      <Unknown index=\"{}\" dependencies=\"{deps}\"/>", i + 1);
        }
    }
    x.push_str("    </Outputs>\n    <Derivatives>\n");
    for (i, v) in model.variables.iter().enumerate() {
        if v.derivative_of.is_some() {
            let deps = index_list(derivative_dependencies(v.name));
            let _ = writeln!(x, "      <Unknown index=\"{}\" dependencies=\"{deps}\"/>", i + 1);
        }
    }
    x.push_str("    </Derivatives>\n    <InitialUnknowns>\n");
    for (i, v) in model.variables.iter().enumerate() {
        let listed = (matches!(v.causality, Causality::Output | Causality::Local) && v.initial == Initial::Calculated)
            || v.causality == Causality::CalculatedParameter;
        if !listed {
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
    x.push_str("</fmiModelDescription>\n");
    x
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

/// `{8-4-4-4-12}` hex of the FNV-1a-128 hash of `text`.
fn guid_of(text: &str) -> String {
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
