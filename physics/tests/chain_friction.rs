//! Coulomb friction with stiction on the chain's bodies (physics/src/chain; the law of
//! docs/model.md §10): closed forms of a body that stops, breaks away and reverses, and a two-stage
//! gearbox with friction on every body against a hybrid integrator written here from the law.

mod common;

use backlash_physics::chain::{
    Body, BodyMode, BodySwitch, Chain, ChainEvent, ChainParams, ChainState, ChainStepper, Coulomb, Motion, Stage,
    TwoStageStepper,
};
use backlash_physics::{ContactMode, Damping, Inputs};

const EPS: f64 = f64::EPSILON;

/// A motor of inertia `j` with friction (τ_c, peak) and no viscous friction, coupled to a load
/// through a gap far wider than its travel here (10 rad): the motor moves alone.
fn lone_motor(j: f64, tau_c: f64, peak: f64) -> Chain<1> {
    Chain::new(ChainParams {
        motor: Body {
            j,
            b: 0.0,
            friction: Coulomb { tau_c, peak },
        },
        driven: [Body::new(1.0, 0.0)],
        stages: [Stage {
            a: 1.0,
            c: 1.0,
            k: 100.0,
            g: 10.0,
            damper: Damping::NONE,
        }],
        web: None,
    })
    .unwrap()
}

/// The lone motor of `chain` at θ = 0 sliding at `omega0`, the load at rest.
fn sliding(chain: &Chain<1>, omega0: f64) -> ChainState<1> {
    ChainState::new(
        chain,
        Motion {
            theta: 0.0,
            omega: omega0,
        },
        [Motion::default()],
    )
}

/// Steps of `h` from `state` over `steps` steps under `inputs(t)`, collecting the body switches
/// with their times; returns the states after each step.
fn run(
    chain: Chain<1>,
    mut state: ChainState<1>,
    h: f64,
    steps: usize,
    inputs: &dyn Fn(f64) -> Inputs,
    switches: &mut Vec<(f64, BodySwitch)>,
) -> Vec<ChainState<1>> {
    let mut stepper = ChainStepper::<1, 10, 8>::new(chain);
    let mut states = Vec::new();
    for k in 0..steps {
        let t = k as f64 * h;
        stepper
            .step(&mut state, &inputs(t), h, &mut |e| match e {
                ChainEvent::Body(e) => switches.push((t + e.offset, e)),
                ChainEvent::Stage(e) => panic!("the gap is never closed here: {e:?}"),
            })
            .unwrap();
        states.push(state);
    }
    states
}

/// A body sliding at ω_0 under no torque decelerates at τ_c/J: it stops at t* = J ω_0/τ_c after
/// θ* = J ω_0²/(2 τ_c), and stays stuck (nothing pulls it: |τ_h| = 0 ≤ peak τ_c), its speed 0
/// exactly.
#[test]
fn a_sliding_body_stops_where_the_closed_form_says_and_sticks() {
    let (j, tau_c, omega0) = (0.5, 2.0, 3.0);
    let chain = lone_motor(j, tau_c, 1.5);
    let start = sliding(&chain, omega0);
    assert_eq!(start.mode.body(0), BodyMode::Forward);
    let mut switches = Vec::new();
    let h = 1e-3;
    let states = run(chain, start, h, 2000, &|_| Inputs::held(0.0, 0.0), &mut switches);
    let (t_stop, theta_stop) = (j * omega0 / tau_c, j * omega0 * omega0 / (2.0 * tau_c));
    assert_eq!(switches.len(), 1, "{switches:?}");
    let (t, e) = switches[0];
    assert_eq!((e.body, e.from, e.to), (0, BodyMode::Forward, BodyMode::Stuck));
    // Located to round-off of the step's time grid: some tens of ulps of t* (t = k h + offset).
    assert!((t - t_stop).abs() <= 64.0 * EPS * t_stop, "{t} vs {t_stop}");
    let end = states.last().unwrap();
    assert_eq!(end.motor.omega, 0.0);
    assert_eq!(end.mode.body(0), BodyMode::Stuck);
    // The angle sums its pieces: a few ulps per piece over the run.
    assert!(
        (end.motor.theta - theta_stop).abs() <= 1e-13 * theta_stop,
        "{} vs {theta_stop}",
        end.motor.theta
    );
    assert_eq!(end.driven[0].omega, 0.0);
}

