//! The model's picture and, in FMI 3.0, its two flanges: `model.png` at the root of an FMI 2.0
//! archive (FMI 2.0 §2.3, "optional image file of FMU icon"), and in an FMI 3.0 archive
//! `terminalsAndIcons/` (FMI 3.0.2 §2.4.9): `icon.png`, `terminalsAndIcons.xml` with the motor-side
//! and the load-side flange as terminals, and one image per flange terminal.
//!
//! The images are drawn here at packaging time (with [`super::image`]), so the repository holds
//! no binary file. One picture serves every plant: all three share the drive train of
//! docs/model.md §1 (motor inertia, compliant member, backlash, load inertia). A controller
//! (docs/model.md §9) has its own picture, a sampled signal following a sine, and no terminal:
//! its inputs and output are signals, connected one by one.

use model_description::xml::escape;
use model_description::Kind;

use super::image::{circle, outline, png, polyline, rect, segment, Canvas, Extent, Rgb};
use super::Entry;

/// The archive entries of this kit for the standard `fmi_version` ("2.0" or "3.0") of model `id`,
/// whose model description is `xml`.
pub fn entries(fmi_version: &str, id: &str, xml: &str) -> Result<Vec<Entry>, String> {
    let (draw, flanges): (fn(&mut Canvas), &[Flange]) = if model_description::controller_identifiers().contains(&id) {
        (draw_controller, &[])
    } else if model_description::model_identifiers().contains(&id)
        && matches!(model_description::model(id).kind, Kind::TwoStage(_))
    {
        (draw_gearbox, &FLANGES)
    } else {
        (draw_drive_train, &FLANGES)
    };
    let icon = picture(ICON_PIXELS, ICON, draw).map_err(|e| format!("{id}: icon: {e}"))?;
    match fmi_version {
        "2.0" => Ok(vec![Entry {
            name: "model.png".into(),
            bytes: icon,
        }]),
        "3.0" => {
            let doc =
                roxmltree::Document::parse(xml).map_err(|e| format!("{id}: model description is not XML: {e}"))?;
            let description_version = doc.root_element().attribute("fmiVersion");
            // FMI 3.0.2 §2.4.9: the two fmiVersion attributes must match.
            if description_version != Some(fmi_version) {
                return Err(format!(
                    "{id}: the model description's fmiVersion is {description_version:?}, not {fmi_version}"
                ));
            }
            let mut kit = vec![
                Entry {
                    name: "terminalsAndIcons/icon.png".into(),
                    bytes: icon,
                },
                Entry {
                    name: "terminalsAndIcons/terminalsAndIcons.xml".into(),
                    bytes: terminals_and_icons(fmi_version, &doc, flanges)
                        .map_err(|e| format!("{id}: {e}"))?
                        .into_bytes(),
                },
            ];
            for flange in flanges {
                kit.push(Entry {
                    name: format!("terminalsAndIcons/{}.png", flange.name),
                    bytes: picture(FLANGE_PIXELS, flange.extent, |canvas| draw_flange(canvas, flange))
                        .map_err(|e| format!("{id}: image of {}: {e}", flange.name))?,
                });
            }
            Ok(kit)
        }
        other => Err(format!("{id}: no icon or terminals for fmiVersion {other:?}")),
    }
}

// ---------------------------------------------------------------------------------------------
// Terminals (FMI 3.0.2 §2.4.9.2)

/// The icon's place in the terminalsAndIcons coordinate system: the default extent of the
/// standard (−100…100 both ways), which is also the coordinate system's.
const ICON: Extent = Extent {
    x1: -100.0,
    y1: -100.0,
    x2: 100.0,
    y2: 100.0,
};

/// The standard's default: 200 units are 20 mm.
const SCALING_TO_MM: f64 = 0.1;

