//! `cargo xtask cross-test`: the libraries built for the other platforms, run on this machine
//! (win64 under Wine, aarch64-linux under qemu-user) by the same C host as the linux64 library,
//! and compared with it.
//!
//! For each model: a closed PI loop and an open-loop torque schedule through FMI 2.0, both with
//! contact switches, sampled along the way (every Real output of its description within 1e-12
//! relative of linux64, every mesh's contact mode the same, the same switch counts; on the web
//! line also its upstream speed and tension as inputs); the same open loop through FMI 3.0
//! from the FMI 3.0 archive, whose fmi3DoStep returns early at every contact switch (each switch
//! instant and the outputs there compared as the samples are); misuse of the C API (the same
//! fmi2Status and number of logged messages as on linux64); an FMU state serialized on each
//! platform, restored on every platform and continued as the saving platform continued it. The
//! Windows DLL in each archive must import only DLLs of a stock Windows 10.

mod compare;
mod host;
pub mod imports;
pub mod toolchain;

use std::collections::BTreeMap;
use std::fs;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::fmu::{self, Standard};
use crate::platform::{self, BinaryFormat, Built, Platform, Tool};
use crate::util::{self, step};
use crate::{abi, python, rigs};
use compare::{Agreement, Sample};
use host::Host;

/// Each model's test rig (tests/fixtures/rigs.toml, shared with the Python tests): its
/// `cross_platform` parameter sets where it has them, else its `parameters`, then its PI gains (the
/// host's loop uses Kp and Ki as its gains).
fn rig(id: &str) -> Result<Vec<(String, f64)>, String> {
    rigs::rig(&util::repo_root(), id, "cross_platform")
}

/// A scenario of the host that samples its outputs along the way (h = 1 ms in the host).
struct Sampled {
    /// Its name on the host's command line (tests/cross/host.c).
    scenario: &'static str,
    /// Its name in the report.
    label: &'static str,
    steps: u32,
    /// Sampling interval, in steps.
    every: u32,
    /// fmi3DoStep returns early at contact switches: at least [`MIN_SWITCHES`] of its returns
    /// must be early, or the early return would not be tested.
    early_return: bool,
}

const CLOSED_LOOP: Sampled = Sampled {
    scenario: "closed",
    label: "closed loop",
    steps: 10_000,
    every: 100,
    early_return: false,
};
const OPEN_LOOP: Sampled = Sampled {
    scenario: "open",
    label: "open loop",
    steps: 4_000,
    every: 50,
    early_return: false,
};
/// The open loop's schedule through FMI 3.0.
const FMI3_OPEN_LOOP: Sampled = Sampled {
    scenario: "fmi3",
    label: "FMI 3.0 open loop",
    early_return: true,
    ..OPEN_LOOP
};

/// The open loop with bearing friction in both bearings ([`FRICTION`]): the motor sticks and
/// breaks away at the torque's reversals, the load besides (docs/model.md §12).
const FRICTION_OPEN_LOOP: Sampled = Sampled {
    label: "open loop with bearing friction",
    ..OPEN_LOOP
};
/// The same through FMI 3.0, returning early at contact and friction switches.
const FMI3_FRICTION_OPEN_LOOP: Sampled = Sampled {
    label: "FMI 3.0 open loop with bearing friction",
    ..FMI3_OPEN_LOOP
};

/// Bearing friction of the friction scenarios, set after the rig's parameters: against the open
/// loop's ±3 N.m motor torque and its load torque of −0.5 N.m.
const FRICTION: [(&str, f64); 4] = [("tau_c_m", 0.5), ("tau_c_L", 1.0), ("peak_m", 1.2), ("peak_L", 1.3)];

/// The loop closed by BacklashController, the controller model of the same library: values passed
/// after each step, as a co-simulation master passes them (docs/model.md §9).
const CONTROLLER_LOOP: Sampled = Sampled {
    scenario: "controller",
    label: "loop closed by the controller",
    ..CLOSED_LOOP
};

