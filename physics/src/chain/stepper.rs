//! Exact stepping of a chain between contact switches (docs/model.md §2, over S stages): each
//! mode's motion is e^{M s} y; every stage's switching surfaces u_i = ±g_i are certified
//! absent piece by piece or located to round-off, and all stages that switch at one instant
//! enter their new modes together.

use super::linear::{mode_matrix, Layout, PIECE_RATE};
use super::params::Chain;
use super::state::{ChainMode, ChainState};
use crate::mode::ContactMode;
use crate::roots::{self, Side, SignalRows};
use crate::stepper::{Inputs, StepError, MAX_PIECES};
use crate::taylor::{exp_series, Sparse, TaylorModel};
use nalgebra::{SMatrix, SVector};

/// A switch of one stage located inside a step. Stages that switch at one instant are
/// reported with the same offset, in the order of their index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageSwitch {
    /// Time since the start of the step [s].
    pub offset: f64,
    /// Which stage (0 .. S).
    pub stage: usize,
    pub from: ContactMode,
    pub to: ContactMode,
}

/// One mode: its augmented matrix and the derivative rows of each stage's u along it.
#[derive(Clone, Debug)]
struct ModeDynamics<const S: usize, const N: usize> {
    m: SMatrix<f64, N, N>,
    sparse: Sparse<N>,
    u_rows: [SignalRows<N>; S],
}

/// One mode's maps over a whole piece of the current step size: e^{M len}, and per stage (one
/// row each) u″ and u‴ at the piece start and the bound on how far u‴ moves over the piece
/// (roots.rs, `SignalRows::remainder_row`, which multiplies |y|): a whole piece is certified
/// by three small products.
#[derive(Clone, Copy, Debug)]
struct PieceMaps<const S: usize, const N: usize> {
    phi: SMatrix<f64, N, N>,
    second: SMatrix<f64, S, N>,
    third: SMatrix<f64, S, N>,
    remainder: SMatrix<f64, S, N>,
}

/// A located crossing of one stage's threshold.
#[derive(Clone, Copy, Debug)]
struct Crossing {
    /// From the start of the span searched [s].
    offset: f64,
    to: ContactMode,
    /// u on the crossed threshold, ±g, exactly.
    u: f64,
}

/// The exact stepper of a chain of S stages with an augmented state of N = 3S + 7 entries
/// (stable Rust cannot write 3S + 7 as a type, so N is a parameter checked at construction).
/// Holds the per-mode exponentials of the current step size, filled for a mode when it is
/// first entered and dropped when the step size changes; nothing is allocated per step.
#[derive(Clone, Debug)]
pub struct ChainStepper<const S: usize, const N: usize> {
    chain: Chain<S>,
    /// By [`ChainMode::index`].
    modes: Vec<ModeDynamics<S, N>>,
    /// Longest piece [s]: PIECE_RATE over the fastest rate.
    len_ref: f64,
    /// Longest step [s]: `MAX_PIECES` pieces.
    max_h: f64,
    /// The step size the maps are for (NaN: none yet), its pieces and their length [s].
    h: f64,
    pieces: usize,
    len: f64,
    /// By [`ChainMode::index`]; None until the mode is entered at this step size.
    maps: Vec<Option<PieceMaps<S, N>>>,
}

/// One stage (docs/model.md §1's shaft or belt): 10 augmented entries.
pub type OneStageStepper = ChainStepper<1, 10>;
/// Two stages (docs/model.md §10): 13 augmented entries.
pub type TwoStageStepper = ChainStepper<2, 13>;

impl<const S: usize, const N: usize> ChainStepper<S, N> {
    pub fn new(chain: Chain<S>) -> Self {
        assert!(
            N == Layout::<S>::DIM,
            "augmented dimension {N} is not 3S + 7 = {}",
            Layout::<S>::DIM
        );
        let len_ref = PIECE_RATE / chain.fastest_rate();
        let modes = (0..ChainMode::<S>::COUNT)
            .map(|index| {
                let m = mode_matrix::<S, N>(&chain, &ChainMode::from_index(index));
                ModeDynamics {
                    m,
                    sparse: Sparse::new(&m),
                    u_rows: std::array::from_fn(|i| {
                        let mut e_u = SVector::<f64, N>::zeros();
                        e_u[Layout::<S>::u(i)] = 1.0;
                        SignalRows::new(e_u, &m, len_ref)
                    }),
                }
            })
            .collect();
        ChainStepper {
            chain,
            modes,
            len_ref,
            max_h: MAX_PIECES as f64 * len_ref,
            h: f64::NAN,
            pieces: 0,
            len: 0.0,
            maps: vec![None; ChainMode::<S>::COUNT],
        }
    }