/// A rotational flange of the drive train as a terminal with the members of Modelica's
/// `Rotational.Interfaces.Flange`: `phi`, the absolute angle, and `tau`, the cut torque (a flow).
struct Flange {
    /// The terminal's name and the base name of its image: Modelica's names for the two flanges
    /// of a two-flange component.
    name: &'static str,
    terminal_kind: &'static str,
    description: &'static str,
    /// The variable served as `phi` (docs/model.md §1: an angle of the state).
    angle: &'static str,
    /// The variable served as `tau` (docs/model.md §1: an applied torque, an input).
    torque: &'static str,
    /// Where the terminal sits: on the icon's edge, at the end of the drawn shaft.
    extent: Extent,
    /// Modelica's flange icons: Flange_a a filled circle, Flange_b an open one.
    fill: Rgb,
}

/// The two flanges, motor side first; their variables are common to every model (docs/model.md §1).
const FLANGES: [Flange; 2] = [
    Flange {
        name: "flange_a",
        terminal_kind: "Modelica.Mechanics.Rotational.Interfaces.Flange_a",
        description: "Motor-side flange: motor angle theta_m and motor torque tau_m",
        angle: "theta_m",
        torque: "tau_m",
        extent: Extent {
            x1: -110.0,
            y1: -10.0,
            x2: -90.0,
            y2: 10.0,
        },
        fill: Rgb(95, 95, 95),
    },
    Flange {
        name: "flange_b",
        terminal_kind: "Modelica.Mechanics.Rotational.Interfaces.Flange_b",
        description: "Load-side flange: load angle theta_L and load torque tau_L",
        angle: "theta_L",
        torque: "tau_L",
        extent: Extent {
            x1: 90.0,
            y1: -10.0,
            x2: 110.0,
            y2: 10.0,
        },
        fill: Rgb(255, 255, 255),
    },
];

/// One member of a flange terminal.
struct Member {
    /// Its name in Modelica's flange.
    member_name: &'static str,
    variable_kind: &'static str,
    /// The causality its variable has in every model (docs/model.md §1).
    causality: &'static str,
}

/// The angle is a potential: connected flanges have equal angles.
const ANGLE: Member = Member {
    member_name: "phi",
    variable_kind: "signal",
    causality: "output",
};

/// `inflow`: τ_m and τ_L enter docs/model.md §1 with a plus sign,
/// `J_m ω_m' = τ_m − b_m ω_m − r_m ψ` and `J_L ω_L' = τ_L − b_L ω_L + r_L ψ`, so a positive torque
/// accelerates its inertia along its angle: it flows into the FMU through its flange, as Modelica's
/// `flange.tau` is positive into the component (an inertia: `J a = flange_a.tau + flange_b.tau`).
const TORQUE: Member = Member {
    member_name: "tau",
    variable_kind: "inflow",
    causality: "input",
};

/// FMI 3.0.2 §2.4.9.2.3: `signal`, `inflow` and `outflow` members are restricted to these.
const MEMBER_CAUSALITIES: [&str; 4] = ["input", "output", "parameter", "calculatedParameter"];

/// `terminalsAndIcons/terminalsAndIcons.xml` for the parsed model description `doc`: the icon's
/// extent and the terminals of `flanges` (a plant's two; none: no `<Terminals>`), each member
/// checked against the description.
fn terminals_and_icons(fmi_version: &str, doc: &roxmltree::Document, flanges: &[Flange]) -> Result<String, String> {
    let mut xml = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    xml += &format!(
        "<fmiTerminalsAndIcons {}>\n",
        attributes(&[("fmiVersion", fmi_version.into())])
    );
    xml += "  <GraphicalRepresentation>\n";
    let mut coordinates = extent_attributes(ICON);
    coordinates.push(("suggestedScalingFactorTo_mm", SCALING_TO_MM.to_string()));
    xml += &empty_element(4, "CoordinateSystem", &coordinates);
    xml += &empty_element(4, "Icon", &extent_attributes(ICON));
    xml += "  </GraphicalRepresentation>\n";
    if flanges.is_empty() {
        return Ok(xml + "</fmiTerminalsAndIcons>\n");
    }
    xml += "  <Terminals>\n";
    for flange in flanges {
        let terminal = attributes(&[
            ("name", flange.name.into()),
            ("matchingRule", "plug".into()),
            ("terminalKind", flange.terminal_kind.into()),
            ("description", flange.description.into()),
        ]);
        xml += &format!("    <Terminal {terminal}>\n");
        for (variable, member) in [(flange.angle, &ANGLE), (flange.torque, &TORQUE)] {
            check_member(doc, flange, variable, member)?;
            let member = [
                ("variableName", variable.into()),
                ("memberName", member.member_name.into()),
                ("variableKind", member.variable_kind.into()),
            ];
            xml += &empty_element(6, "TerminalMemberVariable", &member);
        }
        // Modelica draws rotational connections in black.
        let mut drawn = vec![("defaultConnectionColor", "0 0 0".to_string())];
        drawn.extend(extent_attributes(flange.extent));
        drawn.push(("iconBaseName", flange.name.into()));
        xml += &empty_element(6, "TerminalGraphicalRepresentation", &drawn);
        xml += "    </Terminal>\n";
    }
    xml += "  </Terminals>\n</fmiTerminalsAndIcons>\n";
    Ok(xml)
}

