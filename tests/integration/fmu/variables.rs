//! The generated value-reference table, the generated modelDescription.xml and the instance
//! agree: every variable is served by the get/set of its type, with its start value, and the
//! wrong-type get fails. The XML is read here with an XML parser (roxmltree).

use backlash_fmu::fmu::variables::{Causality, Range, VarType};
use backlash_fmu::fmu::{model_by_identifier, FmuError, Instance, LogCategory, Variable, MODELS};
use model_description::{model_identifiers, xml};

/// One `<ScalarVariable>` as the description states it.
struct XmlVar {
    name: String,
    vr: u32,
    causality: String,
    element: String,
    start: Option<String>,
    initial: Option<String>,
}

fn xml_variables(doc: &roxmltree::Document) -> Vec<XmlVar> {
    doc.descendants()
        .filter(|n| n.has_tag_name("ScalarVariable"))
        .map(|v| {
            let typed = v.children().find(|n| n.is_element()).expect("a type element");
            XmlVar {
                name: v.attribute("name").unwrap().to_string(),
                vr: v.attribute("valueReference").unwrap().parse().unwrap(),
                causality: v.attribute("causality").unwrap().to_string(),
                element: typed.tag_name().name().to_string(),
                start: typed.attribute("start").map(str::to_string),
                initial: v.attribute("initial").map(str::to_string),
            }
        })
        .collect()
}

fn guid_of(xml: &str) -> String {
    let doc = roxmltree::Document::parse(xml).unwrap();
    doc.root_element().attribute("guid").unwrap().to_string()
}

#[test]
fn xml_and_rust_table_describe_the_same_variables() {
    assert!(!model_identifiers().is_empty(), "no model to check");
    for id in model_identifiers() {
        let text = xml::model_description(id);
        let doc = roxmltree::Document::parse(&text).unwrap();
        let model = model_by_identifier(id).unwrap();
        assert_eq!(doc.root_element().attribute("guid"), Some(model.guid), "{id}");
        let element = |tag: &str| doc.descendants().filter(|n| n.has_tag_name(tag)).collect::<Vec<_>>();
        for interface in ["ModelExchange", "CoSimulation"] {
            let found = element(interface);
            assert_eq!(found.len(), 1, "{id} {interface}");
            assert_eq!(found[0].attribute("modelIdentifier"), Some(*id));
        }
        let vars = xml_variables(&doc);
        assert_eq!(vars.len(), model.variables.len(), "{id}");
        for (x, v) in vars.iter().zip(model.variables) {
            assert_eq!((x.name.as_str(), x.vr), (v.name, v.vr));
            let causality = match v.causality {
                Causality::Input => "input",
                Causality::Output => "output",
                Causality::Parameter => "parameter",
                Causality::CalculatedParameter => "calculatedParameter",
                Causality::Local => "local",
            };
            assert_eq!(x.causality, causality, "{}", v.name);
            assert_eq!(
                x.element,
                if v.ty == VarType::Real { "Real" } else { "Integer" },
                "{}",
                v.name
            );
            // Exact: the description writes start with `{:?}`, which round-trips an f64.
            assert_eq!(
                x.start.as_ref().map(|s| s.parse::<f64>().unwrap()),
                v.start,
                "{}",
                v.name
            );
            // FMI 2.0: start is required for inputs, parameters and initial="exact".
            let needs_start =
                matches!(v.causality, Causality::Input | Causality::Parameter) || x.initial.as_deref() == Some("exact");
            assert_eq!(x.start.is_some(), needs_start, "{}", v.name);
            assert!(!v.description.is_empty());
        }
        let categories: Vec<_> = element("Category")
            .iter()
            .map(|c| c.attribute("name").unwrap())
            .collect();
        let names: Vec<_> = LogCategory::ALL.iter().map(|c| c.name()).collect();
        assert_eq!(categories, names, "{id}");
        let mut display_units: Vec<_> = element("DisplayUnit")
            .iter()
            .map(|c| c.attribute("name").unwrap())
            .collect();
        display_units.sort_unstable();
        // Shaft angles have no length: no mm where no variable is in m.
        let lengths = model_by_identifier(id).unwrap().variables.iter().any(|v| v.unit == "m");
        let expected: &[&str] = if lengths {
            &["deg", "mm", "rpm"]
        } else {
            &["deg", "rpm"]
        };
        assert_eq!(display_units, expected, "{id}");
    }
}

