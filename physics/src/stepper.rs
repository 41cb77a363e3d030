//! Exact stepping between contact switches (docs/model.md §2).

use super::kernel::KernelColumn;
use super::linear::{self, AugMatrix, AugVector, AUG, WEB_AUG};
use super::mode::{ContactMode, PlantState};
use super::params::{ContactLaw, Plant};
use super::roots::{self, Side, SignalRows};
use super::taylor::{exp_series, PieceModel, Sparse};
use thiserror::Error;

mod damped;
mod sliding;

pub use sliding::{SlidingDriveStepper, SlidingWebStepper};

/// Inputs over one step: values at the step start and their slopes over the step.
/// Slopes are 0 for a zero-order hold (FMI 2 CS default); non-zero for first-order hold.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inputs {
    /// Motor torque τ_m at the step start [N·m].
    pub tau_m: f64,
    /// Load torque τ_L at the step start [N·m].
    pub tau_l: f64,
    /// dτ_m/dt over the step [N·m/s].
    pub dtau_m: f64,
    /// dτ_L/dt over the step [N·m/s].
    pub dtau_l: f64,
    /// The web span's forcing by the upstream web at the step start, w = (v_ref T_in −
    /// EA v_in)/L_w [N/s] ([`super::WebSpan::forcing`]); unused without a web.
    pub span: f64,
    /// dw/dt over the step [N/s²].
    pub dspan: f64,
}

impl Inputs {
    pub const fn held(tau_m: f64, tau_l: f64) -> Inputs {
        Inputs {
            tau_m,
            tau_l,
            dtau_m: 0.0,
            dtau_l: 0.0,
            span: 0.0,
            dspan: 0.0,
        }
    }
}

/// A contact switch located inside a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwitchEvent {
    /// Time since the start of the step [s].
    pub offset: f64,
    pub from: ContactMode,
    pub to: ContactMode,
}

#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum StepError {
    #[error("step size {h} must be finite and > 0")]
    BadStepSize { h: f64 },
    #[error("input {name} = {value} must be finite")]
    NonFiniteInput { name: &'static str, value: f64 },
    #[error("state is not finite")]
    NonFiniteState,
    #[error("the step overflowed: the state would not be finite at its end")]
    Overflow,
    #[error("more than {limit} contact switches in one step of {h} s")]
    TooManySwitches { limit: usize, h: f64 },
    #[error("a step of {h} s spans more than {MAX_PIECES} periods of the plant's fastest motion; take steps of at most {max_h:e} s")]
    StepTooLong { h: f64, max_h: f64 },
}

/// Most pieces one step may be cut into (bounds the work of a step: about 0.1 s of CPU).
pub const MAX_PIECES: usize = 1 << 20;

/// Longest admissible step, in periods of the undamped contact oscillation.
pub const MAX_PERIODS_PER_STEP: f64 = 1e4;

/// The largest admissible step [s]: [`MAX_PERIODS_PER_STEP`] periods of the undamped contact
/// oscillation (see [`Plant::contact_frequency`]); finite, so that a step no longer than it is.
pub fn max_step(plant: &Plant) -> f64 {
    (MAX_PERIODS_PER_STEP * 2.0 * std::f64::consts::PI / plant.contact_frequency()).min(f64::MAX)
}

/// One contact mode: its augmented matrix and the derivative rows of u along it.
#[derive(Clone, Debug)]
struct ModeDynamics<const N: usize> {
    m: AugMatrix<N>,
    sparse: Sparse<N>,
    u_rows: SignalRows<N>,
}

/// Everything a whole piece in one mode needs, fused into one pass over the augmented state:
/// outputs 0–4 are e^{M len} y restricted to [u, ω_m, ω_L, δθ_m, δθ_L], 5–6 are u″ and u‴ at
/// the piece start, and 7 is `remainder`·|y|, which bounds how far u‴ moves over the piece;
/// with a web span, output 8 is T at the piece end (and 9 pads the column to whole vectors).
/// A stepper of a plant with Coulomb friction has four outputs more, each body's ω′ at the piece
/// start and a bound on its |ω‴| over the piece (`sliding.rs`). Stored by column, `KO` outputs wide, so that the pass
/// vectorizes across the outputs.
#[derive(Clone, Debug)]
struct PieceKernel<const N: usize, const KO: usize> {
    cols: [KernelColumn<KO>; N],
}

/// The output that takes |y|: the growth bound of u‴.
const GROWTH_ROW: usize = 7;
/// The output that carries T with a web span.
const TENSION_ROW: usize = 8;

/// The end of a piece: [u, v, ω_L, δθ_m, δθ_L] in the order of `linear`, then T (with a web
/// span; else unused).
type PieceEnd = [f64; 6];

/// The web span's entries at a piece start, [T, w, ẇ] (unused without one).
type SpanEntries = [f64; 3];

impl<const N: usize, const KO: usize> PieceKernel<N, KO> {
    /// The first output past the frictionless ones: the speeds' bounds, when `KO` has them.
    const SPEED_ROW: usize = if N == WEB_AUG { 10 } else { 8 };
    /// The kernel carries the speeds' bounds (a stepper of the sliding plant).
    const SLIDING: bool = KO > Self::SPEED_ROW;