/// At rest under a torque ramping at r, a body breaks away when r t reaches peak·τ_c, t_b =
/// peak τ_c/r, then slides with J ω′ = r t − τ_c: ω(t) = (r (t² − t_b²)/2 − τ_c (t − t_b))/J.
/// Before, it does not move at all.
#[test]
fn a_stuck_body_breaks_away_at_peak_times_tau_c() {
    let (j, tau_c, peak, r) = (0.5, 2.0, 1.5, 2.0);
    let chain = lone_motor(j, tau_c, peak);
    let start = ChainState::new(&chain, Motion::default(), [Motion::default()]);
    assert_eq!(start.mode.body(0), BodyMode::Stuck);
    let h = 1e-3;
    // First-order hold of τ_m = r t.
    let ramp = |t: f64| Inputs {
        dtau_m: r,
        ..Inputs::held(r * t, 0.0)
    };
    let mut switches = Vec::new();
    let states = run(chain, start, h, 2500, &ramp, &mut switches);
    let t_b = peak * tau_c / r;
    assert_eq!(switches.len(), 1, "{switches:?}");
    let (t, e) = switches[0];
    assert_eq!((e.from, e.to), (BodyMode::Stuck, BodyMode::Forward));
    assert!((t - t_b).abs() <= 64.0 * EPS * t_b, "{t} vs {t_b}");
    for (k, s) in states.iter().enumerate() {
        let t = (k + 1) as f64 * h;
        if t < t_b {
            assert_eq!(
                (s.motor.theta, s.motor.omega),
                (0.0, 0.0),
                "at rest before t_b, t = {t}"
            );
        }
    }
    let t_end = 2500.0 * h;
    let omega = (0.5 * r * (t_end * t_end - t_b * t_b) - tau_c * (t_end - t_b)) / j;
    let end = states.last().unwrap();
    assert!(
        (end.motor.omega - omega).abs() <= 1e-13 * omega,
        "{} vs {omega}",
        end.motor.omega
    );
}

/// Sliding forward against a torque beyond the breakaway: at rest it cannot stick (|τ_h| > peak
/// τ_c), so it reverses there at once, t* = J ω_0/(τ + τ_c), and slides back at (τ − τ_c)/J.
#[test]
fn a_body_pushed_past_its_breakaway_reverses_without_sticking() {
    let (j, tau_c, omega0, tau) = (0.5, 2.0, 3.0, -5.0);
    let chain = lone_motor(j, tau_c, 1.5);
    let start = sliding(&chain, omega0);
    let mut switches = Vec::new();
    let h = 1e-3;
    let states = run(chain, start, h, 1000, &|_| Inputs::held(tau, 0.0), &mut switches);
    let t_stop = j * omega0 / (-tau + tau_c);
    assert_eq!(switches.len(), 1, "{switches:?}");
    let (t, e) = switches[0];
    assert_eq!((e.from, e.to), (BodyMode::Forward, BodyMode::Backward));
    assert!((t - t_stop).abs() <= 64.0 * EPS * t_stop, "{t} vs {t_stop}");
    let t_end = 1.0;
    let omega = (tau + tau_c) / j * (t_end - t_stop);
    let end = states.last().unwrap();
    assert!(
        (end.motor.omega - omega).abs() <= 1e-13 * omega.abs(),
        "{} vs {omega}",
        end.motor.omega
    );
}

