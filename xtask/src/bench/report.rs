//! BENCHMARKS.md from the measurements of one run: the checks that the schedules did what their
//! names say, the targets, one section per benchmark and the commands.

use super::run::{number, Facts, Measurements, Results};
use super::{Plan, DRIVE_AND_WEB, GEARBOX, MODEL};

pub(super) fn render(plan: &Plan, measured: &Measurements, facts: &Facts) -> Result<String, String> {
    let r = &measured.results;
    let schedules = check_schedules(r)?;
    let f = figures(plan, r, &schedules)?;
    let mut md = Md::default();
    machine(&mut md, plan, facts);
    targets(&mut md, &f);
    native_calls(&mut md, plan, r, &f)?;
    native_schedules(&mut md, r, &schedules, &f)?;
    fmpy_loop(&mut md, plan, r, &schedules, &f)?;
    simulate_fmu(&mut md, r)?;
    against_scipy(&mut md, plan, &f);
    growth_in_steps(&mut md, plan, r)?;
    growth_in_instances(&mut md, plan, r)?;
    dask_sweep(&mut md, r)?;
    physics_core(&mut md, measured, &f);
    commands(&mut md, plan, measured);
    Ok(md.0)
}

/// The report as it is written, line by line.
#[derive(Default)]
struct Md(String);

impl Md {
    fn line(&mut self, s: impl AsRef<str>) {
        self.0.push_str(s.as_ref());
        self.0.push('\n');
    }
}

/// `median, q1, q3` of a `@ key median q1 q3 …` line.
type Stat = (f64, f64, f64);

/// `median [q1, q3]` of a `@ key median q1 q3` line, in the unit of the line.
fn stat(r: &Results, key: &str) -> Result<Stat, String> {
    Ok((r.num(key, 0)?, r.num(key, 1)?, r.num(key, 2)?))
}

fn yes(met: bool) -> &'static str {
    if met {
        "**met**"
    } else {
        "**not met**"
    }
}

// ---- checks that the schedules do what their names say ----

/// What the untimed runs of the schedules counted, for the sections that describe them.
struct Schedules {
    pressed_switches: f64,
    pressed_steps: f64,
    switches_per_step: f64,
    /// Steps of the belt and web schedule, the same for both drives, and its step size [s].
    drive_steps: f64,
    drive_h: f64,
    /// Steps of the two-stage gearbox's schedule and its step size [s].
    gearbox_steps: f64,
    gearbox_h: f64,
    /// Largest relative difference of the native and the fmpy loop's final states.
    final_diff: f64,
}

fn check_schedules(r: &Results) -> Result<Schedules, String> {
    let (pressed_switches, pressed_steps) = check_event_free(r)?;
    check_friction_event_free(r)?;
    let switches_per_step = check_switching(r)?;
    let [(drive_steps, drive_h), (gearbox_steps, gearbox_h)] = check_drives_event_free(r)?;
    check_scale_event_free(r)?;
    let final_diff = check_same_loop(r)?;
    Ok(Schedules {
        pressed_switches,
        pressed_steps,
        switches_per_step,
        drive_steps,
        drive_h,
        gearbox_steps,
        gearbox_h,
        final_diff,
    })
}

/// The event-free schedule: no switch and in contact at the end. Its switches and steps.
fn check_event_free(r: &Results) -> Result<(f64, f64), String> {
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
    Ok((pressed_switches, pressed_steps))
}

/// The event-free schedule with bearing friction: no contact or friction switch, and both bodies
/// sliding forward at the end (docs/model.md §12).
fn check_friction_event_free(r: &Results) -> Result<(), String> {
    let key = "pressed_friction_switches";
    let switches = r.num(key, 0)?;
    let sliding = (r.num(key, 2)?, r.num(key, 3)?);
    if switches != 0.0 || sliding != (1.0, 1.0) {
        return Err(format!(
            "the event-free schedule with friction switched {switches} times and ends with sliding_m, sliding_L = \
             {sliding:?}: not an event-free sliding drive"
        ));
    }
    Ok(())
}

/// The switching schedule: at least one switch per step. Its switches per step.
fn check_switching(r: &Results) -> Result<f64, String> {
    let swing = r.row("swinging_switches")?;
    let switches_per_step = number(swing, 0, "swinging_switches")? / number(swing, 1, "swinging_switches")?;
    if switches_per_step < 1.0 {
        return Err(format!(
            "the switching schedule switched only {switches_per_step} times per step"
        ));
    }
    Ok(switches_per_step)
}

/// The other drives of the native suite: the key of their lines, their name in the report, and
/// how many meshes' contacts their check line ends with.
const SUITE_DRIVES: [(&str, &str, usize); 3] = [("belt", "belt", 1), ("web", "web", 1), ("two_stage", "two-stage", 2)];

/// The other drives' schedules: no switch in an untimed run of the run's steps either, and every
/// mesh in contact on its positive flank at the end (`@ <key>_pressed_switches <switches> <steps>
/// <h> <contact>…`). The steps and step size [s] of the belt and web schedule (the same for both
/// drives: those of the web's, the last), then those of the two-stage gearbox's.
fn check_drives_event_free(r: &Results) -> Result<[(f64, f64); 2], String> {
    let mut runs = [(0.0, 0.0); 3];
    for ((key, name, meshes), run) in SUITE_DRIVES.into_iter().zip(&mut runs) {
        let key = format!("{key}_pressed_switches");
        let row = r.row(&key)?;
        if row.len() != 3 + meshes {
            return Err(format!(
                "result `{key}`: {row:?} is not the {name} schedule's check of {meshes} mesh(es)"
            ));
        }
        let switches = number(row, 0, &key)?;
        let contacts: Vec<f64> = (3..3 + meshes)
            .map(|i| number(row, i, &key))
            .collect::<Result<_, _>>()?;
        if switches != 0.0 || contacts.iter().any(|c| *c != 1.0) {
            let contacts: Vec<String> = contacts.iter().map(f64::to_string).collect();
            return Err(format!(
                "the {name} event-free schedule switched {switches} times (final contact{} {}): not event-free",
                if meshes == 1 { "" } else { "s" },
                contacts.join(", ")
            ));
        }
        *run = (number(row, 1, &key)?, number(row, 2, &key)?);
    }
    Ok([runs[1], runs[2]])
}

/// The growth runs: each still in contact at its end.
fn check_scale_event_free(r: &Results) -> Result<(), String> {
    for row in r.rows("scale") {
        if number(row, 6, "scale")? != 1.0 {
            return Err(format!("scale run {row:?} left the contact: not event-free"));
        }
    }
    Ok(())
}

/// The native and the fmpy loop run the same library on the same inputs: same final state.
/// The largest relative difference of the two.
fn check_same_loop(r: &Results) -> Result<f64, String> {
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
    Ok(final_diff)
}

// ---- the figures the targets and the sections share ----

