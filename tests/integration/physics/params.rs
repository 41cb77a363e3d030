//! Bad parameters, step sizes, inputs, states and gains give an error that names the culprit
//! (a clear error, never a crash or a silent NaN). Expected names are the
//! docs/model.md §4 variable names.

use crate::support::rigs;
use backlash_fmu::physics::bound::BoundError;
use backlash_fmu::physics::{
    BoundState, Geometry, Inputs, ParamError, PiGains, Plant, PlantParams, PlantState, SpeedErrorBound, StepError,
    Stepper,
};

/// (name, error) for a parameter that must be > 0 (`strict`) or ≥ 0, set to `value`.
fn expected(name: &'static str, value: f64, strict: bool) -> Option<ParamError> {
    if !value.is_finite() {
        Some(ParamError::NotFinite { name, value })
    } else if strict && value <= 0.0 {
        Some(ParamError::NotPositive { name, value })
    } else if !strict && value < 0.0 {
        Some(ParamError::Negative { name, value })
    } else if value != 0.0 && !(1e-100..=1e100).contains(&value.abs()) {
        Some(ParamError::OutOfScale { name, value })
    } else {
        None
    }
}

fn same(a: &ParamError, b: &ParamError) -> bool {
    let parts = |e: &ParamError| match *e {
        ParamError::NotFinite { name, value } => (0, name, value),
        ParamError::NotPositive { name, value } => (1, name, value),
        ParamError::Negative { name, value } => (2, name, value),
        ParamError::OutOfScale { name, value } => (3, name, value),
        ParamError::DerivedOutOfScale { name, value } => (4, name, value),
    };
    let (ka, na, va) = parts(a);
    let (kb, nb, vb) = parts(b);
    ka == kb && na == nb && (va == vb || (va.is_nan() && vb.is_nan()))
}

type Setter = fn(&mut PlantParams, f64);

