//! Runs `Stepper` and the reference side by side over a schedule of communication steps and
//! measures how far they differ: states relative to the amplitude of each quantity over the
//! run, and switch events (count, direction, time).

use super::reference::{RefEvent, RefState, Reference, TH_L, TH_M, U, W_L, W_M};
use backlash_fmu::physics::{Inputs, Plant, PlantParams, PlantState, Stepper};

#[derive(Debug)]
pub struct Comparison {
    pub steps: usize,
    /// max |stepper − reference| / scale, for angles, speeds and u.
    pub err_theta: f64,
    pub err_omega: f64,
    pub err_u: f64,
    pub worst_step: usize,
    pub scale_theta: f64,
    pub scale_omega: f64,
    pub scale_u: f64,
    pub stepper_events: Vec<RefEvent>,
    pub ref_events: Vec<RefEvent>,
    /// First communication point where the modes differ: (step, stepper, reference).
    pub mode_mismatch: Option<(usize, i32, i32)>,
    /// A breach of the `on_switch` contract (order, offsets, chaining, count returned).
    pub contract_violation: Option<String>,
    pub final_stepper: PlantState,
    pub final_ref: RefState,
    /// How the reference itself responds to a relative perturbation of the initial motor
    /// speed: (state deviation, event-time deviation in s) per unit relative perturbation.
    /// A computation exact to round-off may differ from the reference by about this times the
    /// round-off it injects; bouncing contact makes it large.
    pub conditioning: (f64, f64),
}

/// Relative round-off a run may inject, counted as an equivalent perturbation of the initial
/// state (a few hundred ulps); multiplied by the measured conditioning it bounds the global
/// difference an exact-to-round-off stepper can show. Local accuracy is checked separately
/// and without this allowance (`compare_steps`).
const ROUNDOFF: f64 = 1e-13;
/// The relative perturbation used to measure the conditioning.
const PROBE: f64 = 1e-10;

impl Comparison {
    pub fn max_state_error(&self) -> f64 {
        self.err_theta.max(self.err_omega).max(self.err_u)
    }

    /// Largest |t_stepper − t_ref| over matched events, or an explanation of the mismatch.
    pub fn event_time_error(&self) -> Result<f64, String> {
        if self.stepper_events.len() != self.ref_events.len() {
            let first_diff = self
                .stepper_events
                .iter()
                .zip(&self.ref_events)
                .position(|(a, b)| a.from != b.from || a.to != b.to || (a.t - b.t).abs() > 1e-6);
            return Err(format!(
                "stepper reports {} switches, reference {}; first disagreement at index {:?}: stepper {:?}, reference {:?}",
                self.stepper_events.len(),
                self.ref_events.len(),
                first_diff,
                first_diff.and_then(|i| self.stepper_events.get(i)),
                first_diff.and_then(|i| self.ref_events.get(i)),
            ));
        }
        let mut worst: f64 = 0.0;
        for (i, (a, b)) in self.stepper_events.iter().zip(&self.ref_events).enumerate() {
            if a.from != b.from || a.to != b.to {
                return Err(format!("switch {i}: stepper {a:?}, reference {b:?}"));
            }
            worst = worst.max((a.t - b.t).abs());
        }
        Ok(worst)
    }

    /// Panics with the measured numbers unless states agree to `tol` (relative) and the
    /// events agree in number and direction, with times within `tol_time` seconds.
    pub fn assert_agrees(&self, tol: f64, tol_time: f64, label: &str) {
        let tol = tol.max(self.conditioning.0 * ROUNDOFF);
        let tol_time = tol_time.max(self.conditioning.1 * ROUNDOFF);
        eprintln!(
            "{label}: conditioning {:.2e} (state), {:.2e} s (event times): tolerances {tol:.1e}, {tol_time:.1e} s",
            self.conditioning.0, self.conditioning.1
        );
        let dt = self.event_time_error();
        eprintln!(
            "{label}: {} steps, {} switches (reference {}), rel. error θ {:.2e} ω {:.2e} u {:.2e} (scales {:.3e} {:.3e} {:.3e}), worst step {}, event time error {:?}",
            self.steps,
            self.stepper_events.len(),
            self.ref_events.len(),
            self.err_theta,
            self.err_omega,
            self.err_u,
            self.scale_theta,
            self.scale_omega,
            self.scale_u,
            self.worst_step,
            dt
        );
        let dt = dt.unwrap_or_else(|e| panic!("{label}: {e}"));
        assert!(
            dt <= tol_time,
            "{label}: switch times differ by {dt:e} s > {tol_time:e} s"
        );
        assert!(
            self.max_state_error() <= tol,
            "{label}: state differs from the reference by {:e} (relative) > {tol:e}; worst at step {}; final states: stepper {:?}, reference {:?}",
            self.max_state_error(),
            self.worst_step,
            self.final_stepper,
            self.final_ref
        );
        if let Some(v) = &self.contract_violation {
            panic!("{label}: {v}");
        }
        if let Some((step, s, r)) = self.mode_mismatch {
            panic!("{label}: at communication point {step} the stepper's contact is {s}, the reference's {r}");
        }
    }
}

