//! The affine dynamics of each chain mode as one augmented linear system (docs/model.md §2,
//! written over S stages).
//!
//! Augmented state y (`3S + 7` entries): `[u_0..u_S, v_0..v_S, ω_S, δθ_0..=δθ_S, τ_m, τ_L, 1,
//! τ̇_m, τ̇_L]`: each stage's coordinate and its rate v_i = u_i′, the last body's speed, the
//! angle increments since the piece start, the inputs with their slopes and a constant 1 for
//! the flanks' ∓K g. For S = 1 this is docs/model.md §2's vector, entry for entry. The other
//! speeds follow from v and ω_S as ω_i = (v_i + c_i ω_{i+1})/a_i: with the v_i as states the
//! gaps never see the cancellation of a_i ω_i − c_i ω_{i+1} when the drive turns fast.
//!
//! A web span on the last body (docs/model.md §8) adds `[T, w, ẇ]`, `3S + 10` entries in all:
//! the span's tension, its forcing by the upstream web and that forcing's slope (for S = 1, §2's
//! vector with a web span, entry for entry).

use super::params::Chain;
use super::state::{BodyMode, ChainMode};
use nalgebra::{SMatrix, SVector};

/// Where each quantity sits in the augmented vector of a chain of S stages.
pub struct Layout<const S: usize>;

impl<const S: usize> Layout<S> {
    /// The augmented dimension, 3S + 7.
    pub const DIM: usize = 3 * S + 7;
    /// The augmented dimension with a web span, 3S + 10.
    pub const WEB_DIM: usize = 3 * S + 10;
    /// The span's tension T, its forcing w and w's slope (with a web span only).
    pub const TENSION: usize = 3 * S + 7;
    pub const SPAN: usize = 3 * S + 8;
    pub const DSPAN: usize = 3 * S + 9;
    /// The last body's speed ω_S.
    pub const OMEGA_LAST: usize = 2 * S;
    pub const TAU_M: usize = 3 * S + 2;
    pub const TAU_L: usize = 3 * S + 3;
    pub const ONE: usize = 3 * S + 4;
    pub const DTAU_M: usize = 3 * S + 5;
    pub const DTAU_L: usize = 3 * S + 6;

    /// u_i.
    pub const fn u(i: usize) -> usize {
        i
    }
    /// v_i = u_i′.
    pub const fn v(i: usize) -> usize {
        S + i
    }
    /// δθ_j, body j's angle increment since the piece start (j ≤ S).
    pub const fn dtheta(j: usize) -> usize {
        2 * S + 1 + j
    }
}

/// M of `mode` (y′ = M y): bodies J_j ω_j′ = −b_j ω_j + c_{j−1} ψ_{j−1} − a_j ψ_j (+ τ_m on
/// body 0, + τ_L on body S) with ψ_i = K_i (u_i ∓ g_i) + D_i v_i on a flank, 2 K_i (u_i ∓ g_i)
/// capped and 0 free or slack (docs/model.md §1, docs/model.md §10); with a web span the last
/// body also carries −R_w T and L_w T′ = EA R_w ω_S − v_ref T + L_w w (§8); a body with Coulomb
/// friction sliding carries ∓τ_c, and stuck does not accelerate (ω_j′ = 0). N must be 3S + 7,
/// or 3S + 10 with a web span.
pub fn mode_matrix<const S: usize, const N: usize>(chain: &Chain<S>, mode: &ChainMode<S>) -> SMatrix<f64, N, N> {
    let rows = Rows::<S, N>::new(chain, mode);
    let speed = &rows.speed;
    let accel = |j: usize| rows.acceleration(j);
    let mut m = SMatrix::<f64, N, N>::zeros();
    for i in 0..S {
        let s = chain.stage(i);
        m[(Layout::<S>::u(i), Layout::<S>::v(i))] = 1.0;
        let v_rate = accel(i) * s.a - accel(i + 1) * s.c;
        m.set_row(Layout::<S>::v(i), &v_rate.transpose());
    }
    m.set_row(Layout::<S>::OMEGA_LAST, &accel(S).transpose());
    for (j, row) in speed.iter().enumerate() {
        m.set_row(Layout::<S>::dtheta(j), &row.transpose());
    }
    m[(Layout::<S>::TAU_M, Layout::<S>::DTAU_M)] = 1.0;
    m[(Layout::<S>::TAU_L, Layout::<S>::DTAU_L)] = 1.0;
    if let Some(w) = chain.web() {
        m[(Layout::<S>::TENSION, Layout::<S>::OMEGA_LAST)] = w.ea * w.r_w / w.l_w;
        m[(Layout::<S>::TENSION, Layout::<S>::TENSION)] = -w.v_ref / w.l_w;
        m[(Layout::<S>::TENSION, Layout::<S>::SPAN)] = 1.0;
        m[(Layout::<S>::SPAN, Layout::<S>::DSPAN)] = 1.0;
    }
    m
}