    /// `speed`: the speeds' rows (used only when `KO` has them).
    fn new(phi: &AugMatrix<N>, u_rows: &SignalRows<N>, remainder: &AugVector<N>, speed: &[AugVector<N>; 4]) -> Self {
        PieceKernel {
            cols: KernelColumn::table(|r, j| match r {
                0..=4 => phi[(r, j)],
                5 => u_rows.row(2)[j],
                6 => u_rows.row(3)[j],
                GROWTH_ROW => remainder[j],
                TENSION_ROW if N == WEB_AUG => phi[(linear::TENSION, j)],
                r if r >= Self::SPEED_ROW => speed[r - Self::SPEED_ROW][j],
                _ if N == WEB_AUG => 0.0,
                _ => unreachable!("KO rows"),
            }),
        }
    }

    /// Column U times u: the first term of the sums. |u| in the growth bounds' rows (u‴'s, and
    /// with the speeds' rows their bounds).
    #[inline(always)]
    fn first(&self, u: f64) -> [f64; KO] {
        match Self::SLIDING {
            true => self.cols[linear::U].product_by(KernelColumn::multipliers_from(u, GROWTH_ROW, Self::SPEED_ROW + 2)),
            false => self.cols[linear::U].product(u, GROWTH_ROW),
        }
    }

    /// `acc +=` column `j` times x, as `first`.
    #[inline(always)]
    fn add(&self, acc: &mut [f64; KO], j: usize, x: f64) {
        match Self::SLIDING {
            true => self.cols[j].accumulate_by(acc, KernelColumn::multipliers_from(x, GROWTH_ROW, Self::SPEED_ROW + 2)),
            false => self.cols[j].accumulate(acc, x, GROWTH_ROW),
        }
    }

    /// (propagated [u, ω_m, ω_L, δθ_m, δθ_L, T], u″, bound on sup |u‴| over the piece).
    /// The sums out of line: see `sums`.
    #[inline(always)]
    fn apply(&self, y: &AugVector<N>) -> (PieceEnd, f64, f64) {
        use linear::*;
        debug_assert!(y[DTHETA_M] == 0.0 && y[DTHETA_L] == 0.0 && y[ONE] == 1.0);
        let [u, v, w, tm, tl, dtm, dtl] = [U, V, OMEGA_L, TAU_M, TAU_L, DTAU_M, DTAU_L].map(|j| y[j]);
        let span = if N == WEB_AUG {
            [TENSION, SPAN, DSPAN].map(|j| y[j])
        } else {
            [0.0; 3]
        };
        Self::split(self.sums(u, v, w, tm, tl, dtm, dtl, span))
    }

    /// `apply` at the start of a step from `state` under `inputs`, with the sums inlined:
    /// for the one-piece step, where there is no loop to hoist the coefficients out of. Also
    /// the speeds' bounds, when the kernel has them (else 0). `at` is the state's (u, u′, ω_L)
    /// ([`StepStart`]). The sums stay in registers: kept whole in memory (a `black_box` of
    /// them), the outputs read back from there spanned two of its stores, the stall
    /// `StepStart` avoids.
    #[inline(always)]
    fn apply_at_start(&self, state: &PlantState, at: &StepStart, inputs: &Inputs) -> (PieceEnd, f64, f64, [f64; 4]) {
        let i = inputs;
        let span = [state.tension, i.span, i.dspan];
        let acc = self.sums_inline(at.u, at.du, at.omega_l, i.tau_m, i.tau_l, i.dtau_m, i.dtau_l, span);
        let speed = match Self::SLIDING {
            true => std::array::from_fn(|r| acc[Self::SPEED_ROW + r]),
            false => [0.0; 4],
        };
        let (whole, d2, c3) = Self::split(acc);
        (whole, d2, c3, speed)
    }

    #[inline(always)]
    fn split(acc: [f64; KO]) -> (PieceEnd, f64, f64) {
        let tension = if N == WEB_AUG { acc[TENSION_ROW] } else { 0.0 };
        (
            [acc[0], acc[1], acc[2], acc[3], acc[4], tension],
            acc[5],
            acc[6].abs() + acc[GROWTH_ROW],
        )
    }