/// The controller's reference in that loop: a sine reversing the drive (amplitude [rad/s],
/// frequency [Hz]), the square wave's amplitude of the host's own closed loop; its gains are the
/// drive's rig's Kp and Ki.
const CONTROLLER_SINE: [(&str, f64); 2] = [("amplitude", 5.0), ("frequency", 0.5)];

/// A scenario that switches contact fewer times than this would not test the switching.
const MIN_SWITCHES: u64 = 4;

/// The variables the host drives on every model, by name (tests/cross/host.c): its inputs, the
/// speed its PI loop reads, and the gains of that loop. What it samples is the description's own
/// list: every Real output and each mesh's contact mode ([`sampled`]).
const HOST_VARIABLES: [&str; 5] = ["tau_m", "tau_L", "omega_m", "Kp", "Ki"];

/// The web line's inputs the host drives (the upstream web speed and tension), passed where the
/// description has them (BacklashWeb).
const WEB_VARIABLES: [&str; 2] = ["v_in", "T_in"];

pub fn run(args: &[String]) -> Result<(), String> {
    if let Some(arg) = args.first() {
        return Err(format!("`cargo xtask cross-test` takes no arguments, got `{arg}`"));
    }
    if let Some(line) = unavailable() {
        return Err(line);
    }
    python::ensure_venv()?;
    let built = fmu::package(&platform::ALL)?;
    abi::check(&built)?;
    test(&built)
}

/// None when this machine can build and run every platform; otherwise one line saying what to
/// install.
pub fn unavailable() -> Option<String> {
    let mut missing: Vec<Tool> = Vec::new();
    for platform in platform::cross() {
        for tool in toolchain::missing_tools(&platform.tools()) {
            if !missing.contains(&tool) {
                missing.push(tool);
            }
        }
    }
    let mut problems = Vec::new();
    if !missing.is_empty() {
        problems.push(toolchain::install_line("win64 and aarch64-linux", &missing));
    }
    let platforms: Vec<&Platform> = platform::cross().collect();
    if let Err(line) = toolchain::standard_libraries(&platforms) {
        problems.push(line);
    }
    (!problems.is_empty()).then(|| problems.join("; "))
}