/// `name="value"` for each pair, the values escaped, separated by spaces.
fn attributes(pairs: &[(&str, String)]) -> String {
    let pairs: Vec<String> = pairs
        .iter()
        .map(|(name, value)| format!("{name}=\"{}\"", escape(value)))
        .collect();
    pairs.join(" ")
}

/// One line: the element `name` with `pairs` as its attributes and no content, `indent` spaces in.
fn empty_element(indent: usize, name: &str, pairs: &[(&str, String)]) -> String {
    format!("{:indent$}<{name} {}/>\n", "", attributes(pairs))
}

fn extent_attributes(extent: Extent) -> Vec<(&'static str, String)> {
    let Extent { x1, y1, x2, y2 } = extent;
    vec![
        ("x1", x1.to_string()),
        ("y1", y1.to_string()),
        ("x2", x2.to_string()),
        ("y2", y2.to_string()),
    ]
}

/// The description must have `variable`, a Float64 with the causality `member` expects: a
/// terminal naming a missing variable, or one whose sign convention differs, would mislead the
/// importer that connects it.
fn check_member(doc: &roxmltree::Document, flange: &Flange, variable: &str, member: &Member) -> Result<(), String> {
    let node = doc
        .root_element()
        .children()
        .filter(|n| n.has_tag_name("ModelVariables"))
        .flat_map(|n| n.children())
        .find(|n| n.is_element() && n.attribute("name") == Some(variable))
        .ok_or_else(|| format!("{}: the model description has no variable {variable}", flange.name))?;
    let causality = node.attribute("causality").unwrap_or("local");
    if !node.has_tag_name("Float64") || causality != member.causality || !MEMBER_CAUSALITIES.contains(&causality) {
        return Err(format!(
            "{}: {variable} (member {}, {}) is a {} with causality {causality}; expected a Float64 {}",
            flange.name,
            member.member_name,
            member.variable_kind,
            node.tag_name().name(),
            member.causality
        ));
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Drawing

/// Side of the icon in pixels: one pixel per unit of its extent.
const ICON_PIXELS: u32 = 200;
/// Side of a flange's image in pixels (two per unit of its 20-unit extent).
const FLANGE_PIXELS: u32 = 40;

const BLACK: Rgb = Rgb(0, 0, 0);
const SHAFT_GREY: Rgb = Rgb(160, 160, 160);

/// A square PNG of `pixels` a side showing `extent` as `draw` paints it.
fn picture(pixels: u32, extent: Extent, draw: impl FnOnce(&mut Canvas)) -> Result<Vec<u8>, String> {
    let mut canvas = Canvas::new(pixels, pixels, extent);
    draw(&mut canvas);
    png(pixels, pixels, &canvas.rgba8())
}

/// The drive train of docs/model.md §1 from left to right: the motor flange's shaft, the motor
/// inertia (marked M), the compliant member as a zigzag spring, the backlash as a plate with play
/// inside a slotted cup, the load inertia (larger) and the load flange's shaft; both shafts end on
/// the icon's edge, where the terminals sit.
fn draw_drive_train(canvas: &mut Canvas) {
    shaft(canvas, -100.0, -80.0);
    inertia(canvas, -80.0, -46.0, 32.0);
    motor_mark(canvas, -64.0, 1.0);
    stage(canvas, -46.0, 1.0);
    shaft(canvas, 52.0, 58.0);
    inertia(canvas, 58.0, 92.0, 46.0);
    shaft(canvas, 92.0, 100.0);
}

/// A gearbox of two stages (docs/model.md §10): as the drive train, with a second compliant
/// member and backlash behind a light intermediate inertia, each stage drawn at 0.55 of the drive
/// train's size.
fn draw_gearbox(canvas: &mut Canvas) {
    const SCALE: f64 = 0.55;
    shaft(canvas, -100.0, -92.0);
    inertia(canvas, -92.0, -70.0, 26.0);
    motor_mark(canvas, -81.0, 0.8);
    stage(canvas, -70.0, SCALE);
    shaft(canvas, -16.1, -13.0);
    inertia(canvas, -13.0, -3.0, 16.0);
    stage(canvas, -3.0, SCALE);
    shaft(canvas, 50.9, 56.0);
    inertia(canvas, 56.0, 88.0, 40.0);
    shaft(canvas, 88.0, 100.0);
}

/// A shaft from `from` to `to` on the axis. Its edges are drawn along its length only: its ends
/// meet an inertia or the icon's edge.
fn shaft(canvas: &mut Canvas, from: f64, to: f64) {
    canvas.fill(rect(from, -4.0, to, 4.0, 0.0), SHAFT_GREY);
    for y in [-4.0, 4.0] {
        canvas.fill(segment((from, y), (to, y), 0.6), BLACK);
    }
}

/// The motor's letter M centred on `x`, `scale` times its drive-train size.
fn motor_mark(canvas: &mut Canvas, x: f64, scale: f64) {
    let at = |dx: f64, y: f64| (x + scale * dx, scale * y);
    canvas.fill(
        polyline(
            &[
                at(-10.0, -16.0),
                at(-10.0, 16.0),
                at(0.0, -2.0),
                at(10.0, 16.0),
                at(10.0, -16.0),
            ],
            2.2,
        ),
        Rgb(40, 40, 40),
    );
}

/// One stage from `left` on: the compliant member as a zigzag spring, then the backlash as a plate
/// with play inside a slotted cup, `scale` times the drive train's size (at 1: 98 units long,
/// the cup's back wall ending at `left` + 98).
fn stage(canvas: &mut Canvas, left: f64, scale: f64) {
    // x and y of the drive train's drawing, where the stage starts at -46.
    let x = |drawn: f64| left + scale * (drawn + 46.0);
    let y = |drawn: f64| scale * drawn;
    let rect_at = |x1: f64, y1: f64, x2: f64, y2: f64| rect(x(x1), y(y1), x(x2), y(y2), 0.0);

    // The spring: a lead on either side and four full waves.
    let (start, end, lead, amplitude) = (-46.0, 6.0, 6.0, 16.0);
    let waves = 4;
    let pitch = (end - start - 2.0 * lead) / (2 * waves) as f64;
    let mut zigzag = vec![(x(start), 0.0), (x(start + lead), 0.0)];
    for k in 0..2 * waves {
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        zigzag.push((x(start + lead + (k as f64 + 0.5) * pitch), y(sign * amplitude)));
    }
    zigzag.extend([(x(end - lead), 0.0), (x(end), 0.0)]);
    canvas.fill(polyline(&zigzag, 1.6), BLACK);

    // The backlash: the rod's plate moves 12 units either way inside the cup before touching a lip
    // or the back wall.
    canvas.fill(segment((x(end), 0.0), (x(34.0), 0.0), 1.6), BLACK);
    canvas.fill(rect_at(32.0, -16.0, 36.0, 16.0), BLACK);
    for sign in [1.0, -1.0] {
        let band = |from: f64, to: f64| (sign * from).min(sign * to)..(sign * from).max(sign * to);
        let (arm, lip) = (band(24.0, 28.0), band(10.0, 28.0));
        canvas.fill(rect_at(16.0, arm.start, 52.0, arm.end), BLACK);
        canvas.fill(rect_at(16.0, lip.start, 20.0, lip.end), BLACK);
    }
    canvas.fill(rect_at(48.0, -28.0, 52.0, 28.0), BLACK);
}

/// A controller: a block holding a sine (the reference, thin) and the staircase of its samples
/// (thick), with a signal arrow in on the left and out on the right.
fn draw_controller(canvas: &mut Canvas) {
    let block = rect(-78.0, -62.0, 78.0, 62.0, 8.0);
    canvas.fill(&block, Rgb(240, 244, 250));
    canvas.fill(outline(block, 1.4), BLACK);
    let sine = |x: f64| 40.0 * (std::f64::consts::PI * (x + 60.0) / 60.0).sin();
    let curve: Vec<(f64, f64)> = (0..=120).map(|i| -60.0 + f64::from(i)).map(|x| (x, sine(x))).collect();
    canvas.fill(polyline(&curve, 0.8), SHAFT_GREY);
    // Each sample held until the next: steps of 12 units.
    let mut stairs = Vec::new();
    for k in 0..10 {
        let (from, to) = (-60.0 + 12.0 * f64::from(k), -48.0 + 12.0 * f64::from(k));
        stairs.extend([(from, sine(from)), (to, sine(from))]);
    }
    canvas.fill(polyline(&stairs, 2.0), Rgb(30, 70, 150));
    for (from, to) in [(-100.0, -78.0), (78.0, 100.0)] {
        canvas.fill(segment((from, 0.0), (to - 6.0, 0.0), 1.4), BLACK);
        canvas.fill(polyline(&[(to - 8.0, -5.0), (to, 0.0), (to - 8.0, 5.0)], 1.4), BLACK);
    }
}

/// An inertia between `left` and `right`, `half_height` above and below the axis, shaded as
/// Modelica's rotational inertia: a cylinder lit along its axis.
fn inertia(canvas: &mut Canvas, left: f64, right: f64, half_height: f64) {
    let body = rect(left, -half_height, right, half_height, 3.0);
    canvas.paint(&body, |_, y| {
        let edge = (y / half_height).powi(2).min(1.0);
        let level = (235.0 - edge * 125.0) as u8;
        Rgb(level, level, level)
    });
    canvas.fill(outline(body, 1.0), BLACK);
}

/// A flange terminal's image: Modelica's flange icon, a circle filling the extent.
fn draw_flange(canvas: &mut Canvas, flange: &Flange) {
    let Extent { x1, y1, x2, y2 } = flange.extent;
    let (cx, cy, radius) = ((x1 + x2) / 2.0, (y1 + y2) / 2.0, (x2 - x1) / 2.0 - 0.75);
    canvas.fill(circle(cx, cy, radius), flange.fill);
    canvas.fill(outline(circle(cx, cy, radius), 0.5), BLACK);
}

#[cfg(test)]
mod tests {
    use super::super::image::tests::decode;
    use super::*;

    fn icon_pixels() -> Vec<u8> {
        let mut canvas = Canvas::new(ICON_PIXELS, ICON_PIXELS, ICON);
        draw_drive_train(&mut canvas);
        canvas.rgba8()
    }

    /// The RGBA pixel of the icon at the point (x, y) of its coordinate system.
    fn icon_at(pixels: &[u8], x: f64, y: f64) -> [u8; 4] {
        let column = ((x - ICON.x1) / (ICON.x2 - ICON.x1) * f64::from(ICON_PIXELS)) as usize;
        let row = ((ICON.y2 - y) / (ICON.y2 - ICON.y1) * f64::from(ICON_PIXELS)) as usize;
        let at = (row * ICON_PIXELS as usize + column) * 4;
        pixels[at..at + 4].try_into().unwrap()
    }

    #[test]
    fn icon_shows_the_drive_train_on_a_transparent_background() {
        let pixels = icon_pixels();
        for corner in [(-99.0, -99.0), (-99.0, 99.0), (99.0, -99.0), (99.0, 99.0)] {
            assert_eq!(icon_at(&pixels, corner.0, corner.1)[3], 0, "corner {corner:?}");
        }
        // The motor inertia on the left, the taller load inertia on the right.
        assert_eq!(icon_at(&pixels, -50.0, 25.0)[3], 255);
        assert_eq!(icon_at(&pixels, -50.0, 40.0)[3], 0);
        assert_eq!(icon_at(&pixels, 75.0, 40.0)[3], 255);
        // The shafts reach the edges where the flanges sit.
        assert_eq!(icon_at(&pixels, -99.5, 0.0), [160, 160, 160, 255]);
        assert_eq!(icon_at(&pixels, 99.5, 0.0), [160, 160, 160, 255]);
        // The play either side of the backlash plate is empty.
        assert_eq!(icon_at(&pixels, 26.0, 12.0)[3], 0);
        assert_eq!(icon_at(&pixels, 42.0, 12.0)[3], 0);
        assert_eq!(icon_at(&pixels, 34.0, 12.0), [0, 0, 0, 255]);
    }

    #[test]
    fn the_gearbox_icon_shows_two_stages_and_the_intermediate_inertia() {
        let mut canvas = Canvas::new(ICON_PIXELS, ICON_PIXELS, ICON);
        draw_gearbox(&mut canvas);
        let pixels = canvas.rgba8();
        for corner in [(-99.0, -99.0), (99.0, 99.0)] {
            assert_eq!(icon_at(&pixels, corner.0, corner.1)[3], 0, "corner {corner:?}");
        }
        // The light intermediate inertia between the stages, lower than the motor's.
        assert_eq!(icon_at(&pixels, -8.0, 12.0)[3], 255);
        assert_eq!(icon_at(&pixels, -8.0, 20.0)[3], 0);
        assert_eq!(icon_at(&pixels, -80.0, 20.0)[3], 255);
        // Each stage's plate (the drive train's at x = 34, y = 12, scaled) with its play either
        // side empty: the first stage from -70, the second from -3.
        for left in [-70.0, -3.0] {
            let x = |drawn: f64| left + 0.55 * (drawn + 46.0);
            assert_eq!(
                icon_at(&pixels, x(34.0), 0.55 * 12.0),
                [0, 0, 0, 255],
                "stage at {left}"
            );
            for play in [26.0, 42.0] {
                assert_eq!(
                    icon_at(&pixels, x(play), 0.55 * 12.0)[3],
                    0,
                    "stage at {left}, x {play}"
                );
            }
        }
        // The shafts reach the edges where the flanges sit.
        assert_eq!(icon_at(&pixels, -99.5, 0.0), [160, 160, 160, 255]);
        assert_eq!(icon_at(&pixels, 99.5, 0.0), [160, 160, 160, 255]);
    }

    #[test]
    fn every_image_is_a_png_of_its_declared_size() {
        let xml = model_description::xml3::model_description(model_description::model_identifiers()[0]);
        for entry in entries("3.0", "test", &xml).unwrap() {
            if entry.name.ends_with(".png") {
                let (width, height, pixels) = decode(&entry.bytes);
                let side = if entry.name.ends_with("icon.png") {
                    ICON_PIXELS
                } else {
                    FLANGE_PIXELS
                };
                assert_eq!((width, height), (side, side), "{}", entry.name);
                assert!(pixels.chunks(4).any(|p| p[3] == 255), "{} is empty", entry.name);
            }
        }
    }

    fn names(entries: &[Entry]) -> Vec<&str> {
        entries.iter().map(|e| e.name.as_str()).collect()
    }

    #[test]
    fn fmi2_archives_get_model_png_only() {
        for &id in model_description::model_identifiers() {
            let xml = model_description::xml::model_description(id);
            assert_eq!(names(&entries("2.0", id, &xml).unwrap()), ["model.png"]);
        }
    }

    #[test]
    fn unknown_standard_is_refused() {
        assert!(entries("1.0", "X", "<fmiModelDescription/>").is_err());
    }

    #[test]
    fn every_fmi3_model_gets_both_flanges_with_its_variables() {
        for &id in model_description::model_identifiers() {
            let xml = model_description::xml3::model_description(id);
            let kit = entries("3.0", id, &xml).unwrap();
            assert_eq!(
                names(&kit),
                [
                    "terminalsAndIcons/icon.png",
                    "terminalsAndIcons/terminalsAndIcons.xml",
                    "terminalsAndIcons/flange_a.png",
                    "terminalsAndIcons/flange_b.png"
                ]
            );
            let text = std::str::from_utf8(&kit[1].bytes).unwrap();
            let doc = roxmltree::Document::parse(text).unwrap();
            let root = doc.root_element();
            assert_eq!(root.attribute("fmiVersion"), Some("3.0"));
            let terminals: Vec<_> = root.descendants().filter(|n| n.has_tag_name("Terminal")).collect();
            let found: Vec<_> = terminals
                .iter()
                .map(|t| {
                    let members: Vec<_> = t
                        .children()
                        .filter(|n| n.has_tag_name("TerminalMemberVariable"))
                        .map(|m| {
                            (
                                m.attribute("memberName").unwrap(),
                                m.attribute("variableName").unwrap(),
                                m.attribute("variableKind").unwrap(),
                            )
                        })
                        .collect();
                    (
                        t.attribute("name").unwrap(),
                        t.attribute("terminalKind").unwrap(),
                        t.attribute("matchingRule").unwrap(),
                        members,
                    )
                })
                .collect();
            assert_eq!(
                found,
                [
                    (
                        "flange_a",
                        "Modelica.Mechanics.Rotational.Interfaces.Flange_a",
                        "plug",
                        vec![("phi", "theta_m", "signal"), ("tau", "tau_m", "inflow")]
                    ),
                    (
                        "flange_b",
                        "Modelica.Mechanics.Rotational.Interfaces.Flange_b",
                        "plug",
                        vec![("phi", "theta_L", "signal"), ("tau", "tau_L", "inflow")]
                    ),
                ],
                "{id}"
            );
        }
    }

    /// A minimal FMI 3.0 description with the four flange variables, `tau_L` as `tau_l_element`.
    fn description(tau_l_element: &str) -> String {
        format!(
            r#"<fmiModelDescription fmiVersion="3.0"><ModelVariables>
            <Float64 name="tau_m" valueReference="1" causality="input"/>
            {tau_l_element}
            <Float64 name="theta_m" valueReference="3" causality="output"/>
            <Float64 name="theta_L" valueReference="5" causality="output"/>
            </ModelVariables></fmiModelDescription>"#
        )
    }

    #[test]
    fn a_description_with_the_flange_variables_is_accepted() {
        let xml = description(r#"<Float64 name="tau_L" valueReference="2" causality="input"/>"#);
        assert!(entries("3.0", "X", &xml).is_ok());
    }

    #[test]
    fn a_missing_flange_variable_is_refused() {
        let error = entries("3.0", "X", &description("")).err().unwrap();
        assert!(
            error.contains("flange_b") && error.contains("no variable tau_L"),
            "{error}"
        );
    }

    #[test]
    fn a_flange_variable_of_another_causality_or_type_is_refused() {
        for element in [
            r#"<Float64 name="tau_L" valueReference="2" causality="output"/>"#,
            r#"<Float64 name="tau_L" valueReference="2"/>"#,
            r#"<Int32 name="tau_L" valueReference="2" causality="input"/>"#,
        ] {
            let error = entries("3.0", "X", &description(element)).err().unwrap();
            assert!(error.contains("tau_L (member tau, inflow)"), "{error}");
        }
    }

    #[test]
    fn a_description_of_another_standard_is_refused() {
        let xml = description(r#"<Float64 name="tau_L" valueReference="2" causality="input"/>"#)
            .replace("fmiVersion=\"3.0\"", "fmiVersion=\"2.0\"");
        assert!(entries("3.0", "X", &xml).is_err());
    }
}
