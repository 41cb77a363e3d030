//! `cargo xtask bench [--smoke]`: every benchmark in one run, and BENCHMARKS.md generated from it.
//!
//! Builds the FMUs, unpacks BacklashShaft.fmu, compiles the C host benches/native_host.c against
//! the official FMI 2.0 headers (fmpy's copy in .venv) and the value references of the archive's
//! modelDescription.xml, then runs: the native per-call costs and their floors, the growth with
//! steps and instances, the PI loop natively, through fmpy and in scipy (benches/python_bench.py),
//! and the criterion bench of the physics core. Each tool prints `@ <key> <values>` lines; this
//! file collects them and writes the report with the machine facts and the exact commands.

use std::collections::BTreeMap;
use std::fs;
use std::io::Read;
use std::path::Path;
use std::process::Command;
use std::time::Instant;

use crate::util::{self, step};
use crate::{fmu, python};

const USAGE: &str = "\
usage: cargo xtask bench [--smoke]

Runs every benchmark (native C host through the FMI C ABI, the PI loop through fmpy and in scipy,
growth with steps and instances, criterion bench of the physics core) and rewrites BENCHMARKS.md
with the numbers, the machine facts and the exact commands. Takes a few minutes.

  --smoke   tiny sizes, no criterion: checks that the harness runs (seconds after the build);
            writes target/bench/BENCHMARKS.smoke.md and leaves BENCHMARKS.md alone";

const MODEL: &str = "BacklashShaft";

/// Sizes of one run; `--smoke` shrinks all of them.
struct Plan {
    smoke: bool,
    /// Rounds of the native per-call suite (section 1): one batch of every row per round.
    suite_rounds: u32,
    batches: u32,
    steps_per_batch: u64,
    scale_steps: Vec<u64>,
    instance_counts: Vec<u32>,
    instance_steps_per_batch: u64,
    loop_seconds: f64,
    loop_repeats: u32,
    sweep: &'static str,
}

impl Plan {
    fn full() -> Plan {
        Plan {
            smoke: false,
            // ~10 s in all, longer than the spells of contention seen on shared machines.
            suite_rounds: 101,
            batches: 21,
            steps_per_batch: 20_000,
            scale_steps: vec![1_000, 10_000, 100_000, 1_000_000, 10_000_000],
            instance_counts: vec![1, 10, 100, 1000],
            instance_steps_per_batch: 20_000,
            loop_seconds: 10.0,
            loop_repeats: 7,
            sweep: "RK45:1e-3,RK45:1e-6,RK45:1e-9,RK45:1e-12,DOP853:1e-3,DOP853:1e-8,DOP853:1e-12",
        }
    }

    fn smoke() -> Plan {
        Plan {
            smoke: true,
            suite_rounds: 3,
            batches: 3,
            steps_per_batch: 200,
            scale_steps: vec![1_000, 10_000],
            instance_counts: vec![1, 10],
            instance_steps_per_batch: 200,
            loop_seconds: 0.05,
            loop_repeats: 3,
            sweep: "RK45:1e-3",
        }
    }
}

/// The `@ key values…` lines of every tool, by key, in order of arrival.
#[derive(Default)]
struct Results(BTreeMap<String, Vec<Vec<String>>>);

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

    fn rows(&self, key: &str) -> &[Vec<String>] {
        self.0.get(key).map_or(&[], Vec::as_slice)
    }

    fn row(&self, key: &str) -> Result<&[String], String> {
        self.rows(key)
            .last()
            .map(Vec::as_slice)
            .ok_or_else(|| format!("no result `{key}` in the benchmark output"))
    }

    fn num(&self, key: &str, index: usize) -> Result<f64, String> {
        number(self.row(key)?, index, key)
    }
}

fn number(row: &[String], index: usize, key: &str) -> Result<f64, String> {
    row.get(index)
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| format!("result `{key}`: no number at position {index} in {row:?}"))
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

struct Runner {
    results: Results,
    commands: Vec<String>,
}

impl Runner {
    /// Runs a benchmark tool, keeps its command for the report and collects its results.
    fn run(&mut self, cmd: &mut Command) -> Result<(), String> {
        let text = describe(cmd);
        println!("$ {text}");
        let started = Instant::now();
        let out = util::output(cmd)?;
        println!("  ({:.1} s)", started.elapsed().as_secs_f64());
        self.results.collect(&out);
        self.commands.push(text);
        Ok(())
    }
}

