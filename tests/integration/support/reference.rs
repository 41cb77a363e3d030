//! Reference solution of the plant of docs/model.md §1, built on the Taylor integrator in `taylor.rs`
//! and on nothing from the crate but the parameter types (the generic-form constants r_m,
//! r_L, K, g are derived here again from the geometry).
//!
//! State y = [u, v, ω_m, ω_L, θ_m, θ_L]: u and its rate v = r_m ω_m − r_L ω_L are carried
//! as states of their own (v' follows from the two torque balances), so that the switching
//! function u ∓ g keeps full precision even when the speeds are large and nearly cancel in v;
//! modes are indexed 0 = contact −, 1 = free, 2 = contact + (the `contact` output + 1).

use super::taylor::{backlash_modes, component, integrate_poly, poly_mul, Coeffs, Event, Hybrid, Mode, Piece};
use backlash_fmu::physics::{Geometry, Inputs, PlantParams};

pub const U: usize = 0;
pub const V: usize = 1;
pub const W_M: usize = 2;
pub const W_L: usize = 3;
pub const TH_M: usize = 4;
pub const TH_L: usize = 5;
/// Dimension of the reference state.
pub const DIM: usize = 6;

pub const NEGATIVE: usize = 0;
pub const FREE: usize = 1;
pub const POSITIVE: usize = 2;

/// Generic-form constants of docs/model.md §1, from the user's parameters.
#[derive(Clone, Copy, Debug)]
pub struct GenericForm {
    pub j_m: f64,
    pub j_l: f64,
    pub b_m: f64,
    pub b_l: f64,
    pub r_m: f64,
    pub r_l: f64,
    pub k: f64,
    pub g: f64,
}

impl GenericForm {
    /// Ω² = K (r_m²/J_m + r_L²/J_L): the squared frequency of the undamped contact oscillation.
    pub fn contact_omega_sq(&self) -> f64 {
        self.k * (self.r_m * self.r_m / self.j_m + self.r_l * self.r_l / self.j_l)
    }

    /// [θ_m, ω_m, θ_L, ω_L] that a held motor torque `tau_m` keeps in contact without damping:
    /// the static deflection is q* = r_m τ_m / (J_m Ω²); u starts at g + 1.5 q* with an
    /// oscillation smaller than q*, so u − g stays > 0.
    pub fn preloaded_start(&self, tau_m: f64) -> [f64; 4] {
        let w2 = self.contact_omega_sq();
        let q_star = self.r_m * tau_m / (self.j_m * w2);
        let u0 = self.g + 1.5 * q_star;
        [
            (u0 + 0.1 * self.r_l) / self.r_m,
            0.4,
            0.1,
            0.4 * self.r_m / self.r_l + 0.2 * q_star * w2.sqrt() / self.r_l,
        ]
    }

    /// The table of docs/model.md §1: shaft r_m = r_L = 1, K = k, g = Δ; belt r_m = R_1,
    /// r_L = α_1 = R_2 R_g2 / R_g1, K = K_b, g = α_2 Δ with α_2 = R_2 / R_g1.
    pub fn from_params(p: &PlantParams) -> GenericForm {
        let (r_m, r_l, k, g) = match p.geometry {
            Geometry::Shaft { k, delta } => (1.0, 1.0, k, delta),
            Geometry::Belt {
                k_b,
                r_1,
                r_2,
                r_g1,
                r_g2,
                delta,
            } => (r_1, r_2 * r_g2 / r_g1, k_b, delta * r_2 / r_g1),
        };
        GenericForm {
            j_m: p.j_m,
            j_l: p.j_l,
            b_m: p.b_m,
            b_l: p.b_l,
            r_m,
            r_l,
            k,
            g,
        }
    }

    /// dz(u, g) of docs/model.md §1.
    pub fn dead_zone(&self, u: f64) -> f64 {
        if u >= self.g {
            u - self.g
        } else if u <= -self.g {
            u + self.g
        } else {
            0.0
        }
    }

