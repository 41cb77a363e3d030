//! Running the benchmarks: the native C host, the Python bench and criterion, each measurement
//! collected into plain data for report.rs, with the commands that produced it.

use std::collections::BTreeMap;
use std::fs;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Instant, SystemTime};

use serde::Deserialize;

use super::{Plan, DRIVE_AND_WEB, GEARBOX, MODEL};
use crate::{fmu, python, rigs, util};

/// The `@ key values…` lines of every tool, by key, in order of arrival.
#[derive(Default)]
pub(super) struct Results(BTreeMap<String, Vec<Vec<String>>>);

impl Results {
    fn collect(&mut self, text: &str) {
        for line in text.lines() {
            let mut words = line.split_whitespace();
            if words.next() != Some("@") {
                continue;
            }
            if let Some(key) = words.next() {
                self.0
                    .entry(key.to_string())
                    .or_default()
                    .push(words.map(str::to_string).collect());
            }
        }
    }

    pub(super) fn rows(&self, key: &str) -> &[Vec<String>] {
        self.0.get(key).map_or(&[], Vec::as_slice)
    }

    pub(super) fn row(&self, key: &str) -> Result<&[String], String> {
        self.rows(key)
            .last()
            .map(Vec::as_slice)
            .ok_or_else(|| format!("no result `{key}` in the benchmark output"))
    }

    pub(super) fn num(&self, key: &str, index: usize) -> Result<f64, String> {
        number(self.row(key)?, index, key)
    }
}

#[cfg(test)]
impl Results {
    /// The results of a text of `@ key values…` lines, as the tools print them (report.rs's tests).
    pub(super) fn parse(text: &str) -> Results {
        let mut results = Results::default();
        results.collect(text);
        results
    }
}

pub(super) fn number(row: &[String], index: usize, key: &str) -> Result<f64, String> {
    row.get(index)
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| format!("result `{key}`: no number at position {index} in {row:?}"))
}

/// One criterion bench: the estimate criterion prints and its 95% interval, in ns.
pub(super) struct CriterionEstimate {
    pub name: String,
    pub low_ns: f64,
    pub estimate_ns: f64,
    pub high_ns: f64,
}

/// The paired measure of the damped event-free steps against the plain one (benches/physics.rs,
/// `paired_damped_step`): blocks of each alternating in one process.
pub(super) struct PairedDamped {
    pub rounds: u64,
    pub steps_per_block: u64,
    /// The plain step's median time [ns].
    pub plain_ns: f64,
    /// Per damped bench: its name, median time [ns], and the median of the rounds' ratios to the
    /// plain step with its 95% interval (low, median, high).
    pub damped: Vec<(String, f64, [f64; 3])>,
}

impl PairedDamped {
    /// The `paired-damped-step {json}` line of the bench's output, if it printed one.
    pub fn parse(output: &str) -> Result<Option<PairedDamped>, String> {
        let Some(json) = output.lines().find_map(|l| l.strip_prefix("paired-damped-step ")) else {
            return Ok(None);
        };
        let v: serde_json::Value =
            serde_json::from_str(json).map_err(|e| format!("paired-damped-step: {e}: {json}"))?;
        let num = |key: &str| {
            v[key]
                .as_f64()
                .ok_or_else(|| format!("paired-damped-step: no number `{key}`"))
        };
        let mut damped = Vec::new();
        for name in ["step_1ms_no_switch_damped_law1", "step_1ms_no_switch_damped_law2"] {
            let ratio: Vec<f64> = v[format!("{name}_ratio")]
                .as_array()
                .map(|a| a.iter().filter_map(|x| x.as_f64()).collect())
                .unwrap_or_default();
            let [low, mid, high] = ratio[..] else {
                return Err(format!("paired-damped-step: `{name}_ratio` is not three numbers"));
            };
            damped.push((name.to_string(), num(&format!("{name}_ns"))?, [low, mid, high]));
        }
        Ok(Some(PairedDamped {
            rounds: num("rounds")? as u64,
            steps_per_block: num("steps_per_block")? as u64,
            plain_ns: num("step_1ms_no_switch_ns")?,
            damped,
        }))
    }
}

