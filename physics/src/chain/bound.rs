//! The speed-error bound of a chain under the PI loop of docs/model.md §3 on the motor speed,
//! with one backlash disturbance per stage (docs/model.md §10).
//!
//! The backlash-free twin has every stage's ψ_i = K_i u_i; the chain with backlash has
//! ψ_i = K_i u_i − φ_i with φ_i = K_i sat(u_i, g_i), |φ_i| ≤ K_i g_i. The difference e of the two
//! loop states obeys e′ = A e + Σ_i D_i φ_i from e(0) = 0, so
//! |ω_S^b − ω_S^0|(t) ≤ Σ_i K_i g_i ∫_0^t |h_i(s)| ds with h_i = L e^{A s} D_i, and the φ_i taking
//! their worst signs independently attains it. Each term is a [`LoopBound`] of its own: the
//! same loop, its own column D_i and scale K_i g_i. With a damper D_i the twin's member is the
//! spring-damper K u_i + D u_i′, and stage i's φ_i splits as in docs/model.md §3 ("With a
//! damper") into a part within K_i g_i and one within D_i |u_i′| over its free, slack and capped
//! time: its term gains D_i max|h_i| V_i.
//!
//! Bearing friction (docs/model.md §10, "The bound with bearing friction"): body b's friction
//! torque f_b stays within peak_b τ_c,b in every mode, on the chain and on its twin alike, so the
//! difference of the two enters e′ along E_b (1/J_b at ω_b) within 2 peak_b τ_c,b, and the
//! bound gains 2 peak_b τ_c,b ∫_0^t |L e^{A s} E_b| ds per body with friction: one more
//! [`LoopBound`] each. It stays a true bound but is not attained, and it does not vanish with
//! the gaps.

use super::params::Chain;
use crate::bound::{check_gains, BoundError, BoundState, Disturbance, LoopBound, PiGains, Trajectory, Unbounded};
use crate::closed_loop::{Coord, Reduced};
use nalgebra::{Complex, DMatrix, SMatrix};

/// The loop state of an S-stage chain under the PI: [θ_0, ω_0, θ_1, ω_1, …, θ_S, ω_S, x_c].
pub struct LoopLayout<const S: usize>;

impl<const S: usize> LoopLayout<S> {
    /// 2S + 3 entries.
    pub const DIM: usize = 2 * S + 3;
    /// The PI's integral of the speed error, x_c.
    pub const X_C: usize = 2 * S + 2;
    /// The load's speed ω_S, the bound's output.
    pub const OMEGA_LAST: usize = 2 * S + 1;

    /// θ_j.
    pub const fn theta(j: usize) -> usize {
        2 * j
    }
    /// ω_j.
    pub const fn omega(j: usize) -> usize {
        2 * j + 1
    }
}