/// The results the targets are judged on, with what the sections derive from them.
struct Figures {
    matvec: Stat,
    step_free: Stat,
    /// The same step with bearing friction, both bodies sliding.
    step_friction: Stat,
    loops: Loops,
    accuracy: Accuracy,
    me_derivatives: Stat,
    me_indicators: Stat,
    /// fmi2SetReal(2) + fmi2GetReal(1) without a step.
    set_get: Stat,
    /// The marginal cost of a contact switch [ns]: the switching schedule's step against
    /// `ours_set2_step`, per switch.
    switch_ns: f64,
    step3: Stat,
    drives: Drives,
    gearbox: Gearbox,
    /// Identification of a 10 s run at 1 kHz: median CPU seconds and model evaluations.
    identify: (f64, f64),
}

impl Figures {
    /// The native host's speed against the scipy setting it is compared with (CPU time).
    fn against_scipy(&self) -> f64 {
        self.loops.native_rate / self.accuracy.matched.rate
    }
}

fn figures(plan: &Plan, r: &Results, schedules: &Schedules) -> Result<Figures, String> {
    // Read in this order (fields are evaluated as written): the first missing result is reported.
    Ok(Figures {
        matvec: stat(r, "matvec_4x4")?,
        step_free: stat(r, "ours_step_event_free")?,
        step_friction: stat(r, "ours_step_event_free_friction")?,
        loops: loops(r)?,
        accuracy: accuracy(r)?,
        me_derivatives: stat(r, "me_get_derivatives")?,
        me_indicators: stat(r, "me_get_event_indicators")?,
        set_get: stat(r, "ours_set2_get1")?,
        switch_ns: (stat(r, "ours_set2_step_switching")?.0 - stat(r, "ours_set2_step")?.0)
            / schedules.switches_per_step,
        step3: stat(r, "ours3_step_event_free")?,
        drives: drives(plan, r, schedules)?,
        gearbox: gearbox(plan, r, schedules)?,
        identify: (r.num("identify_10s_1khz", 0)?, r.num("identify_10s_1khz", 1)?),
    })
}

/// The PI loop natively and through fmpy.
struct Loops {
    native_ns: Stat,
    fmpy_us: Stat,
    fmpy_share: Stat,
    fmpy_calls_us: Stat,
    /// Native cost of the fmpy loop's calls / fmpy loop time.
    native_share: f64,
    /// Simulated seconds per second: CPU time (the targets), then wall-clock time.
    native_rate: f64,
    fmpy_rate: f64,
    native_rate_wall: f64,
    fmpy_rate_wall: f64,
}

fn loops(r: &Results) -> Result<Loops, String> {
    let native_ns = stat(r, "piloop_step")?;
    let fmpy_us = stat(r, "fmpy_loop_us")?;
    let fmpy_share = stat(r, "fmpy_inside_calls_share")?;
    let fmpy_calls_us = stat(r, "fmpy_inside_calls_us")?;
    Ok(Loops {
        native_ns,
        fmpy_us,
        fmpy_share,
        fmpy_calls_us,
        native_share: native_ns.0 * 1e-3 / fmpy_us.0,
        native_rate: 1e-3 / (native_ns.0 * 1e-9),
        fmpy_rate: 1e-3 / (fmpy_us.0 * 1e-6),
        native_rate_wall: 1e-3 / (r.num("piloop_step", 3)? * 1e-9),
        fmpy_rate_wall: 1e-3 / (r.num("fmpy_loop_us", 3)? * 1e-6),
    })
}

/// One setting of the scipy sweep.
#[derive(Clone)]
struct ScipyRun {
    method: String,
    rtol: f64,
    atol: f64,
    error: f64,
    /// Simulated seconds per CPU second, then per wall-clock second.
    rate: f64,
    rate_wall: f64,
}

/// Errors against the reference, and the scipy setting ours is compared with.
struct Accuracy {
    fmu_error: f64,
    radau_diff: f64,
    /// Equal accuracy: at most this error.
    equal: f64,
    scipy: Vec<ScipyRun>,
    /// The fastest setting at equal accuracy, else the most accurate one.
    matched: ScipyRun,
    matched_is_equal: bool,
}

fn accuracy(r: &Results) -> Result<Accuracy, String> {
    let fmu_error = r.num("fmu_error", 0)?;
    let radau_diff = r.num("reference_radau_diff", 0)?;
    let equal = fmu_error.max(radau_diff);
    let scipy = scipy_runs(r)?;
    let matched = scipy
        .iter()
        .filter(|s| s.error <= equal)
        .max_by(|a, b| a.rate.total_cmp(&b.rate))
        .or_else(|| scipy.iter().min_by(|a, b| a.error.total_cmp(&b.error)))
        .ok_or("no scipy result")?
        .clone();
    Ok(Accuracy {
        fmu_error,
        radau_diff,
        equal,
        matched_is_equal: matched.error <= equal,
        scipy,
        matched,
    })
}

/// scipy rows: method rtol atol error rate(CPU) switches rate(wall).
fn scipy_runs(r: &Results) -> Result<Vec<ScipyRun>, String> {
    r.rows("scipy")
        .iter()
        .map(|row| {
            let (rtol, atol, error, rate) = (
                number(row, 1, "scipy")?,
                number(row, 2, "scipy")?,
                number(row, 3, "scipy")?,
                number(row, 4, "scipy")?,
            );
            // The switches: not reported, but a number all the same.
            number(row, 5, "scipy")?;
            Ok(ScipyRun {
                method: row.first().cloned().unwrap_or_default(),
                rtol,
                atol,
                error,
                rate,
                rate_wall: number(row, 6, "scipy")?,
            })
        })
        .collect()
}

/// The web line against the belt drive: an instance stepped on through the run, and a fresh
/// instance's first steps (simulated seconds of each).
struct Drives {
    belt_step: Stat,
    web_step: Stat,
    belt_start: Stat,
    web_start: Stat,
    belt_read: Stat,
    web_read: Stat,
    t_web: f64,
    t_web_start: f64,
    t_web_read: f64,
    run_s: f64,
    start_s: f64,
}

fn drives(plan: &Plan, r: &Results, schedules: &Schedules) -> Result<Drives, String> {
    let belt_step = stat(r, "belt_step_event_free")?;
    let web_step = stat(r, "web_step_event_free")?;
    let belt_start = stat(r, "belt_step_from_start")?;
    let web_start = stat(r, "web_step_from_start")?;
    let belt_read = stat(r, "belt_step_read_bounds")?;
    let web_read = stat(r, "web_step_read_bounds")?;
    let seconds = |steps: f64| simulated_seconds(steps, schedules.drive_h);
    Ok(Drives {
        t_web: web_step.0 / belt_step.0,
        t_web_start: web_start.0 / belt_start.0,
        t_web_read: web_read.0 / belt_read.0,
        run_s: seconds(schedules.drive_steps),
        start_s: seconds(plan.steps_per_batch as f64),
        belt_step,
        web_step,
        belt_start,
        web_start,
        belt_read,
        web_read,
    })
}

/// `steps` steps of `h` in simulated seconds, rounded to the microsecond, so that e.g. 20000
/// steps of 1e-4 s read as 2.
fn simulated_seconds(steps: f64, h: f64) -> f64 {
    (steps * h * 1e6).round() / 1e6
}