#[test]
fn every_invalid_parameter_is_named() {
    let shaft_fields: [(&'static str, bool, Setter); 6] = [
        ("J_m", true, |p, v| p.j_m = v),
        ("J_L", true, |p, v| p.j_l = v),
        ("b_m", false, |p, v| p.b_m = v),
        ("b_L", false, |p, v| p.b_l = v),
        ("k", true, |p, v| {
            if let Geometry::Shaft { k, .. } = &mut p.geometry {
                *k = v
            }
        }),
        ("Delta", false, |p, v| {
            if let Geometry::Shaft { delta, .. } = &mut p.geometry {
                *delta = v
            }
        }),
    ];
    let belt_fields: [(&'static str, bool, Setter); 6] = [
        ("K_b", true, |p, v| {
            if let Geometry::Belt { k_b, .. } = &mut p.geometry {
                *k_b = v
            }
        }),
        ("R_1", true, |p, v| {
            if let Geometry::Belt { r_1, .. } = &mut p.geometry {
                *r_1 = v
            }
        }),
        ("R_2", true, |p, v| {
            if let Geometry::Belt { r_2, .. } = &mut p.geometry {
                *r_2 = v
            }
        }),
        ("R_g1", true, |p, v| {
            if let Geometry::Belt { r_g1, .. } = &mut p.geometry {
                *r_g1 = v
            }
        }),
        ("R_g2", true, |p, v| {
            if let Geometry::Belt { r_g2, .. } = &mut p.geometry {
                *r_g2 = v
            }
        }),
        ("Delta", false, |p, v| {
            if let Geometry::Belt { delta, .. } = &mut p.geometry {
                *delta = v
            }
        }),
    ];
    let values = [
        0.0,
        -0.0,
        -1.0,
        -1e-300,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        1e-300,
        1e101,
        2.5,
    ];
    let mut checked = 0;
    for (base, fields) in [
        (PlantParams::paper_rig(1e-3), &shaft_fields[..]),
        (rigs::belt(1e-4), &shaft_fields[..4]),
        (rigs::belt(1e-4), &belt_fields[..]),
    ] {
        for &(name, strict, set) in fields {
            for value in values {
                let mut p = base;
                set(&mut p, value);
                let got = Plant::new(p);
                match (expected(name, value, strict), got) {
                    (None, Ok(_)) => {}
                    (Some(want), Err(e)) => {
                        assert!(same(&want, &e), "{name} = {value}: got {e:?}, want {want:?}");
                        assert!(e.to_string().contains(name), "message {e} does not name {name}");
                    }
                    (want, got) => panic!("{name} = {value}: got {got:?}, want {want:?}"),
                }
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 16 * values.len());
}

#[test]
fn derived_constants_that_overflow_are_rejected() {
    // Every input finite and in scale, K r_m²/J_m = 1e100·(1e60)²/1 = 1e220 is not: the plant
    // must refuse rather than step with rates that products take out of f64.
    let mut p = rigs::belt(1e-4);
    p.j_m = 1.0;
    if let Geometry::Belt { k_b, r_1, .. } = &mut p.geometry {
        *k_b = 1e100;
        *r_1 = 1e60;
    }
    match Plant::new(p) {
        Err(ParamError::DerivedOutOfScale { name, value }) => {
            assert_eq!(name, "K*r_m^2/J_m");
            // Bit for bit: `Plant::new`'s K·r_m·r_m/J_m with the same operands in the same
            // order (J_m = 1: the division is exact).
            assert_eq!(value, 1e100 * 1e60 * 1e60);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn bad_steps_inputs_and_states_are_refused_and_leave_the_state_alone() {
    let plant = Plant::new(PlantParams::paper_rig(1.78e-3)).unwrap();
    let mut stepper = Stepper::new(plant);
    let start = PlantState::new(&plant, 0.01, 0.5, 0.0, -0.2);
    let ok = Inputs::held(1.0, 0.0);
    for h in [0.0, -0.0, -1e-3, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut st = start;
        let mut calls = 0;
        let r = stepper.step(&mut st, &ok, h, &mut |_| calls += 1);
        assert!(matches!(r, Err(StepError::BadStepSize { .. })), "h = {h}: {r:?}");
        assert_eq!((st, calls), (start, 0), "h = {h}: state changed or switches reported");
    }
    let cases: [(&str, fn(&mut Inputs, f64)); 4] = [
        ("tau_m", |i, v| i.tau_m = v),
        ("tau_L", |i, v| i.tau_l = v),
        ("dtau_m", |i, v| i.dtau_m = v),
        ("dtau_L", |i, v| i.dtau_l = v),
    ];
    for (label, set) in cases {
        for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut inputs = ok;
            set(&mut inputs, v);
            let mut st = start;
            let r = stepper.step(&mut st, &inputs, 0.01, &mut |_| {});
            match r {
                Err(StepError::NonFiniteInput { name, value }) => {
                    // The value inputs carry their docs/model.md §4 names; a slope must at least name its input.
                    let base = label.trim_start_matches('d');
                    assert!(name.contains(base), "{label} = {v}: error names {name}");
                    assert!(value.is_nan() == v.is_nan() && (v.is_nan() || value == v));
                }
                other => panic!("{label} = {v}: {other:?}"),
            }
            assert_eq!(st, start);
        }
    }
    for bad in [
        PlantState {
            omega_m: f64::NAN,
            ..start
        },
        PlantState {
            theta_l: f64::INFINITY,
            ..start
        },
        PlantState { u: f64::NAN, ..start },
    ] {
        let mut st = bad;
        let r = stepper.step(&mut st, &ok, 0.01, &mut |_| {});
        assert!(matches!(r, Err(StepError::NonFiniteState)), "{bad:?}: {r:?}");
    }
}

#[test]
fn bad_gains_advances_and_saved_states_are_refused() {
    let plant = Plant::new(PlantParams::paper_rig(1.78e-3)).unwrap();
    for (kp, ki, name) in [
        (f64::NAN, 1.0, "Kp"),
        (f64::INFINITY, 1.0, "Kp"),
        (1.0, f64::NAN, "Ki"),
        (1.0, f64::NEG_INFINITY, "Ki"),
    ] {
        match SpeedErrorBound::new(&plant, PiGains { kp, ki }) {
            Err(BoundError::NonFiniteGain { name: n, .. }) => assert_eq!(n, name),
            other => panic!("Kp = {kp}, Ki = {ki}: {:?}", other.map(|b| b.state())),
        }
    }
    let mut b = SpeedErrorBound::new(&plant, PiGains { kp: 5.0, ki: 20.0 }).unwrap();
    b.advance(0.3).unwrap();
    let saved = b.state();
    for h in [-1e-3, f64::NAN, f64::INFINITY] {
        assert!(
            matches!(b.advance(h), Err(BoundError::BadAdvance { .. })),
            "advance({h})"
        );
        assert_eq!(b.state(), saved, "a refused advance changed the state");
    }
    for bad in [
        BoundState { elapsed: -1.0, ..saved },
        BoundState {
            elapsed: f64::NAN,
            ..saved
        },
        BoundState {
            l1: f64::INFINITY,
            ..saved
        },
        BoundState {
            response: [f64::NAN; 5],
            ..saved
        },
        BoundState {
            integral: [0.0, f64::INFINITY, 0.0, 0.0, 0.0],
            ..saved
        },
    ] {
        assert!(matches!(b.restore(&bad), Err(BoundError::BadState)), "{bad:?}");
        assert_eq!(b.state(), saved);
    }
    b.restore(&saved).unwrap();
    assert_eq!(b.state(), saved);
}
