//! `cargo xtask abi`: checks the C ABI of the cdylib against the official FMI 2.0 and FMI 3.0
//! headers.
//!
//! 1. cbindgen writes a header of the crate's exported functions (tests/abi/cbindgen.toml) that
//!    takes every FMI type from the official fmi2Functions.h;
//! 2. `cc -fsyntax-only -Werror` compiles tests/abi/check.c, which includes both headers: a Rust
//!    signature that differs from the standard's is a "conflicting types" error;
//! 3. a generated C file assigns every FMI 3.0 function (the `fmi3XxxTYPE`s of the official
//!    fmi3FunctionTypes.h) to a pointer of its standard type;
//! 4. the built library must export every FMI 2.0 and FMI 3.0 function: `nm -D --defined-only`
//!    of a shared object, the export table (`objdump -p`) of a DLL.
//!
//! With `--all-platforms` (and in `cargo xtask test` when the cross tools are present) step 2
//! also runs with each platform's C compiler (LLP64 Windows, aarch64) and step 3 on each binary.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::fmu;
use crate::platform::{self, BinaryFormat, Built, Platform};
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
    let platforms = fmu::platforms_from_arguments(args, "usage: cargo xtask abi [--all-platforms]")?;
    let built = if platforms.len() == 1 {
        step("building the FMU library (release) for the ABI check");
        util::run(util::cargo().args(["build", "--release", "--package", "backlash-fmu", "--lib"]))?;
        vec![Built {
            platform: &platform::LINUX64,
            path: fmu::library_path(),
        }]
    } else {
        fmu::package(&platforms)?
    };
    check(&built)
}

/// The checks, on libraries already built (the linux64 one at [`fmu::library_path`]).
pub fn check(built: &[Built]) -> Result<(), String> {
    let header_dirs = official_header_dirs()?;
    let generated = generate_header()?;
    let mut fmi3 = Vec::new();
    for dirs in &header_dirs {
        for b in built {
            compile_check(b.platform, dirs, &generated)?;
            fmi3 = compile_check3(b.platform, dirs, &generated)?;
        }
    }
    for b in built {
        check_exports(b.platform, &b.path, &fmi3)?;
    }
    Ok(())
}

/// Where one copy of the official headers is: FMI 2.0's and FMI 3.0's folders.
pub struct HeaderDirs {
    pub fmi2: PathBuf,
    pub fmi3: PathBuf,
}

