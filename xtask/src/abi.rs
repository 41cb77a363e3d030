//! `cargo xtask abi`: checks the C ABI of the cdylib against the official FMI 2.0 and FMI 3.0
//! headers.
//!
//! 1. cbindgen writes a header of the crate's exported functions (tests/abi/cbindgen.toml) that
//!    takes every FMI type from the official fmi2Functions.h;
//! 2. `cc -fsyntax-only -Werror` compiles tests/abi/check.c, which includes both headers: a Rust
//!    signature that differs from the standard's is a "conflicting types" error;
//! 3. `nm -D --defined-only` on the built library must list every FMI 2.0 function.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::fmu;
use crate::python;
use crate::util::{self, step};

/// FMI 2.0 functions an importer of a Co-Simulation FMU may call: the common API (§2.1) and the
/// Co-Simulation API (§4.2). Unprefixed, as in a binary FMU built without FMI2_FUNCTION_PREFIX.
/// With [`MODEL_EXCHANGE_FUNCTIONS`], every function of FMI 2.0: all must be exported.
pub const CO_SIMULATION_FUNCTIONS: [&str; 34] = [
    "fmi2GetTypesPlatform",
    "fmi2GetVersion",
    "fmi2SetDebugLogging",
    "fmi2Instantiate",
    "fmi2FreeInstance",
    "fmi2SetupExperiment",
    "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode",
    "fmi2Terminate",
    "fmi2Reset",
    "fmi2GetReal",
    "fmi2GetInteger",
    "fmi2GetBoolean",
    "fmi2GetString",
    "fmi2SetReal",
    "fmi2SetInteger",
    "fmi2SetBoolean",
    "fmi2SetString",
    "fmi2GetFMUstate",
    "fmi2SetFMUstate",
    "fmi2FreeFMUstate",
    "fmi2SerializedFMUstateSize",
    "fmi2SerializeFMUstate",
    "fmi2DeSerializeFMUstate",
    "fmi2GetDirectionalDerivative",
    "fmi2SetRealInputDerivatives",
    "fmi2GetRealOutputDerivatives",
    "fmi2DoStep",
    "fmi2CancelStep",
    "fmi2GetStatus",
    "fmi2GetRealStatus",
    "fmi2GetIntegerStatus",
    "fmi2GetBooleanStatus",
    "fmi2GetStringStatus",
];

/// The Model Exchange functions (§3.2), exported beside them: the archives offer both interfaces.
pub const MODEL_EXCHANGE_FUNCTIONS: [&str; 10] = [
    "fmi2EnterEventMode",
    "fmi2NewDiscreteStates",
    "fmi2EnterContinuousTimeMode",
    "fmi2CompletedIntegratorStep",
    "fmi2SetTime",
    "fmi2SetContinuousStates",
    "fmi2GetDerivatives",
    "fmi2GetEventIndicators",
    "fmi2GetContinuousStates",
    "fmi2GetNominalsOfContinuousStates",
];

pub fn run(args: &[String]) -> Result<(), String> {
    if let Some(arg) = args.first() {
        return Err(format!("`cargo xtask abi` takes no arguments, got `{arg}`"));
    }
    step("building the FMU library (release) for the ABI check");
    util::run(util::cargo().args(["build", "--release", "--package", "backlash-fmu", "--lib"]))?;
    check()
}

/// The checks, on the library already built at [`fmu::library_path`].
pub fn check() -> Result<(), String> {
    let header_dirs = official_header_dirs()?;
    let generated = generate_header()?;
    let mut fmi3 = Vec::new();
    for dirs in &header_dirs {
        compile_check(dirs, &generated)?;
        fmi3 = compile_check3(dirs, &generated)?;
    }
    check_exports(&fmu::library_path(), &fmi3)
}

/// Where one copy of the official headers is: FMI 2.0's and FMI 3.0's folders.
struct HeaderDirs {
    fmi2: PathBuf,
    fmi3: PathBuf,
}

/// Every copy of the official headers that this machine has: the one in fmpy (in `.venv`) and
/// the one in the `fmi-sys` crate used by the importer test. At least one must exist.
fn official_header_dirs() -> Result<Vec<HeaderDirs>, String> {
    let mut dirs = Vec::new();
    if let Some(dir) = python::fmpy_header_dir() {
        dirs.push(HeaderDirs {
            fmi3: dir.clone(),
            fmi2: dir,
        });
    }
    if let Some(dir) = fmi_sys_header_dir() {
        let fmi3 = dir
            .parent()
            .and_then(Path::parent)
            .map(|p| p.join("fmi-standard3").join("headers"));
        if let Some(fmi3) = fmi3.filter(|d| d.join("fmi3Functions.h").is_file()) {
            dirs.push(HeaderDirs { fmi2: dir, fmi3 });
        }
    }
    if dirs.is_empty() {
        return Err(
            "official FMI 2.0 headers not found: neither .venv/lib/python3*/site-packages/fmpy/c-code/ \
             (created by `cargo xtask test`) nor the fmi-sys crate (fetched by `cargo build -p importer-test`) \
             holds fmi2Functions.h"
                .into(),
        );
    }
    Ok(dirs)
}

