//! The FMI 3.0 model description (`model_description::xml3`, docs/model.md §7) against the
//! library's tables and the FMI 2.0 description: the same variables with the same attributes in
//! FMI 3.0 form, the same dependency lists by value reference, the event indicators 28 and 29,
//! and an instantiation token that is the one the library checks and not the guid. The XML is
//! read with an XML parser (roxmltree).

use std::collections::BTreeMap;

use backlash_fmu::fmu::variables::{model_by_instantiation_token, Causality, Initial, VarType, Variability};
use backlash_fmu::fmu::{model_by_guid, model_by_identifier, ModelInfo, MODELS};
use model_description::{model_identifiers, xml, xml3};
use roxmltree::{Document, Node};

fn elements<'a, 'i>(node: Node<'a, 'i>) -> impl Iterator<Item = Node<'a, 'i>> {
    node.children().filter(|n| n.is_element())
}

fn child<'a, 'i>(doc: &'a Document<'i>, tag: &str) -> Node<'a, 'i> {
    doc.descendants()
        .find(|n| n.has_tag_name(tag))
        .unwrap_or_else(|| panic!("no <{tag}>"))
}

/// A node's attributes as a sorted map.
fn attributes(node: Node) -> BTreeMap<String, String> {
    node.attributes()
        .map(|a| (a.name().to_string(), a.value().to_string()))
        .collect()
}

fn numbers(list: &str) -> Vec<u32> {
    list.split_whitespace().map(|n| n.parse().unwrap()).collect()
}

fn causality(c: Causality) -> &'static str {
    match c {
        Causality::Input => "input",
        Causality::Output => "output",
        Causality::Parameter => "parameter",
        Causality::CalculatedParameter => "calculatedParameter",
        Causality::Local => "local",
    }
}

fn variability(v: Variability) -> &'static str {
    match v {
        Variability::Fixed => "fixed",
        Variability::Discrete => "discrete",
        Variability::Continuous => "continuous",
    }
}

fn initial(i: Initial) -> Option<&'static str> {
    match i {
        Initial::Unset => None,
        Initial::Exact => Some("exact"),
        Initial::Calculated => Some("calculated"),
    }
}

/// The FMI 2.0 description's model structure by value reference: list name ("Outputs",
/// "Derivatives", "InitialUnknowns") → [(unknown, dependencies or None)].
type Structure = BTreeMap<String, Vec<(u32, Option<Vec<u32>>)>>;

fn fmi2_structure(doc: &Document) -> Structure {
    let vrs: Vec<u32> = doc
        .descendants()
        .filter(|n| n.has_tag_name("ScalarVariable"))
        .map(|v| v.attribute("valueReference").unwrap().parse().unwrap())
        .collect();
    let vr_at = |index: u32| vrs[index as usize - 1];
    elements(child(doc, "ModelStructure"))
        .map(|list| {
            let unknowns = elements(list)
                .map(|u| {
                    let index = u.attribute("index").unwrap().parse().unwrap();
                    let deps = u
                        .attribute("dependencies")
                        .map(|d| numbers(d).into_iter().map(vr_at).collect());
                    (vr_at(index), deps)
                })
                .collect();
            (list.tag_name().name().to_string(), unknowns)
        })
        .collect()
}

struct Fmi3<'a, 'i> {
    root: Node<'a, 'i>,
    /// The variables, without the independent variable.
    variables: Vec<Node<'a, 'i>>,
    /// The independent variable.
    time: Node<'a, 'i>,
    structure: Vec<Node<'a, 'i>>,
}

fn fmi3<'a, 'i>(doc: &'a Document<'i>) -> Fmi3<'a, 'i> {
    let (time, variables): (Vec<_>, Vec<_>) =
        elements(child(doc, "ModelVariables")).partition(|v| v.attribute("causality") == Some("independent"));
    assert_eq!(time.len(), 1, "exactly one independent variable");
    Fmi3 {
        root: doc.root_element(),
        variables,
        time: time[0],
        structure: elements(child(doc, "ModelStructure")).collect(),
    }
}

fn unknowns(doc: &Fmi3, tag: &str) -> Vec<(u32, Option<Vec<u32>>)> {
    doc.structure
        .iter()
        .filter(|n| n.has_tag_name(tag))
        .map(|u| {
            (
                u.attribute("valueReference").unwrap().parse().unwrap(),
                u.attribute("dependencies").map(numbers),
            )
        })
        .collect()
}

