//! The affine dynamics of each contact mode as one augmented linear system (docs/model.md §1–§2).
//!
//! Augmented state y (`AUG` entries):
//! `[u, v, ω_L, δθ_m, δθ_L, τ_m, τ_L, 1, τ̇_m, τ̇_L]` — the transmission coordinate u and its
//! rate v = u' = r_m ω_m − r_L ω_L, the load speed, the angle increments since the last reset,
//! the inputs with their slopes and a constant 1 that carries the ∓K g offset of a contact
//! flank. Inside one mode y' = M y exactly, with inputs that vary linearly (first-order hold) or
//! not at all (zero-order hold), so the solution over a step is e^{M s} y.
//!
//! A load that pulls a web span (docs/model.md §8) adds three entries, `WEB_AUG` in all:
//! `[…, T, w, ẇ]`, the span tension and the span's forcing by the upstream web,
//! w = (v_ref T_in − EA v_in)/L_w, with its slope. The first `AUG` entries are the same.
//!
//! v rather than ω_m is a state because the gap dynamics live in u and v: with ω_m the rate
//! u' = r_m ω_m − r_L ω_L would cancel catastrophically whenever the drive turns fast compared
//! with its relative motion, and u would lose eps·r|ω|·s per piece. ω_m = (v + r_L ω_L)/r_m.

use super::mode::ContactMode;
use super::params::Plant;
use nalgebra::{SMatrix, SVector};

pub const AUG: usize = 10;
/// The augmented dimension with a web span.
pub const WEB_AUG: usize = 13;
pub type AugMatrix<const N: usize = AUG> = SMatrix<f64, N, N>;
pub type AugVector<const N: usize = AUG> = SVector<f64, N>;

pub const U: usize = 0;
pub const V: usize = 1;
pub const OMEGA_L: usize = 2;
pub const DTHETA_M: usize = 3;
pub const DTHETA_L: usize = 4;
pub const TAU_M: usize = 5;
pub const TAU_L: usize = 6;
pub const ONE: usize = 7;
pub const DTAU_M: usize = 8;
pub const DTAU_L: usize = 9;
pub const TENSION: usize = 10;
pub const SPAN: usize = 11;
pub const DSPAN: usize = 12;

/// M for `mode`: ψ = K (u ∓ g) + D u′ on a flank (2 K (u ∓ g) where law 1 caps the damper), 0
/// when free or slack. N is `AUG`, or `WEB_AUG` for a plant
/// with a web span.
pub fn mode_matrix<const N: usize>(plant: &Plant, mode: ContactMode) -> AugMatrix<N> {
    assert!(
        N == if plant.web().is_some() { WEB_AUG } else { AUG },
        "augmented dimension {N} does not fit the plant"
    );
    let p = plant.params();
    let (r_m, r_l, k, g) = (plant.r_m(), plant.r_l(), plant.stiffness(), plant.half_gap());
    // ψ = ks·u + kd·v + kc·1: ks (u ∓ g) + kd u′ on a flank (kd = D, or 2K and no damper where
    // law 1 caps it), 0 when free or slack.
    let (ks, kd) = mode.force_slopes(k, plant.damping());
    let kc = if mode.side() > 0.0 {
        -ks * g
    } else if mode.side() < 0.0 {
        ks * g
    } else {
        0.0
    };
    let (jm, jl) = (p.j_m, p.j_l);
    // Compliance seen by u: κ = r_m²/J_m + r_L²/J_L.
    let kappa = r_m * r_m / jm + r_l * r_l / jl;
    let mut m = AugMatrix::<N>::zeros();
    m[(U, V)] = 1.0;
    // v' = r_m ω_m' − r_L ω_L' with J_m ω_m' = τ_m − b_m ω_m − r_m ψ, J_L ω_L' = τ_L − b_L ω_L + r_L ψ
    // and r_m ω_m = v + r_L ω_L.
    m[(V, TAU_M)] = r_m / jm;
    m[(V, TAU_L)] = -r_l / jl;
    m[(V, V)] = -p.b_m / jm;
    m[(V, OMEGA_L)] = r_l * (p.b_l / jl - p.b_m / jm);
    m[(V, U)] = -kappa * ks;
    m[(V, ONE)] = -kappa * kc;
    m[(OMEGA_L, OMEGA_L)] = -p.b_l / jl;
    m[(OMEGA_L, TAU_L)] = 1.0 / jl;
    m[(OMEGA_L, U)] = r_l * ks / jl;
    m[(OMEGA_L, ONE)] = r_l * kc / jl;
    if kd != 0.0 {
        m[(V, V)] -= kappa * kd;
        m[(OMEGA_L, V)] = r_l * kd / jl;
    }
    m[(DTHETA_M, V)] = 1.0 / r_m;
    m[(DTHETA_M, OMEGA_L)] = r_l / r_m;
    m[(DTHETA_L, OMEGA_L)] = 1.0;
    m[(TAU_M, DTAU_M)] = 1.0;
    m[(TAU_L, DTAU_L)] = 1.0;
    if let Some(w) = plant.web() {
        // J_L ω_L' gains −R_w T, so v' = … − r_L ω_L' gains + r_L R_w T / J_L;
        // L_w T' = EA R_w ω_L − v_ref T + L_w w.
        m[(OMEGA_L, TENSION)] = -w.r_w / jl;
        m[(V, TENSION)] = r_l * w.r_w / jl;
        m[(TENSION, OMEGA_L)] = w.ea * w.r_w / w.l_w;
        m[(TENSION, TENSION)] = -w.v_ref / w.l_w;
        m[(TENSION, SPAN)] = 1.0;
        m[(SPAN, DSPAN)] = 1.0;
    }
    m
}

/// The fastest rate of the plant [1/s]: the contact natural frequency (of the capped contact,
/// stiffness 2K, with law 1 and a damper) or a damping rate (the member's damper's D κ among
/// them); with a
/// web span, the frequency of both springs together, sqrt(ω₀² + EA R_w²/(L_w J_L)), or the
/// span's relaxation rate v_ref/L_w.
/// Steps are cut into pieces of at most `PIECE_RATE / rate` so that Taylor expansions over a
/// piece converge fast and the remainder bounds of `roots` stay tight.
pub fn fastest_rate(plant: &Plant) -> f64 {
    let p = plant.params();
    let mut omega0 = plant.contact_frequency();
    let mut rate = omega0.max(p.b_m / p.j_m).max(p.b_l / p.j_l);
    if plant.damping() > 0.0 {
        let kappa = plant.r_m() * plant.r_m() / p.j_m + plant.r_l() * plant.r_l() / p.j_l;
        if plant.contact_law() == super::params::ContactLaw::ElastoBacklash {
            omega0 *= std::f64::consts::SQRT_2;
        }
        rate = rate.max(omega0).max(plant.damping() * kappa);
    }
    match plant.web() {
        None => rate,
        Some(w) => {
            let web_sq = w.ea * w.r_w * w.r_w / (w.l_w * p.j_l);
            rate.max((omega0 * omega0 + web_sq).sqrt()).max(w.v_ref / w.l_w)
        }
    }
}

/// Length of a piece times the fastest rate.
pub const PIECE_RATE: f64 = 0.5;