/// The backlash-free chain (every ψ_i = K_i u_i) under the PI on ω_0, τ_m = Kp e + Ki x_c,
/// e = ω_ref − ω_0, x_c′ = e, in the loop state of [`LoopLayout`] (N = 2S + 3). For one stage
/// this is [`crate::closed_loop::closed_loop`] entry for entry: K a²/J is rounded as one
/// product, the same way. With Kp = Ki = 0 the x_c row and column are zero (open loop).
pub fn chain_loop<const S: usize, const N: usize>(chain: &Chain<S>, gains: PiGains) -> SMatrix<f64, N, N> {
    assert!(N == LoopLayout::<S>::DIM, "a loop of {N} entries for {S} stages");
    let (theta, omega) = (LoopLayout::<S>::theta, LoopLayout::<S>::omega);
    let mut a = SMatrix::<f64, N, N>::zeros();
    for j in 0..=S {
        let body = chain.body(j);
        a[(theta(j), omega(j))] = 1.0;
        a[(omega(j), omega(j))] = -if j == 0 { body.b + gains.kp } else { body.b } / body.j;
    }
    for i in 0..S {
        let s = chain.stage(i);
        let (driving, driven) = (chain.body(i).j, chain.body(i + 1).j);
        // Body i receives −a ψ_i, body i + 1 receives +c ψ_i, ψ_i = K (a θ_i − c θ_{i+1}).
        a[(omega(i), theta(i))] -= s.k * s.a * s.a / driving;
        a[(omega(i), theta(i + 1))] += s.k * s.a * s.c / driving;
        a[(omega(i + 1), theta(i))] += s.k * s.a * s.c / driven;
        a[(omega(i + 1), theta(i + 1))] -= s.k * s.c * s.c / driven;
        let d = s.d();
        if d != 0.0 {
            // The twin's spring-damper: ψ_i⁰ = K u_i + D u_i′, u_i′ = a ω_i − c ω_{i+1}.
            a[(omega(i), omega(i))] -= d * s.a * s.a / driving;
            a[(omega(i), omega(i + 1))] += d * s.a * s.c / driving;
            a[(omega(i + 1), omega(i))] += d * s.a * s.c / driven;
            a[(omega(i + 1), omega(i + 1))] -= d * s.c * s.c / driven;
        }
    }
    a[(omega(0), LoopLayout::<S>::X_C)] = gains.ki / chain.body(0).j;
    if gains.kp != 0.0 || gains.ki != 0.0 {
        a[(LoopLayout::<S>::X_C, omega(0))] = -1.0;
    }
    a
}

/// The column D_i along which stage i's disturbance φ_i enters the loop: +a_i/J_i at ω_i,
/// −c_i/J_{i+1} at ω_{i+1} (docs/model.md §10).
pub fn disturbance_column<const S: usize, const N: usize>(chain: &Chain<S>, stage: usize) -> [f64; N] {
    let s = chain.stage(stage);
    let mut column = [0.0; N];
    column[LoopLayout::<S>::omega(stage)] = s.a / chain.body(stage).j;
    column[LoopLayout::<S>::omega(stage + 1)] = -s.c / chain.body(stage + 1).j;
    column
}

/// The column E_b along which body b's bearing friction torque enters the loop: 1/J_b at ω_b.
pub fn friction_column<const S: usize, const N: usize>(chain: &Chain<S>, body: usize) -> [f64; N] {
    let mut column = [0.0; N];
    column[LoopLayout::<S>::omega(body)] = 1.0 / chain.body(body).j;
    column
}

/// The poles of the backlash-free chain under the PI `gains` (docs/model.md §10): the
/// eigenvalues of its loop on the reduced coordinates (every gap, every speed, x_c when Ki ≠ 0),
/// without the rigid rotation of the whole chain, which no disturbance excites; None if they
/// cannot be computed. N = 2S + 3.
pub fn loop_poles<const S: usize, const N: usize>(chain: &Chain<S>, gains: PiGains) -> Option<Vec<Complex<f64>>> {
    let a = chain_loop::<S, N>(chain, gains);
    let full = DMatrix::from_iterator(N, N, a.iter().copied());
    Reduced::from_loop(&full, reduced_coords(chain, gains), LoopLayout::<S>::OMEGA_LAST).poles()
}

/// `bound(t)` and `bound_sup` of a chain of S stages (docs/model.md §10) under a PI loop on the
/// motor speed: the sum over the stages of K_i g_i ∫|h_i|, and over the bodies with bearing
/// friction of 2 peak_b τ_c,b ∫|h_b| ([`FrictionBound`]), each a [`LoopBound`] (N = 2S + 3 loop
/// entries, BA = 2N, KO kernel outputs, R = 2S + 2 reduced coordinates, OUT = ω_S).
#[derive(Clone, Debug)]
pub struct ChainBound<
    const S: usize,
    const N: usize,
    const BA: usize,
    const KO: usize,
    const R: usize,
    const OUT: usize,
> {
    stages: [LoopBound<N, BA, KO, R, OUT>; S],
    friction: FrictionBound<S, N, BA, KO, R, OUT>,
}

