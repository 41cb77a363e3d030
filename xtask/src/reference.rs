//! `cargo xtask docs`: docs/fmu-reference.md, the reference of every FMU, written from the
//! model descriptions that `cargo xtask fmu` packs (the FMI 2.0 and FMI 3.0 `modelDescription.xml`
//! of each model, generated from the interface description in modelDescription/src/models/).
//!
//! Nothing on the page is typed by hand: the models and their order are the description's lists
//! (the plants, then the controllers), and every name, value reference, causality, unit, start
//! value and range is read from the XML an importer reads. A variable the two standards describe
//! differently (another causality, variability, unit or start) stops the generator. A test of
//! this crate compares the committed page with a fresh rendering, so the page cannot drift from
//! the archives.

use std::collections::BTreeMap;
use std::fs;
use std::path::PathBuf;

use crate::fmu::{FMI2, FMI3};
use crate::util::{self, step};

const USAGE: &str = "usage: cargo xtask docs [--check]";

/// The page, relative to the repository root.
pub const PAGE: &str = "docs/fmu-reference.md";

fn page_path() -> PathBuf {
    util::repo_root().join(PAGE)
}

/// `cargo xtask docs`: writes the page; `--check`: fails if the committed page differs.
pub fn run(args: &[String]) -> Result<(), String> {
    let check = match args {
        [] => false,
        [flag] if flag == "--check" => true,
        [other, ..] => return Err(format!("unexpected argument `{other}`\n{USAGE}")),
    };
    let page = render()?;
    let path = page_path();
    if check {
        step(&format!("{PAGE} against the model descriptions"));
        let committed = fs::read_to_string(&path).map_err(|e| format!("reading {PAGE}: {e}"))?;
        if committed != page {
            return Err(format!(
                "{PAGE} differs from the model descriptions: run `cargo xtask docs`"
            ));
        }
        println!("{PAGE} is up to date");
        return Ok(());
    }
    step(&format!("{PAGE} from the model descriptions"));
    fs::write(&path, page).map_err(|e| format!("writing {PAGE}: {e}"))?;
    println!("wrote {PAGE}");
    Ok(())
}

/// One variable as a description states it.
#[derive(Clone, Default, PartialEq)]
struct Var {
    name: String,
    vr: String,
    causality: String,
    variability: String,
    initial: String,
    ty: String,
    unit: String,
    start: String,
    min: String,
    max: String,
    description: String,
}

/// What the reference reads from one model description.
struct Description {
    description: String,
    model_exchange: bool,
    co_simulation: bool,
    experiment: (String, String, String),
    event_indicators: usize,
    variables: Vec<Var>,
    units: Vec<(String, Vec<(String, String)>)>,
    log_categories: Vec<String>,
}

fn read(id: &str, xml: &str) -> Result<Description, String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("{id}: model description is not XML: {e}"))?;
    let root = doc.root_element();
    let fmi3 = root.attribute("fmiVersion") == Some("3.0");
    let attr = |n: roxmltree::Node, k: &str| n.attribute(k).unwrap_or("").to_string();
    let child = |name: &str| root.children().find(|n| n.has_tag_name(name));
    let experiment = child("DefaultExperiment").ok_or_else(|| format!("{id}: no <DefaultExperiment>"))?;
    let variables_node = child("ModelVariables").ok_or_else(|| format!("{id}: no <ModelVariables>"))?;
    let mut variables = Vec::new();
    for v in variables_node.children().filter(|n| n.is_element()) {
        let typed = if fmi3 {
            v
        } else {
            v.children()
                .find(|n| n.is_element())
                .ok_or_else(|| format!("{id}: a ScalarVariable without its type"))?
        };
        variables.push(Var {
            name: attr(v, "name"),
            vr: attr(v, "valueReference"),
            causality: attr(v, "causality"),
            variability: attr(v, "variability"),
            initial: attr(v, "initial"),
            ty: typed.tag_name().name().to_string(),
            unit: attr(typed, "unit"),
            start: attr(typed, "start"),
            min: attr(typed, "min"),
            max: attr(typed, "max"),
            description: attr(v, "description"),
        });
    }
    let units = child("UnitDefinitions")
        .map(|u| {
            u.children()
                .filter(|n| n.has_tag_name("Unit"))
                .map(|unit| {
                    let display = unit
                        .children()
                        .filter(|n| n.has_tag_name("DisplayUnit"))
                        .map(|d| (attr(d, "name"), attr(d, "factor")))
                        .collect();
                    (attr(unit, "name"), display)
                })
                .collect()
        })
        .unwrap_or_default();
    let log_categories = child("LogCategories")
        .map(|c| {
            c.children()
                .filter(|n| n.has_tag_name("Category"))
                .map(|n| attr(n, "name"))
                .collect()
        })
        .unwrap_or_default();
    let event_indicators = if fmi3 {
        child("ModelStructure").map_or(0, |s| s.children().filter(|n| n.has_tag_name("EventIndicator")).count())
    } else {
        root.attribute("numberOfEventIndicators")
            .unwrap_or("0")
            .parse()
            .unwrap_or(0)
    };
    Ok(Description {
        description: attr(root, "description"),
        model_exchange: child("ModelExchange").is_some(),
        co_simulation: child("CoSimulation").is_some(),
        experiment: (
            attr(experiment, "startTime"),
            attr(experiment, "stopTime"),
            attr(experiment, "stepSize"),
        ),
        event_indicators,
        variables,
        units,
        log_categories,
    })
}

