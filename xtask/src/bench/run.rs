//! Running the benchmarks: the native C host, the Python bench and criterion, each measurement
//! collected into plain data for report.rs, with the commands that produced it.

use std::collections::BTreeMap;
use std::fs;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use super::{Plan, MODEL};
use crate::{python, util};

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

/// Everything one run measured, and the commands that measured it, in order.
pub(super) struct Measurements {
    pub results: Results,
    pub criterion: Vec<CriterionEstimate>,
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
            python: first_line(Command::new(util::repo_root().join(".venv/bin/python")).arg("--version")),
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

/// The compiled native host and the unpacked archive it loads; collects every tool's results.
pub(super) struct Runner {
    host: PathBuf,
    library: PathBuf,
    guid: String,
    resources: String,
    measured: Measurements,
}

impl Runner {
    /// Unpacks BacklashShaft.fmu into `work` and compiles benches/native_host.c against fmpy's
    /// FMI headers and the value references of the archive's own modelDescription.xml.
    pub(super) fn prepare(work: &Path) -> Result<Runner, String> {
        let unpacked = work.join(MODEL);
        let xml = unpack(&util::fmu_dir().join(format!("{MODEL}.fmu")), &unpacked)?;
        let guid = attribute(&xml, "guid").ok_or("modelDescription.xml has no guid")?;
        fs::write(work.join("bench_vr.h"), vr_header(&xml)?).map_err(|e| format!("writing bench_vr.h: {e}"))?;
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
            library: unpacked.join("binaries").join("linux64").join(format!("{MODEL}.so")),
            guid,
            resources: format!("file://{}", unpacked.join("resources").display()),
            measured: Measurements {
                results: Results::default(),
                criterion: Vec::new(),
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
            .arg(&self.library)
            .arg(&self.guid)
            .arg(&self.resources)
            .args(mode);
        self.run(&mut cmd)
    }

    /// Section 1: the per-call costs and their floors, rows taken in turn round by round.
    pub(super) fn native_suite(&mut self, plan: &Plan) -> Result<(), String> {
        self.native(&strings(&[
            "suite",
            &plan.suite_rounds.to_string(),
            &plan.steps_per_batch.to_string(),
        ]))
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
        let mut py = Command::new(util::repo_root().join(".venv").join("bin").join("python"));
        py.current_dir(util::repo_root())
            .env("BACKLASH_FMU_DIR", util::fmu_dir())
            .arg("benches/python_bench.py")
            .args(["--loop-seconds", &plan.loop_seconds.to_string()])
            .args(["--repeats", &plan.loop_repeats.to_string()])
            .args(["--scipy-seconds", &plan.loop_seconds.to_string()])
            .args(["--sweep", plan.sweep]);
        self.run(&mut py)
    }

    /// The criterion bench of the physics core.
    pub(super) fn criterion(&mut self) -> Result<(), String> {
        let mut cmd = util::cargo();
        cmd.args([
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
        let out = util::output(&mut cmd)?;
        let found = parse_criterion(&out);
        if found.is_empty() {
            return Err(format!("no criterion results in the output of `{text}`:\n{out}"));
        }
        self.measured.criterion = found;
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

/// The estimates in ns from criterion's `name  time: [a unit b unit c unit]` lines.
fn parse_criterion(out: &str) -> Vec<CriterionEstimate> {
    let mut found = Vec::new();
    let mut name = String::new();
    for line in out.lines() {
        let Some(at) = line.find("time:") else {
            if !line.trim().is_empty() && !line.starts_with(' ') {
                name = line.trim().to_string();
            }
            continue;
        };
        let head = line[..at].trim();
        if !head.is_empty() {
            name = head.to_string();
        }
        let inside = line[at..].trim_start_matches("time:").trim().trim_matches(['[', ']']);
        let words: Vec<&str> = inside.split_whitespace().collect();
        let ns = |i: usize| -> Option<f64> {
            let value: f64 = words.get(2 * i)?.parse().ok()?;
            let scale = match *words.get(2 * i + 1)? {
                "ps" => 1e-3,
                "ns" => 1.0,
                "µs" | "us" => 1e3,
                "ms" => 1e6,
                "s" => 1e9,
                _ => return None,
            };
            Some(value * scale)
        };
        if let (Some(lo), Some(mid), Some(hi)) = (ns(0), ns(1), ns(2)) {
            found.push(CriterionEstimate {
                name: name.clone(),
                low_ns: lo,
                estimate_ns: mid,
                high_ns: hi,
            });
        }
    }
    found
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

/// The first `name="…"` attribute value in `xml`.
fn attribute(xml: &str, name: &str) -> Option<String> {
    let key = format!(" {name}=\"");
    let start = xml.find(&key)? + key.len();
    let end = xml[start..].find('"')? + start;
    Some(xml[start..end].to_string())
}

/// `#define VR_<name> <vr>u` for every ScalarVariable, from the archive's description.
fn vr_header(xml: &str) -> Result<String, String> {
    let mut text = String::from("/* Written by cargo xtask bench from the archive's modelDescription.xml. */\n");
    let mut count = 0;
    for element in xml.split("<ScalarVariable").skip(1) {
        let head = &element[..element.find('>').unwrap_or(element.len())];
        let (Some(name), Some(vr)) = (attribute(head, "name"), attribute(head, "valueReference")) else {
            return Err(format!("a ScalarVariable without name or valueReference: {head}"));
        };
        text.push_str(&format!("#define VR_{name} {vr}u\n"));
        count += 1;
    }
    if count == 0 {
        return Err("modelDescription.xml lists no ScalarVariable".into());
    }
    Ok(text)
}