/// The bearing friction's part of a chain's bound (docs/model.md §10): one term
/// 2 peak_b τ_c,b ∫|h_b| per body with friction, h_b = L e^{A s} E_b; none without friction.
#[derive(Clone, Debug)]
pub struct FrictionBound<
    const S: usize,
    const N: usize,
    const BA: usize,
    const KO: usize,
    const R: usize,
    const OUT: usize,
> {
    /// The motor's friction term, None without friction on it.
    motor: Option<LoopBound<N, BA, KO, R, OUT>>,
    /// Each driven body's friction term, None without friction on it.
    driven: [Option<LoopBound<N, BA, KO, R, OUT>>; S],
}

/// The bound of [`crate::chain::TwoStageStepper`]'s chain.
pub type TwoStageBound = ChainBound<2, 7, 14, 18, 6, 5>;
/// The bound of a one-stage chain (the loop of docs/model.md §3).
pub type OneStageBound = ChainBound<1, 5, 10, 16, 4, 3>;
/// The friction's part of a one-stage chain's bound: the FMUs' drive trains with bearing
/// friction add it to docs/model.md §3's bound (their loop is that chain's, entry for entry).
pub type OneStageFrictionBound = FrictionBound<1, 5, 10, 16, 4, 3>;

/// The loop of `chain` under `gains` with its sizes checked, and the reduced loop's coordinates,
/// or the refusal of the gains or of a chain that pulls a web span (its loop is the web line's).
fn checked_loop<const S: usize, const N: usize, const R: usize, const OUT: usize>(
    chain: &Chain<S>,
    gains: PiGains,
) -> Result<(SMatrix<f64, N, N>, DMatrix<f64>), BoundError> {
    assert!(
        N == LoopLayout::<S>::DIM && OUT == LoopLayout::<S>::OMEGA_LAST && R == 2 * S + 2,
        "a chain bound of sizes N = {N}, R = {R}, OUT = {OUT} for {S} stages"
    );
    check_gains(&[("Kp", gains.kp), ("Ki", gains.ki)])?;
    if chain.web().is_some() {
        return Err(BoundError::WebChain);
    }
    let a = chain_loop::<S, N>(chain, gains);
    let full = DMatrix::from_iterator(N, N, a.iter().copied());
    Ok((a, full))
}