    /// `sums_inline`, not inlined: inlined into the piece loop, its 80 coefficients get
    /// hoisted out of it and spilled to the stack.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    fn sums(&self, u: f64, v: f64, w: f64, tm: f64, tl: f64, dtm: f64, dtl: f64, span: SpanEntries) -> [f64; KO] {
        self.sums_inline(u, v, w, tm, tl, dtm, dtl, span)
    }

    /// The `KO` column sums at a piece start y = [u, v, ω_L, 0, 0, τ_m, τ_L, 1, τ̇_m, τ̇_L]
    /// and, with a web span, [T, w, ẇ] = `span` (the angle increments are zero there: their
    /// columns drop out), in the column order of `linear`. The entries come as scalars, in
    /// registers: read back from a vector just stored, they would stall on store forwarding.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn sums_inline(
        &self,
        u: f64,
        v: f64,
        w: f64,
        tm: f64,
        tl: f64,
        dtm: f64,
        dtl: f64,
        span: SpanEntries,
    ) -> [f64; KO] {
        use linear::*;
        // The first product rather than zeros plus it (the same but for a zero's sign); then a
        // loop over the columns rather than one call per column: unrolled after it is
        // vectorized, it keeps each column's outputs together in vector registers.
        let mut acc = self.first(u);
        for (j, yj) in [(V, v), (OMEGA_L, w), (TAU_M, tm), (TAU_L, tl), (ONE, 1.0)] {
            self.add(&mut acc, j, yj);
        }
        // Zero under a zero-order hold: skipped (the sums are the same but for a zero's sign).
        if !((dtm == 0.0) & (dtl == 0.0)) {
            for (j, yj) in [(DTAU_M, dtm), (DTAU_L, dtl)] {
                self.add(&mut acc, j, yj);
            }
        }
        if N == WEB_AUG {
            let [t, w, dw] = span;
            for (j, yj) in [(TENSION, t), (SPAN, w), (DSPAN, dw)] {
                self.add(&mut acc, j, yj);
            }
        }
        acc
    }
}

/// The entries of a state that a quiet step's kernel and test read: u, u′ and ω_L, each loaded by
/// itself. The step before stored the state with stores whose widths the compiler picks (two
/// fields in one 16-byte store, or one alone); a 16-byte load of two fields that spans two such
/// stores cannot take its value from the store buffer and waits until both have reached the
/// cache, on the path from one step's state to the next. Loaded alone (`black_box` of each), a
/// field always lies within one store. With the sums kept in registers (`apply_at_start`), the
/// event-free fmi2DoStep went from 21.5–22.6 ns to 18.8–19.4 ns (native_host suite, four runs
/// of each build in turn, AMD EPYC family 26) although it executes 457 instructions instead of
/// 416 (callgrind).
struct StepStart {
    u: f64,
    du: f64,
    omega_l: f64,
}

impl StepStart {
    #[inline(always)]
    fn of(state: &PlantState) -> StepStart {
        use std::hint::black_box as alone;
        StepStart {
            u: alone(state.u),
            du: alone(state.du),
            omega_l: alone(state.omega_l),
        }
    }
}

/// Exponentials for the current step size: the step is cut into `pieces` of length `len`.
#[derive(Clone, Debug)]
struct StepCache<const N: usize, const KO: usize> {
    h: f64,
    pieces: usize,
    len: f64,
    /// By [`ContactMode::index`]; a mode the plant never enters (the damper's, without one)
    /// holds a copy of the free mode's.
    kernel: [PieceKernel<N, KO>; 7],
}

/// The exact stepper of a plant with an augmented state of `N` entries (`linear::AUG`, or
/// `linear::WEB_AUG` with a web span) and `KO` kernel outputs; [`Stepper`] picks one.
#[derive(Clone, Debug)]
pub struct Exact<const N: usize, const KO: usize> {
    plant: Plant,
    /// D of the compliant member: 0 for the paper's plant, whose three modes switch on u = ±g
    /// alone; > 0 adds the slack and (law 1) capped modes and their surfaces (`damper.rs`).
    damping: f64,
    /// Law 1 (`ElastoBacklash`) with a damper: the cap's surfaces too.
    law1: bool,
    modes: [ModeDynamics<N>; 7],
    /// Longest piece [s]: PIECE_RATE over the fastest rate of the plant.
    len_ref: f64,
    /// Longest step: `MAX_PIECES` pieces.
    max_h: f64,
    cache: Option<StepCache<N, KO>>,
}

/// The drive train alone: 10 augmented entries, 8 kernel outputs.
pub type DriveStepper = Exact<AUG, 8>;
/// The drive train pulling a web span: 13 augmented entries, 10 kernel outputs.
pub type WebStepper = Exact<WEB_AUG, 10>;

/// Advances the plant exactly (docs/model.md §2), with or without a web span. Holds the
/// exponentials for the current step size; they are recomputed only when the step size changes.
// The drive train's stepper stays inline, out of reach of an indirection on the hot path of
// every step; the web line's, larger still, is boxed.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Stepper {
    Drive(DriveStepper),
    Web(Box<WebStepper>),
}

impl Stepper {
    pub fn new(plant: Plant) -> Stepper {
        if plant.web().is_some() {
            Stepper::Web(Box::new(Exact::new(plant)))
        } else {
            Stepper::Drive(Exact::new(plant))
        }
    }

    pub fn plant(&self) -> &Plant {
        match self {
            Stepper::Drive(s) => s.plant(),
            Stepper::Web(s) => s.plant(),
        }
    }

    /// Advances `state` over [t, t+h] with `inputs` (values at t, slopes over the step),
    /// calling `on_switch` for every contact switch in time order. Returns the number of
    /// switches. On error `state` is left unchanged.
    pub fn step(
        &mut self,
        state: &mut PlantState,
        inputs: &Inputs,
        h: f64,
        on_switch: &mut dyn FnMut(SwitchEvent),
    ) -> Result<usize, StepError> {
        match self {
            Stepper::Drive(s) => s.step(state, inputs, h, on_switch),
            Stepper::Web(s) => s.step(state, inputs, h, on_switch),
        }
    }

