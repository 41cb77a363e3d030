//! report.rs's output pinned byte for byte.
//!
//! The golden files under testdata/ were written by the single-function `render` of report.rs as
//! it stood before it was split into one function per section (the commit before that split),
//! from exactly the fixed inputs below: `report_golden.md` from the full plan with every branch
//! of a normal run, `report_golden_smoke.md` from the smoke plan with the other branches (no
//! criterion, no growth rows, no scipy setting as accurate as ours, sweep tables that differ).
//! The error texts below were checked against that same render. To rewrite the golden files
//! after an intended change of the report, run the tests with `BENCH_REPORT_BLESS=1` and review
//! the diff of testdata/.

use std::fs;
use std::path::PathBuf;

use super::super::run::{CriterionEstimate, Facts, Measurements, PairedDamped, Results};
use super::super::Plan;
use super::render;

/// Every `@` line render reads, with plausible numbers in the formats the hosts print.
const COMMON: &str = "\
@ pressed_switches 0 2020000
@ pressed_final_contact 1
@ pressed_friction_switches 0 2020000 1 1
@ swinging_switches 4040000 2020000
@ belt_pressed_switches 0 2020000 0.0001 1
@ web_pressed_switches 0 2020000 0.0001 1
@ two_stage_pressed_switches 0 2020000 0.001 1 1
@ matvec_4x4 5.5 5.45 5.55 5.52 5.46 5.6
@ copy_set2_step_get1 10.4 10.35 10.5 10.41 10.36 10.52
@ ours_set2_get1 20.1 19.9 20.3 20.12 19.95 20.33
@ ours_step_event_free 23.4 23.2 23.6 23.43 23.21 23.62
@ ours_step_event_free_friction 27.1 26.9 27.4 27.12 26.91 27.43
@ ours_set2_step 34.3 34.1 34.7 34.31 34.12 34.74
@ ours_set2_step_get1 43.7 43.4 44.3 43.72 43.41 44.36
@ ours_set2_step_get_all 78.4 78.1 79 78.45 78.13 79.02
@ ours_set2_step_switching 1576.3 1571.8 1582.5 1577.4 1572.2 1583.9
@ piloop_step 58 57.8 59.5 58.04 57.83 59.51
@ me_get_derivatives 19.4 19.3 19.6 19.42 19.31 19.63
@ me_get_event_indicators 11.2 11.1 11.2 11.21 11.12 11.24
@ me_set_states_get_derivatives 38.6 38.5 38.8 38.62 38.51 38.83
@ ours3_step_event_free 25.9 25.8 26.4 25.93 25.81 26.42
@ belt_step_event_free 25.2 25 25.6 25.21 25.02 25.63
@ web_step_event_free 26.7 26.5 27.2 26.73 26.52 27.24
@ belt_step_from_start 26.8 26.6 27.1 26.82 26.61 27.13
@ web_step_from_start 29.6 29.4 30.2 29.62 29.41 30.22
@ belt_step_read_bounds 54.9 54.6 55.6 54.93 54.62 55.64
@ web_step_read_bounds 145.3 144.4 146.7 145.32 144.43 146.71
@ two_stage_step_event_free 49.7 49.3 50.4 49.72 49.31 50.43
@ two_stage_step_from_start 55.2 54.8 55.9 55.23 54.82 55.94
@ two_stage_step_read_bounds 143.8 142.9 145.1 143.84 142.93 145.12
@ instances 1 25.1 24.2 26.3 251234 1964 3024 3072 25.2
@ instances 10 26 25.8 26.4 28123.5 1964 3184 3336 26.1
@ instances 100 25.2 24.4 26.1 11034 1968 4818 4768 25.3
@ instances 1000 27.3 27.1 29.2 9021.7 1972 21172 21332 27.4
@ piloop_final 0.5 -1.25 3.0000000000000004 0.001 10000
@ fmpy_loop_us 4.62 4.54 5.05 4.71 4.58 5.12 10000 7
@ fmpy_inside_calls_share 0.912 0.908 0.915
@ fmpy_inside_calls_us 4.27 4.265 4.301
@ reference_run 10 12.5 35
@ reference_radau_diff 3.1e-13
@ fmu_error 4.5e-13 0.5 -1.25 3.0000000000000004 0.001 10000
@ simulate_me_s 1.6812 1.6734 1.6845 10 3 35
@ simulate_cs_s 0.3012 0.2987 0.3034 10 3 35
@ simulate_me_cs_diff 0.00037 0.2281
@ identify_10s_1khz 1.3526 141 5 1.3474 1.3867
@ sweep_config 240 1.5 0.001 3
@ sweep_serial 42.56 5.639
@ sweep_dask1 41.62 5.7665 0.8711
@ sweep_dask2 79.88 3.0045 1.0632
@ sweep_scaling 1.9193
@ sweep_overhead 2.21
@ sweep_paired 1.012 30 8 0.45 1.64
@ sweep_scaling_paired 1.9391 0.9712 30 8 0.62
@ sweep_chunk 43 12 30 20 23.4
@ sweep_load 0.42 1.37 2
";

