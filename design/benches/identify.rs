//! Identification's cost (issue 36 target: a 10 s run at 1 kHz fitted in ≤ 5 s on one core):
//! the paper's rig under `backlash excite`'s schedule, simulated by the physics crate's exact
//! stepper with measurement noise, fitted with the default fit (Delta, k, J_L, b_L, u0) from the
//! rig's defaults. Prints `@ identify_10s_1khz <median CPU s> <model evaluations> <repeats>
//! <min CPU s> <max CPU s>`. Run: `cargo bench -p backlash-design --bench identify`.

use backlash_design::identify::{build, data::Columns, excite, identify};
use backlash_design::request::Vocabulary;
use backlash_design::Form;
use backlash_physics::{Inputs, Plant, PlantParams, PlantState, Stepper};

/// CPU time of this process [s].
fn cpu_seconds() -> f64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes one timespec into the valid, exclusively borrowed `ts`.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + 1e-9 * ts.tv_nsec as f64
}

fn main() {
    let truth = PlantParams::paper_rig(1.5e-3);
    let h = 1e-3;
    let schedule = excite::schedule(&truth, 10.0, h, None).expect("the rig's schedule");
    let plant = Plant::new(truth).expect("valid rig");
    let u0 = -0.5e-3;
    let mut state = PlantState::new(&plant, u0, 0.0, 0.0, 0.0);
    let mut stepper = Stepper::new(plant);
    let (mut tm, mut tl) = (Vec::new(), Vec::new());
    let mut seed: u64 = 1;
    let mut noise = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        2e-5 * ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5)
    };
    for &(_, tau) in &schedule {
        tm.push(state.theta_m - u0 + noise());
        tl.push(state.theta_l + noise());
        stepper
            .step(&mut state, &Inputs::held(tau, 0.0), h, &mut |_| {})
            .expect("a step");
    }
    let columns: Columns = vec![
        ("time".into(), schedule.iter().map(|s| s.0).collect()),
        ("tau_m".into(), schedule.iter().map(|s| s.1).collect()),
        ("theta_m".into(), tm),
        ("theta_L".into(), tl),
    ];
    let request = build(Form::Shaft, &[], None, Vocabulary::Arguments).expect("defaults");
    let repeats = 5;
    let mut times = Vec::new();
    let mut evaluations = 0;
    for _ in 0..repeats {
        let start = cpu_seconds();
        let answer = identify(&request, &columns).expect("the fit");
        times.push(cpu_seconds() - start);
        evaluations = answer.evaluations;
    }
    times.sort_by(f64::total_cmp);
    println!(
        "@ identify_10s_1khz {:.4} {evaluations} {repeats} {:.4} {:.4}",
        times[repeats / 2],
        times[0],
        times[repeats - 1]
    );
}