/// Everything one run measured, and the commands that measured it, in order.
pub(super) struct Measurements {
    pub results: Results,
    pub criterion: Vec<CriterionEstimate>,
    pub paired_damped: Option<PairedDamped>,
    pub commands: Vec<String>,
}

/// The machine and the load around the run, for the report's first table.
pub(super) struct Facts {
    pub load_start: String,
    pub load_end: String,
    pub elapsed_s: f64,
    pub date: String,
    pub nproc: String,
    pub cpu: String,
    pub kernel: String,
    pub rustc: String,
    pub cc: String,
    pub python: String,
}

impl Facts {
    /// Read at the end of the run; `load_start` was read before anything was built.
    pub(super) fn collect(load_start: String, started: Instant) -> Facts {
        Facts {
            load_start,
            load_end: read_trimmed("/proc/loadavg"),
            elapsed_s: started.elapsed().as_secs_f64(),
            date: first_line(Command::new("date").args(["-u", "+%Y-%m-%d %H:%M"])),
            nproc: first_line(&mut Command::new("nproc")),
            cpu: cpu_model(),
            kernel: first_line(Command::new("uname").args(["-sr"])),
            rustc: first_line(Command::new("rustc").arg("--version")),
            cc: first_line(Command::new("cc").arg("--version")),
            python: first_line(Command::new(python::venv_python()).arg("--version")),
        }
    }
}

pub(super) fn read_trimmed(path: &str) -> String {
    fs::read_to_string(path)
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|_| "unknown".into())
}

fn first_line(cmd: &mut Command) -> String {
    util::output(cmd)
        .ok()
        .and_then(|s| s.lines().next().map(str::to_string))
        .unwrap_or_else(|| "unknown".into())
}

fn cpu_model() -> String {
    read_trimmed("/proc/cpuinfo")
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split(':').nth(1))
        .map_or_else(|| "unknown".into(), |s| s.trim().to_string())
}

/// A command line as text for the report, with paths inside the repository made relative.
fn describe(cmd: &Command) -> String {
    let root = format!("{}/", util::repo_root().display());
    let program = cmd.get_program().to_string_lossy().into_owned();
    // The cargo that runs xtask, shown by name.
    let program = if program.ends_with("/cargo") {
        "cargo".to_string()
    } else {
        program
    };
    let mut words = vec![program];
    words.extend(cmd.get_args().map(|a| a.to_string_lossy().into_owned()));
    let words: Vec<String> = words
        .into_iter()
        .map(|w| {
            let w = w.replace(&root, "");
            if w.contains(['{', '}', ' ']) {
                format!("'{w}'")
            } else {
                w
            }
        })
        .collect();
    words.join(" ")
}

/// An FMI 2.0 archive unpacked for the native host: what the host passes to fmi2Instantiate
/// and where it finds the library.
struct Archive {
    library: PathBuf,
    guid: String,
    resources: String,
}

impl Archive {
    /// Unpacks `target/fmu/<id>.fmu` into `work/<id>`; the archive and the `#define`s of the value
    /// references and start values of its description, named `VR_<infix><variable>` and
    /// `START_<infix><variable>`.
    fn unpack(work: &Path, id: &str, infix: &str) -> Result<(Archive, String), String> {
        let dir = work.join(id);
        let xml = unpack(&util::fmu_dir().join(format!("{id}.fmu")), &dir)?;
        let (guid, defines) = guid_and_vr_defines(&xml, infix)?;
        let archive = Archive {
            library: dir.join("binaries").join("linux64").join(format!("{id}.so")),
            guid,
            resources: format!("file://{}", dir.join("resources").display()),
        };
        Ok((archive, defines))
    }