/// The growth rows, the scipy sweep and the sweep's identity flag of a normal run.
const FULL: &str = "\
@ scale 1000 0.0001 58.2 2000 3020 3020 1 60.1
@ scale 10000 0.0003 29.4 2116 3036 3036 1 29.3
@ scale 100000 0.0027 27.1 1936 2912 2912 1 27.2
@ scale 1000000 0.0241 24.1 1940 2916 2916 1 24.2
@ scale 10000000 0.2957 29.6 1972 2928 2928 1 29.6
@ scipy RK45 0.001 1e-07 3.9e-14 13.66 120 13.65
@ scipy RK45 1e-06 1e-10 3.9e-14 13.56 120 13.56
@ scipy RK45 1e-12 1e-16 1.1e-14 10.07 120 10.07
@ scipy DOP853 0.001 1e-07 8.2e-16 10.5 120 10.5
@ scipy DOP853 1e-12 1e-16 7.5e-16 10.41 120 10.41
@ sweep_identical 1
";

/// Smoke: no scipy setting as accurate as ours, no growth rows, sweep tables that differ.
const SMOKE: &str = "\
@ scipy RK45 0.001 1e-07 2.5e-09 13.66 4 13.65
@ scipy RK45 1e-06 1e-10 7.5e-12 13.56 4 13.56
@ sweep_identical 0
";

fn facts() -> Facts {
    Facts {
        load_start: "1.11 0.95 1.07 1/80 14025".into(),
        load_end: "1.19 1.03 1.08 1/80 14161".into(),
        elapsed_s: 94.4,
        date: "2026-11-25 16:54".into(),
        nproc: "2".into(),
        cpu: "AMD EPYC".into(),
        kernel: "Linux 6.18.44".into(),
        rustc: "rustc 1.95.0 (59807616e 2026-04-14)".into(),
        cc: "cc (Debian 12.2.0-14+deb12u1) 12.2.0".into(),
        python: "Python 3.11.7".into(),
    }
}

fn measured(text: &str, criterion: bool) -> Measurements {
    let criterion = if criterion {
        [
            ("matvec_4x4", 1.68, 1.7, 1.72),
            ("step_1ms_no_switch", 26.4, 26.5, 26.6),
            ("web_bounds_advance_100us", 139.3, 139.6, 139.8),
            ("chain_one_stage_step_1ms_no_switch", 30.1, 30.3, 30.6),
            ("chain_two_stage_step_1ms_no_switch", 44.6, 44.9, 45.3),
            ("chain_two_stage_step_1ms_sliding", 61.0, 61.4, 61.9),
            ("chain_two_stage_step_1ms_sliding_friction", 66.2, 66.8, 67.5),
        ]
        .into_iter()
        .map(|(name, low_ns, estimate_ns, high_ns)| CriterionEstimate {
            name: name.into(),
            low_ns,
            estimate_ns,
            high_ns,
        })
        .collect()
    } else {
        Vec::new()
    };
    Measurements {
        results: Results::parse(text),
        criterion,
        paired_damped: None,
        commands: vec![
            "cc -O2 -o target/bench/native_host benches/native_host.c -ldl -lm".into(),
            "target/bench/native_host target/bench/BacklashShaft.so suite 101 20000".into(),
            ".venv/bin/python benches/python_bench.py --loop-seconds 10".into(),
        ],
    }
}

fn full_text() -> String {
    format!("{COMMON}{FULL}")
}

fn golden(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("src/bench/testdata")
        .join(name)
}