/// Errors of samples [θ_m, ω_m, θ_L, ω_L, u] relative to the amplitude of each kind of
/// quantity over a run: angles to max |θ|, speeds to max |ω|, u to max(|u|, g).
#[derive(Clone, Copy, Debug)]
pub struct RelativeErrors {
    pub theta: f64,
    pub omega: f64,
    pub u: f64,
    pub worst_index: usize,
    pub scale: [f64; 3],
}

impl RelativeErrors {
    /// `span` are the samples the amplitudes are taken from (usually the wanted trajectory
    /// including its initial state).
    pub fn measure(got: &[[f64; 5]], want: &[[f64; 5]], span: &[[f64; 5]], g: f64) -> RelativeErrors {
        let amax = |idx: &[usize]| {
            span.iter()
                .flat_map(|w| idx.iter().map(move |&k| w[k].abs()))
                .fold(f64::MIN_POSITIVE, f64::max)
        };
        let scale = [amax(&[0, 2]), amax(&[1, 3]), amax(&[4]).max(g)];
        let mut e = RelativeErrors {
            theta: 0.0,
            omega: 0.0,
            u: 0.0,
            worst_index: 0,
            scale,
        };
        let mut worst = 0.0;
        for (i, (g, w)) in got.iter().zip(want).enumerate() {
            let et = (g[0] - w[0]).abs().max((g[2] - w[2]).abs()) / scale[0];
            let eo = (g[1] - w[1]).abs().max((g[3] - w[3]).abs()) / scale[1];
            let eu = (g[4] - w[4]).abs() / scale[2];
            e.theta = e.theta.max(et);
            e.omega = e.omega.max(eo);
            e.u = e.u.max(eu);
            let m = et.max(eo).max(eu);
            if m > worst || !m.is_finite() {
                worst = m;
                e.worst_index = i;
            }
        }
        e
    }

    pub fn max(&self) -> f64 {
        self.theta.max(self.omega).max(self.u)
    }
}

/// Runs both from angles/speeds `init` = [θ_m, ω_m, θ_L, ω_L] through `schedule`.
pub fn compare_run(params: &PlantParams, init: [f64; 4], schedule: &[(Inputs, f64)]) -> Comparison {
    run(params, init, schedule, false)
}

/// As [`compare_run`], but the reference restarts from the stepper's state at every step:
/// measures the error made within each step (local error), free of the growth of earlier
/// differences along the trajectory.
pub fn compare_steps(params: &PlantParams, init: [f64; 4], schedule: &[(Inputs, f64)]) -> Comparison {
    run(params, init, schedule, true)
}