/// Model Exchange: the four states in z order with their derivatives (FMI 2.0 §2.2.8), ten
/// event indicators, and nominal values that are those the FMU reports for the default
/// parameters (fmi2GetNominalsOfContinuousStates computes them for any parameters).
#[test]
fn states_derivatives_and_nominals_agree_with_the_running_fmu() {
    use backlash_fmu::fmu::Interface;
    for id in model_identifiers() {
        let text = xml::model_description(id);
        let doc = roxmltree::Document::parse(&text).unwrap();
        let root = doc.root_element();
        let model = model_by_identifier(id).unwrap();
        let indicators = if model.is_geared() { "18" } else { "10" };
        assert_eq!(root.attribute("numberOfEventIndicators"), Some(indicators), "{id}");
        let reals: Vec<_> = doc.descendants().filter(|n| n.has_tag_name("ScalarVariable")).collect();
        let name_at = |index: &str| reals[index.parse::<usize>().unwrap() - 1].attribute("name").unwrap();
        let derivatives: Vec<_> = doc
            .descendants()
            .find(|n| n.has_tag_name("Derivatives"))
            .unwrap()
            .children()
            .filter(|n| n.has_tag_name("Unknown"))
            .map(|n| name_at(n.attribute("index").unwrap()))
            .collect();
        let expected: &[&str] = match *id {
            "BacklashWeb" => &["der(theta_m)", "der(omega_m)", "der(theta_L)", "der(omega_L)", "der(T)"],
            "BacklashTwoStage" => &[
                "der(theta_m)",
                "der(omega_m)",
                "der(theta_i)",
                "der(omega_i)",
                "der(theta_L)",
                "der(omega_L)",
            ],
            _ => &["der(theta_m)", "der(omega_m)", "der(theta_L)", "der(omega_L)"],
        };
        assert_eq!(derivatives, expected, "{id}");
        let mut nominals = Vec::new();
        for der in &derivatives {
            let var = reals.iter().find(|v| v.attribute("name") == Some(der)).unwrap();
            let real = var.children().find(|n| n.has_tag_name("Real")).unwrap();
            let state = name_at(real.attribute("derivative").unwrap());
            assert_eq!(format!("der({state})"), *der);
            let state_real = reals
                .iter()
                .find(|v| v.attribute("name") == Some(state))
                .and_then(|v| v.children().find(|n| n.has_tag_name("Real")))
                .unwrap();
            nominals.push(state_real.attribute("nominal").unwrap().parse::<f64>().unwrap());
        }
        let mut inst = Instance::new_for(model, Interface::ModelExchange, None, false);
        let mut reported = vec![0.0; derivatives.len()];
        inst.get_nominals_of_continuous_states(&mut reported).unwrap();
        for (x, r) in nominals.iter().zip(reported) {
            assert!((x / r - 1.0).abs() < 1e-12, "{id}: description {x}, FMU {r}");
        }
    }
}

#[test]
fn the_guid_is_the_hash_of_the_description_and_differs_per_model() {
    let shaft = xml::model_description("BacklashShaft");
    let guid = guid_of(&shaft);
    let guid = guid.as_str();
    // The same description gives the same guid; another description another one.
    assert_eq!(xml::model_description("BacklashShaft"), shaft);
    assert_ne!(guid_of(&xml::model_description("BacklashBelt")), guid);
    let blanked = shaft.replacen(guid, "", 1);
    assert_eq!(xml::guid("BacklashShaft"), guid);
    assert_ne!(blanked, shaft);
    assert!(guid.len() == 38 && guid.starts_with('{') && guid.ends_with('}'));
}

/// A value in the variable's range, different from its start value.
fn other_value(start: f64, range: Range) -> f64 {
    match range {
        Range::Positive | Range::NonNegative | Range::AtLeastOne => start * 1.5 + 0.25,
        Range::Finite => start - 0.75,
        Range::Integers { max, .. } if start < max as f64 => start + 1.0,
        Range::Integers { .. } => start - 1.0,
    }
}

/// Sets `v` to `value` by the set of its type (an Integer's value is a whole number).
fn set(inst: &mut Instance, v: &Variable, value: f64) -> Result<(), FmuError> {
    match v.ty {
        VarType::Real => inst.set_real(&[v.vr], &[value]),
        VarType::Integer => inst.set_integer(&[v.vr], &[value as i32]),
    }
    .map(|_| ())
}