pub fn run(args: &[String]) -> Result<(), String> {
    let mut plan = Plan::full();
    for arg in args {
        match arg.as_str() {
            "--smoke" => plan = Plan::smoke(),
            "--help" | "-h" => {
                println!("{USAGE}");
                return Ok(());
            }
            other => return Err(format!("unknown argument `{other}`\n\n{USAGE}")),
        }
    }
    let started = Instant::now();
    let load_start = read_trimmed("/proc/loadavg");

    fmu::package_all()?;
    python::ensure_venv()?;

    step("compiling the native host (benches/native_host.c)");
    let work = util::target_dir().join("bench");
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

    let library = unpacked.join("binaries").join("linux64").join(format!("{MODEL}.so"));
    let resources = format!("file://{}", unpacked.join("resources").display());
    let mut runner = Runner {
        results: Results::default(),
        commands: vec![compile_text],
    };
    let native = |mode: &[String]| {
        let mut cmd = Command::new(&host);
        cmd.current_dir(util::repo_root())
            .arg(&library)
            .arg(&guid)
            .arg(&resources)
            .args(mode);
        cmd
    };

    step("native host: per-call costs");
    runner.run(&mut native(&strings(&[
        "suite",
        &plan.suite_rounds.to_string(),
        &plan.steps_per_batch.to_string(),
    ])))?;
    step("native host: growth with the number of steps (one process each)");
    for n in &plan.scale_steps {
        runner.run(&mut native(&strings(&["scale", &n.to_string()])))?;
    }
    step("native host: many instances stepped round-robin (one process each)");
    for k in &plan.instance_counts {
        runner.run(&mut native(&strings(&[
            "instances",
            &k.to_string(),
            &plan.batches.to_string(),
            &plan.instance_steps_per_batch.to_string(),
        ])))?;
    }
    step("native host: the PI loop");
    runner.run(&mut native(&strings(&[
        "piloop",
        &plan.loop_seconds.to_string(),
        &plan.batches.to_string(),
    ])))?;

    step("the PI loop through fmpy and in scipy (benches/python_bench.py)");
    let mut py = Command::new(util::repo_root().join(".venv").join("bin").join("python"));
    py.current_dir(util::repo_root())
        .env("BACKLASH_FMU_DIR", util::fmu_dir())
        .arg("benches/python_bench.py")
        .args(["--loop-seconds", &plan.loop_seconds.to_string()])
        .args(["--repeats", &plan.loop_repeats.to_string()])
        .args(["--scipy-seconds", &plan.loop_seconds.to_string()])
        .args(["--sweep", plan.sweep]);
    runner.run(&mut py)?;

    let mut criterion = Vec::new();
    if !plan.smoke {
        step("criterion bench of the physics core (benches/physics.rs)");
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
        criterion = parse_criterion(&out);
        if criterion.is_empty() {
            return Err(format!("no criterion results in the output of `{text}`:\n{out}"));
        }
        runner.commands.push(text);
    }

    let facts = Facts {
        load_start,
        load_end: read_trimmed("/proc/loadavg"),
        elapsed_s: started.elapsed().as_secs_f64(),
    };
    let report = render(&plan, &runner, &criterion, &facts)?;
    let path = if plan.smoke {
        work.join("BENCHMARKS.smoke.md")
    } else {
        util::repo_root().join("BENCHMARKS.md")
    };
    fs::write(&path, report).map_err(|e| format!("writing {}: {e}", path.display()))?;
    println!(
        "\nwrote {} ({:.0} s in all)",
        util::shown(&path),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

fn strings(words: &[&str]) -> Vec<String> {
    words.iter().map(|w| w.to_string()).collect()
}

fn read_trimmed(path: &str) -> String {
    fs::read_to_string(path)
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|_| "unknown".into())
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

/// (name, low, estimate, high) in ns from criterion's `name  time: [a unit b unit c unit]` lines.
fn parse_criterion(out: &str) -> Vec<(String, f64, f64, f64)> {
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
            found.push((name.clone(), lo, mid, hi));
        }
    }
    found
}