    /// As [`Stepper::step`], but stops at the first contact switch inside the step: `state` is
    /// then the state at the switch (u exactly on ±g, the mode entered) and the returned offset
    /// is the switch instant from the step start, located to round-off. None: no switch, the
    /// whole step was taken.
    pub fn step_to_first_switch(
        &mut self,
        state: &mut PlantState,
        inputs: &Inputs,
        h: f64,
        on_switch: &mut dyn FnMut(SwitchEvent),
    ) -> Result<Option<f64>, StepError> {
        match self {
            Stepper::Drive(s) => s.step_to_first_switch(state, inputs, h, on_switch),
            Stepper::Web(s) => s.step_to_first_switch(state, inputs, h, on_switch),
        }
    }

    /// The step of a co-simulation in the common case, with nothing to locate: `h` is the
    /// step size `step` last took and one piece long, and the piece is certified free of
    /// switches. Returns the state at its end if it is finite; else `None`, and `step` does
    /// the step (or says why not). `state` must be finite.
    ///
    /// Contract: a state it returns is bit for bit the one `step` gives, but for the sign of a
    /// zero. It is `step`'s one-piece path by construction: the same cached kernel summed by
    /// the same `PieceKernel::sums_inline` (which `step` reaches through `sums`) over the same
    /// operands in the same order, then the same `clear` and `finish_piece`; IEEE arithmetic
    /// without contraction gives the same bits on any machine, inlined or not. The one
    /// difference: `step` forms the inputs at the piece start as τ + τ̇·0, which is τ but for
    /// the sign of a zero.
    #[inline]
    pub fn quiet_step(&self, state: &PlantState, inputs: &Inputs, h: f64) -> Option<PlantState> {
        match self {
            Stepper::Drive(s) => s.quiet_step(state, inputs, h),
            Stepper::Web(s) => s.quiet_step(state, inputs, h),
        }
    }

    /// The `order`-th time derivative (order ≥ 1) of [θ_m, ω_m, θ_L, ω_L, T] at `state` under the
    /// mode in force (at a switch instant: the mode being entered, i.e. the right derivative);
    /// T's is 0 without a web span.
    pub fn time_derivative(&self, state: &PlantState, inputs: &Inputs, order: u32) -> [f64; 5] {
        match self {
            Stepper::Drive(s) => s.time_derivative(state, inputs, order),
            Stepper::Web(s) => s.time_derivative(state, inputs, order),
        }
    }
}

/// How a step ended: the switches located, and where it stopped if it stopped at one.
struct StepEnd {
    switches: usize,
    stopped_at: Option<f64>,
}

/// The exit from the mode in force: when it happens and what follows.
#[derive(Clone, Copy, Debug)]
struct Exit {
    offset: f64,
    to: ContactMode,
    /// u on the crossed threshold (±g), exactly, when the surface is one; else None.
    u: Option<f64>,
    /// With a damper, on a surface of the force (τ_c + τ_d = 0, τ_c = τ_d): u′ there, from u.
    du: Option<f64>,
}

impl<const N: usize, const KO: usize> Exact<N, KO> {
    pub fn new(plant: Plant) -> Self {
        let rate = linear::fastest_rate(&plant);
        let len_ref = if rate > 0.0 {
            linear::PIECE_RATE / rate
        } else {
            f64::INFINITY
        };
        let mut e_u = AugVector::<N>::zeros();
        e_u[linear::U] = 1.0;
        let dynamics = |mode: ContactMode| {
            let m = linear::mode_matrix(&plant, mode);
            ModeDynamics {
                m,
                sparse: Sparse::new(&m),
                u_rows: SignalRows::new(e_u, &m, len_ref),
            }
        };
        // Without a damper its four modes are never entered: they hold the free mode's
        // dynamics (as `fill_cache` holds its kernel), not built for nothing.
        let free = dynamics(ContactMode::Free);
        let modes = ContactMode::ALL.map(|mode| match (mode.index() < 3, plant.damping() > 0.0) {
            (true, _) | (false, true) if mode != ContactMode::Free => dynamics(mode),
            _ => free.clone(),
        });
        Exact {
            plant,
            damping: plant.damping(),
            law1: plant.damping() > 0.0 && plant.contact_law() == ContactLaw::ElastoBacklash,
            modes,
            len_ref,
            max_h: MAX_PIECES as f64 * len_ref,
            cache: None,
        }
    }

    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// Makes `h` the step size of the quiet path, when `step` accepts it: for a stepper whose
    /// plant another one steps in general (the sliding stepper's, by the chain).
    pub fn prepare(&mut self, h: f64) {
        if h.is_finite() && h > 0.0 && h <= self.max_h {
            self.ensure_cache(h);
        }
    }

    #[inline(always)]
    fn ensure_cache(&mut self, h: f64) {
        if !self.cache.as_ref().is_some_and(|c| c.h == h) {
            self.fill_cache(h);
        }
    }