    /// The host's arguments for it: `<lib.so> <guid> <resource-uri>`.
    fn arguments(&self) -> [String; 3] {
        [
            self.library.display().to_string(),
            self.guid.clone(),
            self.resources.clone(),
        ]
    }
}

/// The compiled native host and the unpacked archives it loads; collects every tool's results.
pub(super) struct Runner {
    host: PathBuf,
    /// BacklashShaft, the model of every mode.
    shaft: Archive,
    /// The archives of [`DRIVE_AND_WEB`] and [`GEARBOX`], in that order, for the suite's rows of
    /// the other drives.
    drives: Vec<Archive>,
    measured: Measurements,
}

impl Runner {
    /// Unpacks BacklashShaft.fmu and the archives of [`DRIVE_AND_WEB`] and [`GEARBOX`] into `work`
    /// and compiles benches/native_host.c against fmpy's FMI headers, the value references and
    /// start values of the archives' own modelDescription.xml (bench_vr.h: `VR_<name>` of
    /// BacklashShaft, `VR_<model>_<name>` and `START_<model>_<name>` of the others) and
    /// BacklashShaft's rig from tests/fixtures/rigs.toml (bench_rig.h).
    pub(super) fn prepare(work: &Path) -> Result<Runner, String> {
        let (shaft, defines) = Archive::unpack(work, MODEL, "")?;
        let mut vr_header =
            String::from("/* Written by cargo xtask bench from the archives' modelDescription.xml. */\n") + &defines;
        let mut drives = Vec::new();
        for id in DRIVE_AND_WEB.into_iter().chain([GEARBOX]) {
            let (archive, defines) = Archive::unpack(work, id, &format!("{id}_"))?;
            vr_header.push_str(&defines);
            drives.push(archive);
        }
        // The FMI 3.0 archive's token, for the FMI 3.0 step of the suite (same library).
        let xml3 = unpack(
            &fmu::FMI3.out_dir().join(format!("{MODEL}.fmu")),
            &work.join(format!("{MODEL}-fmi3")),
        )?;
        let doc3 = roxmltree::Document::parse(&xml3).map_err(|e| format!("FMI 3.0 modelDescription.xml: {e}"))?;
        let token = fmu::FMI3.token(&doc3)?;
        vr_header.push_str(&format!("#define INSTANTIATION_TOKEN \"{token}\"\n"));
        fs::write(work.join("bench_vr.h"), vr_header).map_err(|e| format!("writing bench_vr.h: {e}"))?;
        // The rig the host sets, by the same names: the parameters and gains the Python bench's
        // loop sets too (tests/python/rigs.py reads the same fixture).
        let xml = fs::read_to_string(work.join(MODEL).join("modelDescription.xml"))
            .map_err(|e| format!("reading the unpacked {MODEL} modelDescription.xml: {e}"))?;
        let rig = rigs::rig(&util::repo_root(), MODEL, "parameters")?;
        fs::write(work.join("bench_rig.h"), rig_header(MODEL, &xml, &rig)?)
            .map_err(|e| format!("writing bench_rig.h: {e}"))?;
        let headers = python::fmpy_header_dir().ok_or("no fmi2Functions.h in .venv (fmpy's c-code)")?;
        let host = work.join("native_host");
        let mut compile = Command::new("cc");
        compile
            .current_dir(util::repo_root())
            .args(["-O2", "-Wall", "-Wextra", "-Werror"])
            .arg(format!("-I{}", headers.display()))
            .arg(format!("-I{}", work.display()))
            .arg("-o")
            .arg(&host)
            .arg("benches/native_host.c")
            .args(["-ldl", "-lm"]);
        let compile_text = describe(&compile);
        util::run(&mut compile)?;

        Ok(Runner {
            host,
            shaft,
            drives,
            measured: Measurements {
                results: Results::default(),
                criterion: Vec::new(),
                paired_damped: None,
                commands: vec![compile_text],
            },
        })
    }

