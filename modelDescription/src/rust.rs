//! Rust source of the library's tables, written by `build.rs` into `OUT_DIR` and included by
//! `src/fmu/variables.rs` and `src/fmu/logging.rs`: the `Symbol` enum (one variant per distinct
//! variable of all models) with where each variable's value comes from, the input lines, the
//! `MODELS` table, and the `LogCategory` enum.

use std::fmt::Write as _;

use crate::models::{parameters, physics_of};
use crate::{
    controller_identifiers, model, model_identifiers, xml, xml3, Causality, Kind, Model, Type, Var, LOG_CATEGORIES,
};

/// Every plant's description, in [`model_identifiers`] order.
fn models() -> Vec<Model> {
    model_identifiers().iter().map(|id| model(id)).collect()
}

/// Every controller's description, in [`controller_identifiers`] order.
fn controllers() -> Vec<Model> {
    controller_identifiers().iter().map(|id| model(id)).collect()
}

/// The distinct symbols of all models, in order of first appearance, with the variable name of
/// their first appearance.
fn symbols(models: &[&Model]) -> Vec<(&'static str, &'static str)> {
    let mut found: Vec<(&'static str, &'static str)> = Vec::new();
    for v in models.iter().flat_map(|m| &m.variables) {
        match found.iter().find(|(symbol, _)| *symbol == v.symbol) {
            Some((_, name)) => assert_eq!(*name, v.name, "symbol {} names two variables", v.symbol),
            None => found.push((v.symbol, v.name)),
        }
    }
    found
}

/// The symbols of the plants' inputs, by slot: each model's inputs in value-reference order fill the
/// slots from 0, and a symbol takes the same slot in every model.
fn input_lines(models: &[Model]) -> Vec<&'static str> {
    let mut lines: Vec<&'static str> = Vec::new();
    for m in models {
        let mut inputs: Vec<&Var> = m.variables.iter().filter(|v| v.causality == Causality::Input).collect();
        inputs.sort_by_key(|v| v.vr);
        for (slot, v) in inputs.iter().enumerate() {
            match lines.get(slot) {
                Some(s) => assert_eq!(
                    *s, v.symbol,
                    "{}: input {} takes another model's slot {slot}",
                    m.identifier, v.name
                ),
                None => lines.push(v.symbol),
            }
        }
    }
    lines
}