/// The unit row e_k.
fn unit<const N: usize>(k: usize) -> SVector<f64, N> {
    let mut e = SVector::<f64, N>::zeros();
    e[k] = 1.0;
    e
}

/// Rows over the augmented state in one mode: each body's speed, and the torques on it.
pub struct Rows<'a, const S: usize, const N: usize> {
    chain: &'a Chain<S>,
    mode: &'a ChainMode<S>,
    /// ω_j as a row over y: ω_S, then ω_i = (v_i + c_i ω_{i+1})/a_i downwards. (Built per
    /// mode, at construction: the Vec is not on the stepping path.)
    pub speed: Vec<SVector<f64, N>>,
}

impl<'a, const S: usize, const N: usize> Rows<'a, S, N> {
    pub fn new(chain: &'a Chain<S>, mode: &'a ChainMode<S>) -> Self {
        let mut speed = vec![SVector::<f64, N>::zeros(); S + 1];
        speed[S] = unit(Layout::<S>::OMEGA_LAST);
        for i in (0..S).rev() {
            let s = chain.stage(i);
            speed[i] = (unit(Layout::<S>::v(i)) + speed[i + 1] * s.c) / s.a;
        }
        Rows { chain, mode, speed }
    }

    /// ψ_i = ks u_i + kd v_i + kc·1 in this mode.
    fn force(&self, i: usize) -> SVector<f64, N> {
        let s = self.chain.stage(i);
        let m = self.mode.stages[i];
        let (ks, kd) = m.force_slopes(s.k, s.d());
        let kc = if m.side() > 0.0 {
            -ks * s.g
        } else if m.side() < 0.0 {
            ks * s.g
        } else {
            0.0
        };
        unit::<N>(Layout::<S>::u(i)) * ks + unit::<N>(Layout::<S>::v(i)) * kd + unit::<N>(Layout::<S>::ONE) * kc
    }

    /// `start` plus the torques on body j other than its bearing's: τ_m on the motor, τ_L (and
    /// −R_w T with a web span) on the last body, and the members' c_{j−1} ψ_{j−1} − a_j ψ_j.
    fn torques(&self, j: usize, start: SVector<f64, N>) -> SVector<f64, N> {
        let mut row = start;
        if j == 0 {
            row += unit::<N>(Layout::<S>::TAU_M);
        }
        if j == S {
            row += unit::<N>(Layout::<S>::TAU_L);
            if let Some(w) = self.chain.web() {
                row -= unit::<N>(Layout::<S>::TENSION) * w.r_w;
            }
        }
        if j > 0 {
            row += self.force(j - 1) * self.chain.stage(j - 1).c;
        }
        if j < S {
            row -= self.force(j) * self.chain.stage(j).a;
        }
        row
    }

    /// ω_j′ as a row over y: J_j ω_j′ = −b_j ω_j + the torques on it, ∓τ_c sliding with
    /// Coulomb friction; 0 stuck.
    pub fn acceleration(&self, j: usize) -> SVector<f64, N> {
        let body = self.chain.body(j);
        let friction = body.friction.tau_c;
        let body_mode = self.mode.body(j);
        if friction > 0.0 && body_mode == BodyMode::Stuck {
            return SVector::<f64, N>::zeros();
        }
        let mut row = self.torques(j, self.speed[j] * (-body.b));
        if friction > 0.0 {
            row += unit::<N>(Layout::<S>::ONE) * (body_mode.friction_sign() * friction);
        }
        row / body.j
    }

    /// τ_h of body j as a row: what its bearing's friction must cancel to hold it at rest
    /// (inputs and members; the viscous term vanishes at rest).
    pub fn holding(&self, j: usize) -> SVector<f64, N> {
        self.torques(j, SVector::<f64, N>::zeros())
    }
}

/// Length of a piece times the fastest rate, as the single-gap stepper's
/// ([`crate::linear::PIECE_RATE`]): Taylor expansions over a piece converge fast and the
/// remainder bounds stay tight.
pub const PIECE_RATE: f64 = crate::linear::PIECE_RATE;
