//! `documentation/index.html` of each archive: a shared page (`template.html`, its style sheet
//! `style.css` inlined where it says `{{STYLE}}`, as in a page of a model's own) with the model's
//! drive-train section (where it says `{{BELT_DRIVE}}`, the belt drive's generic form of
//! `belt_drive.html`) and a variable table taken from the generated model description, so that
//! the documented names, units and start values cannot drift from the ones the FMU serves.
//!
//! One template serves both standards; the description's `fmiVersion` says which page it is:
//! `{{FMI_VERSION}}` becomes `2.0` or `3.0`, `{{fmi}}` the function prefix `fmi2` or `fmi3`, and
//! the text between `{{#fmi2}}` and `{{/fmi2}}` (likewise `fmi3`) appears on that standard's page
//! only.

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
    // A controller's page is its own (`<id>/page.html`); a plant's is the shared page with its
    // drive train, where the belt drive's generic form is shared by BacklashBelt and BacklashWeb.
    let own_page = dir.join(id).join("page.html");
    let (template, drive_train) = if own_page.is_file() {
        (read(own_page)?, String::new())
    } else {
        let drive_train =
            read(dir.join(id).join("drive_train.html"))?.replace("{{BELT_DRIVE}}", &read(dir.join("belt_drive.html"))?);
        (read(dir.join("template.html"))?, drive_train)
    };

    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("{id}: model description is not XML: {e}"))?;
    let root = doc.root_element();
    if !root.has_tag_name("fmiModelDescription") {
        return Err(format!("{id}: no <fmiModelDescription> element"));
    }
    let (version, prefix, other) = match root.attribute("fmiVersion") {
        Some("2.0") => ("2.0", "fmi2", "fmi3"),
        Some("3.0") => ("3.0", "fmi3", "fmi2"),
        other => return Err(format!("{id}: no page for fmiVersion {other:?}")),
    };
    let description = escape(root.attribute("description").unwrap_or_default());
    let table = variable_table(&doc)?;

    let template = sections(&template, prefix, other).map_err(|e| format!("{id}: template.html: {e}"))?;
    let page = template
        .replace("{{STYLE}}", &read(dir.join("style.css"))?)
        .replace("{{FMI_VERSION}}", version)
        .replace("{{fmi}}", prefix)
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

/// `text` with the sections of the standard `keep` (`{{#keep}}...{{/keep}}`) in place, without
/// their markers, and those of `drop` removed with their content.
fn sections(text: &str, keep: &str, drop: &str) -> Result<String, String> {
    let mut text = text.to_string();
    for (tag, kept) in [(keep, true), (drop, false)] {
        let (open, close) = (format!("{{{{#{tag}}}}}"), format!("{{{{/{tag}}}}}"));
        while let Some(start) = text.find(&open) {
            let end = text[start..]
                .find(&close)
                .map(|e| start + e)
                .ok_or_else(|| format!("{open} without {close}"))?;
            let inner = &text[start + open.len()..end];
            if inner.contains(&open) {
                return Err(format!("{open} inside {open}"));
            }
            let replacement = if kept { inner.to_string() } else { String::new() };
            text.replace_range(start..end + close.len(), &replacement);
        }
        if text.contains(&close) {
            return Err(format!("{close} without {open}"));
        }
    }
    Ok(text)
}

/// The variable table: one row per variable, with the unit, start and bounds of its type
/// element. FMI 2.0 writes a `<ScalarVariable>` around the type element (`<Real>`,
/// `<Integer>`, ...); in FMI 3.0 the variable is its type element (`<Float64>`, `<Int32>`, ...).
fn variable_table(doc: &roxmltree::Document) -> Result<String, String> {
    let variables = doc
        .descendants()
        .find(|n| n.has_tag_name("ModelVariables"))
        .ok_or("model description has no <ModelVariables>")?;
    let mut rows = String::new();
    let mut count = 0;
    for variable in variables.children().filter(|n| n.is_element()) {
        let typed = if variable.has_tag_name("ScalarVariable") {
            variable.children().find(|n| n.is_element())
        } else {
            Some(variable)
        };
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
        return Err("model description lists no variable".into());
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

    #[test]
    fn fmi3_variables_are_their_type_elements() {
        let xml = r#"<fmiModelDescription fmiVersion="3.0"><ModelVariables>
            <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
            <Float64 name="J_m" valueReference="12" causality="parameter" variability="fixed" unit="kg.m2" start="2.28" min="0.0"/>
            <Int32 name="contact" valueReference="8" causality="output" variability="discrete" min="-1" max="1"/>
            </ModelVariables></fmiModelDescription>"#;
        let table = variable_table(&roxmltree::Document::parse(xml).unwrap()).unwrap();
        assert_eq!(table.matches("<tr><td>").count(), 3);
        assert!(table.contains("<td><code>time</code></td><td>independent</td><td>continuous</td><td>Float64</td>"));
        assert!(table.contains("<td><code>J_m</code></td><td>parameter</td><td>fixed</td><td>Float64</td><td>kg.m2</td><td>2.28</td><td>[0.0, ∞]</td>"));
        assert!(table.contains("<td>Int32</td><td></td><td></td><td>[-1, 1]</td>"));
    }

    #[test]
    fn sections_keep_one_standard_and_drop_the_other() {
        let text = "a{{#fmi2}}b{{/fmi2}}{{#fmi3}}c{{/fmi3}}d{{#fmi2}}e{{/fmi2}}";
        assert_eq!(sections(text, "fmi2", "fmi3").unwrap(), "abde");
        assert_eq!(sections(text, "fmi3", "fmi2").unwrap(), "acd");
        assert!(sections("a{{#fmi2}}b", "fmi2", "fmi3").is_err());
        assert!(sections("a{{/fmi3}}b", "fmi2", "fmi3").is_err());
    }
}