#[test]
fn every_variable_is_served_by_its_typed_get_and_set() {
    for model in &MODELS {
        let mut inst = Instance::new(model, None, false);
        let mut expected = Vec::new();
        for v in model.variables {
            let settable = v.start.is_some();
            assert_eq!(
                settable,
                !matches!(v.causality, Causality::CalculatedParameter | Causality::Local)
                    && (v.causality != Causality::Output || v.is_initial_state())
            );
            if settable {
                let value = other_value(v.start.unwrap(), v.range);
                set(&mut inst, v, value).unwrap_or_else(|e| panic!("{}: {e}", v.name));
                expected.push((v, value));
            } else {
                let err = inst.set_real(&[v.vr], &[1.0]).unwrap_err();
                assert!(
                    matches!(err, FmuError::NotSettable { .. } | FmuError::WrongType { .. }),
                    "{}: {err}",
                    v.name
                );
                inst.reset().unwrap();
                for (w, value) in &expected {
                    set(&mut inst, w, *value).unwrap();
                }
            }
        }
        inst.enter_initialization_mode().unwrap();
        for (v, value) in &expected {
            let got = match v.ty {
                VarType::Real => {
                    let mut out = [f64::NAN];
                    inst.get_real(&[v.vr], &mut out).unwrap();
                    out[0]
                }
                VarType::Integer => {
                    let mut out = [i32::MIN];
                    inst.get_integer(&[v.vr], &mut out).unwrap();
                    out[0] as f64
                }
            };
            assert_eq!(got.to_bits(), value.to_bits(), "{}: {}", model.identifier, v.name);
        }
        for v in model.variables {
            let mut real = [0.0];
            let mut int = [0];
            match v.ty {
                VarType::Real => {
                    inst.get_real(&[v.vr], &mut real)
                        .unwrap_or_else(|e| panic!("{}: {e}", v.name));
                    let err = inst.get_integer(&[v.vr], &mut int).unwrap_err();
                    assert!(matches!(err, FmuError::WrongType { .. }), "{}: {err}", v.name);
                }
                VarType::Integer => {
                    inst.get_integer(&[v.vr], &mut int).unwrap();
                    assert!(matches!(
                        inst.get_real(&[v.vr], &mut real).unwrap_err(),
                        FmuError::WrongType { .. }
                    ));
                }
            }
            // A wrong-type get enters Error; Error still serves debug gets, and Reset clears it.
            inst.reset().unwrap();
            for (w, value) in &expected {
                set(&mut inst, w, *value).unwrap();
            }
            inst.enter_initialization_mode().unwrap();
        }
    }
}

#[test]
fn calculated_outputs_at_the_start_match_the_model_formulas() {
    // Shaft: psi = k dz(theta_m - theta_L, Delta) (docs/model.md §1), bounds 0 at the start (docs/model.md §4).
    let model = &MODELS[0];
    let mut inst = Instance::new(model, None, false);
    inst.set_real(&[model.vr("theta_m"), model.vr("theta_L")], &[0.01, -0.002])
        .unwrap();
    inst.enter_initialization_mode().unwrap();
    let vrs = [
        model.vr("psi"),
        model.vr("bound"),
        model.vr("bound_paper"),
        model.vr("bound_sup"),
    ];
    let mut out = [0.0; 4];
    inst.get_real(&vrs, &mut out).unwrap();
    let expected_psi = 200.0 * (0.012 - 0.775e-3);
    assert!((out[0] - expected_psi).abs() <= 1e-13 * expected_psi, "{out:?}");
    // Exact: at elapsed time 0 l1 and the integral are zeros, and K g·0 and K g·√0 are 0.
    assert_eq!(&out[1..3], &[0.0, 0.0]);
    assert!(
        out[3].is_finite() && out[3] > 0.0,
        "open loop with damping: finite bound_sup, {}",
        out[3]
    );
    let mut contact = [9];
    inst.get_integer(&[model.vr("contact")], &mut contact).unwrap();
    assert_eq!(contact, [1]);

    // Belt: u = R_1 theta_m - alpha_1 theta_L, g = alpha_2 Delta (docs/model.md §1 table).
    let model = &MODELS[1];
    let mut inst = Instance::new(model, None, false);
    inst.set_real(&[model.vr("theta_m"), model.vr("theta_L")], &[-0.01, 0.0])
        .unwrap();
    inst.enter_initialization_mode().unwrap();
    let mut psi = [0.0];
    inst.get_real(&[model.vr("psi")], &mut psi).unwrap();
    let (r1, r2, rg1, rg2, kb, delta) = (0.02, 0.04, 0.015, 0.045, 2e5, 5e-5);
    let _alpha_1 = r2 * rg2 / rg1;
    let u: f64 = r1 * -0.01;
    let g = r2 / rg1 * delta;
    let expected = kb * (u + g);
    assert!(
        (psi[0] - expected).abs() <= 1e-12 * expected.abs(),
        "{} vs {expected}",
        psi[0]
    );
    inst.get_integer(&[model.vr("contact")], &mut contact).unwrap();
    assert_eq!(contact, [-1]);
}