/// Without friction on any body the chain has no friction modes: every body stays `Forward`
/// whatever its speed, and no body switch is ever reported.
#[test]
fn a_body_without_friction_has_no_friction_modes() {
    let chain = lone_motor(0.5, 0.0, 1.0);
    let start = ChainState::new(
        &chain,
        Motion {
            theta: 0.0,
            omega: -1.0,
        },
        [Motion::default()],
    );
    assert_eq!(start.mode.body(0), BodyMode::Forward);
    let mut switches = Vec::new();
    run(
        chain,
        start,
        1e-3,
        100,
        &|t| Inputs::held((10.0 * t).sin(), 0.0),
        &mut switches,
    );
    assert!(switches.is_empty());
}

/// A bad peak is refused: below 1 the breakaway torque would be below the sliding one.
#[test]
fn a_peak_below_one_is_refused() {
    let mut params = *lone_motor(0.5, 2.0, 1.5).params();
    params.motor.friction.peak = 0.9;
    let why = Chain::new(params).unwrap_err().to_string();
    assert!(why.contains("peak") && why.contains("0.9"), "{why}");
    params.motor.friction = Coulomb { tau_c: -1.0, peak: 1.0 };
    assert!(Chain::new(params).is_err());
}

// ---- a two-stage gearbox with friction on every body, against a hybrid integrator ----

/// The gearbox: docs/model.md §10's two stages with a light intermediate shaft, friction on
/// every body (the intermediate's and the load's stick while the motor's torque is small).
fn gearbox() -> ChainParams<2> {
    let stage = |c: f64, k: f64, g: f64| Stage {
        a: 1.0,
        c,
        k,
        g,
        damper: Damping::NONE,
    };
    let body = |j: f64, b: f64, tau_c: f64, peak: f64| Body {
        j,
        b,
        friction: Coulomb { tau_c, peak },
    };
    ChainParams {
        motor: body(2.28, 0.05, 0.3, 1.2),
        driven: [body(0.05, 0.05, 0.2, 1.5), body(2.55, 0.05, 1.0, 1.3)],
        stages: [stage(2.0, 200.0, 1e-3), stage(3.0, 400.0, 2e-3)],
        web: None,
    }
}

/// The reference: the same law written as a state machine over z = [θ_m, ω_m, θ_i, ω_i, θ_L,
/// ω_L], RK4 inside each combination of modes and bisection on the step length for the first
/// margin that goes negative (a stage's u past its threshold, a sliding body's speed through 0,
/// a stuck body's |τ_h| past peak·τ_c), then the law at that point.
struct Reference {
    p: ChainParams<2>,
}

impl Reference {
    fn u(&self, z: &[f64; 6]) -> [f64; 2] {
        let s = &self.p.stages;
        [z[0] - s[0].c * z[2], z[2] - s[1].c * z[4]]
    }

    fn psi(&self, z: &[f64; 6], stages: &[ContactMode; 2]) -> [f64; 2] {
        let u = self.u(z);
        std::array::from_fn(|i| {
            let s = &self.p.stages[i];
            match stages[i] {
                ContactMode::Positive => s.k * (u[i] - s.g),
                ContactMode::Negative => s.k * (u[i] + s.g),
                _ => 0.0,
            }
        })
    }

    fn body(&self, j: usize) -> &Body {
        if j == 0 {
            &self.p.motor
        } else {
            &self.p.driven[j - 1]
        }
    }

    /// τ_h of each body: τ_m on the motor, the members' n ψ_{j−1} − ψ_j.
    fn holding(&self, z: &[f64; 6], stages: &[ContactMode; 2], tau: f64) -> [f64; 3] {
        let psi = self.psi(z, stages);
        let n = [self.p.stages[0].c, self.p.stages[1].c];
        [tau - psi[0], n[0] * psi[0] - psi[1], n[1] * psi[1]]
    }

