//! Reference solution of the web line of docs/model.md §8: the drive train of §1 whose load
//! roller (radius R_w) pulls one web span, on the Taylor integrator of `taylor.rs` and on
//! nothing from the crate but the parameter types.
//!
//! State y = [u, v, ω_m, ω_L, θ_m, θ_L, T] as in `reference.rs` (u and v = u' carried as states
//! of their own) plus the span tension:
//! J_L ω_L' = τ_L − b_L ω_L + r_L ψ − R_w T, L_w T' = EA (R_w ω_L − v_in) + v_ref (T_in − T).

use super::reference::{GenericForm, RefEvent, TH_L, TH_M, U, V, W_L, W_M};
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
    r_w: f64,
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
            let mut a = [[0.0; DIM]; DIM];
            let mut c = [0.0; DIM];
            let mu = f.r_m * f.r_m / f.j_m + f.r_l * f.r_l / f.j_l;
            a[U][V] = 1.0;
            a[V][W_M] = -f.r_m * f.b_m / f.j_m;
            a[V][W_L] = f.r_l * f.b_l / f.j_l;
            a[W_M][W_M] = -f.b_m / f.j_m;
            a[W_L][W_L] = -f.b_l / f.j_l;
            a[TH_M][W_M] = 1.0;
            a[TH_L][W_L] = 1.0;
            // The web's pull −R_w T on the load, and through ω_L' on v' = r_m ω_m' − r_L ω_L'.
            a[W_L][TENSION] = -r_w / f.j_l;
            a[V][TENSION] = f.r_l * r_w / f.j_l;
            a[TENSION][W_L] = ea * r_w / l_w;
            a[TENSION][TENSION] = -v_ref / l_w;
            if contact {
                a[V][U] = -mu * f.k;
                a[W_M][U] = -f.r_m * f.k / f.j_m;
                a[W_L][U] = f.r_l * f.k / f.j_l;
                c[V] = mu * f.k * sigma * f.g;
                c[W_M] = f.r_m * f.k * sigma * f.g / f.j_m;
                c[W_L] = -f.r_l * f.k * sigma * f.g / f.j_l;
            }
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
            r_w,
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