/// The ModelStructure's `<Derivatives>` dependencies are the Jacobian's sparsity: a state
/// derivative depends on a known (a continuous state or an input) exactly when its column of
/// the exact Jacobian (fmi2GetDirectionalDerivative) is non-zero in some contact mode, at a
/// generic state of each mode (u at -3g, 0.3g and 2.5g, the speeds and the tension non-zero),
/// every parameter at its start value but the damping of the compliant member, set so that the
/// damper is in place (it couples the speeds; its force is not capped at these states). So the
/// hand-written lists cannot drift from the physics.
#[test]
fn derivative_dependencies_are_the_jacobians_sparsity() {
    use backlash_fmu::fmu::Interface;
    use std::collections::{BTreeMap, BTreeSet};
    for id in model_identifiers() {
        let text = xml::model_description(id);
        let doc = roxmltree::Document::parse(&text).unwrap();
        let vars = xml_variables(&doc);
        let name_at = |index: &str| vars[index.parse::<usize>().unwrap() - 1].name.clone();
        let declared: BTreeMap<String, BTreeSet<String>> = doc
            .descendants()
            .find(|n| n.has_tag_name("Derivatives"))
            .unwrap()
            .children()
            .filter(|n| n.has_tag_name("Unknown"))
            .map(|n| {
                let deps = n.attribute("dependencies").unwrap_or("");
                (
                    name_at(n.attribute("index").unwrap()),
                    deps.split_whitespace().map(name_at).collect(),
                )
            })
            .collect();
        let model = model_by_identifier(id).unwrap();
        let states: Vec<&str> = model
            .variables
            .iter()
            .filter(|v| v.is_continuous_state())
            .map(|v| v.name)
            .collect();
        let inputs: Vec<&str> = model
            .variables
            .iter()
            .filter(|v| v.causality == Causality::Input)
            .map(|v| v.name)
            .collect();
        let mut found: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for u_over_g in [-3.0, 0.3, 2.5] {
            let mut inst = Instance::new_for(model, Interface::ModelExchange, None, false);
            let dampers: &[(&str, f64)] = match (model.by_name("d"), model.is_geared()) {
                (_, true) => &[("d_1", 0.05), ("d_2", 0.05)],
                (Some(_), false) => &[("d", 0.05)],
                (None, false) => &[("D_b", 100.0)],
            };
            for (name, d) in dampers {
                inst.set_real(&[model.vr(name)], &[*d]).unwrap();
            }
            inst.setup_experiment(None, 0.0, None).unwrap();
            inst.enter_initialization_mode().unwrap();
            inst.exit_initialization_mode().unwrap();
            inst.enter_continuous_time_mode().unwrap();
            // u = r_m θ_m with θ_L = 0: r_m and g from the event indicators' values and slope (a
            // gearbox's first stage; its second at the same u/g, its ratios and gaps those of
            // its defaults, 1 and equal).
            let stage = if model.is_geared() { "_1" } else { "" };
            let [minus, plus] = [format!("u_minus_g{stage}"), format!("u_plus_g{stage}")].map(|n| model.vr(&n));
            let mut z = [0.0; 2];
            inst.get_real(&[minus, plus], &mut z).unwrap();
            let g = (z[1] - z[0]) / 2.0;
            let mut r_m = [0.0];
            inst.get_directional_derivative(&[minus], &[model.vr("theta_m")], &[1.0], &mut r_m)
                .unwrap();
            let u = u_over_g * g / r_m[0];
            let mut x: Vec<f64> = match model.is_geared() {
                true => vec![2.0 * u, 0.7, u, 0.2, 0.0, -0.4],
                false => vec![u, 0.7, 0.0, -0.4, 3.0],
            };
            x.truncate(states.len());
            inst.set_continuous_states(&x).unwrap();
            for der in declared.keys() {
                for known in states.iter().chain(&inputs) {
                    let mut dv = [0.0];
                    inst.get_directional_derivative(&[model.vr(der)], &[model.vr(known)], &[1.0], &mut dv)
                        .unwrap();
                    if dv[0] != 0.0 {
                        found.entry(der.clone()).or_default().insert(known.to_string());
                    }
                }
            }
        }
        assert_eq!(found, declared, "{id}: the Jacobian's sparsity vs <Derivatives>");
    }
}