/// `fmi-sys` ships the standard's headers; `cargo metadata` says where the locked version is.
fn fmi_sys_header_dir() -> Option<PathBuf> {
    let metadata = util::output(util::cargo().args(["metadata", "--format-version", "1", "--offline"]))
        .or_else(|_| util::output(util::cargo().args(["metadata", "--format-version", "1"])))
        .ok()?;
    let key = "\"manifest_path\":\"";
    metadata.match_indices(key).find_map(|(at, _)| {
        let value = &metadata[at + key.len()..];
        let manifest = &value[..value.find('"')?];
        let package_dir = Path::new(manifest).parent()?;
        let name = package_dir.file_name()?.to_str()?;
        let dir = package_dir.join("fmi-standard2").join("headers");
        (name.starts_with("fmi-sys-") && dir.join("fmi2Functions.h").is_file()).then_some(dir)
    })
}

fn generate_header() -> Result<PathBuf, String> {
    step("generating the C header of backlash_fmu with cbindgen");
    let root = util::repo_root();
    let config_path = root.join("tests").join("abi").join("cbindgen.toml");
    let config =
        cbindgen::Config::from_file(&config_path).map_err(|e| format!("reading {}: {e}", util::shown(&config_path)))?;
    let out_dir = util::target_dir().join("abi");
    fs::create_dir_all(&out_dir).map_err(|e| format!("creating {}: {e}", out_dir.display()))?;
    let header = out_dir.join("backlash_fmu.h");
    cbindgen::Builder::new()
        .with_crate(&root)
        .with_config(config)
        .generate()
        .map_err(|e| format!("cbindgen: {e}"))?
        .write_to_file(&header);
    let text = fs::read_to_string(&header).map_err(|e| format!("reading {}: {e}", header.display()))?;
    let missing: Vec<&str> = all_functions().filter(|name| !declares(&text, name)).collect();
    if !missing.is_empty() {
        return Err(format!(
            "{} does not declare {} of the FMI 2.0 functions: {}",
            util::shown(&header),
            missing.len(),
            missing.join(", ")
        ));
    }
    println!(
        "{}: declares all {} FMI 2.0 functions",
        util::shown(&header),
        all_functions().count()
    );
    Ok(header)
}

/// Every FMI 2.0 function: the common, Co-Simulation and Model Exchange ones.
fn all_functions() -> impl Iterator<Item = &'static str> {
    CO_SIMULATION_FUNCTIONS.into_iter().chain(MODEL_EXCHANGE_FUNCTIONS)
}

/// True if `text` has a declaration `... name(`; a bare mention in a comment does not count.
fn declares(text: &str, name: &str) -> bool {
    text.match_indices(name).any(|(at, _)| {
        let before = text[..at].chars().next_back();
        let after = text[at + name.len()..].trim_start();
        !before.is_some_and(|c| c.is_alphanumeric() || c == '_') && after.starts_with('(')
    })
}

fn compiler() -> String {
    std::env::var("CC").unwrap_or_else(|_| "cc".into())
}

/// Proves that the check can fail with this compiler and these headers: a fmi2DoStep whose
/// first time argument is `float` must be rejected.
fn compiler_rejects_a_wrong_prototype(official: &Path) -> Result<(), String> {
    let dir = util::target_dir().join("abi");
    let wrong = dir.join("wrong_prototype.c");
    let text = "#include \"fmi2Functions.h\"\n\
                fmi2Status fmi2DoStep(fmi2Component c, float t, fmi2Real h, fmi2Boolean b);\n";
    fs::write(&wrong, text).map_err(|e| format!("writing {}: {e}", wrong.display()))?;
    let out = Command::new(compiler())
        .args(["-std=c99", "-Werror", "-fsyntax-only", "-I"])
        .arg(official)
        .arg(&wrong)
        .output()
        .map_err(|e| format!("could not start {}: {e}", compiler()))?;
    if out.status.success() {
        return Err(format!(
            "{} accepted a fmi2DoStep prototype that contradicts {}: the ABI check would prove nothing",
            compiler(),
            official.join("fmi2Functions.h").display()
        ));
    }
    Ok(())
}

fn compile_check(dirs: &HeaderDirs, generated: &Path) -> Result<(), String> {
    let official = &dirs.fmi2;
    step(&format!("compiling tests/abi/check.c against {}", official.display()));
    compiler_rejects_a_wrong_prototype(official)?;
    let check_c = util::repo_root().join("tests").join("abi").join("check.c");
    util::run(syntax_check(dirs, generated).arg(&check_c)).map_err(|e| {
        format!("{e}\nthe Rust signatures disagree with the official FMI 2.0 header (see the errors above)")
    })?;
    println!(
        "ok: the exported prototypes agree with {}",
        official.join("fmi2Functions.h").display()
    );
    Ok(())
}