fn each_model(check: impl Fn(&'static ModelInfo, &Document, &Document)) {
    assert!(!model_identifiers().is_empty(), "no model to check");
    for id in model_identifiers() {
        let model = model_by_identifier(id).unwrap();
        let text3 = xml3::model_description(id);
        let text2 = xml::model_description(id);
        let doc3 = Document::parse(&text3).unwrap_or_else(|e| panic!("{id}: {e}"));
        let doc2 = Document::parse(&text2).unwrap();
        check(model, &doc3, &doc2);
    }
}

#[test]
fn root_and_interfaces_are_fmi3_model_exchange_and_co_simulation() {
    each_model(|model, doc, doc2| {
        let id = model.identifier;
        let root = doc.root_element();
        assert!(root.has_tag_name("fmiModelDescription"));
        assert_eq!(root.attribute("fmiVersion"), Some("3.0"));
        assert_eq!(root.attribute("modelName"), Some(id));
        assert_eq!(root.attribute("variableNamingConvention"), Some("flat"));
        assert_eq!(root.attribute("guid"), None);
        assert_eq!(
            root.attribute("numberOfEventIndicators"),
            None,
            "FMI 3.0 lists them instead"
        );
        for attribute in ["description", "generationTool"] {
            assert_eq!(
                root.attribute(attribute),
                doc2.root_element().attribute(attribute),
                "{id} {attribute}"
            );
        }
        let interface = |tag: &str| {
            let found: Vec<_> = elements(root).filter(|n| n.has_tag_name(tag)).collect();
            assert_eq!(found.len(), 1, "{id} <{tag}>");
            attributes(found[0])
        };
        let expected = |pairs: &[(&str, &str)]| -> BTreeMap<String, String> {
            pairs
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .chain([("modelIdentifier".to_string(), id.to_string())])
                .collect()
        };
        assert_eq!(
            interface("ModelExchange"),
            expected(&[
                ("canGetAndSetFMUState", "true"),
                ("canSerializeFMUState", "true"),
                ("providesDirectionalDerivatives", "true"),
                ("needsCompletedIntegratorStep", "false"),
            ]),
            "{id}"
        );
        assert_eq!(
            interface("CoSimulation"),
            expected(&[
                ("canGetAndSetFMUState", "true"),
                ("canSerializeFMUState", "true"),
                ("canHandleVariableCommunicationStepSize", "true"),
                ("maxOutputDerivativeOrder", "1"),
                ("hasEventMode", "true"),
                ("mightReturnEarlyFromDoStep", "true"),
                ("canReturnEarlyAfterIntermediateUpdate", "false"),
                ("providesIntermediateUpdate", "false"),
                ("providesDirectionalDerivatives", "false"),
            ]),
            "{id}"
        );
        // The schema's order: interfaces, units, categories, experiment, variables, structure.
        let order: Vec<_> = elements(root).map(|n| n.tag_name().name()).collect();
        assert_eq!(
            order,
            [
                "ModelExchange",
                "CoSimulation",
                "UnitDefinitions",
                "LogCategories",
                "DefaultExperiment",
                "ModelVariables",
                "ModelStructure"
            ],
            "{id}"
        );
    });
}

/// Units (with display units), log categories and default experiment are the FMI 2.0 ones,
/// text for text.
#[test]
fn units_categories_and_experiment_are_those_of_fmi2() {
    for id in model_identifiers() {
        let block = |text: &str| {
            let start = text.find("  <UnitDefinitions>").unwrap();
            let end = text.find("  <ModelVariables>").unwrap();
            text[start..end].to_string()
        };
        let fmi3 = block(&xml3::model_description(id));
        assert_eq!(fmi3, block(&xml::model_description(id)), "{id}");
        assert!(fmi3.contains("<DisplayUnit name=\"rpm\""), "{id}");
        assert!(fmi3.contains("<Category name=\"logContactEvents\""), "{id}");
    }
}

#[test]
fn instantiation_token_is_the_tables_and_not_the_guid() {
    each_model(|model, doc, doc2| {
        let id = model.identifier;
        let token = doc.root_element().attribute("instantiationToken").unwrap();
        assert_eq!(token, model.instantiation_token, "{id}");
        assert_eq!(token, xml3::instantiation_token(id), "{id}");
        assert!(
            token.len() == 38 && token.starts_with('{') && token.ends_with('}'),
            "{token}"
        );
        let guid = doc2.root_element().attribute("guid").unwrap();
        assert_eq!(guid, model.guid);
        assert_ne!(token, guid, "{id}");
        assert_eq!(model_by_instantiation_token(token).map(|m| m.identifier), Some(id));
        // Each name opens its own standard only.
        assert!(model_by_instantiation_token(guid).is_none(), "{id}");
        assert!(model_by_guid(token).is_none(), "{id}");
    });
    assert_ne!(MODELS[0].instantiation_token, MODELS[1].instantiation_token);
    assert!(model_by_instantiation_token("").is_none());
}

/// Every row of the tables is one `<Float64>` or `<Int32>` with its name, value reference,
/// causality, variability, initial, start, unit, quantity, description, nominal and range; the
/// type attributes are those of the FMI 2.0 type element, but `derivative`, which names the
/// state by value reference. The only other variable is the independent variable `time`.
#[test]
fn variables_are_the_tables_in_fmi3_form() {
    each_model(|model, doc, doc2| {
        let id = model.identifier;
        let d = fmi3(doc);
        assert_eq!(d.time.tag_name().name(), "Float64");
        assert_eq!(d.time.attribute("name"), Some("time"));
        assert_eq!(d.time.attribute("valueReference"), Some("0"));
        assert_eq!(d.time.attribute("variability"), Some("continuous"));
        for forbidden in ["start", "initial", "unit"] {
            assert_eq!(d.time.attribute(forbidden), None, "time {forbidden}");
        }
        assert!(model.variables.iter().all(|v| v.vr != 0 && v.name != "time"));

        let fmi2: Vec<_> = doc2
            .descendants()
            .filter(|n| n.has_tag_name("ScalarVariable"))
            .collect();
        assert_eq!(d.variables.len(), model.variables.len(), "{id}");
        assert_eq!(fmi2.len(), model.variables.len(), "{id}");
        for ((x, v), x2) in d.variables.iter().zip(model.variables).zip(&fmi2) {
            let what = format!("{id} {}", v.name);
            let element = match v.ty {
                VarType::Real => "Float64",
                VarType::Integer => "Int32",
            };
            assert_eq!(x.tag_name().name(), element, "{what}");
            assert_eq!(x.attribute("name"), Some(v.name), "{what}");
            assert_eq!(x.attribute("valueReference"), Some(v.vr.to_string().as_str()), "{what}");
            assert_eq!(x.attribute("causality"), Some(causality(v.causality)), "{what}");
            assert_eq!(x.attribute("variability"), Some(variability(v.variability)), "{what}");
            assert_eq!(x.attribute("initial"), initial(v.initial), "{what}");
            assert_eq!(x.attribute("description"), Some(v.description), "{what}");
            assert_eq!(x.attribute("unit").unwrap_or(""), v.unit, "{what}");
            assert_eq!(x.attribute("quantity").unwrap_or(""), v.quantity, "{what}");
            // Exact: start and nominal are written with `{:?}`, which round-trips an f64.
            assert_eq!(
                x.attribute("start").map(|s| s.parse::<f64>().unwrap()),
                v.start,
                "{what}"
            );
            assert_eq!(
                x.attribute("nominal").map(|s| s.parse::<f64>().unwrap()),
                v.nominal,
                "{what}"
            );
            // FMI 3.0: start is required for inputs and initial = exact, forbidden otherwise.
            let needs_start = v.causality == Causality::Input || v.initial == Initial::Exact;
            assert_eq!(x.attribute("start").is_some(), needs_start, "{what}");

            // The same attributes as FMI 2.0: the variable's and its type element's.
            let typed2 = elements(*x2).next().unwrap();
            let mut expected = attributes(*x2);
            expected.extend(attributes(typed2));
            let mut found = attributes(*x);
            match v.derivative_of {
                Some(state) => {
                    let derivative = found.remove("derivative").expect("derivative attribute");
                    assert_eq!(derivative, state.to_string(), "{what}");
                    let state = model.by_vr(state).unwrap();
                    assert!(state.is_continuous_state(), "{what}: derivative of {}", state.name);
                    assert_eq!(v.name, format!("der({})", state.name));
                    expected.remove("derivative").expect("FMI 2.0 names the state too");
                }
                None => assert!(!found.contains_key("derivative"), "{what}"),
            }
            assert_eq!(found, expected, "{what}");
        }
        // Every continuous state has exactly one derivative.
        for state in model.variables.iter().filter(|v| v.is_continuous_state()) {
            let derivatives = d
                .variables
                .iter()
                .filter(|x| x.attribute("derivative") == Some(state.vr.to_string().as_str()))
                .count();
            assert_eq!(derivatives, 1, "{id} {}", state.name);
        }
    });
}

/// The model structure names by value reference what FMI 2.0 names by index, with the same
/// dependency lists; the bounds depend on time (value reference 0), which FMI 2.0 cannot name;
/// the event indicators are 28, 29 (on the angles) and 44–47 (on the angles and the speeds);
/// and the initial unknowns are those FMI 3.0 §2.4.8 lists (not the event indicators).
#[test]
fn model_structure_has_the_fmi2_dependencies_by_value_reference() {
    each_model(|model, doc, doc2| {
        let id = model.identifier;
        let d = fmi3(doc);
        let fmi2 = fmi2_structure(doc2);
        let rank = |tag: &str| {
            [
                "Output",
                "ContinuousStateDerivative",
                "InitialUnknown",
                "EventIndicator",
            ]
            .iter()
            .position(|t| *t == tag)
            .unwrap_or_else(|| panic!("{id}: unexpected <{tag}>"))
        };
        let ranks: Vec<_> = d.structure.iter().map(|n| rank(n.tag_name().name())).collect();
        assert!(ranks.windows(2).all(|w| w[0] <= w[1]), "{id}: schema order {ranks:?}");

        // Outputs: every output, with the FMI 2.0 dependencies; time for the bounds.
        let outputs: Vec<u32> = model
            .variables
            .iter()
            .filter(|v| v.causality == Causality::Output)
            .map(|v| v.vr)
            .collect();
        let found = unknowns(&d, "Output");
        assert_eq!(found.iter().map(|u| u.0).collect::<Vec<_>>(), outputs, "{id}");
        for ((vr, deps), (vr2, deps2)) in found.iter().zip(&fmi2["Outputs"]) {
            assert_eq!(vr, vr2);
            let name = model.by_vr(*vr).unwrap().name;
            let mut expected = deps2.clone().unwrap();
            if matches!(name, "bound" | "bound_paper" | "bound_T") {
                assert!(expected.is_empty(), "{name}");
                expected.push(0);
            }
            assert_eq!(deps.as_ref(), Some(&expected), "{id} {name}");
        }

        // The derivatives (24..27, and 33 of T on the web line; a gearbox's 38..43), in the order
        // of their states, with the FMI 2.0 dependencies.
        let found = unknowns(&d, "ContinuousStateDerivative");
        let (derivatives, state_names): (&[u32], &[&str]) = match id {
            "BacklashWeb" => (
                &[24, 25, 26, 27, 33],
                &["theta_m", "omega_m", "theta_L", "omega_L", "T"],
            ),
            "BacklashTwoStage" => (
                &[38, 39, 40, 41, 42, 43],
                &["theta_m", "omega_m", "theta_i", "omega_i", "theta_L", "omega_L"],
            ),
            _ => (&[24, 25, 26, 27], &["theta_m", "omega_m", "theta_L", "omega_L"]),
        };
        assert_eq!(found.iter().map(|u| u.0).collect::<Vec<_>>(), derivatives, "{id}");
        assert_eq!(found, fmi2["Derivatives"], "{id}");
        let states: Vec<u32> = found
            .iter()
            .map(|(vr, _)| model.by_vr(*vr).unwrap().derivative_of.unwrap())
            .collect();
        let expected_states: Vec<u32> = state_names.iter().map(|n| model.vr(n)).collect();
        assert_eq!(states, expected_states, "{id}");

        // Initial unknowns: FMI 2.0's, without the event indicators (FMI 3.0 §2.4.8).
        let expected: Vec<_> = fmi2["InitialUnknowns"]
            .iter()
            .filter(|(vr, _)| *vr != 28 && *vr != 29)
            .cloned()
            .collect();
        let found = unknowns(&d, "InitialUnknown");
        assert_eq!(found, expected, "{id}");
        for (vr, _) in &found {
            let v = model.by_vr(*vr).unwrap();
            let listed = (v.causality == Causality::Output && v.initial == Initial::Calculated)
                || v.causality == Causality::CalculatedParameter
                || v.derivative_of.is_some();
            assert!(listed, "{id} {}", v.name);
        }

        // Event indicators: u - g and u + g on the angles, then the damped force's and the cap's
        // surfaces on the angles and the speeds (u and u'), in the order of the physics; then
        // friction's (docs/model.md §12): a body's speed, and the torque on it at rest, from
        // every state and the body's own input.
        let found = unknowns(&d, "EventIndicator");
        if model.is_geared() {
            // Each stage's surfaces on its two bodies' angles (u_j ∓ g_j) or angles and speeds,
            // then each body's friction surfaces as above (the intermediate shaft has no input).
            let bodies = |names: &[&str]| {
                let mut vrs: Vec<u32> = names.iter().map(|n| model.vr(n)).collect();
                vrs.sort_unstable();
                Some(vrs)
            };
            let states = ["theta_m", "omega_m", "theta_i", "omega_i", "theta_L", "omega_L"];
            let with = |input: Option<&str>| bodies(&states.iter().copied().chain(input).collect::<Vec<_>>());
            let mut expected = Vec::new();
            for (angles, all) in [
                (["theta_m", "theta_i"], ["theta_m", "omega_m", "theta_i", "omega_i"]),
                (["theta_i", "theta_L"], ["theta_i", "omega_i", "theta_L", "omega_L"]),
            ] {
                expected.extend([bodies(&angles), bodies(&angles)]);
                expected.extend([bodies(&all), bodies(&all), bodies(&all), bodies(&all)]);
            }
            for (body, input) in [("m", Some("tau_m")), ("i", None), ("L", Some("tau_L"))] {
                expected.extend([bodies(&[&format!("omega_{body}")]), with(input)]);
            }
            let deps: Vec<Option<Vec<u32>>> = found.iter().map(|(_, d)| d.clone()).collect();
            assert_eq!(deps, expected, "{id}");
            let vrs: Vec<u32> = found.iter().map(|(vr, _)| *vr).collect();
            assert_eq!(vrs, (47..=64).collect::<Vec<u32>>(), "{id}");
        } else {
            single_gap_indicators(model, &found);
        }

        // Every value reference the structure names is a variable of the description.
        let known: Vec<u32> = std::iter::once(0).chain(model.variables.iter().map(|v| v.vr)).collect();
        for n in &d.structure {
            for vr in numbers(n.attribute("valueReference").unwrap())
                .into_iter()
                .chain(n.attribute("dependencies").map(numbers).unwrap_or_default())
            {
                assert!(known.contains(&vr), "{id}: {vr} in <{}>", n.tag_name().name());
            }
        }
        assert!(d.root.attribute("fmiVersion") == Some("3.0"));
    });
}

/// A single gap's event indicators (value reference, dependencies) against the equations.
fn single_gap_indicators(model: &ModelInfo, found: &[(u32, Option<Vec<u32>>)]) {
    let id = model.identifier;
    {
        let angles = vec![model.vr("theta_m"), model.vr("theta_L")];
        let all: Vec<u32> = (3..=6).collect();
        let at_rest = |input: &str| {
            let mut vrs: Vec<u32> = ["theta_m", "omega_m", "theta_L", "omega_L", "T", input]
                .iter()
                .filter_map(|n| model.by_name(n).map(|v| v.vr))
                .collect();
            vrs.sort_unstable();
            Some(vrs)
        };
        assert_eq!(
            found,
            [
                (28, Some(angles.clone())),
                (29, Some(angles)),
                (44, Some(all.clone())),
                (45, Some(all.clone())),
                (46, Some(all.clone())),
                (47, Some(all)),
                (54, Some(vec![model.vr("omega_m")])),
                (55, at_rest("tau_m")),
                (56, Some(vec![model.vr("omega_L")])),
                (57, at_rest("tau_L")),
            ],
            "{id}"
        );
        let names = [
            "u_minus_g",
            "u_plus_g",
            "force_upper",
            "force_lower",
            "cap_upper",
            "cap_lower",
            "stop_m",
            "breakaway_m",
            "stop_L",
            "breakaway_L",
        ];
        for ((vr, _), name) in found.iter().zip(names) {
            assert_eq!(model.by_vr(*vr).unwrap().name, name);
        }
    }
}