    #[cold]
    #[inline(never)]
    fn fill_cache(&mut self, h: f64) {
        let pieces = if self.len_ref.is_finite() {
            (h / self.len_ref).ceil().max(1.0)
        } else {
            1.0
        };
        let len = h / pieces;
        let kernel_of = |i: usize| {
            let ModeDynamics { m, sparse, u_rows } = &self.modes[i];
            let phi = exp_series(sparse, len);
            let speed = match PieceKernel::<N, KO>::SLIDING {
                true => sliding::speed_bound_rows(&self.plant, m, &phi, len),
                false => [AugVector::<N>::zeros(); 4],
            };
            PieceKernel::new(&phi, u_rows, &u_rows.remainder_row(m, len), &speed)
        };
        let paper = [0, 1, 2].map(kernel_of);
        let free = ContactMode::Free.index();
        let kernel = std::array::from_fn(|i| match (i < 3, self.damping > 0.0) {
            (true, _) => paper[i].clone(),
            (false, true) => kernel_of(i),
            (false, false) => paper[free].clone(),
        });
        self.cache = Some(StepCache {
            h,
            pieces: pieces as usize,
            len,
            kernel,
        });
    }

    /// [`Stepper::step`].
    pub fn step(
        &mut self,
        state: &mut PlantState,
        inputs: &Inputs,
        h: f64,
        on_switch: &mut dyn FnMut(SwitchEvent),
    ) -> Result<usize, StepError> {
        self.step_until(state, inputs, h, on_switch, false)
            .map(|end| end.switches)
    }

    /// [`Stepper::step_to_first_switch`].
    pub fn step_to_first_switch(
        &mut self,
        state: &mut PlantState,
        inputs: &Inputs,
        h: f64,
        on_switch: &mut dyn FnMut(SwitchEvent),
    ) -> Result<Option<f64>, StepError> {
        self.step_until(state, inputs, h, on_switch, true)
            .map(|end| end.stopped_at)
    }

    #[inline(always)]
    fn step_until(
        &mut self,
        state: &mut PlantState,
        inputs: &Inputs,
        h: f64,
        on_switch: &mut dyn FnMut(SwitchEvent),
        stop_at_switch: bool,
    ) -> Result<StepEnd, StepError> {
        // One branch for the common case (non-short-circuit `&`); the reason is sorted out
        // only when it fails.
        let finite = h.is_finite()
            & inputs.tau_m.is_finite()
            & inputs.tau_l.is_finite()
            & inputs.dtau_m.is_finite()
            & inputs.dtau_l.is_finite()
            & (N != WEB_AUG || (inputs.span.is_finite() & inputs.dspan.is_finite()))
            & state.is_finite();
        if !(finite & (h > 0.0) & (h <= self.max_h)) {
            return Err(self.refusal(state, inputs, h));
        }
        self.ensure_cache(h);
        let cache = self.cache.as_ref().expect("cache was just filled");
        // The common case, kept small so that it stays in registers: every piece is certified
        // free of switches by one fused pass. The first piece that is not goes to `step_from`.
        let mut next = *state;
        let kernel = &cache.kernel[next.mode.index()];
        for piece in 0..cache.pieces {
            let y = augmented(&next, inputs, piece as f64 * cache.len);
            let (whole, d2, c3) = kernel.apply(&y);
            if !self.clear(next.mode, y[linear::U], y[linear::V], d2, c3, cache.len) {
                return self.step_from(piece, next, state, inputs, h, on_switch, stop_at_switch);
            }
            if self.damping != 0.0 && !next.mode.in_contact() {
                next.variation += self.variation(next.mode, &y, d2, c3, cache.len, whole[linear::U]);
            }
            self.finish_piece(&mut next, &whole);
        }
        if !next.is_finite() {
            return Err(StepError::Overflow);
        }
        *state = next;
        Ok(StepEnd {
            switches: 0,
            stopped_at: None,
        })
    }

    /// [`Stepper::quiet_step`]. Its body is `quiet_step_with`'s without the extra test, written
    /// out: as a call of `quiet_step_with(.., |_, _, _| true)` the frictionless step copied the
    /// state's padding through the stack and took 49 ns instead of 40 per event-free fmi2DoStep
    /// (measured); out of line, 52.
    #[inline(always)]
    pub fn quiet_step(&self, state: &PlantState, inputs: &Inputs, h: f64) -> Option<PlantState> {
        debug_assert!(state.is_finite());
        // The cache holds only step sizes `step` accepted, so h is finite, > 0 and short enough.
        let cache = self.cache.as_ref().filter(|c| c.h == h && c.pieces == 1)?;
        let at = StepStart::of(state);
        let (whole, d2, c3, _) = cache.kernel[state.mode.index()].apply_at_start(state, &at, inputs);
        // Non-finite inputs make u″ or c3 NaN or infinite, which fails the test.
        if !self.clear(state.mode, at.u, at.du, d2, c3, cache.len) {
            return None;
        }
        let mut next = *state;
        if self.damping != 0.0 && !state.mode.in_contact() {
            let y = augmented(state, inputs, 0.0);
            next.variation += self.variation(state.mode, &y, d2, c3, cache.len, whole[linear::U]);
        }
        self.finish_piece(&mut next, &whole);
        // Finite when the sum of its fields is (a NaN or ∞ field makes the sum NaN or ∞);
        // the sum of finite fields that overflows leaves the step to `step`.
        let mut sum = next.theta_m + next.omega_m + next.theta_l + next.omega_l + next.u + next.du;
        if N == WEB_AUG {
            sum += next.tension;
        }
        super::finite(sum).then_some(next)
    }