impl<const S: usize, const N: usize, const BA: usize, const KO: usize, const R: usize, const OUT: usize>
    FrictionBound<S, N, BA, KO, R, OUT>
{
    /// The friction terms of `chain` under the PI `gains`: one per body with friction, none
    /// without. Refuses as [`ChainBound::new`].
    pub fn new(chain: &Chain<S>, gains: PiGains) -> Result<Self, BoundError> {
        let (a, full) = checked_loop::<S, N, R, OUT>(chain, gains)?;
        let rate = chain.fastest_rate();
        let term = |body: usize| {
            let coulomb = chain.body(body).friction;
            (coulomb.tau_c > 0.0).then(|| {
                // |f_b − f_b⁰| ≤ 2 peak_b τ_c,b: each within its breakaway torque.
                let disturbance = Disturbance {
                    column: friction_column::<S, N>(chain, body),
                    scale: 2.0 * coulomb.breakaway(),
                    rate,
                    damping: 0.0,
                    half_gap: 0.0,
                };
                let reduced = Reduced::from_loop(&full, reduced_coords(chain, gains), OUT);
                LoopBound::build(&disturbance, a, reduced)
            })
        };
        Ok(FrictionBound {
            motor: term(0),
            driven: std::array::from_fn(|i| term(i + 1)),
        })
    }

    /// The terms that were built, motor first.
    fn terms(&self) -> impl Iterator<Item = &LoopBound<N, BA, KO, R, OUT>> {
        self.motor.iter().chain(self.driven.iter().flatten())
    }

    /// Whether no body has friction (no term).
    pub fn is_empty(&self) -> bool {
        self.terms().next().is_none()
    }

    /// Advances every term by `h` ≥ 0. On error nothing changes.
    pub fn advance(&mut self, h: f64) -> Result<(), BoundError> {
        if self.is_empty() {
            return Ok(());
        }
        let before = self.clone();
        let terms = self.motor.iter_mut().chain(self.driven.iter_mut().flatten());
        for term in terms {
            if let Err(e) = term.advance(h) {
                *self = before;
                return Err(e);
            }
        }
        Ok(())
    }

    /// Σ_b 2 peak_b τ_c,b ∫_0^t |h_b| (0 without friction).
    pub fn bound(&self) -> f64 {
        self.terms().map(|s| s.bound()).sum()
    }

    /// Its time derivative Σ_b 2 peak_b τ_c,b |h_b(t)|.
    pub fn bound_rate(&self) -> f64 {
        self.terms().map(|s| s.bound_rate()).sum()
    }

    /// Body b's term (b = 0 the motor), None without friction on it.
    pub fn body_bound(&self, body: usize) -> Option<f64> {
        let term = if body == 0 { &self.motor } else { &self.driven[body - 1] };
        term.as_ref().map(|s| s.bound())
    }

    /// Σ_b 2 peak_b τ_c,b ∫_0^∞ |h_b|, or why it is infinite.
    pub fn sup(&self) -> Result<f64, Unbounded> {
        self.terms().map(|s| s.sup()).sum::<Result<f64, Unbounded>>()
    }

    /// Back to the start (elapsed = 0).
    pub fn reset(&mut self) {
        for term in self.motor.iter_mut().chain(self.driven.iter_mut().flatten()) {
            term.reset();
        }
    }

    /// The largest relative slack of the terms' suprema (see `LoopBound::sup_slack`).
    pub fn sup_slack(&self) -> f64 {
        self.terms().filter_map(|s| s.sup_slack()).fold(0.0, f64::max)
    }

    /// The longest advance every term accepts (∞ without friction).
    pub fn max_advance(&self) -> f64 {
        self.terms().map(|s| s.max_advance()).fold(f64::INFINITY, f64::min)
    }

    /// Each body's term's state, motor first (None for a body without friction).
    pub fn states(&self) -> Vec<Option<BoundState<N>>> {
        std::iter::once(&self.motor)
            .chain(&self.driven)
            .map(|t| t.as_ref().map(|s| s.state()))
            .collect()
    }

    /// Continues from [`Self::states`]: each built term from its state; refused
    /// ([`BoundError::BadState`]) unless the states are those of the same bodies and each is one
    /// a term could have.
    pub fn restore(&mut self, states: &[Option<BoundState<N>>]) -> Result<(), BoundError> {
        let before = self.clone();
        let terms = std::iter::once(&mut self.motor).chain(&mut self.driven);
        for (term, state) in terms.zip(states) {
            let result = match (term, state) {
                (Some(t), Some(s)) => t.restore(s),
                (None, None) => Ok(()),
                _ => Err(BoundError::BadState),
            };
            if let Err(e) = result {
                *self = before;
                return Err(e);
            }
        }
        Ok(())
    }
}