/// Each symbol's source, as the library's `Source` in Rust: a parameter (Real or Integer, as
/// `contact_law`) is stored; an input stored in its slot; a continuous state is the plant
/// state's entry of its symbol (and its derivative that entry's rate); the other Integer
/// outputs, `contact` (docs/model.md §4), the sign of ψ in the mode in force, and `sliding_m`,
/// `sliding_L` (§12), each body's friction mode;
/// every other variable is calculated from the physics, by the `Calculated` of its symbol, or a
/// gearbox's own by its `GearQuantity` (a new one without such a variant does not compile). A controller's inputs are stored and sampled,
/// its output is the command it holds.
fn sources(models: &[Model], controllers: &[Model]) -> Vec<(&'static str, String)> {
    let lines = input_lines(models);
    // The symbols of the single-gap plants: a gearbox's other calculated symbols are its own
    // (`Calculated::Gear`).
    let single_gap: Vec<&str> = models
        .iter()
        .filter(|m| matches!(m.kind, Kind::Plant(_)))
        .flat_map(|m| m.variables.iter().map(|v| v.symbol))
        .collect();
    let mut out: Vec<(&'static str, String)> = Vec::new();
    for m in models.iter().chain(controllers) {
        for v in &m.variables {
            let controller = matches!(m.kind, Kind::Controller);
            let source = if v.causality == Causality::Parameter {
                "Source::Parameter".to_string()
            } else if controller && v.causality == Causality::Input {
                "Source::Sampled".to_string()
            } else if controller && v.causality == Causality::Output {
                "Source::Command".to_string()
            } else if controller {
                panic!("{}: {} is neither input, output nor parameter", m.identifier, v.name)
            } else if v.causality == Causality::Input {
                let slot = lines
                    .iter()
                    .position(|s| *s == v.symbol)
                    .expect("every input has a slot");
                format!("Source::Input({slot})")
            } else if v.is_continuous_state() {
                format!("Source::State(StateEntry::{})", v.symbol)
            } else if let Some(of) = v.derivative_of {
                let state = m.variables.iter().find(|w| w.vr == of).expect("a derivative's state");
                format!("Source::Derivative(StateEntry::{})", state.symbol)
            } else if v.ty == Type::Integer {
                match v.name {
                    "contact" => "Source::Contact".to_string(),
                    "contact_1" => "Source::StageContact(0)".to_string(),
                    "contact_2" => "Source::StageContact(1)".to_string(),
                    "sliding_m" => "Source::Sliding(0)".to_string(),
                    "sliding_L" => "Source::Sliding(1)".to_string(),
                    "sliding_i" => "Source::Sliding(2)".to_string(),
                    other => panic!("{}: Integer output {other} has no source", m.identifier),
                }
            } else if matches!(m.kind, Kind::TwoStage(_)) && !single_gap.contains(&v.symbol) {
                format!("Source::Calculated(Calculated::Gear(GearQuantity::{}))", v.symbol)
            } else {
                format!("Source::Calculated(Calculated::{})", v.symbol)
            };
            match out.iter().find(|(s, _)| *s == v.symbol) {
                Some((_, known)) => assert_eq!(*known, source, "symbol {} has two sources", v.symbol),
                None => out.push((v.symbol, source)),
            }
        }
    }
    out
}

/// `Symbol`, its count, and `MODELS` (types `ModelInfo`, `Variable`, ... are the includer's).
pub fn variable_tables() -> String {
    let models = models();
    let controllers = controllers();
    let all: Vec<&Model> = models.iter().chain(&controllers).collect();
    let symbols = symbols(&all);
    let mut out = String::new();
    out.push_str("// Generated by the model-description crate (modelDescription/); do not edit.\n\n");
    out.push_str("/// What a variable is, independent of its value reference: one variant per distinct\n");
    out.push_str("/// variable of all models. The model adapter (`crate::fmu::adapter`) maps each to the physics.\n");
    out.push_str("#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]\npub enum Symbol {\n");
    for (symbol, name) in &symbols {
        let _ = writeln!(out, "    /// `{name}`\n    {symbol},");
    }
    out.push_str("}\n\nimpl Symbol {\n");
    out.push_str("    /// Number of symbols: the size of an instance's value store.\n");
    let _ = writeln!(out, "    pub const COUNT: usize = {};\n", symbols.len());
    out.push_str("    /// The symbol's slot in an instance's value store.\n");
    out.push_str("    pub fn index(self) -> usize {\n        self as usize\n    }\n\n");
    out.push_str("    /// Where the variable's value comes from (`crate::fmu::adapter::Source`).\n");
    out.push_str("    #[inline(always)]\n    pub const fn source(self) -> Source {\n        match self {\n");
    for (symbol, source) in sources(&models, &controllers) {
        let _ = writeln!(out, "            Symbol::{symbol} => {source},");
    }
    out.push_str("        }\n    }\n}\n\n");
    let lines = input_lines(&models);
    out.push_str("/// The input lines of every model, by slot (`Source::Input`).\n");
    let _ = writeln!(out, "pub const INPUT_SYMBOLS: [Symbol; {}] = [", lines.len());
    for symbol in lines {
        let _ = writeln!(out, "    Symbol::{symbol},");
    }
    out.push_str("];\n\n");

    out.push_str("/// Every plant this library serves, in `model_identifiers()` order.\n");
    let _ = writeln!(out, "pub static MODELS: [ModelInfo; {}] = [", models.len());
    for (i, m) in models.iter().enumerate() {
        let kind = format!("model_description::MODELS[{i}].kind");
        write_model_info(&mut out, m, &kind, physics_of(m, &parameters(m)).web().is_some());
    }
    out.push_str("];\n\n");
    out.push_str("/// Every controller this library serves, in `controller_identifiers()` order.\n");
    let _ = writeln!(out, "pub static CONTROLLERS: [ModelInfo; {}] = [", controllers.len());
    for m in &controllers {
        write_model_info(&mut out, m, "Kind::Controller", false);
    }
    out.push_str("];\n");
    out
}

/// One `ModelInfo` of `m`, whose kind is the Rust expression `kind`; `web`: its plant pulls a web
/// span.
fn write_model_info(out: &mut String, m: &Model, kind: &str, web: bool) {
    let _ = writeln!(out, "    ModelInfo {{");
    let _ = writeln!(out, "        identifier: {:?},", m.identifier);
    let _ = writeln!(out, "        guid: {:?},", xml::guid(m.identifier));
    let _ = writeln!(
        out,
        "        instantiation_token: {:?},",
        xml3::instantiation_token(m.identifier)
    );
    let _ = writeln!(out, "        kind: {kind},");
    let _ = writeln!(out, "        web: {web:?},");
    let count = |keep: fn(&crate::Var) -> bool| m.variables.iter().filter(|v| keep(v)).count();
    let _ = writeln!(out, "        states: {},", count(crate::Var::is_continuous_state));
    let _ = writeln!(
        out,
        "        inputs: {},",
        count(|v| v.causality == crate::Causality::Input)
    );
    let e = m.default_experiment;
    let _ = writeln!(
        out,
        "        default_experiment: DefaultExperiment {{ start_time: {:?}, stop_time: {:?}, step_size: {:?} }},",
        e.start_time, e.stop_time, e.step_size
    );
    let _ = writeln!(out, "        variables: &[");
    for v in &m.variables {
        let start = match v.start {
            Some(s) => format!("Some({s:?})"),
            None => "None".to_string(),
        };
        let nominal = match v.nominal {
            Some(x) => format!("Some({x:?})"),
            None => "None".to_string(),
        };
        let _ = writeln!(
            out,
            "            Variable {{ name: {:?}, symbol: Symbol::{}, vr: {}, ty: VarType::{:?}, causality: Causality::{:?}, variability: Variability::{:?}, initial: Initial::{:?}, start: {}, range: Range::{:?}, unit: {:?}, quantity: {:?}, description: {:?}, nominal: {}, derivative_of: {:?} }},",
            v.name, v.symbol, v.vr, v.ty, v.causality, v.variability, v.initial, start, v.range, v.unit, v.quantity, v.description, nominal, v.derivative_of
        );
    }
    let _ = writeln!(out, "        ],");
    let _ = writeln!(out, "    }},");
}

/// The `LogCategory` enum with its names, in the order of the description.
pub fn log_categories() -> String {
    let mut out = String::new();
    out.push_str("// Generated by the model-description crate (modelDescription/); do not edit.\n\n");
    out.push_str("/// The log categories of the model description (`<LogCategories>`).\n");
    out.push_str("#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]\npub enum LogCategory {\n");
    for c in LOG_CATEGORIES {
        let _ = writeln!(out, "    /// `{}`: {}\n    {},", c.name, c.description, c.variant);
    }
    out.push_str("}\n\nimpl LogCategory {\n    /// Every category, in the order of the description.\n");
    let _ = writeln!(out, "    pub const ALL: [LogCategory; {}] = [", LOG_CATEGORIES.len());
    for c in LOG_CATEGORIES {
        let _ = writeln!(out, "        LogCategory::{},", c.variant);
    }
    out.push_str("    ];\n\n    /// The category's name in the description and in fmi2SetDebugLogging.\n");
    out.push_str("    pub fn name(self) -> &'static str {\n        match self {\n");
    for c in LOG_CATEGORIES {
        let _ = writeln!(out, "            LogCategory::{} => {:?},", c.variant, c.name);
    }
    out.push_str("        }\n    }\n}\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_symbol_appears_once_and_keeps_its_name_across_models() {
        let (models, controllers) = (models(), controllers());
        let symbols = symbols(&models.iter().chain(&controllers).collect::<Vec<_>>());
        for (i, (s, _)) in symbols.iter().enumerate() {
            assert!(symbols[i + 1..].iter().all(|(t, _)| t != s));
        }
        assert_eq!(symbols.first(), Some(&("TauM", "tau_m")));
        assert!(variable_tables().contains(&format!("pub const COUNT: usize = {};", symbols.len())));
    }

    #[test]
    fn log_categories_are_generated_in_description_order() {
        let text = log_categories();
        let at = |name: &str| text.find(&format!("LogCategory::{name},")).unwrap();
        assert!(at("ContactEvents") < at("Warnings") && at("Errors") < at("Calls"));
        assert!(text.contains("LogCategory::Calls => \"logCalls\","));
    }
}