/// The cross-platform test on archives already in target/fmu and the libraries in `built`.
pub fn test(built: &[Built]) -> Result<(), String> {
    let started = Instant::now();
    let headers = abi::official_header_dirs()?.remove(0);
    let dir = util::target_dir().join("cross-test");
    step("compiling the test host for every platform (tests/cross/host.c)");
    let hosts = platform::ALL
        .into_iter()
        .map(|p| host::compile(p, &headers, &dir))
        .collect::<Result<Vec<_>, _>>()?;
    let mut timer = Timer::default();
    for &id in model_description::model_identifiers() {
        step(&format!("{id}: every platform against linux64"));
        let unpack = |standard: &Standard| {
            Model::unpack(id, standard, &dir.join("models").join(standard.subdir).join(id), built)
        };
        let model = unpack(&fmu::FMI2)?;
        let model3 = unpack(&fmu::FMI3)?;
        for host in &hosts {
            if host.platform.format == BinaryFormat::Pe {
                let library = model.library(host.platform)?;
                let imports = imports::check(host.platform, library)?;
                println!(
                    "{}: imports only stock Windows DLLs: {}",
                    util::shown(library),
                    imports.join(", ")
                );
            }
        }
        scenario(&model, &hosts, &mut timer, &CLOSED_LOOP, &[])?;
        scenario(&model, &hosts, &mut timer, &OPEN_LOOP, &[])?;
        scenario(&model3, &hosts, &mut timer, &FMI3_OPEN_LOOP, &[])?;
        scenario(&model.with_friction(), &hosts, &mut timer, &FRICTION_OPEN_LOOP, &[])?;
        scenario(
            &model3.with_friction(),
            &hosts,
            &mut timer,
            &FMI3_FRICTION_OPEN_LOOP,
            &[],
        )?;
        scenario(&model, &hosts, &mut timer, &CONTROLLER_LOOP, &controller_arguments(id)?)?;
        misuse(&model, &hosts, &mut timer)?;
        fmu_state(&model, &hosts, &mut timer)?;
    }
    println!("\nhost run time per platform (all scenarios, all models):");
    for (name, time) in &timer.per_platform {
        println!("  {:>6.1} s  {name}", time.as_secs_f64());
    }
    println!(
        "cross-platform test passed in {:.1} s: every platform agrees with linux64",
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

#[derive(Default)]
struct Timer {
    per_platform: BTreeMap<&'static str, Duration>,
}

impl Timer {
    fn run(&mut self, model: &Model, host: &Host, scenario: &[String]) -> Result<String, String> {
        let t0 = Instant::now();
        let output = host.run(&model.arguments(host, scenario)?);
        *self.per_platform.entry(host.platform.name).or_default() += t0.elapsed();
        output.map_err(|e| format!("{}, {}: {e}", model.id, scenario.join(" ")))
    }
}

/// One model as one standard's archive has it: the libraries (from the archive where the standard
/// has a folder for the platform, else as built), the guid or instantiation token, and the value
/// references of the host's variables.
#[derive(Clone)]
struct Model {
    id: &'static str,
    dir: PathBuf,
    libraries: Vec<(&'static Platform, PathBuf)>,
    token: String,
    variables: String,
    /// The Real outputs a sample carries, in its order.
    outputs: Vec<String>,
    parameters: String,
    /// [`FRICTION`] as `vr=bits,...`.
    friction: String,
}

impl Model {
    fn unpack(id: &'static str, standard: &Standard, dir: &Path, built: &[Built]) -> Result<Model, String> {
        if dir.exists() {
            fs::remove_dir_all(dir).map_err(|e| format!("removing {}: {e}", dir.display()))?;
        }
        fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
        let archive = standard.out_dir().join(format!("{id}.fmu"));
        let xml = String::from_utf8(read_entry(&archive, "modelDescription.xml")?)
            .map_err(|_| format!("{}: modelDescription.xml is not UTF-8", archive.display()))?;
        let mut libraries = Vec::new();
        for platform in platform::ALL {
            let file = platform.archive_file(id);
            let bytes = match (standard.folder_of)(platform) {
                Some(folder) => read_entry(&archive, &format!("binaries/{folder}/{file}"))?,
                None => {
                    let built = built
                        .iter()
                        .find(|b| b.platform == platform)
                        .ok_or_else(|| format!("the {} library was not built", platform.name))?;
                    fs::read(&built.path).map_err(|e| format!("reading {}: {e}", built.path.display()))?
                }
            };
            let path = dir.join(platform.fmi3_folder).join(file);
            fs::create_dir_all(path.parent().expect("a file in a folder"))
                .and_then(|()| fs::write(&path, bytes))
                .map_err(|e| format!("writing {}: {e}", path.display()))?;
            libraries.push((platform, path));
        }
        let (token, variables, outputs, parameters) =
            host_arguments(id, standard, &xml).map_err(|e| format!("{id}: {e}"))?;
        let friction = parameter_bits(&xml, &FRICTION).map_err(|e| format!("{id}: {e}"))?;
        Ok(Model {
            id,
            dir: dir.to_path_buf(),
            libraries,
            token,
            variables,
            outputs,
            parameters,
            friction,
        })
    }

    /// The model with [`FRICTION`] set after its rig's parameters.
    fn with_friction(&self) -> Model {
        Model {
            parameters: format!("{},{}", self.parameters, self.friction),
            ..self.clone()
        }
    }

    fn library(&self, platform: &Platform) -> Result<&Path, String> {
        self.libraries
            .iter()
            .find(|(p, _)| *p == platform)
            .map(|(_, path)| path.as_path())
            .ok_or_else(|| format!("{}: no {} library", self.id, platform.name))
    }

    fn arguments(&self, host: &Host, scenario: &[String]) -> Result<Vec<String>, String> {
        let mut args = vec![
            host.path_argument(self.library(host.platform)?),
            self.token.clone(),
            self.variables.clone(),
            self.parameters.clone(),
        ];
        args.extend(scenario.iter().cloned());
        Ok(args)
    }
}

fn read_entry(archive: &Path, name: &str) -> Result<Vec<u8>, String> {
    let file = fs::File::open(archive)
        .map_err(|e| format!("{}: {e} (run `cargo xtask fmu --all-platforms`)", archive.display()))?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| format!("{}: {e}", archive.display()))?;
    let mut bytes = Vec::new();
    zip.by_name(name)
        .map_err(|e| format!("{}: {name}: {e} (built without --all-platforms?)", archive.display()))?
        .read_to_end(&mut bytes)
        .map_err(|e| format!("{}: {name}: {e}", archive.display()))?;
    Ok(bytes)
}

/// From a model description of `standard`: the guid (FMI 2.0) or instantiation token (FMI 3.0),
/// `name=vr,...` of the host's variables (those of [`WEB_VARIABLES`] where the description has
/// them, then what it samples: [`sampled`]), the names of the sampled Real outputs, and the rig's
/// parameters as `vr=bits,...` (the exact f64 of each value, as hexadecimal IEEE-754 bits).
fn host_arguments(id: &str, standard: &Standard, xml: &str) -> Result<(String, String, Vec<String>, String), String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("modelDescription.xml: {e}"))?;
    let token = standard.token(&doc)?;
    let mut variables = HOST_VARIABLES
        .iter()
        .map(|name| value_reference(&doc, name).map(|vr| format!("{name}={vr}")))
        .collect::<Result<Vec<_>, _>>()?;
    let web: Vec<String> = WEB_VARIABLES
        .iter()
        .filter_map(|name| value_reference(&doc, name).ok().map(|vr| format!("{name}={vr}")))
        .collect();
    if !web.is_empty() && web.len() != WEB_VARIABLES.len() {
        return Err(format!(
            "modelDescription.xml has some of the web line's variables {WEB_VARIABLES:?}, not all"
        ));
    }
    variables.extend(web);
    let (outputs, contacts) = sampled(&doc);
    if contacts.is_empty() {
        return Err("modelDescription.xml has no contact output".into());
    }
    variables.extend(outputs.iter().map(|(_, vr)| format!("out={vr}")));
    variables.extend(contacts.iter().map(|vr| format!("contact={vr}")));
    let names = outputs.into_iter().map(|(name, _)| name.to_string()).collect();
    let parameters = parameter_bits(xml, &rig(id)?)?;
    Ok((token.to_string(), variables.join(","), names, parameters))
}

