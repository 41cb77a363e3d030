//! Reference solution of the web line of docs/model.md §8: the drive train of §1 whose load
//! roller (radius R_w) pulls one web span, on the Taylor integrator of `taylor.rs` and on
//! nothing from the crate but the parameter types.
//!
//! State y = [u, v, ω_m, ω_L, θ_m, θ_L, T] as in `reference.rs` (u and v = u' carried as states
//! of their own) plus the span tension:
//! J_L ω_L' = τ_L − b_L ω_L + r_L ψ − R_w T, L_w T' = EA (R_w ω_L − v_in) + v_ref (T_in − T).

use super::closed_loop::sine_taylor;
use super::reference::{drive_mode, GenericForm, RefEvent, TH_L, TH_M, U, V, W_L, W_M};
use super::taylor::{backlash_modes, Coeffs, Event, Hybrid, Mode};
use backlash_fmu::physics::PlantParams;

/// The tension in the reference state.
pub const TENSION: usize = 6;
pub const DIM: usize = 7;

/// The upstream web over a step: v_in(t0 + s) = v_in + s·dv_in, T_in likewise; with the torques.
#[derive(Clone, Copy, Debug, Default)]
pub struct WebInputs {
    pub tau_m: f64,
    pub tau_l: f64,
    pub dtau_m: f64,
    pub dtau_l: f64,
    pub v_in: f64,
    pub t_in: f64,
    pub dv_in: f64,
    pub dt_in: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WebState {
    pub y: [f64; DIM],
    pub mode: usize,
}

pub struct WebReference {
    pub form: GenericForm,
    l_w: f64,
    ea: f64,
    v_ref: f64,
    sys: Hybrid<DIM>,
}

impl WebReference {
    /// Panics unless `params` has a web span.
    pub fn new(params: &PlantParams) -> WebReference {
        let f = GenericForm::from_params(params);
        let web = params.web.expect("a web line");
        let (r_w, l_w, ea, v_ref) = (web.r_w, web.l_w, web.ea, web.v_ref);
        let mode = |sigma: f64, contact: bool| {
            let (mut a, c) = drive_mode::<DIM>(&f, sigma, contact);
            // The web's pull −R_w T on the load, and through ω_L' on v' = r_m ω_m' − r_L ω_L'.
            a[W_L][TENSION] = -r_w / f.j_l;
            a[V][TENSION] = f.r_l * r_w / f.j_l;
            a[TENSION][W_L] = ea * r_w / l_w;
            a[TENSION][TENSION] = -v_ref / l_w;
            (a, c)
        };
        let modes = if f.g == 0.0 {
            let (a, c) = mode(0.0, true);
            (0..3).map(|_| Mode { a, c, guards: vec![] }).collect()
        } else {
            backlash_modes(f.g, U, mode)
        };
        WebReference {
            form: f,
            l_w,
            ea,
            v_ref,
            sys: Hybrid::new(modes, 0.25),
        }
    }

    /// State from angles, speeds and tension.
    pub fn state(&self, z: [f64; 4], tension: f64) -> WebState {
        let f = &self.form;
        let u = f.r_m * z[0] - f.r_l * z[2];
        let du = f.r_m * z[1] - f.r_l * z[3];
        WebState {
            y: [u, du, z[1], z[3], z[0], z[2], tension],
            mode: f.mode_for(u, du),
        }
    }

    /// [θ_m, ω_m, θ_L, ω_L, u, T] of a state.
    pub fn sample(s: &WebState) -> [f64; 6] {
        [s.y[TH_M], s.y[W_M], s.y[TH_L], s.y[W_L], s.y[U], s.y[TENSION]]
    }

