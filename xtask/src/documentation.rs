//! `documentation/index.html` of each archive: a shared page (`template.html`) with the model's
//! drive-train section and a variable table taken from the generated model description, so that
//! the documented names, units and start values cannot drift from the ones the FMU serves.

use std::fs;
use std::path::PathBuf;

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

    let root = opening_tags(xml, "fmiModelDescription")
        .into_iter()
        .next()
        .ok_or_else(|| format!("{id}: no <fmiModelDescription> element"))?;
    let description = attribute(&root, "description").unwrap_or_default();
    let table = variable_table(xml)?;

    let page = template
        .replace("{{MODEL}}", id)
        .replace("{{DESCRIPTION}}", description)
        .replace("{{DRIVE_TRAIN}}", &drive_train)
        .replace("{{VARIABLES}}", &table);
    if let Some(at) = page.find("{{") {
        let end = page[at..].find("}}").map_or(page.len(), |e| at + e + 2);
        return Err(format!("{id}: unknown placeholder {} in template.html", &page[at..end]));
    }
    Ok(page)
}

/// One `<tag ...>` opening: its attributes as they appear (values still XML-escaped, which is
/// also valid HTML text).
type Attributes = Vec<(String, String)>;

fn attribute<'a>(attributes: &'a Attributes, name: &str) -> Option<&'a str> {
    attributes.iter().find(|(k, _)| k == name).map(|(_, v)| v.as_str())
}

/// Attributes of every opening tag named `tag`, in document order. Quote-aware, so a `>` inside
/// a description does not end the tag.
fn opening_tags(xml: &str, tag: &str) -> Vec<Attributes> {
    let pattern = format!("<{tag}");
    let mut found = Vec::new();
    let mut rest = xml;
    while let Some(at) = rest.find(&pattern) {
        let after = &rest[at + pattern.len()..];
        // `<Real` must not match `<RealType`.
        if !after.starts_with(|c: char| c.is_whitespace() || c == '>' || c == '/') {
            rest = after;
            continue;
        }
        let (attributes, consumed) = parse_attributes(after);
        found.push(attributes);
        rest = &after[consumed..];
    }
    found
}

fn parse_attributes(text: &str) -> (Attributes, usize) {
    let bytes = text.as_bytes();
    let mut attributes = Vec::new();
    let mut i = 0;
    loop {
        while i < bytes.len() && bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        if i >= bytes.len() || bytes[i] == b'>' || bytes[i] == b'/' {
            return (attributes, i);
        }
        let name_start = i;
        while i < bytes.len() && bytes[i] != b'=' && !bytes[i].is_ascii_whitespace() && bytes[i] != b'>' {
            i += 1;
        }
        let name = text[name_start..i].to_string();
        while i < bytes.len() && (bytes[i] == b'=' || bytes[i].is_ascii_whitespace()) {
            i += 1;
        }
        if i >= bytes.len() || !(bytes[i] == b'"' || bytes[i] == b'\'') {
            return (attributes, i);
        }
        let quote = bytes[i];
        let value_start = i + 1;
        let value_end = text[value_start..]
            .find(quote as char)
            .map_or(text.len(), |e| value_start + e);
        attributes.push((name, text[value_start..value_end].to_string()));
        i = value_end + 1;
    }
}

/// The variable table: one row per `<ScalarVariable>`, with the unit, start and bounds of its
/// type element (`<Real>`, `<Integer>`, ...).
fn variable_table(xml: &str) -> Result<String, String> {
    let start = xml
        .find("<ModelVariables")
        .ok_or("model description has no <ModelVariables>")?;
    let end = xml[start..].find("</ModelVariables>").map_or(xml.len(), |e| start + e);
    let section = &xml[start..end];

    let mut rows = String::new();
    let mut count = 0;
    let mut pieces = section.split("<ScalarVariable").skip(1);
    for piece in &mut pieces {
        if !piece.starts_with(|c: char| c.is_whitespace()) {
            continue;
        }
        let (variable, consumed) = parse_attributes(piece);
        let body = &piece[consumed..];
        let (kind, typed) = ["Real", "Integer", "Boolean", "String", "Enumeration"]
            .iter()
            .find_map(|kind| opening_tags(body, kind).into_iter().next().map(|a| (*kind, a)))
            .unwrap_or(("?", Vec::new()));
        let get = |a: &Attributes, k: &str| attribute(a, k).unwrap_or("").to_string();
        let range = match (attribute(&typed, "min"), attribute(&typed, "max")) {
            (None, None) => String::new(),
            (min, max) => format!("[{}, {}]", min.unwrap_or("−∞"), max.unwrap_or("∞")),
        };
        rows.push_str(&format!(
            "      <tr><td><code>{}</code></td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
            get(&variable, "name"),
            get(&variable, "causality"),
            get(&variable, "variability"),
            kind,
            get(&typed, "unit"),
            get(&typed, "start"),
            range,
            get(&variable, "description"),
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
    fn attributes_survive_a_greater_than_sign_in_a_value() {
        let tags = opening_tags(r#"<A x="1" d="J > 0"/><A x="2">"#, "A");
        assert_eq!(tags.len(), 2);
        assert_eq!(attribute(&tags[0], "d"), Some("J > 0"));
        assert_eq!(attribute(&tags[1], "x"), Some("2"));
    }

    #[test]
    fn table_has_one_row_per_variable_with_its_type_attributes() {
        let xml = r#"<fmiModelDescription><ModelVariables>
            <ScalarVariable name="J_m" valueReference="0" causality="parameter" variability="fixed" description="inertia">
              <Real unit="kg.m2" start="2.28" min="0"/></ScalarVariable>
            <ScalarVariable name="contact" valueReference="1" causality="output"><Integer/></ScalarVariable>
            </ModelVariables><RealType name="x"/></fmiModelDescription>"#;
        let table = variable_table(xml).unwrap();
        assert_eq!(table.matches("<tr><td>").count(), 2);
        assert!(table.contains("<td><code>J_m</code></td><td>parameter</td><td>fixed</td><td>Real</td><td>kg.m2</td><td>2.28</td><td>[0, ∞]</td><td>inertia</td>"));
        assert!(table.contains("<td><code>contact</code></td><td>output</td><td></td><td>Integer</td>"));
    }
}