/// What the host samples, from a model description: every Real (Float64) output, with its value
/// reference, and the value reference of each mesh's contact mode (the Integer outputs `contact`,
/// or a gearbox's `contact_1`, `contact_2`), each in value-reference order.
fn sampled<'a>(doc: &'a roxmltree::Document) -> (Vec<(&'a str, u32)>, Vec<u32>) {
    let mut outputs = Vec::new();
    let mut contacts = Vec::new();
    for variable in doc
        .descendants()
        .filter(|n| n.parent().is_some_and(|p| p.has_tag_name("ModelVariables")))
        .filter(|n| n.attribute("causality") == Some("output"))
    {
        let (Some(name), Some(vr)) = (
            variable.attribute("name"),
            variable
                .attribute("valueReference")
                .and_then(|vr| vr.parse::<u32>().ok()),
        ) else {
            continue;
        };
        // FMI 2.0 names the type in a child element, FMI 3.0 in the variable's own tag.
        let is = |ty: &str| variable.has_tag_name(ty) || variable.children().any(|c| c.has_tag_name(ty));
        if is("Real") || is("Float64") {
            outputs.push((name, vr));
        } else if (is("Integer") || is("Int32")) && (name == "contact" || name.starts_with("contact_")) {
            contacts.push(vr);
        }
    }
    outputs.sort_by_key(|&(_, vr)| vr);
    contacts.sort_unstable();
    (outputs, contacts)
}

/// The value reference of the variable `name` of a model description: a child of
/// ModelVariables (FMI 2.0's ScalarVariable, FMI 3.0's Float64, Int32...).
fn value_reference<'a>(doc: &'a roxmltree::Document, name: &str) -> Result<&'a str, String> {
    doc.descendants()
        .find(|n| n.parent().is_some_and(|p| p.has_tag_name("ModelVariables")) && n.attribute("name") == Some(name))
        .and_then(|n| n.attribute("valueReference"))
        .ok_or_else(|| format!("modelDescription.xml has no variable {name}"))
}