/// Markdown-safe text for a table cell or a paragraph.
fn text(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '|' => out.push_str("\\|"),
            '*' => out.push_str("\\*"),
            '_' => out.push_str("\\_"),
            '\\' => out.push_str("\\\\"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '`' => out.push_str("\\`"),
            _ => out.push(c),
        }
    }
    out
}

fn code(s: &str) -> String {
    if s.is_empty() {
        String::new()
    } else {
        format!("`{s}`")
    }
}

fn interfaces(d: &Description) -> String {
    match (d.model_exchange, d.co_simulation) {
        (true, true) => "Model Exchange, Co-Simulation".into(),
        (true, false) => "Model Exchange".into(),
        (false, true) => "Co-Simulation".into(),
        (false, false) => "none".into(),
    }
}

fn range(v: &Var) -> String {
    match (v.min.as_str(), v.max.as_str()) {
        ("", "") => String::new(),
        (min, max) => format!(
            "[{}, {}]",
            if min.is_empty() { "−∞" } else { min },
            if max.is_empty() { "∞" } else { max }
        ),
    }
}

/// The page: every model of the description, its archives, capabilities, default experiment and
/// variables (FMI 2.0 and FMI 3.0 side by side), then the units.
pub fn render() -> Result<String, String> {
    let plants = model_description::model_identifiers();
    let controllers = model_description::controller_identifiers();
    let mut described = Vec::new();
    for &id in plants.iter().chain(controllers) {
        let two = read(id, &(FMI2.description)(id))?;
        let three = read(id, &(FMI3.description)(id))?;
        described.push((id, plants.contains(&id), two, three));
    }

    let mut page = String::new();
    page.push_str(
        "# FMU reference\n\n\
         <!-- Generated by `cargo xtask docs` from the model descriptions; do not edit by hand.\n     \
         `cargo test -p xtask` fails when this page differs from a fresh rendering. -->\n\n\
         Every archive that `cargo xtask fmu` writes (FMI 2.0 in `target/fmu/`, FMI 3.0 in\n\
         `target/fmu/fmi3/`) and that the package `backlash_fmu` ships (`backlash_fmu.fmu_path(model, fmi)`),\n\
         as its `modelDescription.xml` states it. The page is generated from those descriptions\n\
         (`cargo xtask docs`), which are themselves generated from the interface description in\n\
         [modelDescription/src/models/](../modelDescription/src/models/). What each variable means\n\
         precisely, and what the FMUs refuse, is in [model.md §4](model.md#4-interface-of-the-fmus);\n\
         the controller's law and sampling in [model.md §9](model.md#9-the-controller-and-the-systems).\n\n\
         ## Archives\n\n\
         | model | kind | FMI 2.0 archive | FMI 3.0 archive | interfaces | event indicators (2.0 / 3.0) |\n\
         |---|---|---|---|---|---|\n",
    );
    for (id, plant, two, three) in &described {
        if interfaces(two) != interfaces(three) {
            return Err(format!(
                "{id}: FMI 2.0 offers {}, FMI 3.0 {}",
                interfaces(two),
                interfaces(three)
            ));
        }
        page.push_str(&format!(
            "| [`{id}`](#{anchor}) | {kind} | `{id}.fmu` | `fmi3/{id}.fmu` | {interfaces} | {e2} / {e3} |\n",
            anchor = id.to_lowercase(),
            kind = if *plant { "plant" } else { "controller" },
            interfaces = interfaces(two),
            e2 = two.event_indicators,
            e3 = three.event_indicators,
        ));
    }

    for (id, _, two, three) in &described {
        page.push_str(&format!("\n## {id}\n\n{}\n\n", text(&two.description)));
        let (start, stop, step) = &two.experiment;
        page.push_str(&format!(
            "Default experiment: start {start} s, stop {stop} s, step {step} s. Interfaces: {}. \
             Log categories: {}.\n\n",
            interfaces(two),
            two.log_categories
                .iter()
                .map(|c| code(c))
                .collect::<Vec<_>>()
                .join(", "),
        ));
        page.push_str(
            "| name | value reference | causality | variability | initial | type (FMI 2.0 / 3.0) | unit | start | range | description |\n\
             |---|---|---|---|---|---|---|---|---|---|\n",
        );
        // FMI 3.0's order (it adds `time` and the event indicators' variables); the FMI 2.0
        // type beside each, or – where FMI 2.0 has no such variable.
        let by_name: BTreeMap<&str, &Var> = two.variables.iter().map(|v| (v.name.as_str(), v)).collect();
        for v in &two.variables {
            if !three.variables.iter().any(|w| w.name == v.name) {
                return Err(format!("{id}: `{}` is in the FMI 2.0 description only", v.name));
            }
        }
        for v in &three.variables {
            let ty2 = match by_name.get(v.name.as_str()) {
                Some(w) => {
                    let same = |a: &str, b: &str| a == b;
                    if !(same(&w.causality, &v.causality)
                        && same(&w.variability, &v.variability)
                        && same(&w.unit, &v.unit)
                        && same(&w.vr, &v.vr)
                        && same(&w.start, &v.start))
                    {
                        return Err(format!(
                            "{id}: `{}` differs between its FMI 2.0 and FMI 3.0 descriptions",
                            v.name
                        ));
                    }
                    w.ty.clone()
                }
                None => "–".into(),
            };
            page.push_str(&format!(
                "| `{}` | {} | {} | {} | {} | {} / {} | {} | {} | {} | {} |\n",
                v.name,
                v.vr,
                v.causality,
                v.variability,
                v.initial,
                ty2,
                v.ty,
                text(&v.unit),
                v.start,
                range(v),
                text(&v.description),
            ));
        }
    }

    // Every unit any model uses, once, with its display units.
    let mut units: BTreeMap<String, Vec<(String, String)>> = BTreeMap::new();
    for (_, _, two, three) in &described {
        for (name, display) in two.units.iter().chain(&three.units) {
            units.entry(name.clone()).or_insert_with(|| display.clone());
        }
    }
    page.push_str("\n## Units\n\n| unit | display units (display value = factor · value) |\n|---|---|\n");
    for (name, display) in &units {
        let shown: Vec<String> = display.iter().map(|(n, f)| format!("`{n}` (factor {f})")).collect();
        page.push_str(&format!("| `{name}` | {} |\n", shown.join(", ")));
    }
    Ok(page)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn committed_reference_is_the_generated_one() {
        let committed =
            fs::read_to_string(page_path()).expect("docs/fmu-reference.md (write it with `cargo xtask docs`)");
        let generated = render().unwrap();
        assert!(
            committed == generated,
            "docs/fmu-reference.md differs from the model descriptions: run `cargo xtask docs`"
        );
    }

    #[test]
    fn every_model_and_variable_of_the_description_is_on_the_page() {
        let page = render().unwrap();
        for &id in model_description::model_identifiers()
            .iter()
            .chain(model_description::controller_identifiers())
        {
            assert!(page.contains(&format!("\n## {id}\n")), "{id} has no section");
            for v in &model_description::model(id).variables {
                assert!(
                    page.contains(&format!("| `{}` | {} |", v.name, v.vr)),
                    "{id}: {} missing",
                    v.name
                );
            }
        }
    }

    #[test]
    fn cells_escape_markdown() {
        assert_eq!(text("|a*b| < c_d"), "\\|a\\*b\\| &lt; c\\_d");
    }
}
