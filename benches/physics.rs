//! Cost of the physics core (issue targets: an event-free step within a few 4×4 matrix–vector
//! products, a step with a switch under 2 µs; the web line's event-free step within 1.5× the
//! belt drive's; with a damper in the compliant member, within 1.1× the step without). Run: `cargo bench --bench physics`.

use backlash_fmu::fmu::adapter;
use backlash_fmu::physics::{
    ContactLaw, ContactMode, Damping, Inputs, PiGains, Plant, PlantParams, PlantState, SpeedErrorBound, Stepper,
    WebSpan, WebSpeedBound, WebTensionBound,
};
use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::{Matrix4, Vector4};
use std::hint::black_box;

const H: f64 = 1e-3;

fn rig() -> Plant {
    Plant::new(PlantParams::paper_rig(0.775e-3)).expect("the paper's rig is valid")
}

/// The rig with a damper of contact damping ratio 0.5: D = 2 ζ sqrt(K J_eff), J_eff = 1/(1/J_m + 1/J_L).
fn damped_rig(law: ContactLaw) -> Plant {
    let p = PlantParams::paper_rig(0.775e-3);
    let j_eff = 1.0 / (1.0 / p.j_m + 1.0 / p.j_l);
    let d = 2.0 * 0.5 * (200.0 * j_eff).sqrt();
    Plant::new(PlantParams {
        damping: Damping { d, law },
        ..p
    })
    .expect("a valid damped rig")
}

fn benches(c: &mut Criterion) {
    let plant = rig();
    let g = plant.half_gap();

    // The floor: a bare 4×4 matrix–vector product.
    let m = Matrix4::from_fn(|i, j| 1.0 / (1.0 + i as f64 + 2.0 * j as f64));
    let v = Vector4::new(0.1, 0.2, 0.3, 0.4);
    c.bench_function("matvec_4x4", |b| b.iter(|| black_box(&m) * black_box(&v)));

    // In contact, pressed well past the gap: no switch within the step.
    let mut stepper = Stepper::new(plant);
    let pressed = PlantState::new(&plant, g + 0.01, 0.0, 0.0, 0.0);
    assert_eq!(pressed.mode, ContactMode::Positive);
    let inputs = Inputs::held(2.0, 0.0);
    c.bench_function("step_1ms_no_switch", |b| {
        b.iter(|| {
            let mut s = black_box(pressed);
            stepper.step(&mut s, &inputs, H, &mut |_| {}).expect("valid step");
            s
        })
    });

    // The same with a damper in the shaft (contact damping ratio 0.5, either law): its
    // surfaces are certified out of reach by the same kernel outputs (docs/model.md §2).
    for (name, law) in [
        ("step_1ms_no_switch_damped_law1", ContactLaw::ElastoBacklash),
        ("step_1ms_no_switch_damped_law2", ContactLaw::ElastoBacklash2),
    ] {
        let damped = damped_rig(law);
        let mut stepper = Stepper::new(damped);
        let pressed = PlantState::new(&damped, g + 0.01, 0.0, 0.0, 0.0);
        assert_eq!(pressed.mode, ContactMode::Positive);
        let mut check = pressed;
        let n = stepper.step(&mut check, &inputs, H, &mut |_| {}).expect("valid step");
        assert_eq!(n, 0, "{name}: no switch in the benchmark step");
        c.bench_function(name, |b| {
            b.iter(|| {
                let mut s = black_box(pressed);
                stepper.step(&mut s, &inputs, H, &mut |_| {}).expect("valid step");
                s
            })
        });
    }

    // Free, closing the gap at 0.1 rad/s from 50 µrad away: one switch half-way.
    let closing = PlantState::new(&plant, g - 5e-5, 0.1, 0.0, 0.0);
    assert_eq!(closing.mode, ContactMode::Free);
    let mut check = closing;
    let n = stepper
        .step(&mut check, &Inputs::held(0.0, 0.0), H, &mut |_| {})
        .expect("valid step");
    assert_eq!(n, 1, "the benchmark state must switch exactly once");
    c.bench_function("step_1ms_one_switch", |b| {
        b.iter(|| {
            let mut s = black_box(closing);
            stepper
                .step(&mut s, &Inputs::held(0.0, 0.0), H, &mut |_| {})
                .expect("valid step");
            s
        })
    });

    // One communication-step update of bound and bound_paper.
    let mut bound = SpeedErrorBound::new(&plant, PiGains { kp: 5.0, ki: 20.0 }).expect("valid gains");
    bound.advance(0.123).expect("valid advance");
    let saved = bound.state();
    c.bench_function("bound_advance_1ms", |b| {
        b.iter(|| {
            bound.restore(&saved).expect("valid state");
            bound.advance(black_box(H)).expect("valid advance");
            bound.bound()
        })
    });
}

/// BacklashBelt's start values, pulling the film line's web span or not.
/// BacklashWeb.fmu's web span: a film line.
fn film_line() -> Option<WebSpan> {
    adapter::default_plant_params("BacklashWeb").web
}

fn belt(web: Option<WebSpan>) -> Plant {
    Plant::new(PlantParams {
        damping: Damping::NONE,
        web,
        ..adapter::default_plant_params("BacklashBelt")
    })
    .expect("valid belt drive")
}

/// The belt drive and the web line side by side: the event-free step of a co-simulation at the
/// belt's default step size (100 µs, one piece: `quiet_step`, the FMU's common case), and one
/// step's update of the web line's two bounds.
fn web_benches(c: &mut Criterion) {
    const H_BELT: f64 = 1e-4;
    for (name, web) in [("belt_quiet_step_100us", None), ("web_quiet_step_100us", film_line())] {
        let plant = belt(web);
        let mut stepper = Stepper::new(plant);
        let pressed = PlantState::new(&plant, (plant.half_gap() + 1e-4) / plant.r_m(), 0.0, 0.0, 0.0).with_tension(5.0);
        let inputs = Inputs::held(0.5, 0.0);
        let mut warm = pressed;
        stepper
            .step(&mut warm, &inputs, H_BELT, &mut |_| {})
            .expect("valid step");
        assert!(
            stepper.quiet_step(&pressed, &inputs, H_BELT).is_some(),
            "{name}: a quiet step"
        );
        c.bench_function(name, |b| {
            b.iter(|| stepper.quiet_step(black_box(&pressed), &inputs, H_BELT))
        });
    }
    let plant = belt(film_line());
    let speed = PiGains { kp: 0.18, ki: 57.6 };
    let tension = PiGains { kp: 0.01, ki: 0.05 };
    let mut speed_bound = WebSpeedBound::new(&plant, speed, tension).expect("valid gains");
    let mut tension_bound = WebTensionBound::new(&plant, speed, tension).expect("valid gains");
    speed_bound.advance(0.0123).expect("valid advance");
    tension_bound.advance(0.0123).expect("valid advance");
    let saved = (speed_bound.state(), tension_bound.state());
    c.bench_function("web_bounds_advance_100us", |b| {
        b.iter(|| {
            speed_bound.restore(&saved.0).expect("valid state");
            speed_bound.advance(black_box(H_BELT)).expect("valid advance");
            tension_bound.restore(&saved.1).expect("valid state");
            tension_bound.advance(black_box(H_BELT)).expect("valid advance");
            tension_bound.bound()
        })
    });
}

criterion_group!(physics, benches, web_benches);
criterion_main!(physics);