    /// [`Stepper::quiet_step`], also refused unless `accept(start, end state, speeds' outputs,
    /// piece length)` (the speeds' outputs are 0 unless the kernel has them).
    #[inline(always)]
    fn quiet_step_with(
        &self,
        state: &PlantState,
        inputs: &Inputs,
        h: f64,
        accept: impl FnOnce(&StepStart, &PlantState, [f64; 4], f64) -> bool,
    ) -> Option<PlantState> {
        debug_assert!(state.is_finite());
        // The cache holds only step sizes `step` accepted, so h is finite, > 0 and short enough.
        let cache = self.cache.as_ref().filter(|c| c.h == h && c.pieces == 1)?;
        let at = StepStart::of(state);
        let (whole, d2, c3, speed) = cache.kernel[state.mode.index()].apply_at_start(state, &at, inputs);
        // Non-finite inputs make u″ or c3 NaN or infinite, which fails the test.
        if !self.clear(state.mode, at.u, at.du, d2, c3, cache.len) {
            return None;
        }
        let mut next = *state;
        if self.damping != 0.0 && !state.mode.in_contact() {
            let y = augmented(state, inputs, 0.0);
            next.variation += self.variation(state.mode, &y, d2, c3, cache.len, whole[linear::U]);
        }
        self.finish_piece(&mut next, &whole);
        // Finite when the sum of its fields is (a NaN or ∞ field makes the sum NaN or ∞);
        // the sum of finite fields that overflows leaves the step to `step`.
        let mut sum = next.theta_m + next.omega_m + next.theta_l + next.omega_l + next.u + next.du;
        if N == WEB_AUG {
            sum += next.tension;
        }
        // One exit (non-short-circuit `&`).
        (super::finite(sum) & accept(&at, &next, speed, cache.len)).then_some(next)
    }

    /// Why `step` refuses its arguments (called only when it does).
    #[cold]
    #[inline(never)]
    fn refusal(&self, state: &PlantState, inputs: &Inputs, h: f64) -> StepError {
        if !(h.is_finite() && h > 0.0) {
            return StepError::BadStepSize { h };
        }
        let named = [
            ("tau_m", inputs.tau_m),
            ("tau_L", inputs.tau_l),
            ("der(tau_m)", inputs.dtau_m),
            ("der(tau_L)", inputs.dtau_l),
            ("the web span's forcing w", inputs.span),
            ("der(w)", inputs.dspan),
        ];
        // The span's forcing is an input of the web line only: the drive train ignores it.
        let inputs_used = if N == WEB_AUG { &named[..] } else { &named[..4] };
        if let Some(&(name, value)) = inputs_used.iter().find(|(_, v)| !v.is_finite()) {
            return StepError::NonFiniteInput { name, value };
        }
        if !state.is_finite() {
            return StepError::NonFiniteState;
        }
        StepError::StepTooLong { h, max_h: self.max_h }
    }