    /// Advances over [t0, t0 + h]; events get absolute times.
    pub fn step(&self, state: &mut WebState, t0: f64, inputs: &WebInputs, h: f64, events: &mut Vec<RefEvent>) {
        let f = self.form;
        let i = *inputs;
        let (ea, v_ref, l_w) = (self.ea, self.v_ref, self.l_w);
        let forcing = move |s: f64, out: &mut Coeffs<DIM>| {
            let (tau_m, tau_l) = (i.tau_m + i.dtau_m * s, i.tau_l + i.dtau_l * s);
            let (v_in, t_in) = (i.v_in + i.dv_in * s, i.t_in + i.dt_in * s);
            out[0][W_M] = tau_m / f.j_m;
            out[0][W_L] = tau_l / f.j_l;
            out[0][V] = f.r_m * tau_m / f.j_m - f.r_l * tau_l / f.j_l;
            out[0][TENSION] = (v_ref * t_in - ea * v_in) / l_w;
            out[1][W_M] = i.dtau_m / f.j_m;
            out[1][W_L] = i.dtau_l / f.j_l;
            out[1][V] = f.r_m * i.dtau_m / f.j_m - f.r_l * i.dtau_l / f.j_l;
            out[1][TENSION] = (v_ref * i.dt_in - ea * i.dv_in) / l_w;
        };
        let mut raw = Vec::new();
        self.sys
            .advance(&mut state.mode, &mut state.y, h, &forcing, &mut raw, &mut |_| {});
        for Event { offset, from, to } in raw {
            events.push(RefEvent {
                t: t0 + offset,
                from: from as i32 - 1,
                to: to as i32 - 1,
            });
        }
    }
}

/// The web line under the continuous-time speed PI and the tension PI that trims its reference
/// (docs/model.md §8), with or without the gap: y = [u, ω_m, ω_L, θ_m, θ_L, x_c, T, x_T],
/// e = ω_ref(t) + Kp_T (T_ref − T) + Ki_T x_T − ω_m, τ_m = Kp e + Ki x_c, x_c' = e,
/// x_T' = T_ref − T, ω_ref(t) = amp sin(w t); τ_L = 0, v_in, T_in and T_ref constant.
pub struct WebPiLoop {
    sys: Hybrid<8>,
    pub mode: usize,
    pub y: [f64; 8],
    pub t: f64,
    /// Kp/J_m and Kp_T T_ref: how ω_ref enters; T_ref.
    kp_over_jm: f64,
    trim: f64,
    t_ref: f64,
    /// The span's constant forcing (v_ref T_in − EA v_in)/L_w.
    span: f64,
    amp: f64,
    w: f64,
}

/// Entries of [`WebPiLoop::y`].
pub const PI_OMEGA_L: usize = 2;
pub const PI_TENSION: usize = 6;

/// The gains and references of a [`WebPiLoop`].
#[derive(Clone, Copy, Debug)]
pub struct WebLoopSetup {
    pub kp: f64,
    pub ki: f64,
    pub kp_t: f64,
    pub ki_t: f64,
    pub t_ref: f64,
    pub v_in: f64,
    pub t_in: f64,
    /// Amplitude [rad/s] and angular frequency [rad/s] of the speed reference.
    pub amp: f64,
    pub w: f64,
}

impl WebPiLoop {
    pub fn new(params: &PlantParams, s: WebLoopSetup, with_gap: bool) -> WebPiLoop {
        let f = GenericForm::from_params(params);
        let web = params.web.expect("a web line");
        let g = if with_gap { f.g } else { 0.0 };
        const U: usize = 0;
        const WM: usize = 1;
        const WL: usize = 2;
        const XC: usize = 5;
        const T: usize = PI_TENSION;
        const XT: usize = 7;
        let build = |sigma: f64, contact: bool| {
            let mut a = [[0.0; 8]; 8];
            let mut c = [0.0; 8];
            a[U][WM] = f.r_m;
            a[U][WL] = -f.r_l;
            a[WM][WM] = -(f.b_m + s.kp) / f.j_m;
            a[WM][XC] = s.ki / f.j_m;
            a[WM][T] = -s.kp * s.kp_t / f.j_m;
            a[WM][XT] = s.kp * s.ki_t / f.j_m;
            a[WL][WL] = -f.b_l / f.j_l;
            a[WL][T] = -web.r_w / f.j_l;
            a[3][WM] = 1.0;
            a[4][WL] = 1.0;
            a[XC][WM] = -1.0;
            a[XC][T] = -s.kp_t;
            a[XC][XT] = s.ki_t;
            a[T][WL] = web.ea * web.r_w / web.l_w;
            a[T][T] = -web.v_ref / web.l_w;
            a[XT][T] = -1.0;
            if contact {
                a[WM][U] = -f.r_m * f.k / f.j_m;
                a[WL][U] = f.r_l * f.k / f.j_l;
                c[WM] = f.r_m * f.k * sigma * g / f.j_m;
                c[WL] = -f.r_l * f.k * sigma * g / f.j_l;
            }
            (a, c)
        };
        let modes = if g == 0.0 {
            let (a, c) = build(0.0, true);
            vec![Mode { a, c, guards: vec![] }]
        } else {
            backlash_modes(g, U, build)
        };
        // Start with u = 0: inside the gap, or the single linear mode; T at T_in.
        let mut y = [0.0; 8];
        y[T] = s.t_in;
        WebPiLoop {
            sys: Hybrid::new(modes, (0.25f64).min(0.5 / s.w)),
            mode: if g == 0.0 { 0 } else { 1 },
            y,
            t: 0.0,
            kp_over_jm: s.kp / f.j_m,
            trim: s.kp_t * s.t_ref,
            t_ref: s.t_ref,
            span: (web.v_ref * s.t_in - web.ea * s.v_in) / web.l_w,
            amp: s.amp,
            w: s.w,
        }
    }

    /// Advances by `dt`; returns the number of contact switches.
    pub fn advance(&mut self, dt: f64) -> usize {
        let (t0, k, trim, t_ref) = (self.t, self.kp_over_jm, self.trim, self.t_ref);
        let (span, amp, w) = (self.span, self.amp, self.w);
        // ω_ref's Taylor coefficients; the constant parts (trim, span, T_ref) in the zeroth.
        let forcing = move |s: f64, out: &mut Coeffs<8>| {
            for (n, (row, r)) in out.iter_mut().zip(sine_taylor(amp, w, t0 + s)).enumerate() {
                let constant = if n == 0 { trim } else { 0.0 };
                row[1] = k * (r + constant);
                row[5] = r + constant;
                if n == 0 {
                    row[PI_TENSION] = span;
                    row[7] = t_ref;
                }
            }
        };
        let mut events = Vec::new();
        self.sys
            .advance(&mut self.mode, &mut self.y, dt, &forcing, &mut events, &mut |_| {});
        self.t += dt;
        events.len()
    }
}