/// `values` as the host's `vr=bits,...` (each f64 as its hexadecimal IEEE-754 bits), by the
/// value references of the model description `xml`.
fn parameter_bits<S: AsRef<str>>(xml: &str, values: &[(S, f64)]) -> Result<String, String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("modelDescription.xml: {e}"))?;
    let set = values
        .iter()
        .map(|(name, value)| value_reference(&doc, name.as_ref()).map(|vr| format!("{vr}={:016x}", value.to_bits())))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(set.join(","))
}

/// The controller scenario's arguments for the drive `id`: BacklashController's guid, the value
/// references of its omega_m and tau_m, and its Real parameters (the drive's rig's gains and
/// [`CONTROLLER_SINE`]) as vr=bits.
fn controller_arguments(id: &str) -> Result<Vec<String>, String> {
    let controller = model_description::model("BacklashController");
    let vr = |name: &str| {
        controller
            .variables
            .iter()
            .find(|v| v.name == name)
            .map(|v| v.vr)
            .ok_or_else(|| format!("BacklashController has no variable {name}"))
    };
    let rig = rig(id)?;
    let gain = |name: &str| {
        rig.iter()
            .find(|(n, _)| n == name)
            .map(|(_, x)| *x)
            .ok_or_else(|| format!("{id}: its rig has no {name}"))
    };
    let values = [("Kp", gain("Kp")?), ("Ki", gain("Ki")?)];
    let parameters = values
        .iter()
        .chain(&CONTROLLER_SINE)
        .map(|(name, value)| vr(name).map(|vr| format!("{vr}={:016x}", value.to_bits())))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(vec![
        model_description::xml::guid("BacklashController"),
        format!("{},{}", vr("omega_m")?, vr("tau_m")?),
        parameters.join(","),
    ])
}

fn strings(words: &[&str]) -> Vec<String> {
    words.iter().map(|w| w.to_string()).collect()
}

fn report(model: &Model, what: &str, platform: &Platform, agreement: &Agreement) {
    println!(
        "  {:<13} {what:<34} {:<13} {:>3}/{} samples bit-identical, max relative difference {:e}",
        model.id, platform.name, agreement.bit_identical, agreement.samples, agreement.max_relative
    );
}