    /// The rest of `step` from the start of `first` (the state there is `next`), for a step
    /// in which some piece may hold a switch.
    #[cold]
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    fn step_from(
        &self,
        first: usize,
        mut next: PlantState,
        state: &mut PlantState,
        inputs: &Inputs,
        h: f64,
        on_switch: &mut dyn FnMut(SwitchEvent),
        stop_at_switch: bool,
    ) -> Result<StepEnd, StepError> {
        let cache = self.cache.as_ref().expect("`step` filled the cache");
        let (pieces, len) = (cache.pieces, cache.len);
        let switch_limit = 64 + 16 * pieces;
        let mut budget = roots::work_budget(pieces);
        let mut switches = 0;
        let mut model = PieceModel::new();
        for piece in first..pieces {
            // Pieces all have length `len`; the last ends on h to round-off of the time grid.
            let start = piece as f64 * len;
            let mut y = augmented(&next, inputs, start);
            let (whole, d2, c3) = cache.kernel[next.mode.index()].apply(&y);
            if self.clear(next.mode, y[linear::U], y[linear::V], d2, c3, len) {
                // No switch in this piece: one fused pass did all the work.
                if self.damping != 0.0 {
                    next.variation += self.variation(next.mode, &y, d2, c3, len, whole[linear::U]);
                }
                self.finish_piece(&mut next, &whole);
                continue;
            }
            let mut probe = Some((d2, c3));
            let mut t = start;
            let mut switched = false;
            loop {
                let span = len - (t - start);
                let mode = next.mode.index();
                model.clear();
                let start_y = y;
                let probed = probe;
                match self.exit(&y, next.mode, span, probe.take(), &mut model, &mut budget) {
                    None if !switched => {
                        set_piece_end(&mut y, &whole);
                        if self.damping != 0.0 {
                            next.variation += self.sub_variation(next.mode, &start_y, probed, span, y[linear::U]);
                        }
                        break;
                    }
                    None => {
                        let sparse = &self.modes[mode].sparse;
                        y = model.get_or_expand(sparse, &y, span).at(span);
                        if self.damping != 0.0 {
                            next.variation += self.sub_variation(next.mode, &start_y, None, span, y[linear::U]);
                        }
                        break;
                    }
                    Some(exit) => {
                        y = model
                            .get()
                            .expect("exits are found on the Taylor model")
                            .at(exit.offset);
                        if self.damping != 0.0 {
                            let end_u = exit.u.unwrap_or(y[linear::U]);
                            let probed = if exit.offset == span { probed } else { None };
                            next.variation += self.sub_variation(next.mode, &start_y, probed, exit.offset, end_u);
                        }
                        if let Some(u) = exit.u {
                            y[linear::U] = u;
                        }
                        if let Some(du) = exit.du {
                            y[linear::V] = du;
                        }
                        t += exit.offset;
                        switched = true;
                        // Inputs are functions of time: re-evaluate rather than carry round-off.
                        y[linear::TAU_M] = inputs.tau_m + inputs.dtau_m * t;
                        y[linear::TAU_L] = inputs.tau_l + inputs.dtau_l * t;
                        if N == WEB_AUG {
                            y[linear::SPAN] = inputs.span + inputs.dspan * t;
                        }
                        on_switch(SwitchEvent {
                            offset: t,
                            from: next.mode,
                            to: exit.to,
                        });
                        next.mode = exit.to;
                        switches += 1;
                        if stop_at_switch {
                            self.finish_piece(&mut next, &piece_end(&y));
                            if !next.is_finite() {
                                return Err(StepError::Overflow);
                            }
                            *state = next;
                            return Ok(StepEnd {
                                switches,
                                stopped_at: Some(t),
                            });
                        }
                        if switches > switch_limit {
                            return Err(StepError::TooManySwitches { limit: switch_limit, h });
                        }
                        if t - start >= len {
                            break;
                        }
                    }
                }
            }
            self.finish_piece(&mut next, &piece_end(&y));
        }
        if !next.is_finite() {
            return Err(StepError::Overflow);
        }
        *state = next;
        Ok(StepEnd {
            switches,
            stopped_at: None,
        })
    }