/// `cc -fsyntax-only` with both official header folders and the generated header's.
fn syntax_check(dirs: &HeaderDirs, generated: &Path) -> Command {
    let generated_dir = generated.parent().expect("header is inside target/abi");
    let mut cmd = Command::new(compiler());
    cmd.args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-fsyntax-only"])
        .arg("-I")
        .arg(&dirs.fmi2)
        .arg("-I")
        .arg(&dirs.fmi3)
        .arg("-I")
        .arg(generated_dir);
    cmd
}

/// The FMI 3.0 functions, read from the official fmi3FunctionTypes.h (every `fmi3XxxTYPE`), each
/// assigned to a pointer of its standard type in a generated C file: a Rust signature that
/// differs from the standard's is an incompatible-pointer error. Returns the names.
fn compile_check3(dirs: &HeaderDirs, generated: &Path) -> Result<Vec<String>, String> {
    let types = dirs.fmi3.join("fmi3FunctionTypes.h");
    step(&format!("checking the FMI 3.0 functions against {}", types.display()));
    let text = fs::read_to_string(&types).map_err(|e| format!("reading {}: {e}", types.display()))?;
    let mut names: Vec<String> = text
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .filter_map(|word| word.strip_suffix("TYPE"))
        .filter(|name| name.starts_with("fmi3"))
        .map(str::to_string)
        .collect();
    names.sort();
    names.dedup();
    if names.len() < 70 {
        return Err(format!(
            "{} declares only {} fmi3 function types: not the official header?",
            types.display(),
            names.len()
        ));
    }
    let mut c = String::from(
        "/* Generated by `cargo xtask abi`: every FMI 3.0 function of backlash_fmu assigned to a pointer of its\n          * standard type, without a cast. */\n#include \"fmi3Functions.h\"\n#include \"backlash_fmu.h\"\n",
    );
    for name in &names {
        c.push_str(&format!("{name}TYPE *const check_{name} = {name};\n"));
    }
    let file = util::target_dir().join("abi").join("check3.c");
    fs::write(&file, c).map_err(|e| format!("writing {}: {e}", file.display()))?;
    util::run(syntax_check(dirs, generated).arg(&file)).map_err(|e| {
        format!("{e}\nthe Rust signatures disagree with the official FMI 3.0 header (see the errors above)")
    })?;
    println!(
        "ok: all {} FMI 3.0 functions agree with {}",
        names.len(),
        types.display()
    );
    Ok(names)
}

fn check_exports(library: &Path, fmi3: &[String]) -> Result<(), String> {
    step(&format!("exported dynamic symbols of {}", util::shown(library)));
    let listing = util::output(Command::new("nm").args(["-D", "--defined-only"]).arg(library))?;
    let mut exported: Vec<String> = listing
        .lines()
        .filter_map(|line| {
            let mut fields = line.split_whitespace().rev();
            let name = fields.next()?;
            let kind = fields.next()?;
            ((name.starts_with("fmi2") || name.starts_with("fmi3")) && kind == "T").then(|| name.to_string())
        })
        .collect();
    exported.sort();
    for name in &exported {
        println!("  {name}");
    }
    let mut required: Vec<&str> = all_functions().collect();
    required.extend(fmi3.iter().map(String::as_str));
    let missing: Vec<&str> = required
        .iter()
        .copied()
        .filter(|name| !exported.iter().any(|e| e == name))
        .collect();
    let unknown: Vec<&str> = exported
        .iter()
        .map(String::as_str)
        .filter(|e| !required.contains(e))
        .collect();
    if !missing.is_empty() {
        return Err(format!("the library does not export: {}", missing.join(", ")));
    }
    if !unknown.is_empty() {
        return Err(format!(
            "the library exports fmi2/fmi3 names that the standards do not define: {}",
            unknown.join(", ")
        ));
    }
    println!(
        "ok: all {} FMI 2.0 functions (Model Exchange and Co-Simulation) and all {} FMI 3.0 functions are exported",
        all_functions().count(),
        fmi3.len()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::declares;

    #[test]
    fn a_declaration_is_a_name_followed_by_its_argument_list() {
        let header = "/* fmi2DoStep is below */\nfmi2Status fmi2DoStep (fmi2Component c);\nvoid fmi2DoStepX(void);";
        assert!(declares(header, "fmi2DoStep"));
        assert!(!declares(header, "fmi2CancelStep"));
        assert!(!declares("void xfmi2Reset(void);", "fmi2Reset"));
        assert!(!declares("/* fmi2Reset */", "fmi2Reset"));
    }
}