    /// Runs a benchmark tool, keeps its command for the report and collects its results.
    fn run(&mut self, cmd: &mut Command) -> Result<(), String> {
        let text = describe(cmd);
        println!("$ {text}");
        let started = Instant::now();
        let out = util::output(cmd)?;
        println!("  ({:.1} s)", started.elapsed().as_secs_f64());
        self.measured.results.collect(&out);
        self.measured.commands.push(text);
        Ok(())
    }

    fn native(&mut self, mode: &[String]) -> Result<(), String> {
        let mut cmd = Command::new(&self.host);
        cmd.current_dir(util::repo_root())
            .args(self.shaft.arguments())
            .args(mode);
        self.run(&mut cmd)
    }

    /// Section 1: the per-call costs and their floors, and the event-free steps of the archives
    /// of [`DRIVE_AND_WEB`] and [`GEARBOX`]; rows taken in turn round by round.
    pub(super) fn native_suite(&mut self, plan: &Plan) -> Result<(), String> {
        let mut mode = strings(&[
            "suite",
            &plan.suite_rounds.to_string(),
            &plan.steps_per_batch.to_string(),
        ]);
        mode.extend(self.drives.iter().flat_map(Archive::arguments));
        self.native(&mode)
    }

    /// Growth with the number of steps, one process each.
    pub(super) fn native_scale(&mut self, plan: &Plan) -> Result<(), String> {
        for n in &plan.scale_steps {
            self.native(&strings(&["scale", &n.to_string()]))?;
        }
        Ok(())
    }

    /// Many instances stepped round-robin, one process each.
    pub(super) fn native_instances(&mut self, plan: &Plan) -> Result<(), String> {
        for k in &plan.instance_counts {
            self.native(&strings(&[
                "instances",
                &k.to_string(),
                &plan.batches.to_string(),
                &plan.instance_steps_per_batch.to_string(),
            ]))?;
        }
        Ok(())
    }

    pub(super) fn native_piloop(&mut self, plan: &Plan) -> Result<(), String> {
        self.native(&strings(&[
            "piloop",
            &plan.loop_seconds.to_string(),
            &plan.batches.to_string(),
        ]))
    }

    /// The PI loop through fmpy and in scipy (benches/python_bench.py).
    pub(super) fn python(&mut self, plan: &Plan) -> Result<(), String> {
        let mut py = Command::new(python::venv_python());
        py.current_dir(util::repo_root())
            .env("BACKLASH_FMU_DIR", util::fmu_dir())
            .arg("benches/python_bench.py")
            .args(["--loop-seconds", &plan.loop_seconds.to_string()])
            .args(["--repeats", &plan.loop_repeats.to_string()])
            .args(["--scipy-seconds", &plan.loop_seconds.to_string()])
            .args(["--simulate-seconds", &plan.loop_seconds.to_string()])
            .args(["--sweep", plan.sweep]);
        self.run(&mut py)
    }

    /// Samples per second of the tolerance sweep, serially and on LocalClusters of 1 and 2 workers
    /// (benches/sweep_bench.py).
    pub(super) fn sweep(&mut self, plan: &Plan) -> Result<(), String> {
        let mut py = Command::new(python::venv_python());
        py.current_dir(util::repo_root())
            .env("BACKLASH_FMU_DIR", util::fmu_dir())
            .arg("benches/sweep_bench.py")
            .args(["--samples", &plan.tolerance_samples.to_string()])
            .args(["--repeats", &plan.tolerance_repeats.to_string()]);
        self.run(&mut py)
    }