impl<const S: usize, const N: usize, const BA: usize, const KO: usize, const R: usize, const OUT: usize>
    ChainBound<S, N, BA, KO, R, OUT>
{
    /// The bound of `chain` under the PI `gains` (both 0: open loop). Refuses gains that are
    /// not finite or not in scale, and a chain that pulls a web span (its loop is the web
    /// line's). A body with bearing friction adds its term; without friction none is built.
    pub fn new(chain: &Chain<S>, gains: PiGains) -> Result<Self, BoundError> {
        let (a, full) = checked_loop::<S, N, R, OUT>(chain, gains)?;
        let rate = chain.fastest_rate();
        Ok(ChainBound {
            stages: std::array::from_fn(|i| {
                let s = chain.stage(i);
                let disturbance = Disturbance {
                    column: disturbance_column::<S, N>(chain, i),
                    scale: s.k * s.g,
                    rate,
                    damping: s.d(),
                    half_gap: s.g,
                };
                let reduced = Reduced::from_loop(&full, reduced_coords(chain, gains), OUT);
                LoopBound::build(&disturbance, a, reduced)
            }),
            friction: FrictionBound::new(chain, gains)?,
        })
    }

    /// Advances the time since the start by `h` ≥ 0 (every stage's and body's term). On error
    /// nothing changes.
    pub fn advance(&mut self, h: f64) -> Result<(), BoundError> {
        let before = self.stages.clone();
        for stage in &mut self.stages {
            if let Err(e) = stage.advance(h) {
                self.stages = before;
                return Err(e);
            }
        }
        self.friction.advance(h).inspect_err(|_| self.stages = before)
    }

    /// Σ_i K_i g_i ∫_0^t |h_i| + Σ_b 2 peak_b τ_c,b ∫_0^t |h_b|: a true bound on
    /// |ω_S^b − ω_S^0| [rad/s] at the elapsed time t without dampers; with one, the part of
    /// [`Self::damped_bound`] that the gaps and the friction cause.
    pub fn bound(&self) -> f64 {
        self.stages.iter().map(|s| s.bound()).sum::<f64>() + self.friction_bound()
    }

    /// Σ_b 2 peak_b τ_c,b ∫_0^t |h_b|, the bearing friction's part of [`Self::bound`] (0 without
    /// friction).
    pub fn friction_bound(&self) -> f64 {
        self.friction.bound()
    }

    /// Body b's term 2 peak_b τ_c,b ∫_0^t |h_b| (b = 0 the motor), None without friction on it.
    pub fn body_bound(&self, body: usize) -> Option<f64> {
        self.friction.body_bound(body)
    }

    /// Stage i's term K_i g_i ∫_0^t |h_i| of [`Self::bound`].
    pub fn stage_bound(&self, stage: usize) -> f64 {
        self.stages[stage].bound()
    }

    /// The bound with dampers: Σ_i (K_i g_i ∫_0^t |h_i| + D_i max_{[0,t]} |h_i| V_i), with V_i
    /// the stage's ∫|u_i′| over its free, slack and capped time on the trajectory
    /// ([`super::ChainState::variation`]), plus the friction's part; [`Self::bound`] without a
    /// damper, whatever V.
    pub fn damped_bound(&self, variation: &[f64; S]) -> f64 {
        let gaps: f64 = self
            .stages
            .iter()
            .zip(variation)
            .map(|(s, &v)| {
                s.damped_bound(Trajectory::Stepped {
                    variation: v,
                    rate: 0.0,
                })
            })
            .sum();
        gaps + self.friction_bound()
    }

    /// Σ_i K_i g_i ∫_0^∞ |h_i| + Σ_b 2 peak_b τ_c,b ∫_0^∞ |h_b| (`bound_sup`; with dampers the
    /// gaps' and the friction's part), or why it is infinite.
    pub fn sup(&self) -> Result<f64, Unbounded> {
        let gaps: f64 = self.stages.iter().map(|s| s.sup()).sum::<Result<f64, Unbounded>>()?;
        if self.friction.is_empty() {
            return Ok(gaps);
        }
        Ok(gaps + self.friction.sup()?)
    }

    /// Stage i's term K_i g_i ∫_0^∞ |h_i| of [`Self::sup`]: linear in g_i, the rest of the chain
    /// held.
    pub fn stage_sup(&self, stage: usize) -> Result<f64, Unbounded> {
        self.stages[stage].sup()
    }

    /// Time since the start [s].
    pub fn elapsed(&self) -> f64 {
        self.stages[0].elapsed()
    }

    /// The longest advance accepted in one call.
    pub fn max_advance(&self) -> f64 {
        self.stages
            .iter()
            .map(|s| s.max_advance())
            .fold(self.friction.max_advance(), f64::min)
    }

    /// The time derivative of [`Self::bound`]: Σ_i K_i g_i |h_i(t)| + Σ_b 2 peak_b τ_c,b |h_b(t)|.
    pub fn bound_rate(&self) -> f64 {
        self.stages.iter().map(|s| s.bound_rate()).sum::<f64>() + self.friction.bound_rate()
    }

    /// Back to the start (elapsed = 0).
    pub fn reset(&mut self) {
        self.stages.iter_mut().for_each(|s| s.reset());
        self.friction.reset();
    }

    /// The largest relative slack of the terms' suprema (see `LoopBound::sup_slack`).
    pub fn sup_slack(&self) -> f64 {
        self.stages
            .iter()
            .filter_map(|s| s.sup_slack())
            .fold(self.friction.sup_slack(), f64::max)
    }

    /// Each term's state: the stages', then each body's (None for a body without friction).
    pub fn states(&self) -> Vec<Option<BoundState<N>>> {
        let stages = self.stages.iter().map(|s| Some(s.state()));
        stages.chain(self.friction.states()).collect()
    }

    /// Continues from [`Self::states`]; refused ([`BoundError::BadState`]) unless they are those of
    /// the same terms and each is one a term could have. On error nothing changes.
    pub fn restore(&mut self, states: &[Option<BoundState<N>>]) -> Result<(), BoundError> {
        if states.len() != S + S + 1 {
            return Err(BoundError::BadState);
        }
        let before = self.clone();
        for (stage, state) in self.stages.iter_mut().zip(states) {
            let result = match state {
                Some(s) => stage.restore(s),
                None => Err(BoundError::BadState),
            };
            if let Err(e) = result {
                *self = before;
                return Err(e);
            }
        }
        self.friction
            .restore(&states[S..])
            .inspect_err(|_| *self = before.clone())
    }
}