/// The two-stage gearbox against the shaft, h = 1 ms both: its instance stepped on through the
/// run as the shaft's `ours_step_event_free` is, and a fresh instance's first steps, without and
/// with its bound read after each step.
struct Gearbox {
    step: Stat,
    start: Stat,
    read: Stat,
    /// Its step over the shaft's, medians of the same run.
    t_step: f64,
    /// Simulated seconds of the untimed check and of a fresh instance's batch.
    run_s: f64,
    start_s: f64,
}

fn gearbox(plan: &Plan, r: &Results, schedules: &Schedules) -> Result<Gearbox, String> {
    let step = stat(r, "two_stage_step_event_free")?;
    let seconds = |steps: f64| simulated_seconds(steps, schedules.gearbox_h);
    Ok(Gearbox {
        t_step: step.0 / stat(r, "ours_step_event_free")?.0,
        step,
        start: stat(r, "two_stage_step_from_start")?,
        read: stat(r, "two_stage_step_read_bounds")?,
        run_s: seconds(schedules.gearbox_steps),
        start_s: seconds(plan.steps_per_batch as f64),
    })
}

// ---- the report, section by section ----

/// The title, the machine facts and how to read the costs.
fn machine(md: &mut Md, plan: &Plan, facts: &Facts) {
    md.line("# Benchmarks");
    md.line("");
    md.line(format!(
        "Generated by `cargo xtask {}` from one run ({:.0} s); do not edit by hand: rerun the command. \
         Every number below comes from the commands listed under [Commands](#commands).",
        if plan.smoke { "bench --smoke" } else { "bench" },
        facts.elapsed_s
    ));
    if plan.smoke {
        md.line("");
        md.line("**Smoke run: sizes far too small for the numbers to mean anything.**");
    }
    md.line("");
    md.line("## Machine");
    md.line("");
    md.line("| fact | value |");
    md.line("|---|---|");
    md.line(format!("| date (UTC) | {} |", facts.date));
    md.line(format!("| nproc | {} |", facts.nproc));
    md.line(format!("| CPU (/proc/cpuinfo) | {} |", facts.cpu));
    md.line(format!("| /proc/loadavg at start | `{}` |", facts.load_start));
    md.line(format!("| /proc/loadavg at end | `{}` |", facts.load_end));
    md.line(format!("| kernel | {} |", facts.kernel));
    md.line(format!("| rustc | {} |", facts.rustc));
    md.line(format!("| cc | {} |", facts.cc));
    md.line(format!(
        "| Python | {} (fmpy, numpy, scipy as pinned in tests/python/requirements.txt) |",
        facts.python
    ));
    md.line("");
    md.line(
        "The machine is shared: a load average above the core count means other jobs competed for the CPU \
         during the run, which shows as wide interquartile ranges (IQR) below. Costs are therefore given in CPU \
         time (CLOCK_THREAD_CPUTIME_ID in C, time.process_time in Python), which leaves out the time a process \
         waited for a core, with the wall-clock time beside them; medians over repeated batches throughout. \
         The targets are judged on CPU time.",
    );
    md.line("");
}

/// The targets table: the native per-call costs, then the loops.
fn targets(md: &mut Md, f: &Figures) {
    md.line("## Targets");
    md.line("");
    md.line("| target | measured | |");
    md.line("|---|---|---|");
    native_targets(md, f);
    loop_targets(md, f);
    md.line("");
    md.line(FIRST_TARGET_NOTE);
    md.line("");
}

fn native_targets(md: &mut Md, f: &Figures) {
    let (matvec, step_free, step3, d) = (f.matvec.0, f.step_free.0, f.step3.0, &f.drives);
    let t1 = step_free / matvec;
    let (t_derivatives, t_indicators) = (f.me_derivatives.0 / matvec, f.me_indicators.0 / matvec);
    let t3_step = step3 / step_free;
    md.line(format!(
        "| native event-free `fmi2DoStep` within 4x a bare 4x4 matrix-vector product | {:.1} ns / {:.1} ns = {:.1}x | {} |",
        step_free,
        matvec,
        t1,
        yes(t1 <= 4.0)
    ));
    md.line(format!(
        "| marginal cost of a contact switch inside `fmi2DoStep` <= 600 ns (switching schedule, section 1) | {:.0} ns | {} |",
        f.switch_ns,
        yes(f.switch_ns <= 600.0)
    ));
    md.line(format!(
        "| `fmi2SetReal(2)` + `fmi2GetReal(1)` without a step <= 30 ns | {:.1} ns | {} |",
        f.set_get.0,
        yes(f.set_get.0 <= 30.0)
    ));
    md.line(format!(
        "| native `fmi2GetDerivatives` and `fmi2GetEventIndicators` (Model Exchange) each within 5x a bare 4x4 matrix-vector product | {:.1} ns and {:.1} ns / {:.1} ns = {:.1}x and {:.1}x | {} |",
        f.me_derivatives.0,
        f.me_indicators.0,
        matvec,
        t_derivatives,
        t_indicators,
        yes(t_derivatives.max(t_indicators) <= 5.0)
    ));
    let t_friction = f.step_friction.0 / step_free;
    md.line(format!(
        "| native event-free `fmi2DoStep` of a drive sliding with bearing friction within 1.2x the frictionless step, same run | {:.1} ns / {:.1} ns = {:.2}x | {} |",
        f.step_friction.0,
        step_free,
        t_friction,
        yes(t_friction <= 1.2)
    ));
    md.line(format!(
        "| native event-free `fmi3DoStep` (FMI 3.0 Co-Simulation) within 10% of the FMI 2.0 step, same run | {:.1} ns / {:.1} ns = {:.3} | {} |",
        step3,
        step_free,
        t3_step,
        yes(t3_step <= 1.10)
    ));
    md.line(format!(
        "| native event-free `fmi2DoStep` of {web} within 1.5x {belt}'s, same run: over a fresh instance's first \
         {start_s} s and over an instance stepped on for {run_s} s | {:.1} ns / {:.1} ns = {:.2}x and \
         {:.1} ns / {:.1} ns = {:.2}x | {} |",
        d.web_start.0,
        d.belt_start.0,
        d.t_web_start,
        d.web_step.0,
        d.belt_step.0,
        d.t_web,
        yes(d.t_web_start <= 1.5 && d.t_web <= 1.5),
        belt = DRIVE_AND_WEB[0],
        web = DRIVE_AND_WEB[1],
        start_s = d.start_s,
        run_s = d.run_s,
    ));
    let g = &f.gearbox;
    md.line(format!(
        "| native event-free `fmi2DoStep` of {GEARBOX} (two meshes) within 2.5x {MODEL}'s, same run, h = 1 ms \
         both | {:.1} ns / {:.1} ns = {:.2}x | {} |",
        g.step.0,
        step_free,
        g.t_step,
        yes(g.t_step <= 2.5)
    ));
}