    /// True when u cannot leave `mode`'s region within `span`, given u, u′, u″ and the bound c3
    /// on |u‴|.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn clear(&self, mode: ContactMode, u: f64, du: f64, d2: f64, c3: f64, span: f64) -> bool {
        if self.damping != 0.0 {
            return self.clear_damped(mode, u, du, d2, c3, span);
        }
        let g = self.plant.half_gap();
        if g == 0.0 {
            return true;
        }
        let tol = 8.0 * f64::EPSILON * (u.abs() + g);
        // The cheap test of `roots::cubic_clear` for each threshold, its drop computed once:
        // it is the same on both sides.
        let drop = roots::largest_drop(du, d2, c3, span);
        let clear = match mode {
            ContactMode::Free => (g - u - drop > -tol) & (g + u - drop > -tol),
            ContactMode::Positive => u - g - drop > -tol,
            ContactMode::Negative => -u - g - drop > -tol,
            _ => unreachable!("the damper's modes need a damper"),
        };
        clear || self.clear_exactly(mode, u, du, d2, c3, span, tol)
    }

    /// `clear` past its cheap test.
    #[allow(clippy::too_many_arguments)]
    #[cold]
    #[inline(never)]
    fn clear_exactly(&self, mode: ContactMode, u: f64, du: f64, d2: f64, c3: f64, span: f64, tol: f64) -> bool {
        let g = self.plant.half_gap();
        let side_clear = |f0: f64, sign: f64| roots::cubic_clear(f0, sign * du, sign * d2, c3, span, tol);
        match mode {
            ContactMode::Free => side_clear(g - u, -1.0) && side_clear(g + u, 1.0),
            ContactMode::Positive => side_clear(u - g, 1.0),
            ContactMode::Negative => side_clear(-u - g, -1.0),
            _ => unreachable!("the damper's modes need a damper"),
        }
    }

    /// The first exit from `mode` within `span` after the state `y`, if any.
    /// `probe` carries u″ and the bound on |u‴| when the piece kernel computed them already.
    /// The Taylor model of the piece, when the search needed it, is left in `model`.
    fn exit(
        &self,
        y: &AugVector<N>,
        mode: ContactMode,
        span: f64,
        probe: Option<(f64, f64)>,
        model: &mut PieceModel<N>,
        budget: &mut usize,
    ) -> Option<Exit> {
        if self.damping != 0.0 {
            return self.exit_damped(y, mode, span, probe, model, budget);
        }
        let g = self.plant.half_gap();
        if g == 0.0 {
            // No free region: both flanks carry ψ = K u, the plant is linear.
            return None;
        }
        let rows = &self.modes[mode.index()].u_rows;
        let u = y[linear::U];
        // Round-off floor of u ∓ g: a few ulps of the larger of |u| and g.
        let tol = 8.0 * f64::EPSILON * (u.abs() + g);
        let up = (
            Side {
                offset: g,
                sign: -1.0,
                tol,
            },
            ContactMode::Positive,
            g,
        );
        let down = (
            Side {
                offset: g,
                sign: 1.0,
                tol,
            },
            ContactMode::Negative,
            -g,
        );
        let sides = match mode {
            ContactMode::Free => [Some(up), Some(down)],
            ContactMode::Positive => [
                Some((
                    Side {
                        offset: -g,
                        sign: 1.0,
                        tol,
                    },
                    ContactMode::Free,
                    g,
                )),
                None,
            ],
            ContactMode::Negative => [
                Some((
                    Side {
                        offset: -g,
                        sign: -1.0,
                        tol,
                    },
                    ContactMode::Free,
                    -g,
                )),
                None,
            ],
            _ => unreachable!("the damper's modes need a damper"),
        };
        let (d2, c3) = probe.unwrap_or_else(|| (rows.derivative(2, y), rows.third_bound(y, span)));
        let d = [u, rows.derivative(1, y), d2];
        let mut poly = None;
        let mut best: Option<Exit> = None;
        for (side, to, u_cross) in sides.into_iter().flatten() {
            let (f0, f1, f2) = (side.value(d[0]), side.sign * d[1], side.sign * d[2]);
            if roots::cubic_clear(f0, f1, f2, c3, span, tol) {
                continue;
            }
            if poly.is_none() {
                let sparse = &self.modes[mode.index()].sparse;
                poly = Some(model.get_or_expand(sparse, y, span).poly(linear::U));
            }
            let p = poly.as_ref().expect("filled above");
            let limit = best.map_or(span, |b| b.offset);
            // Undecided: u stays within round-off of the threshold over much of the span, so
            // no switch is distinguishable from none; the mode in force is kept.
            if let Ok(Some(offset)) = roots::first_exit(p, side, limit, budget) {
                best = Some(Exit {
                    offset,
                    to,
                    u: Some(u_cross),
                    du: None,
                });
            }
        }
        best
    }

    /// The `order`-th time derivative (order ≥ 1) of [θ_m, ω_m, θ_L, ω_L, T] at `state` under the
    /// mode in force (at a switch instant: the mode being entered, i.e. the right derivative).
    pub fn time_derivative(&self, state: &PlantState, inputs: &Inputs, order: u32) -> [f64; 5] {
        let m = &self.modes[state.mode.index()].m;
        let mut y = augmented(state, inputs, 0.0);
        for _ in 0..order {
            y = m * y;
        }
        [
            y[linear::DTHETA_M],
            self.motor_speed(y[linear::V], y[linear::OMEGA_L]),
            y[linear::DTHETA_L],
            y[linear::OMEGA_L],
            if N == WEB_AUG { y[linear::TENSION] } else { 0.0 },
        ]
    }

    /// Takes the end of a piece, [u, v, ω_L, δθ_m, δθ_L, T], into the state.
    #[inline]
    fn finish_piece(&self, next: &mut PlantState, end: &PieceEnd) {
        if N == WEB_AUG {
            next.tension = end[5];
        }
        next.theta_m += end[linear::DTHETA_M];
        next.theta_l += end[linear::DTHETA_L];
        next.u = end[linear::U];
        next.du = end[linear::V];
        next.omega_l = end[linear::OMEGA_L];
        next.omega_m = self.motor_speed(next.du, next.omega_l);
    }

    /// ω_m = (v + r_L ω_L)/r_m, and likewise for any time derivative of the three.
    fn motor_speed(&self, v: f64, omega_l: f64) -> f64 {
        (v + self.plant.r_l() * omega_l) / self.plant.r_m()
    }
}

/// The augmented vector of `state` at time `t` into the step (angle increments zero).
#[inline(always)]
fn augmented<const N: usize>(state: &PlantState, inputs: &Inputs, t: f64) -> AugVector<N> {
    // In the order of `linear`: [u, v, ω_L, δθ_m, δθ_L, τ_m, τ_L, 1, τ̇_m, τ̇_L] and, with a
    // web span, [T, w, ẇ].
    let drive = [
        state.u,
        state.du,
        state.omega_l,
        0.0,
        0.0,
        inputs.tau_m + inputs.dtau_m * t,
        inputs.tau_l + inputs.dtau_l * t,
        1.0,
        inputs.dtau_m,
        inputs.dtau_l,
    ];
    let span = [state.tension, inputs.span + inputs.dspan * t, inputs.dspan];
    AugVector::<N>::from_fn(|i, _| if i < AUG { drive[i] } else { span[i - AUG] })
}

/// The end of a piece from the augmented state there.
#[inline(always)]
fn piece_end<const N: usize>(y: &AugVector<N>) -> PieceEnd {
    let tension = if N == WEB_AUG { y[linear::TENSION] } else { 0.0 };
    [y[0], y[1], y[2], y[3], y[4], tension]
}

/// Writes a piece end into the augmented state.
#[inline(always)]
fn set_piece_end<const N: usize>(y: &mut AugVector<N>, end: &PieceEnd) {
    y.as_mut_slice()[..5].copy_from_slice(&end[..5]);
    if N == WEB_AUG {
        y[linear::TENSION] = end[5];
    }
}
