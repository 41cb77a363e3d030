//! The quiet path of a plant with Coulomb friction while each body that has it slides
//! (docs/model.md §12). Sliding, a bearing adds the constant torque ∓τ_c to the torques on its
//! body, so the plant is the frictionless one under shifted torques until a sliding body's speed
//! reaches 0. The sliding steppers' piece kernels carry four more outputs, each body's ω′ at the
//! piece start and a bound on its |ω‴| over the piece; with the speeds at both ends they bound
//! the speed from below (`keeps_sign`), which certifies that no sliding body's speed reaches 0
//! within the piece, and the frictionless quiet step under the shifted torques is then the step.

use super::{Exact, Inputs};
use crate::linear::{self, AugMatrix, AugVector, AUG, WEB_AUG};
use crate::mode::PlantState;
use crate::params::Plant;
use crate::taylor::exp_nonnegative;

/// The drive train's sliding stepper: [`super::DriveStepper`]'s kernel and the speeds' bounds.
pub type SlidingDriveStepper = Exact<AUG, 12>;
/// The web line's: [`super::WebStepper`]'s kernel and the speeds' bounds.
pub type SlidingWebStepper = Exact<WEB_AUG, 14>;

/// Relative rounding allowed for in the quantities the test compares (the speeds at both ends
/// and ω′ at the start, each a sum of at most 13 products): the bound rows carry
/// (81·ROUNDING/(2 len³)) times c (I + |e^{M len}|) + len/2·|c M|, so that 2 len³/81 times the
/// bound covers ROUNDING times those over |y|, more than the rounding of the test's control
/// points.
const ROUNDING: f64 = 32.0 * f64::EPSILON;

/// For a piece of length `len` in one contact mode with matrix `m` and `phi` = e^{M len}, the
/// kernel rows of the speeds: c M over y at the piece start ((r_m ω_m)′ and ω_L′ there), then over |y|
/// the bounds on |(r_m ω_m)‴| and |ω_L‴| over the piece, |c M³| e^{|M| len} (since ω‴(σ) = c M³ e^{M σ} y
/// and e^{|M| σ} bounds |e^{M σ}| entrywise and grows with σ), plus the rounding allowance of
/// [`ROUNDING`].
pub(super) fn speed_bound_rows<const N: usize>(
    plant: &Plant,
    m: &AugMatrix<N>,
    phi: &AugMatrix<N>,
    len: f64,
) -> [AugVector<N>; 4] {
    let grow = exp_nonnegative(&(m.abs() * len)).transpose();
    let reach = (AugMatrix::<N>::identity() + phi.abs()).transpose();
    let mt = m.transpose();
    let [motor, load] = speed_rows::<N>(plant).map(|speed| {
        let first = mt * speed;
        let third = mt * (mt * first);
        let rounding = (reach * speed.abs() + first.abs() * (0.5 * len)) * (40.5 * ROUNDING / len.powi(3));
        (first, grow * third.abs() + rounding)
    });
    [motor.0, load.0, motor.1, load.1]
}

/// The speeds as rows over y: the motor's as r_m ω_m = v + r_L ω_L (the test is the same for
/// any positive multiple, and this one needs no division at the step's end), and ω_L.
fn speed_rows<const N: usize>(plant: &Plant) -> [AugVector<N>; 2] {
    let mut motor = AugVector::<N>::zeros();
    motor[linear::V] = 1.0;
    motor[linear::OMEGA_L] = plant.r_l();
    let mut load = AugVector::<N>::zeros();
    load[linear::OMEGA_L] = 1.0;
    [motor, load]
}

/// Whether a speed ω with ω = `w0` > 0 and ω′ = `a0` at σ = 0, ω = `w1` at σ = len and |ω‴| ≤ `s`
/// over [0, len] stays above 0 there. ω lies within 2 len³/81·s of the quadratic p that
/// interpolates those three values (the error σ²(σ − len)/3!·ω‴(ξ), at most 4 len³/27 in its
/// polynomial part), and p lies above the least of its Bernstein coefficients w0, w0 + len a0/2,
/// w1. A margin of 16 ulps of the terms covers the rounding of the test itself; NaN fails it.
#[inline(always)]
fn keeps_sign(w0: f64, a0: f64, w1: f64, s: f64, len: f64) -> bool {
    let b1 = w0 + 0.5 * len * a0;
    let error = len * len * len * s * (2.0 / 81.0);
    let least = w0.min(b1).min(w1);
    let scale = w0.abs() + b1.abs() + w1.abs() + error;
    (least - error > 16.0 * f64::EPSILON * scale) & (w0 > 0.0)
}