fn run(params: &PlantParams, init: [f64; 4], schedule: &[(Inputs, f64)], restart: bool) -> Comparison {
    let plant = Plant::new(*params).expect("valid parameters");
    let mut stepper = Stepper::new(plant);
    let reference = Reference::new(params);
    let mut st = PlantState::new(&plant, init[0], init[1], init[2], init[3]);
    let mut rs = reference.state(init[0], init[1], init[2], init[3]);
    let mut stepper_events = Vec::new();
    let mut ref_events = Vec::new();
    let mut got = Vec::with_capacity(schedule.len() + 1);
    let mut want = Vec::with_capacity(schedule.len() + 1);
    let mut mode_mismatch = None;
    let mut contract_violation = None;
    let gap = reference.form.g;
    let mut t = 0.0;
    for (i, (inputs, h)) in schedule.iter().enumerate() {
        let t0 = t;
        if restart {
            let f = &reference.form;
            let v = f.r_m * st.omega_m - f.r_l * st.omega_l;
            let mode = (st.mode.as_i32() + 1) as usize;
            rs = RefState {
                y: [st.u, v, st.omega_m, st.omega_l, st.theta_m, st.theta_l],
                mode,
            };
        }
        let before = stepper_events.len();
        let mode_before = st.mode.as_i32();
        let mut offsets = Vec::new();
        let returned = stepper
            .step(&mut st, inputs, *h, &mut |e| {
                offsets.push(e.offset);
                stepper_events.push(RefEvent {
                    t: t0 + e.offset,
                    from: e.from.as_i32(),
                    to: e.to.as_i32(),
                })
            })
            .unwrap_or_else(|e| panic!("step {i} (t = {t0}, h = {h}) failed: {e}"));
        // The callback contract of `Stepper::step`: one call per switch, in time order,
        // offsets inside the step, each switch leaving the mode the previous one entered.
        let emitted = &stepper_events[before..];
        if contract_violation.is_none() {
            let mut prev_to = mode_before;
            let mut prev_offset = 0.0;
            for (e, &off) in emitted.iter().zip(&offsets) {
                if !(off >= prev_offset && off <= *h) || (gap > 0.0 && e.from != prev_to) || e.from == e.to {
                    contract_violation = Some(format!("step {i} (h = {h}): events {emitted:?}, offsets {offsets:?}"));
                }
                prev_to = e.to;
                prev_offset = off;
            }
            if returned != emitted.len() {
                contract_violation = Some(format!("step {i}: returned {returned}, reported {}", emitted.len()));
            }
            if gap > 0.0 && st.mode.as_i32() != prev_to {
                contract_violation = Some(format!("step {i}: ends in {:?} after events {emitted:?}", st.mode));
            }
        }
        reference.step(&mut rs, t0, inputs, *h, &mut ref_events, None);
        t += h;
        got.push([st.theta_m, st.omega_m, st.theta_l, st.omega_l, st.u]);
        want.push([rs.y[TH_M], rs.y[W_M], rs.y[TH_L], rs.y[W_L], rs.y[U]]);
        if gap > 0.0 && mode_mismatch.is_none() && st.mode.as_i32() != rs.contact() {
            mode_mismatch = Some((i, st.mode.as_i32(), rs.contact()));
        }
    }
    let mut all_want = vec![[
        init[0],
        init[1],
        init[2],
        init[3],
        reference.state(init[0], init[1], init[2], init[3]).y[U],
    ]];
    all_want.extend_from_slice(&want);
    let e = RelativeErrors::measure(&got, &want, &all_want, gap);
    let conditioning = if restart {
        (0.0, 0.0)
    } else {
        // The same schedule on the reference from a perturbed start.
        let bump = PROBE * e.scale[1];
        let mut ps = reference.state(init[0], init[1] + bump, init[2], init[3]);
        let mut p_events = Vec::new();
        let mut perturbed = Vec::with_capacity(schedule.len());
        let mut t = 0.0;
        for (inputs, h) in schedule {
            reference.step(&mut ps, t, inputs, *h, &mut p_events, None);
            t += h;
            perturbed.push([ps.y[TH_M], ps.y[W_M], ps.y[TH_L], ps.y[W_L], ps.y[U]]);
        }
        let d = RelativeErrors::measure(&perturbed, &want, &all_want, gap);
        let dt = if p_events.len() == ref_events.len() {
            p_events
                .iter()
                .zip(&ref_events)
                .map(|(a, b)| (a.t - b.t).abs())
                .fold(0.0, f64::max)
        } else {
            f64::INFINITY
        };
        (d.theta.max(d.omega).max(d.u) / PROBE, dt / PROBE)
    };
    Comparison {
        conditioning,
        steps: schedule.len(),
        err_theta: e.theta,
        err_omega: e.omega,
        err_u: e.u,
        worst_step: e.worst_index,
        scale_theta: e.scale[0],
        scale_omega: e.scale[1],
        scale_u: e.scale[2],
        stepper_events,
        ref_events,
        mode_mismatch,
        contract_violation,
        final_stepper: st,
        final_ref: rs,
    }
}

/// Square wave ±amp with the given period, sampled at each step start (zero-order hold).
pub fn square_wave_schedule(amp: f64, period: f64, h: f64, steps: usize, tau_l: f64) -> Vec<(Inputs, f64)> {
    (0..steps)
        .map(|i| {
            let t = i as f64 * h;
            let phase = (t / period).fract();
            let tau = if phase < 0.5 { amp } else { -amp };
            (Inputs::held(tau, tau_l), h)
        })
        .collect()
}

/// Sinusoid amp·sin(2π t/period), sampled per step; `foh` adds the slope to the next sample.
pub fn sine_schedule(amp: f64, period: f64, h: f64, steps: usize, tau_l: f64, foh: bool) -> Vec<(Inputs, f64)> {
    let w = 2.0 * std::f64::consts::PI / period;
    (0..steps)
        .map(|i| {
            let t0 = i as f64 * h;
            let a = amp * (w * t0).sin();
            let b = amp * (w * (t0 + h)).sin();
            let slope = if foh { (b - a) / h } else { 0.0 };
            (
                Inputs {
                    tau_m: a,
                    tau_l,
                    dtau_m: slope,
                    dtau_l: 0.0,
                    span: 0.0,
                    dspan: 0.0,
                },
                h,
            )
        })
        .collect()
}