fn loop_targets(md: &mut Md, f: &Figures) {
    let (l, a, t3) = (&f.loops, &f.accuracy, f.against_scipy());
    md.line(format!(
        "| fmpy PI loop spends < 5% of its time inside the FMU | {:.1}% (native cost of the same calls / fmpy loop time); {:.0}% inside the fmpy call wrappers | {} |",
        100.0 * l.native_share,
        100.0 * l.fmpy_share.0,
        yes(l.native_share < 0.05)
    ));
    md.line(format!(
        "| >= 100x faster than scipy at equal accuracy, native host | {:.0}x ({:.0} vs {:.2} simulated s per CPU s){} | {} |",
        t3,
        l.native_rate,
        a.matched.rate,
        if a.matched_is_equal { "" } else { "; no scipy setting of the sweep was as accurate as ours" },
        yes(t3 >= 100.0 && a.matched_is_equal)
    ));
    let (seconds, evaluations) = f.identify;
    md.line(format!(
        "| identify a 10 s run at 1 kHz (BacklashShaft, the paper's rig, default fit) in <= 5 s CPU on one core \
         (design/benches/identify.rs) | {seconds:.2} s CPU median of 5, {evaluations:.0} model evaluations | {} |",
        yes(seconds <= 5.0)
    ));
}

/// Below the targets table: what the first target compares.
const FIRST_TARGET_NOTE: &str =
    "The first target compares an FMI call that checks its arguments and state, advances the exact \
     solution (matrix exponential applied to the state and the held input, docs/model.md §2), proves the step \
     free of contact switches (a bound on u over the step; the search for a switch runs only where \
     that proof fails) and advances both bounds (docs/model.md §3), with a single product of a 4x4 matrix and \
     a vector. The criterion bench of the physics core (below) splits the step: its \
     `step_1ms_no_switch` is the plant alone, `bound_advance_1ms` the bounds alone while the loop's \
     response h is still decaying. Once h is below the round-off of `bound` (after the first seconds \
     of these runs), `bound` is final and advancing the bounds costs one multiply-add per entry of the \
     integral behind `bound_paper`, and one more for a running bound that rules out its overflow.";

/// Section 1: the native host's per-call costs, one row per measurement.
fn native_calls(md: &mut Md, plan: &Plan, r: &Results, f: &Figures) -> Result<(), String> {
    md.line("## 1. Native cost per call (C host through the FMI C ABI)");
    md.line("");
    md.line(format!(
        "benches/native_host.c dlopens `binaries/linux64/{MODEL}.so` from the packaged archive and calls \
         it through the function pointers it resolves, as any C importer does. BacklashShaft with the \
         FMU's start values (the paper's rig, Delta = 0.775 mm) and Kp = 42, Ki = 180 (tests/python/rigs.py), \
         h = 1 ms; the last {others} rows load `{belt}.so`, `{web}.so` and `{gearbox}.so`, each from its own \
         archive, into the same process (their schedules below). Time per item: median over {} batches of {} items \
         (floors: {} items), with the interquartile range; the rows' batches are taken in turn, one \
         batch of each row per round, so that a spell of contention on the machine reaches a few \
         batches of every row rather than all batches of one.",
        plan.suite_rounds,
        plan.steps_per_batch,
        plan.steps_per_batch * 20,
        // The rows of the other archives: the belt drive's first, to the end of the table.
        others = NATIVE_ROWS.len()
            - NATIVE_ROWS
                .iter()
                .position(|row| row.0 == "belt_step_event_free")
                .unwrap_or(0),
        belt = DRIVE_AND_WEB[0],
        web = DRIVE_AND_WEB[1],
        gearbox = GEARBOX,
    ));
    md.line("");
    md.line("| measurement | what one item contains | CPU median ns | CPU IQR ns | x matvec | wall median ns |");
    md.line("|---|---|---|---|---|---|");
    for (key, name, contains) in NATIVE_ROWS {
        let (med, q1, q3) = stat(r, key)?;
        md.line(format!(
            "| {name} (`{key}`) | {contains} | {med:.1} | {q1:.1} – {q3:.1} | {:.1} | {:.1} |",
            med / f.matvec.0,
            r.num(key, 3)?
        ));
    }
    Ok(())
}

/// The rows of section 1: key, measurement, what one item contains.
const NATIVE_ROWS: [(&str, &str, &str); 23] = [
    ("matvec_4x4", "floor: bare 4x4 matrix-vector product", "y = M x (16 mul, 12 add), inline C, each product feeding the next"),
    ("copy_set2_step_get1", "floor: FMI call pattern", "setReal(2) + doStep + getReal(1) on a trivial C copy-input-to-output component, through function pointers"),
    ("ours_set2_get1", "our call guard", "fmi2SetReal(tau_m, tau_L) + fmi2GetReal(omega_m), no step"),
    ("ours_step_event_free", "event-free step", "fmi2DoStep alone, in permanent contact (u pressed past g, constant 2 N.m)"),
    ("ours_step_event_free_friction", "event-free step with friction", "as `ours_step_event_free` with bearing friction in both bearings (tau_c_m = tau_c_L = 0.05 N.m), both bodies sliding: the sliding quiet step (docs/model.md §12)"),
    ("ours_set2_step", "step with inputs", "fmi2SetReal(tau_m, tau_L) + fmi2DoStep, event-free"),
    ("ours_set2_step_get1", "PI loop's calls", "fmi2SetReal(2) + fmi2DoStep + fmi2GetReal(omega_m), event-free"),
    ("ours_set2_step_get_all", "all outputs", "fmi2SetReal(2) + fmi2DoStep + fmi2GetReal of all 7 Real outputs (incl. bound, bound_paper) + fmi2GetInteger(contact), event-free"),
    ("ours_set2_step_switching", "switching step", "fmi2SetReal(2) + fmi2DoStep with a contact made and lost inside every step (schedule below)"),
    ("piloop_step", "native PI loop", "one step of the loop of sections 2-3 in C: fmi2GetReal(omega_m), PI, fmi2SetReal(2), fmi2DoStep"),
    ("me_get_derivatives", "Model Exchange right-hand side", "fmi2GetDerivatives(4) of a Model Exchange instance in Continuous-Time Mode, in contact"),
    ("me_get_event_indicators", "Model Exchange event indicators", "fmi2GetEventIndicators(10): u - g, u + g, the damper's four and friction's four (1 without them)"),
    ("me_set_states_get_derivatives", "one solver evaluation", "fmi2SetContinuousStates(4) + fmi2GetDerivatives(4)"),
    ("ours3_step_event_free", "FMI 3.0 event-free step", "fmi3DoStep alone (FMI 3.0 archive's token, no early return), the schedule of `ours_step_event_free`"),
    ("belt_step_event_free", "belt drive's event-free step", "BacklashBelt's fmi2DoStep alone, in permanent contact, one instance stepped on through the run (belt and web schedule below)"),
    ("web_step_event_free", "web line's event-free step", "BacklashWeb's fmi2DoStep alone, the same schedule with the web span pulling on the load (T stepped too; the bounds follow when read)"),
    ("belt_step_from_start", "belt drive's first steps", "as `belt_step_event_free`, but each batch is the first steps of a fresh instance (made and freed untimed)"),
    ("web_step_from_start", "web line's first steps", "as `web_step_event_free`, each batch the first steps of a fresh instance"),
    ("belt_step_read_bounds", "belt drive's first steps, bounds read", "as `belt_step_from_start`, with fmi2GetReal(bound, bound_paper) after each step"),
    ("web_step_read_bounds", "web line's first steps, bounds read", "as `web_step_from_start`, with fmi2GetReal(bound, bound_paper, bound_T) after each step"),
    ("two_stage_step_event_free", "two-stage gearbox's event-free step", "BacklashTwoStage's fmi2DoStep alone, both meshes in permanent contact, h = 1 ms, one instance stepped on through the run as `ours_step_event_free`'s (two-stage schedule below)"),
    ("two_stage_step_from_start", "two-stage gearbox's first steps", "as `two_stage_step_event_free`, each batch the first steps of a fresh instance"),
    ("two_stage_step_read_bounds", "two-stage gearbox's first steps, bound read", "as `two_stage_step_from_start`, with fmi2GetReal(bound) after each step"),
];