    pub fn chain(&self) -> &Chain<S> {
        &self.chain
    }

    /// The longest step `step` accepts [s]: `MAX_PIECES` pieces of PIECE_RATE over the fastest
    /// rate.
    pub fn max_step(&self) -> f64 {
        self.max_h
    }

    /// Advances `state` over [t, t + h] with `inputs` (values at t, slopes over the step; the
    /// web span's entries are ignored), calling `on_switch` for every stage's switch in time
    /// order. Returns the number of switches. On error `state` is left unchanged.
    pub fn step(
        &mut self,
        state: &mut ChainState<S>,
        inputs: &Inputs,
        h: f64,
        on_switch: &mut dyn FnMut(StageSwitch),
    ) -> Result<usize, StepError> {
        self.advance(state, inputs, h, on_switch, false).map(|(n, _)| n)
    }

    /// As [`ChainStepper::step`], but stops at the first switch instant inside the step:
    /// `state` is then the state there (each switching stage's u exactly on its ±g, its mode
    /// entered; all stages switching at that instant switch together) and the returned offset
    /// is the instant from the step start, located to round-off. None: no switch, the whole
    /// step was taken.
    pub fn step_to_first_switch(
        &mut self,
        state: &mut ChainState<S>,
        inputs: &Inputs,
        h: f64,
        on_switch: &mut dyn FnMut(StageSwitch),
    ) -> Result<Option<f64>, StepError> {
        self.advance(state, inputs, h, on_switch, true).map(|(_, at)| at)
    }

    fn advance(
        &mut self,
        state: &mut ChainState<S>,
        inputs: &Inputs,
        h: f64,
        on_switch: &mut dyn FnMut(StageSwitch),
        stop_at_switch: bool,
    ) -> Result<(usize, Option<f64>), StepError> {
        self.check(state, inputs, h)?;
        // Bitwise: a cache for h = 0.1 must not serve 0.1 + 1 ulp.
        if self.h.to_bits() != h.to_bits() {
            self.set_step(h);
        }
        let (pieces, len) = (self.pieces, self.len);
        let switch_limit = 64 + 16 * pieces;
        let mut budget = roots::work_budget(pieces);
        let mut next = *state;
        let mut switches = 0;
        for piece in 0..pieces {
            // Pieces all have length `len`; the last ends on h to round-off of the time grid.
            let start = piece as f64 * len;
            let mut y = augmented::<S, N>(&next, inputs, start);
            // Offset of y from the step start, and whether y is still at the piece start.
            let mut t = start;
            let mut whole = true;
            loop {
                let span = if whole { len } else { len - (t - start) };
                let index = next.mode.index();
                self.fill_maps(index);
                let dynamics = &self.modes[index];
                let maps = self.maps[index].as_ref().expect("filled above");
                if self.clear(&next.mode, dynamics, whole.then_some(maps), &y, span) {
                    // No stage can switch in this span: one product (or one expansion) does it.
                    y = if whole {
                        maps.phi * y
                    } else {
                        TaylorModel::new(&dynamics.sparse, &y, span).at(span)
                    };
                    break;
                }
                let model = TaylorModel::new(&dynamics.sparse, &y, span);
                let Some((offset, crossings)) = self.earliest(&next.mode, dynamics, &model, &y, t, span, &mut budget)
                else {
                    y = if whole { maps.phi * y } else { model.at(span) };
                    break;
                };
                y = model.at(offset);
                t += offset;
                whole = false;
                for (i, crossing) in crossings.iter().enumerate() {
                    let Some(c) = crossing else { continue };
                    y[Layout::<S>::u(i)] = c.u;
                    on_switch(StageSwitch {
                        offset: t,
                        stage: i,
                        from: next.mode.stages[i],
                        to: c.to,
                    });
                    next.mode.stages[i] = c.to;
                    switches += 1;
                }
                // Inputs are functions of time: re-evaluate rather than carry round-off.
                y[Layout::<S>::TAU_M] = inputs.tau_m + inputs.dtau_m * t;
                y[Layout::<S>::TAU_L] = inputs.tau_l + inputs.dtau_l * t;
                if stop_at_switch {
                    self.finish_piece(&mut next, &y);
                    if !next.is_finite() {
                        return Err(StepError::Overflow);
                    }
                    *state = next;
                    return Ok((switches, Some(t)));
                }
                if switches > switch_limit {
                    return Err(StepError::TooManySwitches { limit: switch_limit, h });
                }
                if t - start >= len {
                    break;
                }
            }
            self.finish_piece(&mut next, &y);
        }
        if !next.is_finite() {
            return Err(StepError::Overflow);
        }
        *state = next;
        Ok((switches, None))
    }