    /// Identification of a 10 s run at 1 kHz (design/benches/identify.rs), built first, then
    /// measured on one core (taskset), as the issue's target says.
    pub(super) fn identify(&mut self) -> Result<(), String> {
        util::run(util::cargo().args(["bench", "-p", "backlash-design", "--bench", "identify", "--no-run"]))?;
        let mut cmd = Command::new("taskset");
        cmd.current_dir(util::repo_root())
            .args(["-c", "0"])
            .arg(util::cargo().get_program())
            .args(["bench", "-p", "backlash-design", "--bench", "identify"]);
        self.run(&mut cmd)
    }

    /// The criterion bench of the physics core; its figures are read from the estimates.json
    /// files criterion writes during this run.
    pub(super) fn criterion(&mut self) -> Result<(), String> {
        // Built first on every core; then measured on one (taskset): the host may run this
        // machine's cores at different speeds, and benches that are compared (the damped step
        // with the plain one) must not each land on another.
        util::run(util::cargo().args(["bench", "--bench", "physics", "--no-run"]))?;
        let mut cmd = Command::new("taskset");
        cmd.current_dir(util::repo_root())
            .args(["-c", "0"])
            .arg(util::cargo().get_program())
            .args([
                "bench",
                "--bench",
                "physics",
                "--",
                "--warm-up-time",
                "1",
                "--measurement-time",
                "3",
            ]);
        let text = describe(&cmd);
        println!("$ {text}");
        // Whole seconds, so that a file system with coarse timestamps still counts this run's files.
        let since = SystemTime::now() - std::time::Duration::from_secs(1);
        let out = util::output(&mut cmd)?;
        let dir = criterion_dir();
        let found = read_criterion(&dir, since)?;
        if found.is_empty() {
            return Err(format!(
                "no criterion results written under {} by `{text}`:\n{out}",
                dir.display()
            ));
        }
        self.measured.criterion = found;
        self.measured.paired_damped = PairedDamped::parse(&out)?;
        self.measured.commands.push(text);
        Ok(())
    }

    pub(super) fn finish(self) -> Measurements {
        self.measured
    }
}

fn strings(words: &[&str]) -> Vec<String> {
    words.iter().map(|w| w.to_string()).collect()
}

/// Where criterion writes its results: $CRITERION_HOME, else `<target>/criterion` (criterion's
/// own order of precedence, cargo's target directory being the one xtask uses).
fn criterion_dir() -> PathBuf {
    std::env::var_os("CRITERION_HOME")
        .filter(|dir| !dir.is_empty())
        .map_or_else(|| util::target_dir().join("criterion"), PathBuf::from)
}

/// The parts of criterion's `new/estimates.json` the report uses (values in ns).
#[derive(Deserialize)]
struct Estimates {
    mean: Estimate,
    /// Present when criterion sampled linearly; null for flat sampling.
    slope: Option<Estimate>,
}

#[derive(Deserialize)]
struct Estimate {
    point_estimate: f64,
    confidence_interval: Interval,
}

#[derive(Deserialize)]
struct Interval {
    lower_bound: f64,
    upper_bound: f64,
}

/// criterion's `new/benchmark.json`: the id of the bench as criterion prints it.
#[derive(Deserialize)]
struct BenchmarkId {
    title: String,
}

fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, String> {
    let text = fs::read_to_string(path).map_err(|e| format!("reading {}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// Every bench under `dir` whose `new/estimates.json` was written at or after `since`, in the
/// order criterion ran them. The figure is the one criterion prints as `time:` (its "typical"
/// estimate): the slope of the linear regression when sampled linearly, else the mean.
fn read_criterion(dir: &Path, since: SystemTime) -> Result<Vec<CriterionEstimate>, String> {
    let mut files = Vec::new();
    estimates_files(dir, &mut files)?;
    let mut written = Vec::new();
    for path in files {
        let modified = fs::metadata(&path)
            .and_then(|m| m.modified())
            .map_err(|e| format!("{}: {e}", path.display()))?;
        if modified >= since {
            written.push((modified, path));
        }
    }
    written.sort();
    written
        .into_iter()
        .map(|(_, path)| {
            let estimates: Estimates = read_json(&path)?;
            let id: BenchmarkId = read_json(&path.with_file_name("benchmark.json"))?;
            let typical = estimates.slope.unwrap_or(estimates.mean);
            Ok(CriterionEstimate {
                name: id.title,
                low_ns: typical.confidence_interval.lower_bound,
                estimate_ns: typical.point_estimate,
                high_ns: typical.confidence_interval.upper_bound,
            })
        })
        .collect()
}

/// The `<bench>/new/estimates.json` files below `dir` (a bench id may span several levels);
/// `base/` and `change/` hold copies and comparisons, not this run's estimates.
fn estimates_files(dir: &Path, found: &mut Vec<PathBuf>) -> Result<(), String> {
    let entries = match fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(format!("{}: {e}", dir.display())),
    };
    for entry in entries {
        let path = entry.map_err(|e| format!("{}: {e}", dir.display()))?.path();
        if !path.is_dir() {
            continue;
        }
        if path.file_name().is_some_and(|name| name == "new") {
            let file = path.join("estimates.json");
            if file.is_file() {
                found.push(file);
            }
        } else {
            estimates_files(&path, found)?;
        }
    }
    Ok(())
}

/// Unpacks the archive into `dir` (fresh) and returns its modelDescription.xml.
fn unpack(archive: &Path, dir: &Path) -> Result<String, String> {
    let _ = fs::remove_dir_all(dir);
    let file = fs::File::open(archive).map_err(|e| format!("{}: {e}", archive.display()))?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| format!("{}: {e}", archive.display()))?;
    zip.extract(dir)
        .map_err(|e| format!("unpacking {}: {e}", archive.display()))?;
    fs::create_dir_all(dir.join("resources")).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut xml = String::new();
    fs::File::open(dir.join("modelDescription.xml"))
        .and_then(|mut f| f.read_to_string(&mut xml))
        .map_err(|e| format!("reading the unpacked modelDescription.xml: {e}"))?;
    Ok(xml)
}

/// The guid of the archive's description, `#define VR_<infix><name> <vr>u` for every
/// ScalarVariable of it, `#define START_<infix><name> <start>` for every Real with a finite start
/// value (the host computes its schedules' states from them), and
/// `#define VR_<infix>EVENT_INDICATORS <n>` of its event indicators.
fn guid_and_vr_defines(xml: &str, infix: &str) -> Result<(String, String), String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("modelDescription.xml: {e}"))?;
    let guid = fmu::FMI2.token(&doc)?;
    let mut text = String::new();
    let mut count = 0;
    for variable in doc.descendants().filter(|n| n.has_tag_name("ScalarVariable")) {
        let (Some(name), Some(vr)) = (variable.attribute("name"), variable.attribute("valueReference")) else {
            return Err(format!("a ScalarVariable without name or valueReference: {variable:?}"));
        };
        // der(theta_m) → VR_der_theta_m: a C identifier.
        let ident: String = name
            .trim_end_matches(')')
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .collect();
        text.push_str(&format!("#define VR_{infix}{ident} {vr}u\n"));
        let start = variable
            .children()
            .find(|n| n.has_tag_name("Real"))
            .and_then(|real| real.attribute("start"));
        if let Some(start) = start {
            let value: f64 = start
                .parse()
                .map_err(|e| format!("{name}'s start value `{start}` is not a number: {e}"))?;
            // Rust's shortest decimal that reads back as the same f64; C reads it back exactly too.
            if value.is_finite() {
                text.push_str(&format!("#define START_{infix}{ident} {value:?}\n"));
            }
        }
        count += 1;
    }
    if count == 0 {
        return Err("modelDescription.xml lists no ScalarVariable".into());
    }
    // The number of event indicators Model Exchange's fmi2GetEventIndicators fills.
    let indicators = doc
        .root_element()
        .attribute("numberOfEventIndicators")
        .ok_or("modelDescription.xml has no numberOfEventIndicators")?;
    text.push_str(&format!("#define VR_{infix}EVENT_INDICATORS {indicators}\n"));
    Ok((guid.to_string(), text))
}