/// Below section 1's table: the schedules, what the switching and the web line cost, the FMI
/// call overhead.
fn native_schedules(md: &mut Md, r: &Results, s: &Schedules, f: &Figures) -> Result<(), String> {
    let switching = stat(r, "ours_set2_step_switching")?;
    let set_step = stat(r, "ours_set2_step")?;
    let (pressed_steps, pressed_switches, switches_per_step) =
        (s.pressed_steps, s.pressed_switches, s.switches_per_step);
    md.line("");
    md.line(format!(
        "- Event-free schedule: theta_m starts 5.5 mrad past the gap, near the equilibrium of the constant \
         torque, so the shaft never leaves the positive flank; an untimed run of the same {pressed_steps:.0} \
         steps with `logContactEvents` on counted {pressed_switches:.0} switches."
    ));
    md.line(format!(
        "- Switching schedule: the motor swings inside the gap, its speed alternating between -6 and +6 rad/s \
         at each communication point (held torque +-27 360 N.m), so that u passes +g or -g and returns within \
         every step; the logger counted {switches_per_step:.2} switches per step in an untimed run of the \
         same schedule. Marginal cost per switch, against fmi2SetReal(2) + fmi2DoStep without a switch \
         (`ours_set2_step`, {:.0} ns): ({:.0} - {:.0}) / {switches_per_step:.2} = **{:.0} ns**.",
        set_step.0, switching.0, set_step.0, f.switch_ns
    ));
    drive_schedule(md, s, &f.drives);
    gearbox_schedule(md, s, &f.gearbox, f.step_free.0);
    md.line(format!(
        "- FMI call overhead itself: the same call pattern costs {:.1} ns on the trivial component, {:.1} ns \
         for our setReal + getReal without a step (argument, state and value-reference checks behind \
         `catch_unwind`).",
        stat(r, "copy_set2_step_get1")?.0,
        f.set_get.0
    ));
    md.line("");
    Ok(())
}

/// Section 1's note on the belt and web schedule and on the web line's cost against the belt's.
fn drive_schedule(md: &mut Md, s: &Schedules, d: &Drives) {
    let (drive_steps, t_web_start, t_web, t_web_read) = (s.drive_steps, d.t_web_start, d.t_web, d.t_web_read);
    let (start_s, run_s) = (d.start_s, d.run_s);
    md.line(format!(
        "- Belt and web schedule (that of benches/physics.rs `web_benches`): each FMU's start values (the web \
         line's drive is {belt}'s, its span the film line of docs/model.md §8), h = {:.0} µs (their default step \
         size), from rest with theta_m = (g + 0.1 mm)/R_1, so that the belt is stretched 0.1 mm past the gap, \
         under a constant 0.5 N.m; the web's tension from 5 N with v_in = T_in = 0. Speed PI Kp = 0.18, \
         Ki = 57.6 for the bounds of both, and on the web a tension PI Kp_T = 0.01, Ki_T = 0.05, so that its \
         bounds are those of the 7-state loop. The drives' batches (these two's and the two-stage gearbox's) \
         take turns going first, one round to the next. Untimed runs of the same {drive_steps:.0} steps with `logContactEvents` on counted 0 \
         switches on either. A step advances the plant; the bounds, functions of elapsed time alone, are \
         brought up to the step when read (docs/model.md §3). The web line's step costs {t_web_start:.2}x \
         the belt drive's over a fresh instance's first {start_s} s ({:.1} ns more) and {t_web:.2}x over \
         {run_s} s of one instance ({:.1} ns more). Read after every step, the bounds add the cost of their \
         advance over the step: over the first {start_s} s \
         a step with the bounds read costs {:.1} ns on the web line (two bounds of the 7-state loop) and \
         {:.1} ns on the belt drive (one of the 5-state loop), {t_web_read:.2}x.",
        s.drive_h * 1e6,
        d.web_start.0 - d.belt_start.0,
        d.web_step.0 - d.belt_step.0,
        d.web_read.0,
        d.belt_read.0,
        belt = DRIVE_AND_WEB[0],
    ));
}

/// Section 1's note on the two-stage gearbox's schedule and its cost against the shaft's.
fn gearbox_schedule(md: &mut Md, s: &Schedules, g: &Gearbox, shaft_ns: f64) {
    md.line(format!(
        "- Two-stage schedule: {GEARBOX}'s start values (the two-stage rig of docs/model.md §10), h = {:.0} ms \
         (the shaft's rows' step, not its default experiment's), the shaft's constant 2 N.m and its Kp = 42, \
         Ki = 180 for the bound, from rest with theta_L at its start value (0) and theta_i, theta_m past each gap by the \
         deflection psi_j / k_j of the rigid motion that torque gives (each mesh carrying what accelerates the \
         bodies beyond it), so that neither mesh oscillates. An untimed run of the \
         same {:.0} steps ({} s) with `logContactEvents` on counted 0 switches and ended with both meshes on \
         their positive flanks. Its step costs {:.2}x the shaft's (`ours_step_event_free`, {shaft_ns:.1} ns; \
         {:.1} ns more); over a fresh instance's first {} s {:.1} ns, and {:.1} ns with the bound read after \
         each step.",
        s.gearbox_h * 1e3,
        s.gearbox_steps,
        g.run_s,
        g.t_step,
        g.step.0 - shaft_ns,
        g.start_s,
        g.start.0,
        g.read.0,
    ));
}