/// The reference platform's samples must switch contact (and return early as often, where
/// fmi3DoStep may), and every other platform must agree; `extra`: the scenario's arguments after
/// its steps and sampling interval.
fn scenario(model: &Model, hosts: &[Host], timer: &mut Timer, run: &Sampled, extra: &[String]) -> Result<(), String> {
    let Sampled {
        scenario: name,
        label,
        steps,
        every,
        early_return,
    } = *run;
    let mut args = strings(&[name, &steps.to_string(), &every.to_string()]);
    args.extend_from_slice(extra);
    let mut reference: Option<Vec<Sample>> = None;
    for host in hosts {
        let samples = compare::samples(&timer.run(model, host, &args)?)
            .map_err(|e| format!("{}, {label}, {}: {e}", model.id, host.platform.name))?;
        let Some(reference) = &reference else {
            let switches = samples.last().map_or(0, |s| s.switches);
            if switches < MIN_SWITCHES {
                return Err(format!(
                    "{}, {label}: {switches} contact switches, fewer than {MIN_SWITCHES}",
                    model.id
                ));
            }
            let early = samples.iter().filter(|s| s.early.is_some()).count() as u64;
            if early_return && early < MIN_SWITCHES {
                return Err(format!(
                    "{}, {label}: fmi3DoStep returned early {early} times, fewer than {MIN_SWITCHES}",
                    model.id
                ));
            }
            let returns = if early_return {
                format!(", {early} early returns")
            } else {
                String::new()
            };
            println!(
                "  {:<13} {label}: {steps} steps, {switches} contact switches{returns} on linux64",
                model.id
            );
            reference = Some(samples);
            continue;
        };
        let agreement = compare::agree(reference, &samples, &model.outputs)
            .map_err(|e| format!("{}, {label}, {} against linux64: {e}", model.id, host.platform.name))?;
        report(model, label, host.platform, &agreement);
    }
    Ok(())
}

/// Calls FMI 2.0 forbids: refused (fmi2Discard or fmi2Error) on linux64, and answered the same
/// way, with as many logged messages, on every platform; then a live instance steps on after
/// the library was closed and reopened, and the next one gets a handle of its own.
fn misuse(model: &Model, hosts: &[Host], timer: &mut Timer) -> Result<(), String> {
    let mut reference = None;
    for host in hosts {
        let cases = compare::misuse(&timer.run(model, host, &strings(&["misuse"]))?)?;
        let Some(reference) = &reference else {
            for (case, status, _) in &cases {
                let expected_ok = match case.as_str() {
                    "instantiate_wrong_guid" => status == "null",
                    "fresh_instance_steps" | "step_after_reload" => status == "0",
                    "reload_distinct_handles" => status == "distinct",
                    _ => status == "2" || status == "3",
                };
                if !expected_ok {
                    return Err(format!(
                        "{}, misuse {case}: answered with {status} on linux64",
                        model.id
                    ));
                }
            }
            reference = Some(cases);
            continue;
        };
        if &cases != reference {
            let differ: Vec<String> = cases
                .iter()
                .zip(reference)
                .filter(|(c, r)| c != r)
                .map(|(c, r)| {
                    format!(
                        "{} gives {} ({} logged), linux64 {} ({} logged)",
                        c.0, c.1, c.2, r.1, r.2
                    )
                })
                .collect();
            return Err(format!(
                "{}, misuse on {} ({} cases, linux64 {}): {}",
                model.id,
                host.platform.name,
                cases.len(),
                reference.len(),
                differ.join("; ")
            ));
        }
        println!(
            "  {:<13} {:<34} {:<13} the same {} answers as linux64",
            model.id,
            "misuse",
            host.platform.name,
            cases.len()
        );
    }
    Ok(())
}