/// Every copy of the official headers that this machine has: the one in fmpy (in `.venv`) and
/// the one in the `fmi-sys` crate used by the importer test. At least one must exist.
pub fn official_header_dirs() -> Result<Vec<HeaderDirs>, String> {
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

/// The platform's C compiler; for linux64 `$CC` when set.
fn compiler(platform: &Platform) -> String {
    match std::env::var("CC") {
        Ok(cc) if platform.is_host() => cc,
        _ => platform.c_compiler.command.to_string(),
    }
}

/// Proves that the check can fail with this compiler and these headers: a fmi2DoStep whose
/// first time argument is `float` must be rejected.
fn compiler_rejects_a_wrong_prototype(compiler: &str, official: &Path) -> Result<(), String> {
    let dir = util::target_dir().join("abi");
    let wrong = dir.join("wrong_prototype.c");
    let text = "#include \"fmi2Functions.h\"\n\
                fmi2Status fmi2DoStep(fmi2Component c, float t, fmi2Real h, fmi2Boolean b);\n";
    fs::write(&wrong, text).map_err(|e| format!("writing {}: {e}", wrong.display()))?;
    let out = Command::new(compiler)
        .args(["-std=c99", "-Werror", "-fsyntax-only", "-I"])
        .arg(official)
        .arg(&wrong)
        .output()
        .map_err(|e| format!("could not start {compiler}: {e}"))?;
    if out.status.success() {
        return Err(format!(
            "{compiler} accepted a fmi2DoStep prototype that contradicts {}: the ABI check would prove nothing",
            official.join("fmi2Functions.h").display()
        ));
    }
    Ok(())
}

fn compile_check(platform: &Platform, dirs: &HeaderDirs, generated: &Path) -> Result<(), String> {
    let official = &dirs.fmi2;
    let compiler = compiler(platform);
    step(&format!(
        "compiling tests/abi/check.c against {} ({}, {compiler})",
        official.display(),
        platform.name
    ));
    compiler_rejects_a_wrong_prototype(&compiler, official)?;
    let check_c = util::repo_root().join("tests").join("abi").join("check.c");
    util::run(syntax_check(&compiler, dirs, generated).arg(&check_c)).map_err(|e| {
        format!("{e}\nthe Rust signatures disagree with the official FMI 2.0 header (see the errors above)")
    })?;
    println!(
        "ok: the exported prototypes agree with {}",
        official.join("fmi2Functions.h").display()
    );
    Ok(())
}

/// `compiler -fsyntax-only` with both official header folders and the generated header's.
fn syntax_check(compiler: &str, dirs: &HeaderDirs, generated: &Path) -> Command {
    let generated_dir = generated.parent().expect("header is inside target/abi");
    let mut cmd = Command::new(compiler);
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
fn compile_check3(platform: &Platform, dirs: &HeaderDirs, generated: &Path) -> Result<Vec<String>, String> {
    let compiler = compiler(platform);
    let types = dirs.fmi3.join("fmi3FunctionTypes.h");
    step(&format!(
        "checking the FMI 3.0 functions against {} ({}, {compiler})",
        types.display(),
        platform.name
    ));
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
        "/* Generated by `cargo xtask abi`: every FMI 3.0 function of backlash_fmu assigned to a pointer of its\n \
         * standard type, without a cast. */\n#include \"fmi3Functions.h\"\n#include \"backlash_fmu.h\"\n",
    );
    for name in &names {
        c.push_str(&format!("{name}TYPE *const check_{name} = {name};\n"));
    }
    let file = util::target_dir().join("abi").join("check3.c");
    fs::write(&file, c).map_err(|e| format!("writing {}: {e}", file.display()))?;
    util::run(syntax_check(&compiler, dirs, generated).arg(&file)).map_err(|e| {
        format!("{e}\nthe Rust signatures disagree with the official FMI 3.0 header (see the errors above)")
    })?;
    println!(
        "ok: all {} FMI 3.0 functions agree with {}",
        names.len(),
        types.display()
    );
    Ok(names)
}

fn check_exports(platform: &Platform, library: &Path, fmi3: &[String]) -> Result<(), String> {
    step(&format!(
        "exported functions of {} ({})",
        util::shown(library),
        platform.name
    ));
    let mut exported = exported_functions(platform, library)?;
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

/// The fmi2* and fmi3* functions `library` exports, read with the platform's binutils.
fn exported_functions(platform: &Platform, library: &Path) -> Result<Vec<String>, String> {
    Ok(match platform.format {
        BinaryFormat::Elf => {
            let nm = platform.binutil("nm");
            dynamic_text_symbols(&util::output(
                Command::new(nm).args(["-D", "--defined-only"]).arg(library),
            )?)
        }
        BinaryFormat::Pe => {
            let objdump = platform.binutil("objdump");
            dll_export_names(&util::output(Command::new(objdump).arg("-p").arg(library))?)
        }
    }
    .into_iter()
    .filter(|name| name.starts_with("fmi2") || name.starts_with("fmi3"))
    .collect())
}

/// Functions (type `T`) of `nm -D --defined-only`.
fn dynamic_text_symbols(nm: &str) -> Vec<String> {
    nm.lines()
        .filter_map(|line| {
            let mut fields = line.split_whitespace().rev();
            let name = fields.next()?;
            let kind = fields.next()?;
            (kind == "T").then(|| name.to_string())
        })
        .collect()
}

/// Names of the "[Ordinal/Name Pointer] Table" of `objdump -p`: one `[ n] name` line per
/// export, up to the next blank line.
fn dll_export_names(objdump: &str) -> Vec<String> {
    objdump
        .lines()
        .skip_while(|line| !line.starts_with("[Ordinal/Name Pointer] Table"))
        .skip(1)
        .take_while(|line| !line.trim().is_empty())
        .filter_map(|line| {
            let (_, name) = line.trim().split_once(']')?;
            Some(name.trim().to_string())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{declares, dll_export_names, dynamic_text_symbols};

    #[test]
    fn exports_are_read_from_nm_and_from_the_dll_export_table() {
        let nm = "0000000000023fa4 T fmi2DoStep\n                 U malloc\n0000000000001000 D fmi2Data\n";
        assert_eq!(dynamic_text_symbols(nm), ["fmi2DoStep"]);
        let objdump = "\
Export Address Table -- Ordinal Base 1
\t[   0] +base[   1] 31880 Export RVA

[Ordinal/Name Pointer] Table
\t[   0] fmi2CancelStep
\t[   1] fmi2DoStep

PE File Base Relocations
\t[   2] not_an_export
";
        assert_eq!(dll_export_names(objdump), ["fmi2CancelStep", "fmi2DoStep"]);
        assert!(dll_export_names("no export table").is_empty());
    }

    #[test]
    fn a_declaration_is_a_name_followed_by_its_argument_list() {
        let header = "/* fmi2DoStep is below */\nfmi2Status fmi2DoStep (fmi2Component c);\nvoid fmi2DoStepX(void);";
        assert!(declares(header, "fmi2DoStep"));
        assert!(!declares(header, "fmi2CancelStep"));
        assert!(!declares("void xfmi2Reset(void);", "fmi2Reset"));
        assert!(!declares("/* fmi2Reset */", "fmi2Reset"));
    }
}