/// Section 2: the PI loop through fmpy, and the share of its time inside our FMU.
fn fmpy_loop(md: &mut Md, plan: &Plan, r: &Results, s: &Schedules, f: &Figures) -> Result<(), String> {
    let l = &f.loops;
    md.line("## 2. The PI loop through fmpy");
    md.line("");
    md.line(format!(
        "benches/python_bench.py: the sampled PI of tests/python/reference.py on omega_m, speed reference \
         5 sin(pi t) rad/s, load torque -2 N.m from t = 4 s, h = 1 ms, {} simulated s, BacklashShaft with \
         rigs.SHAFT (Delta = 2.69 mm) and rigs.SHAFT_GAINS, driven with fmpy's FMU2Slave through \
         backlash_fmu.fmu (`inst.get(\"omega_m\")`, `inst.step(...)` = setReal + doStep). \
         Median [IQR] of {} runs.",
        plan.loop_seconds, plan.loop_repeats
    ));
    md.line("");
    md.line("| quantity | value |");
    md.line("|---|---|");
    md.line(format!(
        "| loop time per step, CPU | {:.2} µs [{:.2} – {:.2}] |",
        l.fmpy_us.0, l.fmpy_us.1, l.fmpy_us.2
    ));
    md.line(format!(
        "| loop time per step, wall clock | {:.2} µs [{:.2} – {:.2}] |",
        r.num("fmpy_loop_us", 3)?,
        r.num("fmpy_loop_us", 4)?,
        r.num("fmpy_loop_us", 5)?
    ));
    md.line(format!(
        "| of which inside the fmpy calls (getReal, setReal, doStep: fmpy wrapper + ctypes + our FMU), timed \
         with perf_counter (wall) in a separate instrumented run, as a share of that run's wall time | {:.2} µs [{:.2} – {:.2}] = {:.0}% [{:.0} – {:.0}] |",
        l.fmpy_calls_us.0,
        l.fmpy_calls_us.1,
        l.fmpy_calls_us.2,
        100.0 * l.fmpy_share.0,
        100.0 * l.fmpy_share.1,
        100.0 * l.fmpy_share.2
    ));
    md.line(format!(
        "| of which inside our FMU: the same calls from the C host (`piloop_step`, section 1), CPU | {:.3} µs = **{:.1}%** |",
        l.native_ns.0 * 1e-3,
        100.0 * l.native_share
    ));
    md.line("");
    md.line(format!(
        "The FMU's own share is estimated with the native cost of exactly the same call sequence on the same \
         inputs (the native loop ends in the same state as the fmpy loop: largest relative difference of the \
         final states {:.1e}). Python cannot time the inside of a ctypes call without the marshalling around it.",
        s.final_diff
    ));
    md.line("");
    Ok(())
}

/// Section 2's fmpy.simulate_fmu runs: Model Exchange beside Co-Simulation.
fn simulate_fmu(md: &mut Md, r: &Results) -> Result<(), String> {
    let me_run = stat(r, "simulate_me_s")?;
    let cs_run = stat(r, "simulate_cs_s")?;
    md.line("### fmpy's simulate_fmu: Model Exchange beside Co-Simulation");
    md.line("");
    md.line(format!(
        "benches/python_bench.py `bench_simulate`: `fmpy.simulate_fmu` over {:.0} simulated s of the same rig, \
         open loop, motor torque 1.5 sin(pi t) N.m sampled every 1 ms, outputs every 1 ms; Model Exchange with \
         fmpy's CVode at relative tolerance 1e-8 (absolute tolerances from the FMU's nominals, switches \
         located by the event indicators), Co-Simulation with h = 1 ms. Wall time, median [IQR] of {:.0} runs.",
        r.num("simulate_me_s", 3)?,
        r.num("simulate_me_s", 4)?
    ));
    md.line("");
    md.line("| run | wall s | contact changes seen at the output points |");
    md.line("|---|---|---|");
    md.line(format!(
        "| Model Exchange, CVode | {:.2} [{:.2} – {:.2}] | {:.0} |",
        me_run.0,
        me_run.1,
        me_run.2,
        r.num("simulate_me_s", 5)?
    ));
    md.line(format!(
        "| Co-Simulation, exact steps | {:.2} [{:.2} – {:.2}] | {:.0} |",
        cs_run.0,
        cs_run.1,
        cs_run.2,
        r.num("simulate_cs_s", 5)?
    ));
    md.line("");
    md.line(format!(
        "Largest difference of omega_L between the two runs at the output points: {:.1e} rad/s (of a largest \
         |omega_L| of {:.3} rad/s); fmpy holds the input over each Co-Simulation step but interpolates it \
         linearly for Model Exchange, so the two runs do not solve quite the same problem. The Model Exchange \
         run costs {:.1}x the Co-Simulation one: CVode calls the FMU through ctypes for every right-hand side.",
        r.num("simulate_me_cs_diff", 0)?,
        r.num("simulate_me_cs_diff", 1)?,
        me_run.0 / cs_run.0
    ));
    md.line("");
    Ok(())
}

/// Section 3: the loop in scipy's solve_ivp, each setting of the sweep against ours.
fn against_scipy(md: &mut Md, plan: &Plan, f: &Figures) {
    let (l, a) = (&f.loops, &f.accuracy);
    let (fmu_error, radau_diff, equal) = (a.fmu_error, a.radau_diff, a.equal);
    let (native_rate, fmpy_rate) = (l.native_rate, l.fmpy_rate);
    let (native_rate_wall, fmpy_rate_wall) = (l.native_rate_wall, l.fmpy_rate_wall);
    md.line("## 3. Against scipy's solve_ivp at equal accuracy");
    md.line("");
    md.line(format!(
        "The same loop, {} simulated s, in tests/python/reference.py: solve_ivp with terminal events on \
         u = +-g, restarted at each switch and at each communication step (the controller samples every \
         1 ms), atol = 1e-4 rtol. Errors: largest relative error (signals.rel_err) of the four states at the \
         {} communication points against the shared reference, reference.py's own setting (DOP853, rtol \
         1e-13, atol 1e-17). That reference resolves differences down to ~{radau_diff:.1e} (Radau at the same \
         tolerances differs from it by that much), so errors below that are equal for this comparison.",
        plan.loop_seconds,
        (plan.loop_seconds / 1e-3).round()
    ));
    md.line("");
    md.line("| solver | error vs reference | simulated s per CPU s | simulated s per wall-clock s |");
    md.line("|---|---|---|---|");
    md.line(format!(
        "| **ours, native C host** | {fmu_error:.1e} | **{native_rate:.0}** | {native_rate_wall:.0} |"
    ));
    md.line(format!(
        "| **ours, fmpy host** | {fmu_error:.1e} | **{fmpy_rate:.0}** | {fmpy_rate_wall:.0} |"
    ));
    for s in &a.scipy {
        md.line(format!(
            "| scipy {} rtol {:.0e} atol {:.0e} | {:.1e} | {:.2} | {:.2} |",
            s.method, s.rtol, s.atol, s.error, s.rate, s.rate_wall
        ));
    }
    md.line("");
    md.line(format!(
        "Equal accuracy = error <= {equal:.1e} (the larger of ours and the reference's resolution). {}: \
         {} rtol {:.0e}, {:.2} simulated s per CPU s. Speed ratio against it (CPU time): native host **{:.0}x**, \
         fmpy host **{:.0}x**; in wall-clock time {:.0}x and {:.0}x. At h = 1 ms every solve_ivp call covers one millisecond in a handful of internal \
         steps, so its cost is the per-call overhead and barely depends on the tolerance.",
        if a.matched_is_equal {
            "Fastest scipy setting at equal accuracy"
        } else {
            "No scipy setting of the sweep reached it (so the target counts as not met); the most accurate one"
        },
        a.matched.method,
        a.matched.rtol,
        a.matched.rate,
        f.against_scipy(),
        fmpy_rate / a.matched.rate,
        native_rate_wall / a.matched.rate_wall,
        fmpy_rate_wall / a.matched.rate_wall
    ));
    md.line("");
}