/// bench_rig.h: the rig of the model `id` as the native host sets it, `#define RIG_<name> <value>`
/// for each of its values (Rust's shortest decimal that reads back as the same f64, which C reads
/// back exactly too), and `RIG_VR`, `RIG_VALUE`: initializers of every value reference and value
/// of it, in the same order, for one fmi2SetReal. Every name must be a variable of the
/// description `xml`, whose `VR_<name>` bench_vr.h defines.
fn rig_header(id: &str, xml: &str, rig: &[(String, f64)]) -> Result<String, String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("modelDescription.xml: {e}"))?;
    let described = |name: &str| {
        doc.descendants()
            .any(|n| n.has_tag_name("ScalarVariable") && n.attribute("name") == Some(name))
    };
    let identifier = |name: &str| {
        name.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
    };
    if rig.is_empty() {
        return Err(format!("{id}'s rig in tests/fixtures/rigs.toml sets nothing"));
    }
    let mut text = format!("/* Written by cargo xtask bench: {id}'s rig from tests/fixtures/rigs.toml. */\n");
    for (name, value) in rig {
        if !identifier(name) || !described(name) {
            return Err(format!(
                "{id}'s rig in tests/fixtures/rigs.toml sets `{name}`, not a variable of its modelDescription.xml"
            ));
        }
        if !value.is_finite() {
            return Err(format!("{id}'s rig in tests/fixtures/rigs.toml sets {name} = {value}"));
        }
        text.push_str(&format!("#define RIG_{name} {value:?}\n"));
    }
    let list = |prefix: &str| {
        let items: Vec<String> = rig.iter().map(|(name, _)| format!("{prefix}{name}")).collect();
        format!("{{{}}}", items.join(", "))
    };
    text.push_str(&format!(
        "#define RIG_VR {}\n#define RIG_VALUE {}\n",
        list("VR_"),
        list("RIG_")
    ));
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn write_bench(root: &Path, dir: &str, title: &str, estimates: &str, at: SystemTime) {
        let new = root.join(dir).join("new");
        fs::create_dir_all(&new).unwrap();
        fs::write(
            new.join("benchmark.json"),
            format!(r#"{{"title":"{title}","full_id":"{title}"}}"#),
        )
        .unwrap();
        let file = new.join("estimates.json");
        fs::write(&file, estimates).unwrap();
        fs::File::options()
            .write(true)
            .open(&file)
            .unwrap()
            .set_modified(at)
            .unwrap();
    }

    fn estimate(point: f64) -> String {
        format!(
            r#"{{"confidence_interval":{{"confidence_level":0.95,"lower_bound":{},"upper_bound":{}}},"point_estimate":{point},"standard_error":0.1}}"#,
            point - 1.0,
            point + 1.0
        )
    }

    #[test]
    fn criterion_estimates_are_read_in_run_order_slope_first() {
        let root = std::env::temp_dir().join(format!("xtask-criterion-{}", std::process::id()));
        let _ = fs::remove_dir_all(&root);
        let since = SystemTime::now() - Duration::from_secs(100);
        let all = |mean: f64, slope: &str| {
            format!(
                r#"{{"mean":{m},"median":{m},"median_abs_dev":{m},"slope":{slope},"std_dev":{m}}}"#,
                m = estimate(mean)
            )
        };
        // Written in the order b, a: the run order, not the name order.
        write_bench(
            &root,
            "b",
            "b",
            &all(20.0, &estimate(21.0)),
            since + Duration::from_secs(10),
        );
        write_bench(&root, "a", "a", &all(30.0, "null"), since + Duration::from_secs(20));
        // Before this run: left out.
        write_bench(&root, "old", "old", &all(40.0, "null"), since - Duration::from_secs(10));
        // A group with a function id, two levels deep, and criterion's copy of a baseline.
        write_bench(&root, "g/f", "g/f", &all(50.0, "null"), since + Duration::from_secs(30));
        fs::create_dir_all(root.join("g/f/base")).unwrap();
        fs::write(root.join("g/f/base/estimates.json"), all(60.0, "null")).unwrap();

        let found = read_criterion(&root, since).unwrap();
        let got: Vec<(&str, f64, f64, f64)> = found
            .iter()
            .map(|e| (e.name.as_str(), e.low_ns, e.estimate_ns, e.high_ns))
            .collect();
        assert_eq!(
            got,
            [
                ("b", 20.0, 21.0, 22.0),
                ("a", 29.0, 30.0, 31.0),
                ("g/f", 49.0, 50.0, 51.0)
            ]
        );
        fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn the_vr_header_defines_every_value_reference_and_each_real_start_value() {
        let xml = r#"<fmiModelDescription guid="{g}" numberOfEventIndicators="2"><ModelVariables>
            <ScalarVariable name="J_m" valueReference="15"><Real start="2.28"/></ScalarVariable>
            <ScalarVariable name="Delta_1" valueReference="23"><Real start="0.3875e-3"/></ScalarVariable>
            <ScalarVariable name="bound_sup" valueReference="14"><Real/></ScalarVariable>
            <ScalarVariable name="contact_law" valueReference="29"><Integer start="1"/></ScalarVariable>
            <ScalarVariable name="der(theta_m)" valueReference="38"><Real/></ScalarVariable>
        </ModelVariables></fmiModelDescription>"#;
        let (guid, text) = guid_and_vr_defines(xml, "M_").unwrap();
        assert_eq!(guid, "{g}");
        assert_eq!(
            text,
            "#define VR_M_J_m 15u\n\
             #define START_M_J_m 2.28\n\
             #define VR_M_Delta_1 23u\n\
             #define START_M_Delta_1 0.0003875\n\
             #define VR_M_bound_sup 14u\n\
             #define VR_M_contact_law 29u\n\
             #define VR_M_der_theta_m 38u\n\
             #define VR_M_EVENT_INDICATORS 2\n"
        );
        let bad = xml.replace("2.28", "fast");
        assert!(guid_and_vr_defines(&bad, "")
            .unwrap_err()
            .contains("J_m's start value `fast`"));
    }

    #[test]
    fn the_rig_header_defines_each_value_exactly_and_the_lists_for_one_set_real() {
        let xml = r#"<fmiModelDescription guid="g"><ModelVariables>
            <ScalarVariable name="Kp" valueReference="7"/>
            <ScalarVariable name="Delta" valueReference="3"/>
            <ScalarVariable name="der(theta_m)" valueReference="9"/>
        </ModelVariables></fmiModelDescription>"#;
        let rig = [("Delta".to_string(), 5.38e-3 / 2.0), ("Kp".to_string(), 42.0)];
        assert_eq!(
            rig_header("M", xml, &rig).unwrap(),
            "/* Written by cargo xtask bench: M's rig from tests/fixtures/rigs.toml. */\n\
             #define RIG_Delta 0.00269\n\
             #define RIG_Kp 42.0\n\
             #define RIG_VR {VR_Delta, VR_Kp}\n\
             #define RIG_VALUE {RIG_Delta, RIG_Kp}\n"
        );
        for name in ["Ki", "der(theta_m)"] {
            let error = rig_header("M", xml, &[(name.to_string(), 1.0)]).unwrap_err();
            assert!(error.contains(&format!("`{name}`, not a variable")), "{error}");
        }
        assert!(rig_header("M", xml, &[("Kp".to_string(), f64::NAN)]).is_err());
        assert!(rig_header("M", xml, &[]).is_err());
    }
}
