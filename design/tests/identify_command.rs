//! `backlash excite` and `backlash identify` as a user runs them: a schedule from excite, a run
//! simulated here by the physics crate's exact stepper (not the identification's model), and
//! identify's answer, which must contain the truth in its 95% intervals; bad data refused.

mod common;

use backlash_physics::{Inputs, Plant, PlantParams, PlantState, Stepper};
use common::{backlash, text};
use std::path::PathBuf;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("backlash-identify-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// The run of the paper's rig with half gap `delta` under the schedule in `schedule` (CSV
/// time,tau_m), from rest at u(0) = u0, θ_m and θ_L measured with noise of `noise` rad.
fn measured_csv(schedule: &str, delta: f64, u0: f64, noise: f64) -> String {
    let rows: Vec<(f64, f64)> = schedule
        .lines()
        .skip(1)
        .map(|l| {
            let (t, tau) = l.split_once(',').unwrap();
            (t.parse().unwrap(), tau.parse().unwrap())
        })
        .collect();
    let h = rows[1].0 - rows[0].0;
    let plant = Plant::new(PlantParams::paper_rig(delta)).unwrap();
    let mut state = PlantState::new(&plant, u0, 0.0, 0.0, 0.0);
    let mut stepper = Stepper::new(plant);
    let mut seed: u64 = 7;
    let mut noisy = |x: f64| {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        x + noise * ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5)
    };
    let mut csv = String::from("time,tau_m,theta_m,theta_L\n");
    for (t, tau) in rows {
        csv += &format!("{t},{tau},{},{}\n", noisy(state.theta_m - u0), noisy(state.theta_l));
        stepper
            .step(&mut state, &Inputs::held(tau, 0.0), h, &mut |_| {})
            .unwrap();
    }
    csv
}

#[test]
fn excite_then_identify_recovers_the_drive() {
    let schedule_path = scratch("schedule.csv");
    let out = backlash(&["excite", "--model", "shaft", "--out", schedule_path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(text(&out.stdout).starts_with("wrote "));
    let (delta, u0) = (1.5e-3, -0.6e-3);
    let run = scratch("run.csv");
    std::fs::write(
        &run,
        measured_csv(&std::fs::read_to_string(&schedule_path).unwrap(), delta, u0, 2e-5),
    )
    .unwrap();
    let out = backlash(&[
        "identify",
        "--model",
        "shaft",
        run.to_str().unwrap(),
        "--json",
        "--accuracy",
        "0.05",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let answer: serde_json::Value = serde_json::from_str(text(&out.stdout)).unwrap();
    assert_eq!(answer["model"], "shaft");
    assert_eq!(answer["samples"], 10_001);
    for (name, truth) in [("Delta", delta), ("k", 200.0), ("J_L", 2.55), ("b_L", 0.05), ("u0", u0)] {
        let e = &answer["estimates"][name];
        let (lo, hi) = (e["ci95"][0].as_f64().unwrap(), e["ci95"][1].as_f64().unwrap());
        assert!(e["identifiable"] == true && lo <= truth && truth <= hi, "{name}: {e}");
    }
    // The noise is uniform on ±1e-5: its RMS is 1e-5/√3, which the residual must match.
    let rms = answer["residual_rms"]["theta_m"].as_f64().unwrap();
    assert!((rms / (2e-5 / 12f64.sqrt()) - 1.0).abs() < 0.05, "{rms}");
    let acc = &answer["accuracy"];
    let (est, worst) = (
        acc["bound_sup_estimate"].as_f64().unwrap(),
        acc["bound_sup_worst"].as_f64().unwrap(),
    );
    assert!(worst >= est && acc["meets"] == (worst <= 0.05), "{acc}");
    std::fs::remove_dir_all(schedule_path.parent().unwrap()).ok();
}

#[test]
fn bad_data_gives_one_error_line_naming_it_and_status_2() {
    let good: String = (0..50).map(|i| format!("{},1,0\n", i as f64 * 1e-3)).collect();
    let cases = [
        ("time,omega_L\n0,1\n".to_string(), "column tau_m"),
        (
            "time,tau_m\n".to_string() + &(0..50).map(|i| format!("{},1\n", i as f64 * 1e-3)).collect::<String>(),
            "no measured output",
        ),
        (format!("time,tau_m,omega_L\n{}0.0495,1,nan\n", good), "row 52"),
        (format!("time,tau_m,omega_L\n{}0.04,1,0\n", good), "row 52, column time"),
        ("time,tau_m,omega_L\n0,1,0\n0.001,1,0\n".to_string(), "too few"),
        (format!("time,tau_m,omega_X\n{good}"), "omega_X"),
    ];
    for (i, (csv, named)) in cases.iter().enumerate() {
        let path = scratch(&format!("bad{i}.csv"));
        std::fs::write(&path, csv).unwrap();
        let out = backlash(&["identify", "--model", "shaft", path.to_str().unwrap()]);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{named}: {stderr}");
        assert!(
            stderr.starts_with("error: ") && stderr.lines().count() == 1 && stderr.contains(named),
            "{named}: {stderr:?}"
        );
    }
    for args in [
        &["identify"][..],
        &["identify", "--model", "shaft", "/nonexistent/run.csv"],
        &["identify", "--model", "gear", "x.csv"],
        &["identify", "x.csv", "--fit", "Delta,frob"],
        &["identify", "x.csv", "--set", "J_L=-1"],
        &["identify", "x.csv", "--frobnicate"],
        &["excite", "--torque-limit", "nan"],
        &["excite", "--step", "0"],
        &["excite", "--json"],
    ] {
        let out = backlash(args);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.starts_with("error: ") && stderr.lines().count() == 1,
            "{args:?}: {stderr:?}"
        );
    }
}

#[test]
fn the_commands_are_listed_and_explain_themselves() {
    let out = backlash(&["--help"]);
    let usage = text(&out.stdout);
    assert!(
        usage.contains("\n  identify  ") && usage.contains("\n  excite    "),
        "{usage}"
    );
    for (args, first) in [
        (
            &["identify", "--help"][..],
            "usage: backlash identify --model shaft|belt|web FILE",
        ),
        (&["excite", "-h"], "usage: backlash excite --model shaft|belt|web"),
    ] {
        let out = backlash(args);
        assert_eq!(out.status.code(), Some(0), "{args:?}");
        assert!(text(&out.stdout).starts_with(first), "{args:?}: {}", text(&out.stdout));
    }
}