    /// Refuses what the step cannot take: h not finite, ≤ 0 or longer than `max_step`,
    /// inputs or state not finite.
    fn check(&self, state: &ChainState<S>, inputs: &Inputs, h: f64) -> Result<(), StepError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(StepError::BadStepSize { h });
        }
        let named = [
            ("tau_m", inputs.tau_m),
            ("tau_L", inputs.tau_l),
            ("der(tau_m)", inputs.dtau_m),
            ("der(tau_L)", inputs.dtau_l),
        ];
        if let Some(&(name, value)) = named.iter().find(|(_, v)| !v.is_finite()) {
            return Err(StepError::NonFiniteInput { name, value });
        }
        if !state.is_finite() {
            return Err(StepError::NonFiniteState);
        }
        if h > self.max_h {
            return Err(StepError::StepTooLong { h, max_h: self.max_h });
        }
        Ok(())
    }

    /// Cuts steps of size h into equal pieces no longer than `len_ref` and drops the maps of
    /// the previous size.
    fn set_step(&mut self, h: f64) {
        let pieces = (h / self.len_ref).ceil().max(1.0);
        self.h = h;
        self.pieces = pieces as usize;
        self.len = h / pieces;
        self.maps.iter_mut().for_each(|m| *m = None);
    }

    fn fill_maps(&mut self, index: usize) {
        if self.maps[index].is_none() {
            let ModeDynamics { m, sparse, u_rows } = &self.modes[index];
            let rows = |row: &dyn Fn(&SignalRows<N>) -> SVector<f64, N>| {
                SMatrix::<f64, S, N>::from_fn(|i, j| row(&u_rows[i])[j])
            };
            self.maps[index] = Some(PieceMaps {
                phi: exp_series(sparse, self.len),
                second: rows(&|r| *r.row(2)),
                third: rows(&|r| *r.row(3)),
                remainder: rows(&|r| r.remainder_row(m, self.len)),
            });
        }
    }

    /// True when no stage's u can leave its mode's region within `span` after y: the cubic
    /// test of docs/model.md §2 per stage, with the whole piece's remainder bound from `maps`
    /// when y is at a piece start.
    fn clear(
        &self,
        mode: &ChainMode<S>,
        dynamics: &ModeDynamics<S, N>,
        maps: Option<&PieceMaps<S, N>>,
        y: &SVector<f64, N>,
        span: f64,
    ) -> bool {
        // u″ and the bound on |u‴| over the span, per stage.
        let (second, third) = match maps {
            Some(maps) => {
                let third = (maps.third * y).abs() + maps.remainder * y.abs();
                (maps.second * y, third)
            }
            None => (
                SVector::<f64, S>::from_fn(|i, _| dynamics.u_rows[i].derivative(2, y)),
                SVector::<f64, S>::from_fn(|i, _| dynamics.u_rows[i].third_bound(y, span)),
            ),
        };
        (0..S).all(|i| {
            let g = self.chain.stage(i).g;
            if g == 0.0 {
                // No free region: both flanks carry K u.
                return true;
            }
            let (u, du) = (y[Layout::<S>::u(i)], y[Layout::<S>::v(i)]);
            let (d2, c3) = (second[i], third[i]);
            let tol = floor(u, g);
            sides(mode.stages[i], g, tol)
                .into_iter()
                .flatten()
                .all(|(side, _, _)| roots::cubic_clear(side.value(u), side.sign * du, side.sign * d2, c3, span, tol))
        })
    }

    /// The earliest instant in (0, span] after y at which some stage leaves its mode's region,
    /// and every stage that leaves at that instant: crossings within a few ulps of the step's
    /// time of the earliest are one instant, and all those stages switch there together.
    #[allow(clippy::too_many_arguments)]
    fn earliest(
        &self,
        mode: &ChainMode<S>,
        dynamics: &ModeDynamics<S, N>,
        model: &TaylorModel<N>,
        y: &SVector<f64, N>,
        t: f64,
        span: f64,
        budget: &mut usize,
    ) -> Option<(f64, [Option<Crossing>; S])> {
        // The time grid's resolution here: the step time t + span to a few ulps, and the
        // search's own resolution (roots.rs: f64::EPSILON/4 of the span).
        let same_instant = 4.0 * f64::EPSILON * (t + span);
        let mut found: [Option<Crossing>; S] = [None; S];
        let mut best = f64::INFINITY;
        for (i, slot) in found.iter_mut().enumerate() {
            let g = self.chain.stage(i).g;
            if g == 0.0 {
                continue;
            }
            let rows = &dynamics.u_rows[i];
            let u = y[Layout::<S>::u(i)];
            let (du, d2, c3) = (y[Layout::<S>::v(i)], rows.derivative(2, y), rows.third_bound(y, span));
            let tol = floor(u, g);
            let mut poly = None;
            for (side, to, u_cross) in sides(mode.stages[i], g, tol).into_iter().flatten() {
                if roots::cubic_clear(side.value(u), side.sign * du, side.sign * d2, c3, span, tol) {
                    continue;
                }
                let p = poly.get_or_insert_with(|| model.poly(Layout::<S>::u(i)));
                // Searched up to the earliest so far (and the slack that makes it one instant);
                // Undecided (u hovering within round-off of ±g) keeps the mode, as stepper.rs.
                let limit = span.min(best + same_instant);
                if let Ok(Some(offset)) = roots::first_exit(p, side, limit, budget) {
                    if slot.is_none_or(|c| offset < c.offset) {
                        *slot = Some(Crossing { offset, to, u: u_cross });
                    }
                    best = best.min(offset);
                }
            }
        }
        if best == f64::INFINITY {
            return None;
        }
        for slot in found.iter_mut() {
            if slot.is_some_and(|c| c.offset > best + same_instant) {
                *slot = None;
            }
        }
        Some((best, found))
    }

    /// Takes the augmented state at the end of a piece (or at a switch) into the state.
    fn finish_piece(&self, next: &mut ChainState<S>, y: &SVector<f64, N>) {
        for j in 0..=S {
            next.body_mut(j).theta += y[Layout::<S>::dtheta(j)];
        }
        for i in 0..S {
            next.u[i] = y[Layout::<S>::u(i)];
            next.du[i] = y[Layout::<S>::v(i)];
        }
        next.body_mut(S).omega = y[Layout::<S>::OMEGA_LAST];
        // ω_i = (v_i + c_i ω_{i+1})/a_i, from the load down (chain/linear.rs).
        for i in (0..S).rev() {
            let s = self.chain.stage(i);
            let driven = next.body(i + 1).omega;
            next.body_mut(i).omega = (next.du[i] + s.c * driven) / s.a;
        }
    }
}