/// Section 4, first part: the event-free step over more and more steps, one process each.
fn growth_in_steps(md: &mut Md, plan: &Plan, r: &Results) -> Result<(), String> {
    md.line("## 4. Growth");
    md.line("");
    md.line(
        "Event-free `fmi2DoStep` (schedule of section 1), one process per row, one timed run each. RSS from \
         /proc/self/status: VmRSS before instantiating, VmRSS and VmHWM (peak) at the end.",
    );
    md.line("");
    md.line("| steps | wall s | CPU ns per step | wall ns per step | VmRSS before kB | VmRSS end kB | VmHWM kB |");
    md.line("|---|---|---|---|---|---|---|");
    for row in r.rows("scale") {
        md.line(format!(
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
    md.line("");
    if let (Some(first), Some(last)) = (r.rows("scale").first(), r.rows("scale").last()) {
        let (a, b) = (number(first, 2, "scale")?, number(last, 2, "scale")?);
        md.line("");
        md.line(format!(
            "CPU time per step: {a:.0} ns over the first {} steps, {b:.0} ns averaged over {} steps ({:.1}x). \
             The cost per step is not uniform in simulated time: compare \
             the rows (section 1's batches cover {} s of simulated time).",
            first[0],
            last[0],
            b / a,
            (plan.suite_rounds as f64 * plan.steps_per_batch as f64 * 1e-3).round()
        ));
    }
    md.line("");
    Ok(())
}

/// Section 4, second part: many instances stepped round-robin, time and memory per instance.
fn growth_in_instances(md: &mut Md, plan: &Plan, r: &Results) -> Result<(), String> {
    md.line(format!(
        "Many instances, each instantiated and initialised (Kp, Ki, theta_m set), then stepped round-robin \
         (every instance one step, then the next round); time per instance-step: median [IQR] over {} \
         batches of ~{} instance-steps. Memory per instance = (VmRSS after setting up all instances - VmRSS \
         before) / count; the first row also carries the library's one-time set-up.",
        plan.batches, plan.instance_steps_per_batch
    ));
    md.line("");
    md.line(
        "| instances | CPU ns per instance-step | CPU IQR ns | wall ns | setup CPU µs per instance | memory per instance kB | VmHWM kB |",
    );
    md.line("|---|---|---|---|---|---|---|");
    for row in r.rows("instances") {
        let count = number(row, 0, "instances")?;
        let grown = number(row, 6, "instances")? - number(row, 5, "instances")?;
        md.line(format!(
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
    md.line("");
    Ok(())
}

/// Section 5: the tolerance sweep serially and on a Dask LocalCluster of one and two workers, in
/// tasks of several samples sized by the sweep's engine.
fn dask_sweep(md: &mut Md, r: &Results) -> Result<(), String> {
    md.line("## 5. Tolerance sweep on Dask (benches/sweep_bench.py)");
    md.line("");
    let (serial_rate, serial_s) = (r.num("sweep_serial", 0)?, r.num("sweep_serial", 1)?);
    let scaling = r.num("sweep_scaling", 0)?;
    let overhead = r.num("sweep_overhead", 0)?;
    md.line(format!(
        "The same {} samples of `python -m backlash_fmu.sweep` (default config: twin closed-loop runs of {} s each \
         through fmpy), wall time from the first task handed out to the last row received, median of {} \
         interleaved repeats; start = the LocalCluster's start, the archive sent once to each worker (a worker \
         plugin), their imports and unpacking. The tables of every run are {}.",
        r.num("sweep_config", 0)?,
        r.num("sweep_config", 1)?,
        r.num("sweep_config", 3)?,
        if r.num("sweep_identical", 0)? == 1.0 {
            "identical"
        } else {
            "**not identical**"
        }
    ));
    md.line("");
    md.line(format!(
        "On Dask a task runs several samples, its size chosen from the time of a sample measured on the workers \
         by the first tasks ({:.1} ms): about a second of work a task, at least 0.2 s, and at least four tasks per \
         worker among the samples left, so that the chunks shrink towards the end. First size chosen: {} samples \
         with 1 worker ({} tasks in all), {} with 2 workers ({} tasks).",
        r.num("sweep_chunk", 4)?,
        r.num("sweep_chunk", 0)?,
        r.num("sweep_chunk", 1)?,
        r.num("sweep_chunk", 2)?,
        r.num("sweep_chunk", 3)?
    ));
    md.line("");
    md.line("| run | samples/s | s | start s |");
    md.line("|---|---|---|---|");
    md.line(format!("| serial, no Dask | {serial_rate:.2} | {serial_s:.2} | – |"));
    for workers in [1, 2] {
        let key = format!("sweep_dask{workers}");
        md.line(format!(
            "| LocalCluster, {workers} worker{} | {:.2} | {:.2} | {:.2} |",
            if workers == 1 { "" } else { "s" },
            r.num(&key, 0)?,
            r.num(&key, 1)?,
            r.num(&key, 2)?
        ));
    }
    md.line("");
    let (compute, idle, paired) = (
        r.num("sweep_paired", 0)?,
        r.num("sweep_paired", 3)?,
        r.num("sweep_paired", 4)?,
    );
    let (paired_scaling, shared, idle2) = (
        r.num("sweep_scaling_paired", 0)?,
        r.num("sweep_scaling_paired", 1)?,
        r.num("sweep_scaling_paired", 4)?,
    );
    md.line(format!(
        "Scaling from 1 to 2 workers: {paired_scaling:.2}x (target >= 1.8x: {}), from its parts, each measured \
         within one stretch of time: the workers idle {idle2:.1}% of the median 2-worker run (1 - its tasks' \
         compute time / twice its wall time; the tail where one worker waits for the other included) and {idle:.1}% \
         of the median 1-worker run, and a sample computing {shared:.3}x as fast on each of two workers sharing \
         the machine as on one worker alone ({} blocks of {} samples, on a 1-worker cluster and at once on both \
         workers of a 2-worker cluster, by turns, not pinned); scaling = 2 x {shared:.3} x (1 - {:.3}) / (1 - \
         {:.3}). The ratio of the median whole runs above is {scaling:.2}x.",
        yes(paired_scaling >= 1.8),
        r.num("sweep_scaling_paired", 2)?,
        r.num("sweep_scaling_paired", 3)?,
        idle2 / 100.0,
        idle / 100.0,
    ));
    md.line("");
    md.line(format!(
        "Dask's overhead per sample: \
         {paired:.1}% (target <= 5%: {}), from its two parts, each measured within one stretch of time: the \
         worker idle {idle:.1}% of the median 1-worker run (1 - its tasks' compute time / its wall time), and a \
         sample computing {compute:.3}x as long in a worker as in a plain Python process without Dask ({} blocks \
         of {} samples, computed in each by turns, both processes on one core); 1-worker time = serial time x {compute:.3} / (1 - \
         {:.3}). The ratio of the whole runs above, 1 - serial time / 1-worker time = {overhead:.1}%, compares \
         runs timed minutes apart, over which this machine's speed drifts by tens of percent. The 1-minute load \
         average was {:.2} when this bench started and {:.2} when it ended, on {} cores.",
        yes(paired <= 5.0),
        r.num("sweep_paired", 1)?,
        r.num("sweep_paired", 2)?,
        idle / 100.0,
        r.num("sweep_load", 0)?,
        r.num("sweep_load", 1)?,
        r.num("sweep_load", 2)?
    ));
    md.line("");
    Ok(())
}

/// The criterion bench of the physics core (none in smoke mode).
fn physics_core(md: &mut Md, measured: &Measurements, f: &Figures) {
    md.line("## Physics core (criterion, benches/physics.rs)");
    md.line("");
    if measured.criterion.is_empty() {
        md.line("Not run in smoke mode.");
    } else {
        md.line("Rust calls into `backlash_fmu::physics`, no FMI layer; criterion's estimate and 95% interval.");
        md.line("");
        md.line("| bench | ns | interval ns |");
        md.line("|---|---|---|");
        for c in &measured.criterion {
            md.line(format!(
                "| {} | {:.1} | {:.1} – {:.1} |",
                c.name, c.estimate_ns, c.low_ns, c.high_ns
            ));
        }
        damper_target(md, measured);
        chain_ratio(md, measured, &f.gearbox);
        friction_ratio(md, measured);
    }
    md.line("");
}

/// Criterion's estimate of bench `name` in this run [ns], if it ran.
fn criterion_ns(measured: &Measurements, name: &str) -> Option<f64> {
    measured
        .criterion
        .iter()
        .find(|c| c.name == name)
        .map(|c| c.estimate_ns)
}

/// Bearing friction on every body of the two-stage drive (docs/model.md §10): the chain's general
/// step sliding event-free over the same step without friction, from criterion's estimates of
/// this run. The chain has no quiet sliding step (the FMUs' one-stage plants take the single-gap
/// stepper's, measured in section 1); BacklashTwoStage steps the chain, so this is the physics of
/// its step with friction.
fn friction_ratio(md: &mut Md, measured: &Measurements) {
    let (Some(plain), Some(rough)) = (
        criterion_ns(measured, "chain_two_stage_step_1ms_sliding"),
        criterion_ns(measured, "chain_two_stage_step_1ms_sliding_friction"),
    ) else {
        return;
    };
    md.line("");
    md.line(format!(
        "Bearing friction on every body of the two-stage drive (docs/model.md §10), the chain's general step \
         (no quiet sliding step of its own; {GEARBOX} takes this step, physics alone here): its sliding event-free step \
         {rough:.1} ns = **{:.2}x** the same step without friction, {plain:.1} ns (1.2x would be **{}** here; \
         criterion's separate estimates, not a paired measure).",
        rough / plain,
        if rough <= 1.2 * plain { "met" } else { "not met" }
    ));
}

/// The chain of stages (docs/model.md §10) against the single-gap stepper: the physics step
/// of the two-stage drive and of the shaft as a one-stage chain, each over the shaft's
/// `step_1ms_no_switch`, from criterion's estimates of this run: the physics part of
/// BacklashTwoStage's step, whose FMU step the targets judge from section 1 (`g`).
fn chain_ratio(md: &mut Md, measured: &Measurements, g: &Gearbox) {
    let ns = |name: &str| criterion_ns(measured, name);
    let (Some(shaft), Some(one), Some(two)) = (
        ns("step_1ms_no_switch"),
        ns("chain_one_stage_step_1ms_no_switch"),
        ns("chain_two_stage_step_1ms_no_switch"),
    ) else {
        return;
    };
    md.line("");
    md.line(format!(
        "The chain of stages (docs/model.md §10), physics alone: the two-stage drive's event-free step \
         {two:.1} ns = **{:.2}x** the shaft's {shaft:.1} ns, the physics part of {GEARBOX}'s step (through \
         the FMI layer, section 1: {:.2}x the shaft's, the target of 2.5x judged there); the shaft stepped as a \
         one-stage chain {one:.1} ns = {:.2}x the shaft's own stepper.",
        two / shaft,
        g.t_step,
        one / shaft
    ));
}

/// The target of the event-free step with a damper in the compliant member: within 1.1x the step
/// without (docs/model.md §2, "With a damper"). Judged on the paired measure of this run (blocks
/// alternating in one process on one core); criterion's separate estimates are shown beside it.
fn damper_target(md: &mut Md, measured: &Measurements) {
    let ns = |name: &str| criterion_ns(measured, name);
    let Some(paired) = &measured.paired_damped else {
        return;
    };
    let ratios: Vec<String> = paired
        .damped
        .iter()
        .map(|(name, damped_ns, [low, mid, high])| {
            let criterion = match (ns(name), ns("step_1ms_no_switch")) {
                (Some(d), Some(p)) => format!("; criterion's separate estimates {d:.1} ns / {p:.1} ns = {:.2}x", d / p),
                _ => String::new(),
            };
            format!(
                "`{name}` **{mid:.3}x** (95% interval {low:.3}x to {high:.3}x; medians {damped_ns:.1} ns and {:.1} ns{criterion})",
                paired.plain_ns
            )
        })
        .collect();
    let worst = paired.damped.iter().map(|(_, _, [_, mid, _])| *mid).fold(0.0, f64::max);
    md.line("");
    md.line(format!(
        "Event-free step with a damper in the shaft (contact damping ratio 0.5) within 1.1x the step without: \
         the median over {} rounds of the ratio of block times ({} steps per block, the three steps' blocks \
         alternating in one process on one core): {} (target: **{}**).",
        paired.rounds,
        paired.steps_per_block,
        ratios.join("; "),
        if worst <= 1.1 { "met" } else { "not met" }
    ));
}

/// The commands of the run, in order.
fn commands(md: &mut Md, plan: &Plan, measured: &Measurements) {
    md.line("## Commands");
    md.line("");
    md.line(format!(
        "All run by `cargo xtask bench{}` from the repository root, after `cargo xtask fmu` (release build) \
         and the `.venv` set-up; `target/bench/bench_vr.h` holds the value references read from the archives' \
         modelDescription.xml.",
        if plan.smoke { " --smoke" } else { "" }
    ));
    md.line("");
    md.line("```sh");
    for c in &measured.commands {
        md.line(c);
    }
    md.line("```");
}

#[cfg(test)]
#[path = "report_tests.rs"]
mod tests;