struct Facts {
    load_start: String,
    load_end: String,
    elapsed_s: f64,
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

/// `median [q1, q3]` of a `@ key median q1 q3` line, in the unit of the line.
fn stat(r: &Results, key: &str) -> Result<(f64, f64, f64), String> {
    Ok((r.num(key, 0)?, r.num(key, 1)?, r.num(key, 2)?))
}

fn yes(met: bool) -> &'static str {
    if met {
        "**met**"
    } else {
        "**not met**"
    }
}

fn render(
    plan: &Plan,
    runner: &Runner,
    criterion: &[(String, f64, f64, f64)],
    facts: &Facts,
) -> Result<String, String> {
    let r = &runner.results;
    let mut md = String::new();
    let mut line = |s: String| {
        md.push_str(&s);
        md.push('\n');
    };

    // ---- checks that the schedules do what their names say ----
    let pressed = r.row("pressed_switches")?;
    let (pressed_switches, pressed_steps) = (
        number(pressed, 0, "pressed_switches")?,
        number(pressed, 1, "pressed_switches")?,
    );
    if pressed_switches != 0.0 || r.num("pressed_final_contact", 0)? != 1.0 {
        return Err(format!(
            "the event-free schedule switched {pressed_switches} times: not event-free"
        ));
    }
    let swing = r.row("swinging_switches")?;
    let switches_per_step = number(swing, 0, "swinging_switches")? / number(swing, 1, "swinging_switches")?;
    if switches_per_step < 1.0 {
        return Err(format!(
            "the switching schedule switched only {switches_per_step} times per step"
        ));
    }
    for row in r.rows("scale") {
        if number(row, 6, "scale")? != 1.0 {
            return Err(format!("scale run {row:?} left the contact: not event-free"));
        }
    }
    // The native and the fmpy loop run the same library on the same inputs: same final state.
    let native_final: Vec<f64> = (0..4).map(|i| r.num("piloop_final", i)).collect::<Result<_, _>>()?;
    let fmpy_final: Vec<f64> = (1..5).map(|i| r.num("fmu_error", i)).collect::<Result<_, _>>()?;
    let final_diff = native_final
        .iter()
        .zip(&fmpy_final)
        .map(|(a, b)| (a - b).abs() / b.abs().max(1e-300))
        .fold(0.0, f64::max);
    if final_diff > 1e-12 {
        return Err(format!(
            "the native loop ends at {native_final:?}, the fmpy loop at {fmpy_final:?}: not the same loop"
        ));
    }

    let matvec = stat(r, "matvec_4x4")?;
    let step_free = stat(r, "ours_step_event_free")?;
    let native_loop_ns = stat(r, "piloop_step")?;
    let fmpy_us = stat(r, "fmpy_loop_us")?;
    let fmpy_share = stat(r, "fmpy_inside_calls_share")?;
    let fmpy_calls_us = stat(r, "fmpy_inside_calls_us")?;
    let native_share = native_loop_ns.0 * 1e-3 / fmpy_us.0;
    // Simulated seconds per second: CPU time (the targets), then wall-clock time.
    let native_rate = 1e-3 / (native_loop_ns.0 * 1e-9);
    let fmpy_rate = 1e-3 / (fmpy_us.0 * 1e-6);
    let native_rate_wall = 1e-3 / (r.num("piloop_step", 3)? * 1e-9);
    let fmpy_rate_wall = 1e-3 / (r.num("fmpy_loop_us", 3)? * 1e-6);
    let fmu_error = r.num("fmu_error", 0)?;
    let radau_diff = r.num("reference_radau_diff", 0)?;
    let equal = fmu_error.max(radau_diff);
    // scipy rows: method rtol atol error rate(CPU) switches rate(wall)
    let scipy: Vec<(String, f64, f64, f64, f64, f64, f64)> = r
        .rows("scipy")
        .iter()
        .map(|row| {
            Ok((
                row.first().cloned().unwrap_or_default(),
                number(row, 1, "scipy")?,
                number(row, 2, "scipy")?,
                number(row, 3, "scipy")?,
                number(row, 4, "scipy")?,
                number(row, 5, "scipy")?,
                number(row, 6, "scipy")?,
            ))
        })
        .collect::<Result<_, String>>()?;
    let matched = scipy
        .iter()
        .filter(|s| s.3 <= equal)
        .max_by(|a, b| a.4.total_cmp(&b.4))
        .or_else(|| scipy.iter().min_by(|a, b| a.3.total_cmp(&b.3)))
        .ok_or("no scipy result")?;
    let matched_is_equal = matched.3 <= equal;

    let t1 = step_free.0 / matvec.0;
    let t3 = native_rate / matched.4;

    line("# Benchmarks".into());
    line(String::new());
    line(format!(
        "Generated by `cargo xtask {}` from one run ({:.0} s); do not edit by hand: rerun the command. \
         Every number below comes from the commands listed under [Commands](#commands).",
        if plan.smoke { "bench --smoke" } else { "bench" },
        facts.elapsed_s
    ));
    if plan.smoke {
        line(String::new());
        line("**Smoke run: sizes far too small for the numbers to mean anything.**".into());
    }
    line(String::new());
    line("## Machine".into());
    line(String::new());
    line("| fact | value |".into());
    line("|---|---|".into());
    line(format!(
        "| date (UTC) | {} |",
        first_line(Command::new("date").args(["-u", "+%Y-%m-%d %H:%M"]))
    ));
    line(format!("| nproc | {} |", first_line(&mut Command::new("nproc"))));
    line(format!("| CPU (/proc/cpuinfo) | {} |", cpu_model()));
    line(format!("| /proc/loadavg at start | `{}` |", facts.load_start));
    line(format!("| /proc/loadavg at end | `{}` |", facts.load_end));
    line(format!(
        "| kernel | {} |",
        first_line(Command::new("uname").args(["-sr"]))
    ));
    line(format!(
        "| rustc | {} |",
        first_line(Command::new("rustc").arg("--version"))
    ));
    line(format!("| cc | {} |", first_line(Command::new("cc").arg("--version"))));
    line(format!(
        "| Python | {} (fmpy, numpy, scipy as pinned in tests/python/requirements.txt) |",
        first_line(Command::new(util::repo_root().join(".venv/bin/python")).arg("--version"))
    ));
    line(String::new());
    line(
        "The machine is shared: a load average above the core count means other jobs competed for the CPU \
         during the run, which shows as wide interquartile ranges (IQR) below. Costs are therefore given in CPU \
         time (CLOCK_THREAD_CPUTIME_ID in C, time.process_time in Python), which leaves out the time a process \
         waited for a core, with the wall-clock time beside them; medians over repeated batches throughout. \
         The targets are judged on CPU time."
            .into(),
    );
    line(String::new());

    line("## Targets".into());
    line(String::new());
    line("| target | measured | |".into());
    line("|---|---|---|".into());
    line(format!(
        "| native event-free `fmi2DoStep` within 5x a bare 4x4 matrix-vector product | {:.1} ns / {:.1} ns = {:.1}x | {} |",
        step_free.0,
        matvec.0,
        t1,
        yes(t1 <= 5.0)
    ));
    line(format!(
        "| fmpy PI loop spends < 5% of its time inside the FMU | {:.1}% (native cost of the same calls / fmpy loop time); {:.0}% inside the fmpy call wrappers | {} |",
        100.0 * native_share,
        100.0 * fmpy_share.0,
        yes(native_share < 0.05)
    ));
    line(format!(
        "| >= 100x faster than scipy at equal accuracy, native host | {:.0}x ({:.0} vs {:.2} simulated s per CPU s){} | {} |",
        t3,
        native_rate,
        matched.4,
        if matched_is_equal { "" } else { "; no scipy setting of the sweep was as accurate as ours" },
        yes(t3 >= 100.0 && matched_is_equal)
    ));
    line(String::new());
    line(format!(
        "The first target compares an FMI call that checks its arguments and state, advances the exact \
         solution (matrix exponential applied to the state and the held input, spec §2), proves the step \
         free of contact switches (a bound on u over the step; the search for a switch runs only where \
         that proof fails) and advances both bounds (spec §3), with a single product of a 4x4 matrix and \
         a vector. The criterion bench of the physics core (below) splits the step: its \
         `step_1ms_no_switch` is the plant alone, `bound_advance_1ms` the bounds alone while the loop's \
         response h is still decaying. Once h is below the round-off of `bound` (after the first seconds \
         of these runs), `bound` is final and advancing the bounds costs one multiply-add per entry of the \
         integral behind `bound_paper`, and one more for a running bound that rules out its overflow."
    ));
    line(String::new());

    line("## 1. Native cost per call (C host through the FMI C ABI)".into());
    line(String::new());
    line(format!(
        "benches/native_host.c dlopens `binaries/linux64/{MODEL}.so` from the packaged archive and calls \
         it through the function pointers it resolves, as any C importer does. BacklashShaft with the \
         FMU's start values (the paper's rig, Delta = 0.775 mm) and Kp = 42, Ki = 180 (tests/python/rigs.py), \
         h = 1 ms. Time per item: median over {} batches of {} items (floors: {} items), with the \
         interquartile range; the rows' batches are taken in turn, one batch of each row per round, so \
         that a spell of contention on the machine reaches a few batches of every row rather than all \
         batches of one.",
        plan.suite_rounds,
        plan.steps_per_batch,
        plan.steps_per_batch * 20
    ));
    line(String::new());
    line("| measurement | what one item contains | CPU median ns | CPU IQR ns | x matvec | wall median ns |".into());
    line("|---|---|---|---|---|---|".into());
    let rows: [(&str, &str, &str); 9] = [
        ("matvec_4x4", "floor: bare 4x4 matrix-vector product", "y = M x (16 mul, 12 add), inline C, each product feeding the next"),
        ("copy_set2_step_get1", "floor: FMI call pattern", "setReal(2) + doStep + getReal(1) on a trivial C copy-input-to-output component, through function pointers"),
        ("ours_set2_get1", "our call guard", "fmi2SetReal(tau_m, tau_L) + fmi2GetReal(omega_m), no step"),
        ("ours_step_event_free", "event-free step", "fmi2DoStep alone, in permanent contact (u pressed past g, constant 2 N.m)"),
        ("ours_set2_step", "step with inputs", "fmi2SetReal(tau_m, tau_L) + fmi2DoStep, event-free"),
        ("ours_set2_step_get1", "PI loop's calls", "fmi2SetReal(2) + fmi2DoStep + fmi2GetReal(omega_m), event-free"),
        ("ours_set2_step_get_all", "all outputs", "fmi2SetReal(2) + fmi2DoStep + fmi2GetReal of all 7 Real outputs (incl. bound, bound_paper) + fmi2GetInteger(contact), event-free"),
        ("ours_set2_step_switching", "switching step", "fmi2SetReal(2) + fmi2DoStep with a contact made and lost inside every step (schedule below)"),
        ("piloop_step", "native PI loop", "one step of the loop of sections 2-3 in C: fmi2GetReal(omega_m), PI, fmi2SetReal(2), fmi2DoStep"),
    ];
    for (key, name, contains) in rows {
        let (med, q1, q3) = stat(r, key)?;
        line(format!(
            "| {name} (`{key}`) | {contains} | {med:.1} | {q1:.1} – {q3:.1} | {:.1} | {:.1} |",
            med / matvec.0,
            r.num(key, 3)?
        ));
    }
    let switching = stat(r, "ours_set2_step_switching")?;
    let set_step = stat(r, "ours_set2_step")?;
    line(String::new());
    line(format!(
        "- Event-free schedule: theta_m starts 5.5 mrad past the gap, near the equilibrium of the constant \
         torque, so the shaft never leaves the positive flank; an untimed run of the same {pressed_steps:.0} \
         steps with `logContactEvents` on counted {pressed_switches:.0} switches."
    ));
    line(format!(
        "- Switching schedule: the motor swings inside the gap, its speed alternating between -6 and +6 rad/s \
         at each communication point (held torque +-27 360 N.m), so that u passes +g or -g and returns within \
         every step; the logger counted {switches_per_step:.2} switches per step in an untimed run of the \
         same schedule. Marginal cost per switch, against fmi2SetReal(2) + fmi2DoStep without a switch \
         (`ours_set2_step`, {:.0} ns): ({:.0} - {:.0}) / {switches_per_step:.2} = **{:.0} ns**.",
        set_step.0,
        switching.0,
        set_step.0,
        (switching.0 - set_step.0) / switches_per_step
    ));
    line(format!(
        "- FMI call overhead itself: the same call pattern costs {:.1} ns on the trivial component, {:.1} ns \
         for our setReal + getReal without a step (argument, state and value-reference checks behind \
         `catch_unwind`).",
        stat(r, "copy_set2_step_get1")?.0,
        stat(r, "ours_set2_get1")?.0
    ));
    line(String::new());

    line("## 2. The PI loop through fmpy".into());
    line(String::new());
    line(format!(
        "benches/python_bench.py: the sampled PI of tests/python/reference.py on omega_m, speed reference \
         5 sin(pi t) rad/s, load torque -2 N.m from t = 4 s, h = 1 ms, {} simulated s, BacklashShaft with \
         rigs.SHAFT (Delta = 2.69 mm) and rigs.SHAFT_GAINS, driven with fmpy's FMU2Slave through \
         tests/python/fmu_driver.py (`inst.get(\"omega_m\")`, `inst.step(...)` = setReal + doStep). \
         Median [IQR] of {} runs.",
        plan.loop_seconds, plan.loop_repeats
    ));
    line(String::new());
    line("| quantity | value |".into());
    line("|---|---|".into());
    line(format!(
        "| loop time per step, CPU | {:.2} µs [{:.2} – {:.2}] |",
        fmpy_us.0, fmpy_us.1, fmpy_us.2
    ));
    line(format!(
        "| loop time per step, wall clock | {:.2} µs [{:.2} – {:.2}] |",
        r.num("fmpy_loop_us", 3)?,
        r.num("fmpy_loop_us", 4)?,
        r.num("fmpy_loop_us", 5)?
    ));
    line(format!(
        "| of which inside the fmpy calls (getReal, setReal, doStep: fmpy wrapper + ctypes + our FMU), timed \
         with perf_counter (wall) in a separate instrumented run, as a share of that run's wall time | {:.2} µs [{:.2} – {:.2}] = {:.0}% [{:.0} – {:.0}] |",
        fmpy_calls_us.0,
        fmpy_calls_us.1,
        fmpy_calls_us.2,
        100.0 * fmpy_share.0,
        100.0 * fmpy_share.1,
        100.0 * fmpy_share.2
    ));
    line(format!(
        "| of which inside our FMU: the same calls from the C host (`piloop_step`, section 1), CPU | {:.3} µs = **{:.1}%** |",
        native_loop_ns.0 * 1e-3,
        100.0 * native_share
    ));
    line(String::new());
    line(
        "The FMU's own share is estimated with the native cost of exactly the same call sequence on the same \
         inputs (the native loop ends in the same state as the fmpy loop: largest relative difference of the \
         final states "
            .to_string()
            + &format!(
                "{final_diff:.1e}). Python cannot time the inside of a ctypes call without the marshalling around it."
            ),
    );
    line(String::new());

    line("## 3. Against scipy's solve_ivp at equal accuracy".into());
    line(String::new());
    line(format!(
        "The same loop, {} simulated s, in tests/python/reference.py: solve_ivp with terminal events on \
         u = +-g, restarted at each switch and at each communication step (the controller samples every \
         1 ms), atol = 1e-4 rtol. Errors: largest relative error (signals.rel_err) of the four states at the \
         {} communication points against the shared reference, reference.py's own setting (DOP853, rtol \
         1e-13, atol 1e-17). That reference resolves differences down to ~{radau_diff:.1e} (Radau at the same \
         tolerances differs from it by that much), so errors below that are equal for this comparison.",
        plan.loop_seconds,
        (plan.loop_seconds / 1e-3).round()
    ));
    line(String::new());
    line("| solver | error vs reference | simulated s per CPU s | simulated s per wall-clock s |".into());
    line("|---|---|---|---|".into());
    line(format!(
        "| **ours, native C host** | {fmu_error:.1e} | **{native_rate:.0}** | {native_rate_wall:.0} |"
    ));
    line(format!(
        "| **ours, fmpy host** | {fmu_error:.1e} | **{fmpy_rate:.0}** | {fmpy_rate_wall:.0} |"
    ));
    for s in &scipy {
        line(format!(
            "| scipy {} rtol {:.0e} atol {:.0e} | {:.1e} | {:.2} | {:.2} |",
            s.0, s.1, s.2, s.3, s.4, s.6
        ));
    }
    line(String::new());
    line(format!(
        "Equal accuracy = error <= {equal:.1e} (the larger of ours and the reference's resolution). {}: \
         {} rtol {:.0e}, {:.2} simulated s per CPU s. Speed ratio against it (CPU time): native host **{:.0}x**, \
         fmpy host **{:.0}x**; in wall-clock time {:.0}x and {:.0}x. At h = 1 ms every solve_ivp call covers one millisecond in a handful of internal \
         steps, so its cost is the per-call overhead and barely depends on the tolerance.",
        if matched_is_equal {
            "Fastest scipy setting at equal accuracy"
        } else {
            "No scipy setting of the sweep reached it (so the target counts as not met); the most accurate one"
        },
        matched.0,
        matched.1,
        matched.4,
        t3,
        fmpy_rate / matched.4,
        native_rate_wall / matched.6,
        fmpy_rate_wall / matched.6
    ));
    line(String::new());

    line("## 4. Growth".into());
    line(String::new());
    line(
        "Event-free `fmi2DoStep` (schedule of section 1), one process per row, one timed run each. RSS from \
         /proc/self/status: VmRSS before instantiating, VmRSS and VmHWM (peak) at the end."
            .into(),
    );
    line(String::new());
    line("| steps | wall s | CPU ns per step | wall ns per step | VmRSS before kB | VmRSS end kB | VmHWM kB |".into());
    line("|---|---|---|---|---|---|---|".into());
    for row in r.rows("scale") {
        line(format!(
            "| {} | {:.4} | {:.0} | {:.0} | {} | {} | {} |",
            row[0],
            number(row, 1, "scale")?,
            number(row, 2, "scale")?,
            number(row, 7, "scale")?,
            row[3],
            row[4],
            row[5]
        ));
    }
    line(String::new());
    if let (Some(first), Some(last)) = (r.rows("scale").first(), r.rows("scale").last()) {
        let (a, b) = (number(first, 2, "scale")?, number(last, 2, "scale")?);
        line(String::new());
        line(format!(
            "CPU time per step: {a:.0} ns over the first {} steps, {b:.0} ns averaged over {} steps ({:.1}x). \
             The cost per step is not uniform in simulated time: compare \
             the rows (section 1's batches cover {} s of simulated time).",
            first[0],
            last[0],
            b / a,
            (plan.suite_rounds as f64 * plan.steps_per_batch as f64 * 1e-3).round()
        ));
    }
    line(String::new());
    line(format!(
        "Many instances, each instantiated and initialised (Kp, Ki, theta_m set), then stepped round-robin \
         (every instance one step, then the next round); time per instance-step: median [IQR] over {} \
         batches of ~{} instance-steps. Memory per instance = (VmRSS after setting up all instances - VmRSS \
         before) / count; the first row also carries the library's one-time set-up.",
        plan.batches, plan.instance_steps_per_batch
    ));
    line(String::new());
    line(
        "| instances | CPU ns per instance-step | CPU IQR ns | wall ns | setup CPU µs per instance | memory per instance kB | VmHWM kB |"
            .into(),
    );
    line("|---|---|---|---|---|---|---|".into());
    for row in r.rows("instances") {
        let count = number(row, 0, "instances")?;
        let grown = number(row, 6, "instances")? - number(row, 5, "instances")?;
        line(format!(
            "| {} | {:.0} | {:.0} – {:.0} | {:.0} | {:.0} | {:.1} | {} |",
            row[0],
            number(row, 1, "instances")?,
            number(row, 2, "instances")?,
            number(row, 3, "instances")?,
            number(row, 8, "instances")?,
            number(row, 4, "instances")? * 1e-3,
            grown / count,
            row[7]
        ));
    }
    line(String::new());

    line("## Physics core (criterion, benches/physics.rs)".into());
    line(String::new());
    if criterion.is_empty() {
        line("Not run in smoke mode.".into());
    } else {
        line("Rust calls into `backlash_fmu::physics`, no FMI layer; criterion's estimate and 95% interval.".into());
        line(String::new());
        line("| bench | ns | interval ns |".into());
        line("|---|---|---|".into());
        for (name, lo, mid, hi) in criterion {
            line(format!("| {name} | {mid:.1} | {lo:.1} – {hi:.1} |"));
        }
    }
    line(String::new());

    line("## Commands".into());
    line(String::new());
    line(format!(
        "All run by `cargo xtask bench{}` from the repository root, after `cargo xtask fmu` (release build) \
         and the `.venv` set-up; `target/bench/bench_vr.h` holds the value references read from the archive's \
         modelDescription.xml.",
        if plan.smoke { " --smoke" } else { "" }
    ));
    line(String::new());
    line("```sh".into());
    for c in &runner.commands {
        line(c.clone());
    }
    line("```".into());
    Ok(md)
}
