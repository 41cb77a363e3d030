//! `documentation/index.html` of each archive: a shared page (`template.html`) with the model's
//! drive-train section and a variable table taken from the generated model description, so that
//! the documented names, units and start values cannot drift from the ones the FMU serves.

use std::fs;
use std::path::PathBuf;

use model_description::xml::escape;

use crate::util;

fn source_dir() -> PathBuf {
    util::repo_root().join("modelDescription").join("documentation")
}

/// The page for model `id`, whose model description is `xml`.
pub fn render(id: &str, xml: &str) -> Result<String, String> {
    let dir = source_dir();
    let read = |path: PathBuf| fs::read_to_string(&path).map_err(|e| format!("reading {}: {e}", util::shown(&path)));
    let template = read(dir.join("template.html"))?;
    let drive_train = read(dir.join(id).join("drive_train.html"))?;

    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("{id}: model description is not XML: {e}"))?;
    let root = doc.root_element();
    if !root.has_tag_name("fmiModelDescription") {
        return Err(format!("{id}: no <fmiModelDescription> element"));
    }
    let description = escape(root.attribute("description").unwrap_or_default());
    let table = variable_table(&doc)?;

    let page = template
        .replace("{{MODEL}}", id)
        .replace("{{DESCRIPTION}}", &description)
        .replace("{{DRIVE_TRAIN}}", &drive_train)
        .replace("{{VARIABLES}}", &table);
    if let Some(at) = page.find("{{") {
        let end = page[at..].find("}}").map_or(page.len(), |e| at + e + 2);
        return Err(format!("{id}: unknown placeholder {} in template.html", &page[at..end]));
    }
    Ok(page)
}

/// The variable table: one row per `<ScalarVariable>`, with the unit, start and bounds of its
/// type element (`<Real>`, `<Integer>`, ...).
fn variable_table(doc: &roxmltree::Document) -> Result<String, String> {
    let variables = doc
        .descendants()
        .find(|n| n.has_tag_name("ModelVariables"))
        .ok_or("model description has no <ModelVariables>")?;
    let mut rows = String::new();
    let mut count = 0;
    for variable in variables.children().filter(|n| n.has_tag_name("ScalarVariable")) {
        let typed = variable.children().find(|n| n.is_element());
        let kind = typed.map_or("?", |t| t.tag_name().name());
        let get = |node: Option<roxmltree::Node>, k: &str| escape(node.and_then(|n| n.attribute(k)).unwrap_or(""));
        let range = match (
            typed.and_then(|t| t.attribute("min")),
            typed.and_then(|t| t.attribute("max")),
        ) {
            (None, None) => String::new(),
            (min, max) => format!("[{}, {}]", min.unwrap_or("−∞"), max.unwrap_or("∞")),
        };
        rows.push_str(&format!(
            "      <tr><td><code>{}</code></td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
            get(Some(variable), "name"),
            get(Some(variable), "causality"),
            get(Some(variable), "variability"),
            kind,
            get(typed, "unit"),
            get(typed, "start"),
            range,
            get(Some(variable), "description"),
        ));
        count += 1;
    }
    if count == 0 {
        return Err("model description lists no <ScalarVariable>".into());
    }
    Ok(format!(
        "<table>\n    <thead><tr><th>name</th><th>causality</th><th>variability</th><th>type</th><th>unit</th>\
         <th>start</th><th>range</th><th>description</th></tr></thead>\n    <tbody>\n{rows}    </tbody>\n  </table>"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_has_one_row_per_variable_with_its_type_attributes() {
        let xml = r#"<fmiModelDescription><ModelVariables>
            <ScalarVariable name="J_m" valueReference="0" causality="parameter" variability="fixed" description="J &gt; 0 &amp; finite">
              <Real unit="kg.m2" start="2.28" min="0"/></ScalarVariable>
            <ScalarVariable name="contact" valueReference="1" causality="output"><Integer/></ScalarVariable>
            </ModelVariables><RealType name="x"/></fmiModelDescription>"#;
        let table = variable_table(&roxmltree::Document::parse(xml).unwrap()).unwrap();
        assert_eq!(table.matches("<tr><td>").count(), 2);
        assert!(table.contains("<td><code>J_m</code></td><td>parameter</td><td>fixed</td><td>Real</td><td>kg.m2</td><td>2.28</td><td>[0, ∞]</td><td>J &gt; 0 &amp; finite</td>"));
        assert!(table.contains("<td><code>contact</code></td><td>output</td><td></td><td>Integer</td>"));
    }
}
