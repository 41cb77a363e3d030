//! The speed-error bounds of docs/model.md §3 for a PI loop on motor speed, and the bounds of the
//! web line (docs/model.md §8) on its load speed and span tension: one [`LoopBound`] for each.

pub use super::closed_loop::PiGains;

use super::closed_loop::{closed_loop, spectral_radius, web_loop, Reduced, TailBound, CL, OMEGA_L, TENSION, WEB_CL};
use super::kernel::KernelColumn;
use super::linear;
use super::params::Plant;
use super::roots::{self, Side, SignalRows, Undecided};
use super::taylor::{exp_series, Sparse, TaylorModel};
use nalgebra::{SMatrix, SVector};
use thiserror::Error;

/// What the damper's term of `bound` follows on the trajectory (docs/model.md §3, "With a
/// damper"); it counts only with a damper in the compliant member.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Trajectory {
    /// Co-Simulation: the stepper's V ([`super::PlantState::variation`]), growing at `rate`.
    Stepped { variation: f64, rate: f64 },
    /// Model Exchange: Σ|Δu| over the slack and capped phases between the importer's events
    /// (`monotone`, growing at `rate`) and the number of phases in the gap (`gaps`).
    AtEvents { monotone: f64, gaps: f64, rate: f64 },
}

/// Why `bound_sup` is +∞.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum Unbounded {
    #[error("the loop is unstable in the modes the backlash disturbance excites (spectral abscissa {abscissa:e} 1/s)")]
    Unstable { abscissa: f64 },
    #[error("the loop is undamped in the modes the backlash disturbance excites: the impulse response never decays")]
    Undamped,
    #[error("the eigenvalues of the loop could not be computed (parameters too far apart in scale)")]
    Indeterminate,
    #[error(
        "stage {stage} has a damper: the bound over several stages does not cover a damped stage's clipped force yet"
    )]
    DampedStage { stage: usize },
}

/// Everything that evolves in a [`LoopBound`] of an `N`-entry loop state, as plain numbers (for
/// FMU-state saving).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundState<const N: usize = CL> {
    /// Time since the experiment's start [s].
    pub elapsed: f64,
    /// e^{A s} D_1 at s = elapsed (in open loop the integrators' entries are 0).
    pub response: [f64; N],
    /// ∫_0^elapsed e^{A s} D_1 ds.
    pub integral: [f64; N],
    /// ∫_0^elapsed |h(s)| ds.
    pub l1: f64,
    /// With a damper in the compliant member: an upper bound on max |h| over [0, elapsed]
    /// (docs/model.md §3, "With a damper"); 0 without one.
    pub peak: f64,
    /// With a damper: an upper bound on ∫_0^elapsed |h′(s)| ds, the total variation of h; 0
    /// without one.
    pub variation: f64,
}