/// `rendered` byte for byte against the golden file `name` (or writes it, when blessing).
fn check_golden(name: &str, rendered: &str) {
    let path = golden(name);
    if std::env::var_os("BENCH_REPORT_BLESS").is_some() {
        fs::create_dir_all(path.parent().unwrap()).unwrap();
        fs::write(&path, rendered).unwrap();
        return;
    }
    let expected = fs::read_to_string(&path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
    if rendered != expected {
        let line = rendered
            .lines()
            .zip(expected.lines())
            .position(|(a, b)| a != b)
            .unwrap_or_else(|| rendered.lines().count().min(expected.lines().count()));
        panic!(
            "render differs from {} (first at line {}):\n  got:      {:?}\n  expected: {:?}\n\
             ({} bytes rendered, {} expected)",
            path.display(),
            line + 1,
            rendered.lines().nth(line),
            expected.lines().nth(line),
            rendered.len(),
            expected.len()
        );
    }
}

#[test]
fn full_report_is_unchanged() {
    let rendered = render(&Plan::full(), &measured(&full_text(), true), &facts()).unwrap();
    check_golden("report_golden.md", &rendered);
}

#[test]
fn smoke_report_is_unchanged() {
    let text = format!("{COMMON}{SMOKE}");
    let rendered = render(&Plan::smoke(), &measured(&text, false), &facts()).unwrap();
    check_golden("report_golden_smoke.md", &rendered);
}

/// The error of rendering the full inputs with `text` changed: lines appended (a key's last line
/// is the one read) and the lines of the keys in `drop` left out.
fn error(append: &str, drop: &[&str]) -> String {
    let text: String = full_text()
        .lines()
        .filter(|l| !drop.iter().any(|k| l.split_whitespace().nth(1) == Some(*k)))
        .map(|l| format!("{l}\n"))
        .collect::<String>()
        + append;
    match render(&Plan::full(), &measured(&text, true), &facts()) {
        Ok(_) => panic!("rendered despite {append:?} without {drop:?}"),
        Err(e) => e,
    }
}

#[test]
fn schedule_checks_fail_with_unchanged_messages() {
    let cases: [(&str, &[&str], &str); 13] = [
        (
            "@ pressed_switches 3 2020000\n",
            &[],
            "the event-free schedule switched 3 times: not event-free",
        ),
        (
            "@ pressed_final_contact 0\n",
            &[],
            "the event-free schedule switched 0 times: not event-free",
        ),
        (
            "@ swinging_switches 1 4\n",
            &[],
            "the switching schedule switched only 0.25 times per step",
        ),
        (
            "@ belt_pressed_switches 2 2020000 0.0001 1\n",
            &[],
            "the belt event-free schedule switched 2 times (final contact 1): not event-free",
        ),
        (
            "@ web_pressed_switches 0 2020000 0.0001 0\n",
            &[],
            "the web event-free schedule switched 0 times (final contact 0): not event-free",
        ),
        (
            "@ two_stage_pressed_switches 0 2020000 0.001 1 0\n",
            &[],
            "the two-stage event-free schedule switched 0 times (final contacts 1, 0): not event-free",
        ),
        (
            "@ two_stage_pressed_switches 0 2020000 0.001 1\n",
            &[],
            "result `two_stage_pressed_switches`: [\"0\", \"2020000\", \"0.001\", \"1\"] is not the two-stage \
             schedule's check of 2 mesh(es)",
        ),
        (
            "@ scale 5 0.1 2.5 1 2 3 0 4\n",
            &[],
            "scale run [\"5\", \"0.1\", \"2.5\", \"1\", \"2\", \"3\", \"0\", \"4\"] left the contact: not event-free",
        ),
        (
            "@ piloop_final 0.5 -1.25 3.0000000001 0.001 10000\n",
            &[],
            "the native loop ends at [0.5, -1.25, 3.0000000001, 0.001], the fmpy loop at \
             [0.5, -1.25, 3.0000000000000004, 0.001]: not the same loop",
        ),
        ("", &["scipy"], "no scipy result"),
        ("", &["matvec_4x4"], "no result `matvec_4x4` in the benchmark output"),
        (
            "@ sweep_config 40\n",
            &[],
            "result `sweep_config`: no number at position 1 in [\"40\"]",
        ),
        (
            "@ instances 3 x\n",
            &[],
            "result `instances`: no number at position 6 in [\"3\", \"x\"]",
        ),
    ];
    for (append, drop, expected) in cases {
        assert_eq!(error(append, drop), expected, "appending {append:?}, without {drop:?}");
    }
}

/// The paired measure of the damped step: read from the bench's line, and judged on the median
/// ratio (1.104 fails the 1.1x target, 1.066 meets it).
#[test]
fn paired_damped_step_is_read_and_judged() {
    let line = |law2: f64| {
        format!(
            "Benchmarking ...\npaired-damped-step {{\"rounds\": 301, \"steps_per_block\": 20000, \
             \"step_1ms_no_switch_ns\": 26.9, \"step_1ms_no_switch_damped_law1_ns\": 28.9, \
             \"step_1ms_no_switch_damped_law1_ratio\": [1.06, 1.066, 1.069], \
             \"step_1ms_no_switch_damped_law2_ns\": 29.2, \
             \"step_1ms_no_switch_damped_law2_ratio\": [1.08, {law2}, 1.2]}}\n"
        )
    };
    let plan = Plan::full();
    for (law2, verdict) in [(1.086, "(target: **met**)."), (1.104, "(target: **not met**).")] {
        let paired = PairedDamped::parse(&line(law2))
            .expect("valid line")
            .expect("a paired line");
        assert_eq!(paired.rounds, 301);
        assert_eq!(paired.damped[1].2, [1.08, law2, 1.2]);
        let mut m = measured(&full_text(), true);
        m.paired_damped = Some(paired);
        let report = render(&plan, &m, &facts()).expect("renders");
        let target = report
            .lines()
            .find(|l| l.starts_with("Event-free step with a damper"))
            .expect("the target's line");
        assert!(target.contains("**1.066x**") && target.ends_with(verdict), "{target}");
    }
    assert!(PairedDamped::parse("no such line").expect("nothing to read").is_none());
    assert!(PairedDamped::parse("paired-damped-step {\"rounds\": 3}").is_err());
}

/// The friction line: the ratio of the two sliding steps' estimates, judged against 1.2x, and
/// no line when either bench did not run.
#[test]
fn friction_ratio_is_judged() {
    let plan = Plan::full();
    for (rough, ratio, verdict) in [
        (73.6, "**1.20x**", "**met** here"),
        (73.8, "**1.20x**", "**not met** here"),
    ] {
        let mut m = measured(&full_text(), true);
        let entry = m
            .criterion
            .iter_mut()
            .find(|c| c.name == "chain_two_stage_step_1ms_sliding_friction")
            .expect("in the fixture");
        entry.estimate_ns = rough;
        // 61.4 ns without friction: 1.2x is 73.68 ns.
        let report = render(&plan, &m, &facts()).expect("renders");
        let line = report
            .lines()
            .find(|l| l.starts_with("Bearing friction on every body"))
            .expect("the friction line");
        assert!(line.contains(ratio) && line.contains(verdict), "{line}");
    }
    let mut m = measured(&full_text(), true);
    m.criterion.retain(|c| c.name != "chain_two_stage_step_1ms_sliding");
    let report = render(&plan, &m, &facts()).expect("renders");
    assert!(!report.contains("Bearing friction on every body"));
}

/// The two-stage gearbox's target: its event-free step over the shaft's, medians of the same
/// run, judged against 2.5x (the shaft's 23.4 ns: 2.5x is 58.5 ns), and quoted beside the physics.
#[test]
fn two_stage_ratio_is_judged() {
    let plan = Plan::full();
    for (two_stage, ratio, verdict) in [(58.4, "2.50x", "**met**"), (58.6, "2.50x", "**not met**")] {
        let text = format!(
            "{}@ two_stage_step_event_free {two_stage} 58 59 58.5 58 59\n",
            full_text()
        );
        let report = render(&plan, &measured(&text, true), &facts()).expect("renders");
        let line = report
            .lines()
            .find(|l| l.starts_with("| native event-free `fmi2DoStep` of BacklashTwoStage"))
            .expect("the target's line");
        assert!(
            line.contains(&format!("{two_stage:.1} ns / 23.4 ns = {ratio} | {verdict} |")),
            "{line}"
        );
    }
    // The physics line quotes the FMU's ratio beside the chain's, and no longer says no FMU steps it.
    let report = render(&plan, &measured(&full_text(), true), &facts()).expect("renders");
    let physics = report
        .lines()
        .find(|l| l.starts_with("The chain of stages"))
        .expect("the chain's line");
    assert!(
        physics.contains("**1.69x**") && physics.contains("section 1: 2.12x the shaft's"),
        "{physics}"
    );
    assert!(!report.contains("no FMU steps the two-stage chain yet"));
}