/// Each platform serializes its state half-way through the open loop and continues; every
/// platform restores each of these states into a fresh instance, and its continuation must
/// agree with the saving platform's own.
fn fmu_state(model: &Model, hosts: &[Host], timer: &mut Timer) -> Result<(), String> {
    let (steps, every) = (OPEN_LOOP.steps.to_string(), OPEN_LOOP.every.to_string());
    let mut saved: Vec<(&Platform, PathBuf, Vec<Sample>)> = Vec::new();
    for host in hosts {
        let file = model.dir.join(format!("state-{}.bin", host.platform.name));
        let args = vec!["save".into(), steps.clone(), every.clone(), host.path_argument(&file)];
        let continuation = compare::samples(&timer.run(model, host, &args)?)?;
        if continuation.last().map_or(0, |s| s.switches) < MIN_SWITCHES {
            return Err(format!(
                "{}: fewer than {MIN_SWITCHES} contact switches after the saved state",
                model.id
            ));
        }
        saved.push((host.platform, file, continuation));
    }
    let reference_bytes = fs::read(&saved[0].1).map_err(|e| format!("{}: {e}", saved[0].1.display()))?;
    for (platform, file, continuation) in &saved[1..] {
        let bytes = fs::read(file).map_err(|e| format!("{}: {e}", file.display()))?;
        let agreement = compare::agree(&saved[0].2, continuation, &model.outputs)
            .map_err(|e| format!("{}, continuation after saving on {}: {e}", model.id, platform.name))?;
        println!(
            "  {:<13} {:<34} {:<13} serialized state ({} bytes) {} linux64's",
            model.id,
            "FMU state",
            platform.name,
            bytes.len(),
            if bytes == reference_bytes {
                "byte-identical to"
            } else {
                "differs from"
            }
        );
        report(model, "continuation after saving", platform, &agreement);
    }
    for host in hosts {
        for (saver, file, continuation) in &saved {
            let args = vec!["restore".into(), steps.clone(), every.clone(), host.path_argument(file)];
            let restored = compare::samples(&timer.run(model, host, &args)?)?;
            let agreement = compare::agree(continuation, &restored, &model.outputs).map_err(|e| {
                format!(
                    "{}, state saved on {} and restored on {}, against its continuation on {}: {e}",
                    model.id, saver.name, host.platform.name, saver.name
                )
            })?;
            report(
                model,
                &format!("state from {} restored", saver.name),
                host.platform,
                &agreement,
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every model has a rig in the fixture, and a rig is its sets then its gains (the numbers
    /// the Python tests read from the same file).
    #[test]
    fn every_model_has_its_rig_from_the_fixture() {
        for id in model_description::model_identifiers() {
            let values = rig(id).unwrap();
            assert!(values.iter().any(|(name, _)| name == "Kp"), "{id}: {values:?}");
            assert!(values.iter().any(|(name, _)| name == "J_m"), "{id}: {values:?}");
        }
        let shaft = rig("BacklashShaft").unwrap();
        assert!(shaft.contains(&("Delta".to_string(), 5.38e-3 / 2.0)), "{shaft:?}");
        let web = rig("BacklashWeb").unwrap();
        assert!(
            web.contains(&("EA".to_string(), 1.0e3)),
            "the cross-platform sets: {web:?}"
        );
        assert!(rig("NoSuchModel").unwrap_err().contains("no rig for NoSuchModel"));
    }

    /// What the host samples, read from each standard's XML, is the description's table: every
    /// Real output and every contact output, in value-reference order.
    #[test]
    fn the_host_samples_every_real_output_and_each_meshs_contact() {
        use model_description::{Causality, Type};
        for &id in model_description::model_identifiers() {
            let model = model_description::model(id);
            let mut outputs: Vec<_> = model
                .variables
                .iter()
                .filter(|v| v.causality == Causality::Output)
                .collect();
            outputs.sort_by_key(|v| v.vr);
            let reals: Vec<(&str, u32)> = outputs
                .iter()
                .filter(|v| v.ty == Type::Real)
                .map(|v| (v.name, v.vr))
                .collect();
            let contacts: Vec<u32> = outputs
                .iter()
                .filter(|v| v.ty == Type::Integer && v.name.starts_with("contact"))
                .map(|v| v.vr)
                .collect();
            let expected_contacts = if id == "BacklashTwoStage" { 2 } else { 1 };
            assert_eq!(contacts.len(), expected_contacts, "{id}");
            for standard in fmu::STANDARDS {
                let xml = (standard.description)(id);
                let doc = roxmltree::Document::parse(&xml).unwrap();
                assert_eq!(
                    sampled(&doc),
                    (reals.clone(), contacts.clone()),
                    "{id}, FMI {}",
                    standard.fmi_version
                );
            }
        }
    }
}