/// Round-off floor of u ∓ g: a few ulps of the larger of |u| and g (as stepper.rs).
fn floor(u: f64, g: f64) -> f64 {
    8.0 * f64::EPSILON * (u.abs() + g)
}

/// The thresholds a stage in `mode` may cross (half gap g > 0), each as the admissible side,
/// the mode entered and u there: free, +g into Positive and −g into Negative; on a flank, its
/// threshold back into Free.
fn sides(mode: ContactMode, g: f64, tol: f64) -> [Option<(Side, ContactMode, f64)>; 2] {
    let side = |offset: f64, sign: f64| Side { offset, sign, tol };
    match mode {
        ContactMode::Free => [
            Some((side(g, -1.0), ContactMode::Positive, g)),
            Some((side(g, 1.0), ContactMode::Negative, -g)),
        ],
        ContactMode::Positive => [Some((side(-g, 1.0), ContactMode::Free, g)), None],
        ContactMode::Negative => [Some((side(-g, -1.0), ContactMode::Free, -g)), None],
        _ => unreachable!("the chain's stages carry no damper"),
    }
}

/// The augmented vector of `state` at time `t` into the step (angle increments zero), in the
/// order of chain/linear.rs.
fn augmented<const S: usize, const N: usize>(state: &ChainState<S>, inputs: &Inputs, t: f64) -> SVector<f64, N> {
    let mut y = SVector::<f64, N>::zeros();
    for i in 0..S {
        y[Layout::<S>::u(i)] = state.u[i];
        y[Layout::<S>::v(i)] = state.du[i];
    }
    y[Layout::<S>::OMEGA_LAST] = state.body(S).omega;
    y[Layout::<S>::TAU_M] = inputs.tau_m + inputs.dtau_m * t;
    y[Layout::<S>::TAU_L] = inputs.tau_l + inputs.dtau_l * t;
    y[Layout::<S>::ONE] = 1.0;
    y[Layout::<S>::DTAU_M] = inputs.dtau_m;
    y[Layout::<S>::DTAU_L] = inputs.dtau_l;
    y
}