impl<const N: usize> Default for BoundState<N> {
    fn default() -> Self {
        BoundState {
            elapsed: 0.0,
            response: [0.0; N],
            integral: [0.0; N],
            l1: 0.0,
            peak: 0.0,
            variation: 0.0,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum BoundError {
    #[error("gain {name} = {value} must be finite")]
    NonFiniteGain { name: &'static str, value: f64 },
    #[error("gain {name} = {value:e} is outside the range this model integrates: 0 or 1e-100 ..= 1e100 in magnitude")]
    GainOutOfScale { name: &'static str, value: f64 },
    #[error("time advance {h} must be finite and >= 0")]
    BadAdvance { h: f64 },
    #[error("an advance of {h} s spans more than {} periods of the loop's fastest motion; advance at most {max_h:e} s at a time", super::stepper::MAX_PIECES)]
    AdvanceTooLong { h: f64, max_h: f64 },
    #[error("bound state is not finite or has negative time")]
    BadState,
    #[error("the bounds at {elapsed:e} s after the start time are out of reach: the loop's response has not decayed by {reached:e} s, and following it further takes too long; read them at an earlier time")]
    TooFar { elapsed: f64, reached: f64 },
    #[error("the bounds overflow: bound = {bound:e}, bound_paper = {bound_paper:e}")]
    Overflow { bound: f64, bound_paper: f64 },
    #[error("the chain pulls a web span: its bounds are the web line's (docs/model.md §8), not built over several stages yet")]
    WebChain,
}

// The augmented state [v, I] with v = e^{A s} D_1 and I = ∫_0^s v: y' = [A v; v], `BA` = 2 N
// entries for a loop state of N.
type BoundMatrix<const BA: usize> = SMatrix<f64, BA, BA>;
type BoundVector<const BA: usize> = SVector<f64, BA>;
const MAX_CROSSINGS: usize = 64;

/// Exponential for the current advance length, cut into `pieces` of `len`.
#[derive(Clone, Debug)]
struct AdvanceCache<const N: usize, const BA: usize, const KO: usize> {
    h: f64,
    pieces: usize,
    len: f64,
    kernel: PieceKernel<N, BA, KO>,
}

/// Everything a whole piece needs, fused into one pass over the response v (at a piece start
/// y = [v, 0]: the integral columns drop out): outputs 0..BA are e^{M len} y, the next three
/// are h′, h″ and h‴ at the start, the next `remainder`·|v|, which bounds how far h‴ moves over
/// the piece (the speed loop: outputs 0–9, 10–12, 13). Stored by column, `KO` outputs wide, so
/// that the pass vectorizes across the outputs.
#[derive(Clone, Debug)]
struct PieceKernel<const N: usize, const BA: usize, const KO: usize> {
    cols: [KernelColumn<KO>; N],
}

/// What the kernel gives for one piece: the end state, [h, h′, h″] at the start and a bound on
/// |h‴| over the piece.
struct Piece<const BA: usize> {
    end: BoundVector<BA>,
    d: [f64; 3],
    c3: f64,
}

impl<const N: usize, const BA: usize, const KO: usize> PieceKernel<N, BA, KO> {
    /// The output that takes |v|: the growth bound of h‴.
    const GROWTH_ROW: usize = BA + 3;

    fn new(phi: &BoundMatrix<BA>, rows: &SignalRows<BA>, remainder: &BoundVector<BA>) -> Self {
        assert!(
            BA == 2 * N && KO > Self::GROWTH_ROW,
            "kernel of {KO} outputs for a loop of {N}"
        );
        PieceKernel {
            cols: KernelColumn::table(|r, j| match r {
                _ if r < BA => phi[(r, j)],
                _ if r < Self::GROWTH_ROW => rows.row(r - BA + 1)[j],
                _ if r == Self::GROWTH_ROW => remainder[j],
                _ => 0.0,
            }),
        }
    }

    fn apply(&self, v: &[f64; N], out: usize) -> Piece<BA> {
        let mut acc = [0.0; KO];
        for (col, &vj) in self.cols.iter().zip(v) {
            col.accumulate(&mut acc, vj, Self::GROWTH_ROW);
        }
        Piece {
            end: BoundVector::from_column_slice(&acc[..BA]),
            d: [v[out], acc[BA], acc[BA + 1]],
            c3: acc[BA + 2].abs() + acc[Self::GROWTH_ROW],
        }
    }
}

/// How a backlash disturbance φ enters a loop of `N` states (docs/model.md §3): along the column
/// D, with |φ| ≤ K g (`scale`), from a plant whose fastest rate is `rate`; a damper D (`damping`)
/// in the compliant member with half gap g (`half_gap`) adds the trajectory terms of
/// [`LoopBound::damped_bound`].
pub(crate) struct Disturbance<const N: usize> {
    pub(crate) column: [f64; N],
    pub(crate) scale: f64,
    pub(crate) rate: f64,
    pub(crate) damping: f64,
    pub(crate) half_gap: f64,
}

impl<const N: usize> Disturbance<N> {
    /// The single gap of a plant of docs/model.md §1: D_1 = r_m/J_m at ω_m, −r_L/J_L at ω_L.
    fn of_plant(plant: &Plant) -> Self {
        let p = plant.params();
        let mut column = [0.0; N];
        column[1] = plant.r_m() / p.j_m;
        column[OMEGA_L] = -plant.r_l() / p.j_l;
        Disturbance {
            column,
            scale: plant.stiffness() * plant.half_gap(),
            rate: linear::fastest_rate(plant),
            damping: plant.damping(),
            half_gap: plant.half_gap(),
        }
    }
}

/// The bounds of the speed loop of docs/model.md §3 (`bound`, `bound_paper`, `bound_sup`).
pub type SpeedErrorBound = LoopBound<CL, { 2 * CL }, 16, 4, OMEGA_L>;
/// A bound of the web line (docs/model.md §8) on the entry `OUT` of its loop state.
pub type WebLoopBound<const OUT: usize> = LoopBound<WEB_CL, { 2 * WEB_CL }, 18, 6, OUT>;
/// The web line's bounds on its load speed ω_L: `bound`, `bound_paper`, `bound_sup`.
pub type WebSpeedBound = WebLoopBound<OMEGA_L>;
/// The web line's bounds on its span tension T: `bound_T`, `bound_T_sup`.
pub type WebTensionBound = WebLoopBound<TENSION>;

/// bound(t), bound_paper(t) and bound_sup of docs/model.md §3, advanced over elapsed time,
/// for a backlash-free loop of `N` states (augmented to `BA` = 2 N, `KO` kernel outputs, at
/// most `R` coordinates in the tail bound) and the response of its entry `OUT` (ω_L, or T on a
/// web line).
///
/// h(s) = L_c e^{A s} D_1 is tracked exactly through the augmented state [v, ∫v]; ∫|h| is the
/// sum of |∫h| between the sign changes of h, which are located like contact switches
/// (`roots`): no quadrature.
#[derive(Clone, Debug)]
pub struct LoopBound<const N: usize, const BA: usize, const KO: usize, const R: usize, const OUT: usize> {
    /// K g [N·m or N].
    scale: f64,
    m: BoundMatrix<BA>,
    sparse: Sparse<BA>,
    h_rows: SignalRows<BA>,
    start: BoundVector<BA>,
    state: BoundState<N>,
    /// bound_sup and its relative slack (see `compute_sup`).
    sup: Result<(f64, f64), Unbounded>,
    /// Bounds what is left of ∫|h|; None when the loop does not decay.
    tail: Option<TailBound<N, R>>,
    cache: Option<AdvanceCache<N, BA, KO>>,
    /// `settled_now()` of `state`, kept with it: in the settled regime the response no longer
    /// moves, so the answer cannot change until the state is replaced.
    settled: bool,
    /// In the settled regime: an upper bound on every |integral_i|, and the largest
    /// |response_i|, by which it grows per second (see `advance`).
    reach: f64,
    drift_peak: f64,
    /// Up to this `reach`, `bound_paper` cannot overflow.
    reach_limit: f64,
    /// D of the compliant member: > 0 tracks `BoundState::peak` and `variation` for the
    /// damper's terms.
    damping: f64,
    /// g, the half gap in u (the damper's terms of the Model Exchange form).
    half_gap: f64,
}

/// An upper bound on max |h| over [0, w] from h, h′, h″ at 0 (`d`) and |h‴| ≤ `c3` on [0, w]:
/// the largest |h₀ + h₁σ + h₂σ²/2| (at an end or at the vertex) plus c3 w³/6.
fn peak_bound(d: [f64; 3], c3: f64, w: f64) -> f64 {
    let quad = |x: f64| (d[0] + x * (d[1] + 0.5 * x * d[2])).abs();
    let mut top = quad(0.0).max(quad(w));
    if d[2] != 0.0 {
        let vertex = -d[1] / d[2];
        if vertex > 0.0 && vertex < w {
            top = top.max(quad(vertex));
        }
    }
    top + c3 * w * w * w / 6.0
}

/// An upper bound on ∫_0^w |h′| from h′, h″ at 0 (`d[1]`, `d[2]`), |h‴| ≤ `c3` on [0, w] and
/// the net change `dh` of h over [0, w]: |dh| where h′ provably keeps its sign (h′(σ) ≥ h′(0) +
/// h″(0) σ − c3 σ²/2 for its sign), else ∫ (|h′(0)| + |h″(0)| σ + c3 σ²/2) dσ.
fn variation_bound(d: [f64; 3], c3: f64, w: f64, dh: f64) -> f64 {
    let sign = if d[1] != 0.0 { d[1].signum() } else { d[2].signum() };
    if d[1] != 0.0 && roots::cubic_clear(sign * d[1], sign * d[2], -c3, 0.0, w, 0.0) {
        dh.abs()
    } else {
        w * (d[1].abs() + w * (0.5 * d[2].abs() + w * c3 / 6.0))
    }
}

/// Refuses gains that are not finite or not in scale.
pub(crate) fn check_gains(named: &[(&'static str, f64)]) -> Result<(), BoundError> {
    for &(name, value) in named {
        if !value.is_finite() {
            return Err(BoundError::NonFiniteGain { name, value });
        }
        if super::params::in_scale(name, value).is_err() {
            return Err(BoundError::GainOutOfScale { name, value });
        }
    }
    Ok(())
}

impl SpeedErrorBound {
    pub fn new(plant: &Plant, gains: PiGains) -> Result<SpeedErrorBound, BoundError> {
        check_gains(&[("Kp", gains.kp), ("Ki", gains.ki)])?;
        Ok(Self::build(
            &Disturbance::of_plant(plant),
            closed_loop(plant, gains),
            Reduced::new(plant, gains),
        ))
    }
}

impl<const OUT: usize> WebLoopBound<OUT> {
    /// The bound of the web line under the speed PI `speed` and the tension PI `tension`
    /// (both gains 0: no tension loop). Panics unless `plant` has a web span.
    pub fn new(plant: &Plant, speed: PiGains, tension: PiGains) -> Result<Self, BoundError> {
        check_gains(&[
            ("Kp", speed.kp),
            ("Ki", speed.ki),
            ("Kp_T", tension.kp),
            ("Ki_T", tension.ki),
        ])?;
        let reduced = Reduced::web(plant, speed, tension, OUT);
        Ok(Self::build(
            &Disturbance::of_plant(plant),
            web_loop(plant, speed, tension),
            reduced,
        ))
    }
}

impl<const N: usize, const BA: usize, const KO: usize, const R: usize, const OUT: usize> LoopBound<N, BA, KO, R, OUT> {
    /// The bound of loop `a` on the response of entry `OUT` to `disturbance`, with the reduced
    /// loop for its tail.
    pub(crate) fn build(disturbance: &Disturbance<N>, a: SMatrix<f64, N, N>, reduced: Reduced) -> Self {
        let mut m = BoundMatrix::<BA>::zeros();
        m.fixed_view_mut::<N, N>(0, 0).copy_from(&a);
        m.fixed_view_mut::<N, N>(N, 0)
            .copy_from(&SMatrix::<f64, N, N>::identity());
        let mut start = BoundVector::<BA>::zeros();
        start.as_mut_slice()[..N].copy_from_slice(&disturbance.column);
        let rate = disturbance.rate.max(spectral_radius(&a));
        let len_ref = linear::PIECE_RATE / rate;
        let mut c = BoundVector::<BA>::zeros();
        c[OUT] = 1.0;
        let scale = disturbance.scale;
        let mut bound = LoopBound {
            scale,
            m,
            sparse: Sparse::new(&m),
            h_rows: SignalRows::new(c, &m, len_ref),
            start,
            state: BoundState::default(),
            sup: Err(Unbounded::Undamped),
            tail: None,
            cache: None,
            settled: false,
            reach: 0.0,
            drift_peak: 0.0,
            // Then the squares in ‖integral‖₂ stay finite, and K g ‖integral‖₂ ≤ K g √N reach
            // is below f64::MAX.
            reach_limit: (f64::MAX / (4.0 * scale)).min(1e150),
            damping: disturbance.damping,
            half_gap: disturbance.half_gap,
        };
        bound.tail = reduced.tail_bound().ok();
        bound.reset();
        bound.sup = bound.compute_sup(&reduced);
        bound.reset();
        bound
    }

    /// Back to the experiment's start (elapsed = 0).
    pub fn reset(&mut self) {
        self.state = BoundState::default();
        self.state.response.copy_from_slice(&self.start.as_slice()[..N]);
        self.settle();
    }

    /// Advances time since the start by `h` ≥ 0. On error nothing changes; `Overflow` when
    /// `bound` or `bound_paper` would not be finite after it.
    #[inline]
    pub fn advance(&mut self, h: f64) -> Result<(), BoundError> {
        if self.settled & (h > 0.0) & super::finite(h) {
            // The common case once the response has decayed. `bound` does not change, and
            // `bound_paper` cannot overflow while `reach` stays below its limit. `reach` bounds
            // every |integral_i| after the drift too, rounding being monotonic:
            // |fl(I_i + fl(r_i h))| ≤ fl(reach + fl(max|r| h)).
            let reach = self.reach + self.drift_peak * h;
            if reach <= self.reach_limit {
                self.state.integral = self.drift(h);
                self.state.elapsed += h;
                self.reach = reach;
                return Ok(());
            }
        }
        self.advance_in_general(h)
    }

    /// `settled` for the current state, and `reach` and `drift_peak` with it.
    fn settle(&mut self) {
        self.settled = self.settled_now();
        self.refresh_reach();
    }

    fn refresh_reach(&mut self) {
        let peak = |xs: &[f64; N]| xs.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
        self.reach = peak(&self.state.integral);
        self.drift_peak = peak(&self.state.response);
    }

    /// `advance` past its settled case.
    #[cold]
    #[inline(never)]
    fn advance_in_general(&mut self, h: f64) -> Result<(), BoundError> {
        let before = self.state;
        self.advance_within(h, None)?;
        if self.outputs_finite() {
            return Ok(());
        }
        let (bound, bound_paper) = (self.bound(), self.bound_paper());
        self.state = before;
        self.settle();
        Err(BoundError::Overflow { bound, bound_paper })
    }

    /// `advance`, with the sign-change searches charged to `budget` when given (else to a
    /// budget of their own). Returns how much of the growth of ∫|h| is an upper bound taken
    /// where the search gave up, beyond the net |∫h| over those spans: the most by which l1
    /// may exceed the exact ∫|h| from this advance.
    fn advance_within(&mut self, h: f64, budget: Option<&mut usize>) -> Result<f64, BoundError> {
        if !(h.is_finite() && h >= 0.0) {
            return Err(BoundError::BadAdvance { h });
        }
        if h == 0.0 {
            return Ok(0.0);
        }
        if self.settled {
            self.state.integral = self.drift(h);
            self.state.elapsed += h;
            self.refresh_reach();
            return Ok(0.0);
        }
        let len_ref = self.h_rows.len_ref();
        if h / len_ref > super::stepper::MAX_PIECES as f64 {
            return Err(BoundError::AdvanceTooLong {
                h,
                max_h: super::stepper::MAX_PIECES as f64 * len_ref,
            });
        }
        if !self.cache.as_ref().is_some_and(|c| c.h == h) {
            let pieces = (h / self.h_rows.len_ref()).ceil().max(1.0);
            let len = h / pieces;
            let phi = exp_series(&self.sparse, len);
            self.cache = Some(AdvanceCache {
                h,
                pieces: pieces as usize,
                len,
                kernel: PieceKernel::new(&phi, &self.h_rows, &self.h_rows.remainder_row(&self.m, len)),
            });
        }
        let cache = self.cache.as_ref().expect("cache was just filled");
        let mut response = self.state.response;
        let mut l1 = self.state.l1;
        let mut excess = 0.0;
        let mut own_budget = roots::work_budget(cache.pieces);
        let budget = budget.unwrap_or(&mut own_budget);
        for _ in 0..cache.pieces {
            // Each piece integrates from zero, so ∫h over it keeps full precision however large
            // the running integral has grown.
            let mut y = BoundVector::<BA>::zeros();
            y.as_mut_slice()[..N].copy_from_slice(&response);
            let mut whole_piece = Some(cache.kernel.apply(&response, OUT));
            let piece_start = if self.damping != 0.0 {
                let piece = whole_piece.as_ref().expect("just computed");
                self.state.peak = self.state.peak.max(peak_bound(piece.d, piece.c3, cache.len));
                Some((piece.d, piece.c3))
            } else {
                None
            };
            let mut done = 0.0;
            // A piece is shorter than a half period of the loop: it holds few sign changes.
            // Past `MAX_CROSSINGS`, or where the search cannot decide (h within round-off of 0
            // over much of the span), the rest of the piece adds an upper bound of ∫|h|, so
            // that `bound` stays a guarantee.
            for crossing in 0..=MAX_CROSSINGS {
                let span = cache.len - done;
                // The kernel's pass covers the piece from its start only.
                let whole = whole_piece.take();
                let before = y[N + OUT];
                let mut model = None;
                let found = if crossing < MAX_CROSSINGS {
                    let probe = whole.as_ref().map(|p| (p.d, p.c3));
                    self.sign_change(&y, span, probe, &mut model, budget)
                } else {
                    Err(Undecided)
                };
                match found {
                    Ok(None) => {
                        y = match (whole, &model) {
                            (Some(piece), _) => piece.end,
                            (None, Some(model)) => model.at(span),
                            (None, None) => TaylorModel::new(&self.sparse, &y, span).at(span),
                        };
                        l1 += (y[N + OUT] - before).abs();
                        break;
                    }
                    Ok(Some(offset)) => {
                        y = model
                            .as_ref()
                            .expect("sign changes are found on the Taylor model")
                            .at(offset);
                        // On the root: h is 0 there to round-off, and exactly 0 keeps the
                        // search on the new side from seeing the crossing again.
                        y[OUT] = 0.0;
                        l1 += (y[N + OUT] - before).abs();
                        done += offset;
                        if done >= cache.len {
                            break;
                        }
                    }
                    Err(Undecided) => {
                        let model = model.unwrap_or_else(|| TaylorModel::new(&self.sparse, &y, span));
                        y = model.at(span);
                        let net = (y[N + OUT] - before).abs();
                        let upper = roots::abs_integral_bound(&model.poly(OUT), span).max(net);
                        l1 += upper;
                        excess += upper - net;
                        break;
                    }
                }
            }
            for (total, piece) in self.state.integral.iter_mut().zip(&y.as_slice()[N..]) {
                *total += piece;
            }
            if let Some((d, c3)) = piece_start {
                self.state.variation += variation_bound(d, c3, cache.len, y[OUT] - response[OUT]);
            }
            response.copy_from_slice(&y.as_slice()[..N]);
        }
        self.state.response = response;
        self.state.l1 = l1;
        self.settle();
        self.state.elapsed += h;
        Ok(excess)
    }

    /// The first sign change of h within `span`, if any, or `Undecided`. `probe` carries
    /// [h, h′, h″] and the bound on |h‴| when the piece kernel computed them already.
    /// The Taylor model of the piece, when the search needed it, is left in `model`.
    fn sign_change(
        &self,
        y: &BoundVector<BA>,
        span: f64,
        probe: Option<([f64; 3], f64)>,
        model: &mut Option<TaylorModel<BA>>,
        budget: &mut usize,
    ) -> Result<Option<f64>, Undecided> {
        let (d, c3) = probe.unwrap_or_else(|| {
            let d = [0, 1, 2].map(|k| self.h_rows.derivative(k, y));
            (d, self.h_rows.third_bound(y, span))
        });
        // Keep to the side h is on (or, at a zero, is heading to).
        let sign = if d[0] != 0.0 {
            d[0].signum()
        } else if d[1] != 0.0 {
            d[1].signum()
        } else {
            d[2].signum()
        };
        // The smallest positive floor keeps an h that is zero to the last bit (no response
        // left) on its side, rather than searched for a sign it does not have.
        let tol = 8.0 * f64::EPSILON * (y[1].abs() + y[OUT].abs()) + f64::MIN_POSITIVE;
        let side = Side { offset: 0.0, sign, tol };
        if roots::cubic_clear(sign * d[0], sign * d[1], sign * d[2], c3, span, tol) {
            return Ok(None);
        }
        let poly = model
            .get_or_insert_with(|| TaylorModel::new(&self.sparse, y, span))
            .poly(OUT);
        roots::first_exit(&poly, side, span, budget)
    }

    /// K g ∫_0^t |h(s)| ds: a true bound on |ω_L^b − ω_L^0| [rad/s] without a damper in the
    /// compliant member; with one, the part of [`Self::damped_bound`] that the gap causes.
    pub fn bound(&self) -> f64 {
        self.scale * self.state.l1
    }

    /// `bound` on a trajectory with a damper D in the compliant member (docs/model.md §3, "With a
    /// damper"): K g ∫_0^t |h| + D max_{[0,t]} |h| V with the stepper's V
    /// ([`Trajectory::Stepped`]), or K g ∫_0^t |h| + D (max|h| (Σ|Δu| + 2 g N) + g ∫_0^t |h′|)
    /// from the phases between events ([`Trajectory::AtEvents`]). Without a damper,
    /// [`Self::bound`], whatever the trajectory.
    pub fn damped_bound(&self, trajectory: Trajectory) -> f64 {
        if self.damping == 0.0 {
            return self.bound();
        }
        let peak = self.state.peak;
        let term = match trajectory {
            Trajectory::Stepped { variation, .. } => peak * variation,
            Trajectory::AtEvents { monotone, gaps, .. } => {
                peak * (monotone + 2.0 * self.half_gap * gaps) + self.half_gap * self.state.variation
            }
        };
        self.bound() + self.damping * term
    }

    /// d/dt of [`Self::damped_bound`]: K g |h| + D max|h| |u′| while u′ counts (free, slack or
    /// capped; at events, slack or capped), and at events also D g |h′|, h′ = (A e^{A t} D_1) at
    /// the output. max|h| is bounded piece by piece: between pieces it does not move.
    pub fn damped_bound_rate(&self, trajectory: Trajectory) -> f64 {
        if self.damping == 0.0 {
            return self.bound_rate();
        }
        let term = match trajectory {
            Trajectory::Stepped { rate, .. } => self.state.peak * rate,
            Trajectory::AtEvents { rate, .. } => {
                let response = &self.state.response;
                let h_rate: f64 = (0..N).map(|j| self.m[(OUT, j)] * response[j]).sum();
                self.state.peak * rate + self.half_gap * h_rate.abs()
            }
        };
        self.bound_rate() + self.damping * term
    }

    /// max |h| over [0, elapsed], bounded from above; 0 without a damper (not tracked).
    pub fn peak(&self) -> f64 {
        self.state.peak
    }

    /// ∫ e^{As}D_1 after `h` more in the settled regime: bound is final, and what remains of
    /// e^{As}D_1 is the constant rigid-body part, so the integral grows by it linearly (the
    /// rest is below round-off).
    fn drift(&self, h: f64) -> [f64; N] {
        let mut integral = self.state.integral;
        for (total, v) in integral.iter_mut().zip(&self.state.response) {
            *total += v * h;
        }
        integral
    }

    /// Whether `bound()` and `bound_paper()` are both finite.
    fn outputs_finite(&self) -> bool {
        self.bound().is_finite() && self.bound_paper().is_finite()
    }

    /// K g ‖∫_0^t e^{A s} D_1 ds‖₂, eq. (37)/(41) as printed: not a guarantee [rad/s].
    pub fn bound_paper(&self) -> f64 {
        self.scale * self.state.integral.iter().map(|x| x * x).sum::<f64>().sqrt()
    }

    /// d bound/dt = K g |h(t)|, h = ω_L entry of e^{A t} D_1 (docs/model.md §3) [rad/s²].
    pub fn bound_rate(&self) -> f64 {
        self.scale * self.state.response[OUT].abs()
    }

    /// d bound_paper/dt = K g (I·r)/‖I‖ with I = ∫ e^{A s} D_1 ds and r = e^{A t} D_1; at I = 0
    /// (t = start) the right derivative K g ‖r‖, since I ≈ t r there [rad/s²].
    pub fn bound_paper_rate(&self) -> f64 {
        let s = &self.state;
        let norm = s.integral.iter().map(|x| x * x).sum::<f64>().sqrt();
        let rate = if norm > 0.0 {
            s.integral.iter().zip(&s.response).map(|(i, r)| i * r).sum::<f64>() / norm
        } else {
            s.response.iter().map(|x| x * x).sum::<f64>().sqrt()
        };
        self.scale * rate
    }

    /// K g ∫_0^∞ |h(s)| ds, or why it is infinite.
    pub fn sup(&self) -> Result<f64, Unbounded> {
        self.sup.map(|(value, _)| value)
    }

    /// How much `sup()` may exceed K g ∫_0^∞ |h|, relative: ≤ 1e-13 unless the integration
    /// horizon was capped (a very lightly damped loop), in which case `sup()` is a looser
    /// upper bound that stays valid.
    pub fn sup_slack(&self) -> Option<f64> {
        self.sup.ok().map(|(_, slack)| slack)
    }

    pub fn elapsed(&self) -> f64 {
        self.state.elapsed
    }

    /// The longest advance accepted in one call (longer ones are refused with
    /// `AdvanceTooLong`).
    pub fn max_advance(&self) -> f64 {
        super::stepper::MAX_PIECES as f64 * self.h_rows.len_ref()
    }

    pub fn state(&self) -> BoundState<N> {
        self.state
    }

    /// Restores a saved state (validated: finite, elapsed ≥ 0, l1 ≥ 0).
    pub fn restore(&mut self, state: &BoundState<N>) -> Result<(), BoundError> {
        let finite = state
            .response
            .iter()
            .chain(state.integral.iter())
            .all(|x| x.is_finite());
        let non_negative = |x: f64| x.is_finite() && x >= 0.0;
        if !(finite
            && non_negative(state.elapsed)
            && non_negative(state.l1)
            && non_negative(state.peak)
            && non_negative(state.variation))
        {
            return Err(BoundError::BadState);
        }
        self.state = *state;
        self.settle();
        Ok(())
    }

    /// ∫_0^∞ |h|: integrate until a bound on the tail is below `SUP_TOLERANCE` of the sum,
    /// and return the sum plus that tail: an upper bound, tight to the returned slack. The work
    /// is capped at `SUP_MAX_PIECES` pieces; past it the slack says how loose the value is.
    fn compute_sup(&mut self, reduced: &Reduced) -> Result<(f64, f64), Unbounded> {
        let tail = match &self.tail {
            Some(tail) => tail.clone(),
            None => return Err(reduced.tail_bound::<N, R>().err().unwrap_or(Unbounded::Undamped)),
        };
        let chunk = SUP_CHECK_PIECES as f64 * self.h_rows.len_ref();
        let mut pieces = 0;
        // One budget for all searches: where h hovers at 0 they give up, and the sum takes
        // upper bounds of ∫|h| there (counted in the slack) rather than searching on.
        let mut budget = roots::work_budget(roots::SEARCH_PIECES);
        let mut excess = 0.0;
        loop {
            let rest = tail.of(&self.state.response);
            let l1 = self.state.l1;
            let done = rest <= SUP_TOLERANCE * l1 || pieces >= SUP_MAX_PIECES;
            match (!done).then(|| self.advance_within(chunk, Some(&mut budget))) {
                Some(Ok(more)) => excess += more,
                _ => return Ok((self.scale * (l1 + rest), (rest + excess) / l1)),
            }
            pieces += SUP_CHECK_PIECES;
        }
    }

    /// True once what is left of ∫|h| cannot change `bound` in double precision: the response
    /// has decayed for good, and stepping it on would only walk it into subnormal numbers.
    fn settled_now(&self) -> bool {
        self.tail
            .as_ref()
            .is_some_and(|t| t.at_most(&self.state.response, SETTLED * self.state.l1))
    }
}

/// ∫_t^∞ |h| below this fraction of ∫_0^t |h| is below half an ulp of it.
const SETTLED: f64 = 1.0 / (1u64 << 60) as f64;
/// bound_sup is returned within this relative slack when the work cap allows.
const SUP_TOLERANCE: f64 = 1e-13;
const SUP_CHECK_PIECES: usize = 256;
const SUP_MAX_PIECES: usize = 1 << 21;