/// The reduced coordinates of the chain's loop: every stage's gap a θ_i − c θ_{i+1}, every
/// body's speed, and x_c when Ki ≠ 0 (without gain it feeds nothing back).
fn reduced_coords<const S: usize>(chain: &Chain<S>, gains: PiGains) -> Vec<Coord> {
    let gaps = (0..S).map(|i| {
        let s = chain.stage(i);
        Coord::Gap {
            a: s.a,
            i: LoopLayout::<S>::theta(i),
            c: s.c,
            j: LoopLayout::<S>::theta(i + 1),
        }
    });
    let speeds = (0..=S).map(|j| Coord::Entry(LoopLayout::<S>::omega(j)));
    let integrator = (gains.ki != 0.0).then_some(Coord::Entry(LoopLayout::<S>::X_C));
    gaps.chain(speeds).chain(integrator).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::ChainParams;
    use crate::closed_loop::closed_loop;
    use crate::{Plant, PlantParams};

    #[test]
    fn one_stage_is_the_plant_loop_entry_for_entry() {
        let plant = Plant::new(PlantParams::paper_rig(0.775e-3)).unwrap();
        let chain = Chain::new(ChainParams::from_plant(&plant).unwrap()).unwrap();
        for gains in [PiGains::default(), PiGains { kp: 42.0, ki: 180.0 }] {
            // The same products in the same order: equal to the bit.
            assert_eq!(chain_loop::<1, 5>(&chain, gains), closed_loop(&plant, gains));
        }
    }

    #[test]
    fn the_reduced_loop_commutes_with_its_projection() {
        let chain = Chain::new(crate::chain::ChainParams::<2>::two_stage_rig()).unwrap();
        let gains = PiGains { kp: 42.0, ki: 180.0 };
        let a = chain_loop::<2, 7>(&chain, gains);
        let full = DMatrix::from_iterator(7, 7, a.iter().copied());
        let reduced = Reduced::from_loop(&full, reduced_coords(&chain, gains), 5);
        let (lhs, rhs) = reduced.commutation(&full);
        let scale = lhs.abs().max();
        assert!((&lhs - &rhs).abs().max() <= 1e-13 * scale, "{lhs} vs {rhs}");
    }
}