    fn rates(&self, z: &[f64; 6], stages: &[ContactMode; 2], bodies: &[BodyMode; 3], tau: f64) -> [f64; 6] {
        let held = self.holding(z, stages, tau);
        let mut r = [0.0; 6];
        for j in 0..3 {
            let b = self.body(j);
            let (w, friction) = match bodies[j] {
                BodyMode::Stuck => (0.0, None),
                m => (z[2 * j + 1], Some(m.friction_sign() * b.friction.tau_c)),
            };
            r[2 * j] = w;
            r[2 * j + 1] = match friction {
                None => 0.0,
                Some(f) => (held[j] - b.b * w + f) / b.j,
            };
        }
        r
    }

    fn rk4(
        &self,
        z: &[f64; 6],
        st: &[ContactMode; 2],
        bo: &[BodyMode; 3],
        tau: &dyn Fn(f64) -> f64,
        t: f64,
        dt: f64,
    ) -> [f64; 6] {
        let add = |k: &[f64; 6], s: f64| std::array::from_fn::<f64, 6, _>(|i| z[i] + s * k[i]);
        let k1 = self.rates(z, st, bo, tau(t));
        let k2 = self.rates(&add(&k1, dt / 2.0), st, bo, tau(t + dt / 2.0));
        let k3 = self.rates(&add(&k2, dt / 2.0), st, bo, tau(t + dt / 2.0));
        let k4 = self.rates(&add(&k3, dt), st, bo, tau(t + dt));
        std::array::from_fn(|i| z[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
    }

    /// How far inside its mode each stage and body is (< 0: it has left).
    fn margins(&self, z: &[f64; 6], st: &[ContactMode; 2], bo: &[BodyMode; 3], tau: f64) -> [f64; 5] {
        let u = self.u(z);
        let held = self.holding(z, st, tau);
        let mut m = [0.0; 5];
        for i in 0..2 {
            let g = self.p.stages[i].g;
            m[i] = match st[i] {
                ContactMode::Positive => u[i] - g,
                ContactMode::Negative => -u[i] - g,
                _ => (g - u[i]).min(g + u[i]),
            };
        }
        for j in 0..3 {
            let breakaway = self.body(j).friction.breakaway();
            m[2 + j] = match bo[j] {
                BodyMode::Forward => z[2 * j + 1],
                BodyMode::Backward => -z[2 * j + 1],
                BodyMode::Stuck => breakaway - held[j].abs(),
            };
        }
        m
    }

    fn at_rest(held: f64, breakaway: f64) -> BodyMode {
        if held > breakaway {
            BodyMode::Forward
        } else if held < -breakaway {
            BodyMode::Backward
        } else {
            BodyMode::Stuck
        }
    }

    /// From rest over `steps` intervals of h under the motor torque τ(t), `substeps` RK4 steps
    /// each: [θ_m, ω_m, θ_i, ω_i, θ_L, ω_L] after each interval, and the body switches' times.
    fn run(&self, tau: &dyn Fn(f64) -> f64, h: f64, steps: usize, substeps: usize) -> (Vec<[f64; 6]>, Vec<f64>) {
        let mut z = [0.0; 6];
        let mut st = [ContactMode::Free; 2];
        let mut bo = [BodyMode::Stuck; 3];
        let (mut states, mut switches) = (Vec::new(), Vec::new());
        for k in 0..steps {
            let t0 = k as f64 * h;
            // The law at rest with the step's input (as the stepper applies it at a step's start).
            let held = self.holding(&z, &st, tau(t0));
            for j in 0..3 {
                if z[2 * j + 1] == 0.0 {
                    bo[j] = Self::at_rest(held[j], self.body(j).friction.breakaway());
                }
            }
            let mut done = 0.0;
            for target in common::substep_ends(h, substeps) {
                while done < target {
                    let (next, cut) = common::rk4_to_first_exit(
                        target - done,
                        |len| self.rk4(&z, &st, &bo, tau, t0 + done, len),
                        |z, len| {
                            let at = t0 + done + len;
                            self.margins(z, &st, &bo, tau(at)).iter().all(|&m| m >= 0.0)
                        },
                    );
                    z = next;
                    let Some(hi) = cut else {
                        done = target;
                        continue;
                    };
                    done += hi;
                    let at = t0 + done;
                    let margins = self.margins(&z, &st, &bo, tau(at));
                    let u = self.u(&z);
                    for i in 0..2 {
                        if margins[i] < 0.0 {
                            st[i] = match st[i] {
                                ContactMode::Free if u[i] > 0.0 => ContactMode::Positive,
                                ContactMode::Free => ContactMode::Negative,
                                _ => ContactMode::Free,
                            };
                        }
                    }
                    let held = self.holding(&z, &st, tau(at));
                    for j in 0..3 {
                        if margins[2 + j] < 0.0 {
                            let breakaway = self.body(j).friction.breakaway();
                            bo[j] = match bo[j] {
                                BodyMode::Stuck => Self::at_rest(held[j], breakaway),
                                _ => {
                                    z[2 * j + 1] = 0.0;
                                    Self::at_rest(held[j], breakaway)
                                }
                            };
                            switches.push(at);
                        }
                    }
                }
            }
            states.push(z);
        }
        (states, switches)
    }
}

/// The two-stage gearbox from rest under a slow reversing motor torque that breaks the bodies
/// away and lets them stick again: the chain against the reference at two step sizes (RK4: the
/// finer run is ~16x closer to the exact solution than the two are to each other), within that
/// difference plus 64 ulps of each quantity's scale, and the same number of body switches.
#[test]
fn a_gearbox_with_friction_on_every_body_agrees_with_a_hybrid_integrator() {
    let params = gearbox();
    let chain = Chain::new(params).unwrap();
    let tau = |t: f64| 4.0 * (2.0 * std::f64::consts::PI * 0.8 * t).sin();
    let (h, steps) = (1e-3, 2500);
    // Both take the sine sampled at the step starts and held to first order over each step.
    let held = |t: f64| {
        let k = (t / h).floor();
        let (a, b) = (tau(k * h), tau((k + 1.0) * h));
        a + (b - a) * (t - k * h) / h
    };
    let reference = Reference { p: params };
    let (coarse, coarse_switches) = reference.run(&held, h, steps, 20);
    let (fine, fine_switches) = reference.run(&held, h, steps, 40);

    let mut stepper = TwoStageStepper::new(chain);
    let mut state = ChainState::new(&chain, Motion::default(), [Motion::default(); 2]);
    let mut body_switches = Vec::new();
    let mut entered = Vec::new();
    let mut states = Vec::new();
    for k in 0..steps {
        let t = k as f64 * h;
        let (a, b) = (tau(t), tau(t + h));
        let inputs = Inputs {
            dtau_m: (b - a) / h,
            ..Inputs::held(a, 0.0)
        };
        stepper
            .step(&mut state, &inputs, h, &mut |e| {
                if let ChainEvent::Body(e) = e {
                    body_switches.push(t + e.offset);
                    entered.push(e.to);
                }
            })
            .unwrap();
        states.push([
            state.motor.theta,
            state.motor.omega,
            state.driven[0].theta,
            state.driven[0].omega,
            state.driven[1].theta,
            state.driven[1].omega,
        ]);
    }
    let mut scale = [0.0f64; 6];
    let mut estimate = [0.0f64; 6];
    let mut deviation = [0.0f64; 6];
    for k in 0..steps {
        for i in 0..6 {
            scale[i] = scale[i].max(fine[k][i].abs());
            estimate[i] = estimate[i].max((coarse[k][i] - fine[k][i]).abs());
            deviation[i] = deviation[i].max((states[k][i] - fine[k][i]).abs());
        }
    }
    eprintln!(
        "body switches: chain {}, reference {} / {}; entered {:?}",
        body_switches.len(),
        fine_switches.len(),
        coarse_switches.len(),
        entered.iter().fold([0; 3], |mut n, m| {
            n[match m {
                BodyMode::Forward => 0,
                BodyMode::Backward => 1,
                BodyMode::Stuck => 2,
            }] += 1;
            n
        })
    );
    eprintln!("scale {scale:?}\nestimate {estimate:?}\ndeviation {deviation:?}");
    assert!(
        entered.contains(&BodyMode::Stuck)
            && entered.contains(&BodyMode::Forward)
            && entered.contains(&BodyMode::Backward)
    );
    assert_eq!(body_switches.len(), fine_switches.len());
    for i in 0..6 {
        assert!(deviation[i] <= estimate[i] + 64.0 * EPS * scale[i], "component {i}");
    }
}

/// The order of switches at one instant (docs/model.md §12), in runs built so that the events
/// fall on t* = 0.5 s exactly (binary fractions throughout, no viscous friction). In a gap too
/// wide to close, the motor (J = 1, τ_c = 2, from 1 rad/s) and the load (J = 1, τ_c = 1, from
/// 0.5 rad/s) stop together: located in one search, they are reported at one instant, the
/// motor's first. With g = 0.5 and the motor without friction at 1 rad/s from θ_m = 0.125, the
/// gap closes at t* too (u = 0.125 + t/2 + t²/2 reaches 0.5 there, at u′ = 1) as the load
/// stops: each surface is located at its own round-off floor (the contact where u passes g by
/// 8 ulps of |u| + g), so the two are located a few ulps apart and reported in that order, both
/// within 64 ulps of t*.
#[test]
fn simultaneous_switches_are_reported_in_a_defined_order() {
    let chain = |tau_m: f64, g: f64| {
        Chain::new(ChainParams {
            motor: Body {
                j: 1.0,
                b: 0.0,
                friction: Coulomb {
                    tau_c: tau_m,
                    peak: 1.0,
                },
            },
            driven: [Body {
                j: 1.0,
                b: 0.0,
                friction: Coulomb { tau_c: 1.0, peak: 1.0 },
            }],
            stages: [Stage {
                a: 1.0,
                c: 1.0,
                k: 100.0,
                g,
                damper: Damping::NONE,
            }],
            web: None,
        })
        .unwrap()
    };
    // The switches near t*, in the order reported: (which, offset).
    let near_t_star = |tau_m: f64, g: f64, theta_m: f64| {
        let chain = chain(tau_m, g);
        let motor = Motion {
            theta: theta_m,
            omega: 1.0,
        };
        let load = Motion { theta: 0.0, omega: 0.5 };
        let mut state = ChainState::new(&chain, motor, [load]);
        let mut stepper = ChainStepper::<1, 10, 8>::new(chain);
        let mut events = Vec::new();
        stepper
            .step(&mut state, &Inputs::held(0.0, 0.0), 0.75, &mut |e| events.push(e))
            .unwrap();
        let near: Vec<(String, f64)> = events
            .iter()
            .map(|e| match e {
                ChainEvent::Stage(s) => ("contact".to_string(), s.offset),
                ChainEvent::Body(b) => (BODY[b.body].to_string(), b.offset),
            })
            .filter(|(_, t)| (t - 0.5).abs() <= 64.0 * EPS * 0.5)
            .collect();
        near
    };
    const BODY: [&str; 2] = ["motor", "load"];
    let stops = near_t_star(2.0, 10.0, 0.0);
    let names: Vec<&str> = stops.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["motor", "load"], "{stops:?}");
    assert_eq!(stops[0].1, stops[1].1, "one instant: {stops:?}");
    let closing = near_t_star(0.0, 0.5, 0.125);
    let mut names: Vec<&str> = closing.iter().map(|(n, _)| n.as_str()).collect();
    assert!(
        closing.windows(2).all(|w| w[0].1 <= w[1].1),
        "in time order: {closing:?}"
    );
    names.sort();
    assert_eq!(names, ["contact", "load"], "both located near t*: {closing:?}");
}