impl<const N: usize, const KO: usize> Exact<N, KO> {
    /// The quiet step (as [`super::Stepper::quiet_step`]) of the plant with Coulomb friction
    /// while each body that has it slides: `bearings[j]` is the torque body j's bearing adds
    /// while it slides, −τ_c forward and +τ_c backward, 0 on a body without friction (not
    /// watched). Taken, under the torques so shifted, when besides the frictionless certificate
    /// no watched body's speed can reach 0 within the step; else `None`, and the chain steps the
    /// plant. Sliding, the plant is exactly the frictionless one under shifted torques, so the
    /// state is the chain's to round-off (not bit for bit: the chain adds the bearing's torque
    /// through its constant column).
    #[inline]
    pub fn quiet_sliding_step(
        &self,
        state: &PlantState,
        inputs: &Inputs,
        bearings: [f64; 2],
        h: f64,
    ) -> Option<PlantState> {
        debug_assert!(KO == if N == WEB_AUG { 14 } else { 12 }, "a sliding stepper");
        let shifted = Inputs {
            tau_m: inputs.tau_m + bearings[0],
            tau_l: inputs.tau_l + bearings[1],
            ..*inputs
        };
        // Sliding forward (ω > 0) the bearing's torque is −τ_c: the direction is minus its sign.
        let d = bearings.map(|b| -b.signum());
        // The motor's speed as r_m ω_m = u′ + r_L ω_L (`speed_rows`).
        let r_l = self.plant.r_l();
        let watched = bearings.map(|b| b != 0.0);
        self.quiet_step_with(state, &shifted, h, |start, next, speeds, len| {
            let w0 = [start.du + r_l * start.omega_l, start.omega_l];
            let [a0, s] = [[speeds[0], speeds[1]], [speeds[2], speeds[3]]];
            let w1 = [next.du + r_l * next.omega_l, next.omega_l];
            let clear = |j: usize| keeps_sign(d[j] * w0[j], d[j] * a0[j], d[j] * w1[j], s[j], len);
            // Non-short-circuit: one branch.
            (!watched[0] | clear(0)) & (!watched[1] | clear(1))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::keeps_sign;

    #[test]
    fn the_sign_test_bounds_the_interpolating_quadratic() {
        // ω = 1 − σ on [0, 1.5]: reaches 0 at σ = 1; on [0, 0.9] it stays above 0.1.
        assert!(!keeps_sign(1.0, -1.0, -0.5, 0.0, 1.5));
        assert!(keeps_sign(1.0, -1.0, 0.1, 0.0, 0.9));
        // (1 − σ)² + 0.01 dips to 0.01 at σ = 1 between two ends at 1.01: its Bernstein
        // coefficients on [0, 2] are 1.01, −0.99, 1.01, so it is not cleared although it stays
        // above 0 (the test is sufficient, not necessary); on [0, 0.5] (1.01, 0.51, 0.26) it is.
        assert!(!keeps_sign(1.01, -2.0, 1.01, 0.0, 2.0));
        assert!(keeps_sign(1.01, -2.0, 0.26, 0.0, 0.5));
        // The error term: a third derivative as large as 81·0.1/(2·0.9³) takes the 0.1 margin.
        assert!(!keeps_sign(1.0, -1.0, 0.1, 81.0 * 0.1 / (2.0 * 0.9f64.powi(3)), 0.9));
        assert!(keeps_sign(
            1.0,
            -1.0,
            0.1,
            0.9 * 81.0 * 0.1 / (2.0 * 0.9f64.powi(3)),
            0.9
        ));
        // At rest, or NaN: never clear.
        assert!(!keeps_sign(0.0, 1.0, 1.0, 0.0, 1.0));
        assert!(!keeps_sign(f64::NAN, 1.0, 1.0, 0.0, 1.0));
        assert!(!keeps_sign(1.0, 1.0, 1.0, f64::NAN, 1.0));
    }
}