    /// The mode for u moving at du (docs/model.md §4 `contact`: on ±g the mode being entered).
    pub fn mode_for(&self, u: f64, du: f64) -> usize {
        let g = self.g;
        if g == 0.0 {
            return if u > 0.0 || (u == 0.0 && du >= 0.0) {
                POSITIVE
            } else {
                NEGATIVE
            };
        }
        if u > g || (u == g && du > 0.0) {
            POSITIVE
        } else if u < -g || (u == -g && du < 0.0) {
            NEGATIVE
        } else {
            FREE
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefState {
    pub y: [f64; DIM],
    pub mode: usize,
}

impl RefState {
    pub fn contact(&self) -> i32 {
        self.mode as i32 - 1
    }
}

/// A switch at absolute time `t`, modes as `contact` values (−1, 0, +1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefEvent {
    pub t: f64,
    pub from: i32,
    pub to: i32,
}

/// ∫ τ_m ω_m dt, ∫ τ_L ω_L dt, ∫ (b_m ω_m² + b_L ω_L²) dt accumulated along the reference.
#[derive(Clone, Copy, Debug, Default)]
pub struct PowerIntegrals {
    pub work_m: f64,
    pub work_l: f64,
    pub dissipated: f64,
}

/// (A, c) of the drive train in the mode on flank `sigma` (−1, +1) or free, for a state whose
/// first `DIM` entries are [u, v, ω_m, ω_L, θ_m, θ_L] (further entries left to the caller):
/// v' = r_m ω_m' − r_L ω_L' = F(t) − (r_m b_m/J_m) ω_m + (r_L b_L/J_L) ω_L − μ ψ, and in contact
/// ψ = K (u − σ g), J_m ω_m' = … − r_m ψ, J_L ω_L' = … + r_L ψ.
pub fn drive_mode<const N: usize>(f: &GenericForm, sigma: f64, contact: bool) -> ([[f64; N]; N], [f64; N]) {
    let mut a = [[0.0; N]; N];
    let mut c = [0.0; N];
    let mu = f.r_m * f.r_m / f.j_m + f.r_l * f.r_l / f.j_l;
    a[U][V] = 1.0;
    a[V][W_M] = -f.r_m * f.b_m / f.j_m;
    a[V][W_L] = f.r_l * f.b_l / f.j_l;
    a[W_M][W_M] = -f.b_m / f.j_m;
    a[W_L][W_L] = -f.b_l / f.j_l;
    a[TH_M][W_M] = 1.0;
    a[TH_L][W_L] = 1.0;
    if contact {
        a[V][U] = -mu * f.k;
        a[W_M][U] = -f.r_m * f.k / f.j_m;
        a[W_L][U] = f.r_l * f.k / f.j_l;
        c[V] = mu * f.k * sigma * f.g;
        c[W_M] = f.r_m * f.k * sigma * f.g / f.j_m;
        c[W_L] = -f.r_l * f.k * sigma * f.g / f.j_l;
    }
    (a, c)
}

pub struct Reference {
    pub form: GenericForm,
    sys: Hybrid<DIM>,
}

impl Reference {
    pub fn new(params: &PlantParams) -> Reference {
        Self::from_form(GenericForm::from_params(params))
    }

    pub fn from_form(f: GenericForm) -> Reference {
        let mode = |sigma: f64, contact: bool| drive_mode::<DIM>(&f, sigma, contact);
        let g = f.g;
        let modes = if g == 0.0 {
            // No gap: both flanks carry K u, one mode in effect and no switch.
            let (a, c) = mode(0.0, true);
            vec![
                Mode { a, c, guards: vec![] },
                Mode { a, c, guards: vec![] },
                Mode { a, c, guards: vec![] },
            ]
        } else {
            // Indexed NEGATIVE, FREE, POSITIVE.
            backlash_modes(g, U, mode)
        };
        Reference {
            form: f,
            sys: Hybrid::new(modes, 0.25),
        }
    }

    /// State from angles and speeds; u = r_m θ_m − r_L θ_L.
    pub fn state(&self, theta_m: f64, omega_m: f64, theta_l: f64, omega_l: f64) -> RefState {
        let f = &self.form;
        let u = f.r_m * theta_m - f.r_l * theta_l;
        let du = f.r_m * omega_m - f.r_l * omega_l;
        RefState {
            y: [u, du, omega_m, omega_l, theta_m, theta_l],
            mode: f.mode_for(u, du),
        }
    }

    /// Advances over [t0, t0 + h] with τ(t0 + s) = τ + s·dτ; events get absolute times.
    pub fn step(
        &self,
        state: &mut RefState,
        t0: f64,
        inputs: &Inputs,
        h: f64,
        events: &mut Vec<RefEvent>,
        power: Option<&mut PowerIntegrals>,
    ) {
        let f = self.form;
        let inp = *inputs;
        let forcing = move |s: f64, out: &mut Coeffs<DIM>| {
            let (tau_m, tau_l) = (inp.tau_m + inp.dtau_m * s, inp.tau_l + inp.dtau_l * s);
            out[0][W_M] = tau_m / f.j_m;
            out[0][W_L] = tau_l / f.j_l;
            out[0][V] = f.r_m * tau_m / f.j_m - f.r_l * tau_l / f.j_l;
            out[1][W_M] = inp.dtau_m / f.j_m;
            out[1][W_L] = inp.dtau_l / f.j_l;
            out[1][V] = f.r_m * inp.dtau_m / f.j_m - f.r_l * inp.dtau_l / f.j_l;
        };
        let mut raw = Vec::new();
        let mut acc = PowerIntegrals::default();
        let want_power = power.is_some();
        let mut on_piece = |p: Piece<DIM>| {
            if !want_power {
                return;
            }
            let w_m = component(p.coeffs, W_M);
            let w_l = component(p.coeffs, W_L);
            let tau_m = [inp.tau_m + inp.dtau_m * p.start, inp.dtau_m];
            let tau_l = [inp.tau_l + inp.dtau_l * p.start, inp.dtau_l];
            acc.work_m += integrate_poly(&poly_mul(&tau_m, &w_m), p.len);
            acc.work_l += integrate_poly(&poly_mul(&tau_l, &w_l), p.len);
            acc.dissipated += f.b_m * integrate_poly(&poly_mul(&w_m, &w_m), p.len)
                + f.b_l * integrate_poly(&poly_mul(&w_l, &w_l), p.len);
        };
        self.sys
            .advance(&mut state.mode, &mut state.y, h, &forcing, &mut raw, &mut on_piece);
        for Event { offset, from, to } in raw {
            events.push(RefEvent {
                t: t0 + offset,
                from: from as i32 - 1,
                to: to as i32 - 1,
            });
        }
        if let Some(p) = power {
            p.work_m += acc.work_m;
            p.work_l += acc.work_l;
            p.dissipated += acc.dissipated;
        }
    }

    /// ½K dz² + ½J_m ω_m² + ½J_L ω_L² (spring energy: the contact is elastic, docs/model.md §5).
    pub fn stored_energy(&self, u: f64, omega_m: f64, omega_l: f64) -> f64 {
        let f = &self.form;
        let d = f.dead_zone(u);
        0.5 * f.k * d * d + 0.5 * f.j_m * omega_m * omega_m + 0.5 * f.j_l * omega_l * omega_l
    }
}
