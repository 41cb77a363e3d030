//! Exact stepping of a chain between contact switches (docs/model.md §2, over S stages): each
//! mode's motion is e^{M s} y; every stage's switching surfaces u_i = ±g_i are certified
//! absent piece by piece or located to round-off, and all stages that switch at one instant
//! enter their new modes together.

use super::linear::{mode_matrix, Layout, Rows, PIECE_RATE};
use super::params::Chain;
use super::state::{BodyMode, ChainMode, ChainState};
use crate::damper::variation;
use crate::kernel::KernelColumn;
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

/// A switch of one body's friction mode inside a step (docs/model.md §10, Coulomb friction
/// with stiction): it stops and sticks or reverses, or it breaks away.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodySwitch {
    /// Time since the start of the step [s].
    pub offset: f64,
    /// Which body (0 ..= S).
    pub body: usize,
    pub from: BodyMode,
    pub to: BodyMode,
}

/// A switch inside a step: of a stage's contact mode or of a body's friction mode. Switches at
/// one instant (within 4 ulps of the step's time) are reported together, stages first, then the
/// bodies in order; switches located further apart, in time order (docs/model.md §12).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ChainEvent {
    Stage(StageSwitch),
    Body(BodySwitch),
}

impl ChainEvent {
    /// Time since the start of the step [s].
    pub fn offset(&self) -> f64 {
        match self {
            ChainEvent::Stage(e) => e.offset,
            ChainEvent::Body(e) => e.offset,
        }
    }
}

/// One mode: its augmented matrix, the derivative rows of each stage's u along it, and for each
/// body with friction the signal its friction mode ends on.
#[derive(Clone, Debug)]
struct ModeDynamics<const S: usize, const N: usize> {
    m: SMatrix<f64, N, N>,
    sparse: Sparse<N>,
    u_rows: [SignalRows<N>; S],
    /// By body (0 ..= S); None without friction.
    bodies: Vec<Option<BodySignal<N>>>,
}

/// What ends a body's friction mode: sliding, its speed reaching 0; stuck, the torque τ_h that
/// the bearing holds reaching ±peak·τ_c. The rows of that signal along the mode, and τ_h's row
/// (what decides the mode where the body stops).
#[derive(Clone, Debug)]
struct BodySignal<const N: usize> {
    rows: SignalRows<N>,
    holding: SVector<f64, N>,
}

/// One mode's maps over a whole piece of the current step size, fused into one kernel
/// (kernel.rs) of `KO` = 6S + 2 outputs: rows 0 .. 3S + 2 are e^{M len}'s rows of the state
/// entries (u_i, v_i, ω_S, δθ_j: the first 3S + 2 of chain/linear.rs), then per stage u″ and u‴
/// at the piece start and the bound on how far u‴ moves over the piece (roots.rs,
/// `SignalRows::remainder_row`, which multiplies |y|). One pass over the piece start's
/// non-zero entries (the angle increments are 0 there) gives the end state and the certificate
/// of every stage.
#[derive(Clone, Copy, Debug)]
struct PieceKernel<const S: usize, const N: usize, const KO: usize> {
    cols: [KernelColumn<KO>; N],
}

/// The entries of the augmented vector at a piece start that are not 0 (the angle increments
/// are): each stage's u and v, the last body's speed, the inputs at the piece start and their
/// slopes (the constant 1 is implied).
#[derive(Clone, Copy, Debug)]
struct PieceStart<const S: usize> {
    u: [f64; S],
    v: [f64; S],
    omega_last: f64,
    tau_m: f64,
    tau_l: f64,
    dtau_m: f64,
    dtau_l: f64,
    /// With a web span: [T, w, ẇ] (else unused).
    span: [f64; 3],
}

impl<const S: usize> PieceStart<S> {
    /// At offset `t` into the step from `state` under `inputs` (as [`augmented`] writes them).
    fn of(state: &ChainState<S>, inputs: &Inputs, t: f64) -> Self {
        PieceStart {
            u: state.u,
            v: state.du,
            omega_last: state.body(S).omega,
            tau_m: inputs.tau_m + inputs.dtau_m * t,
            tau_l: inputs.tau_l + inputs.dtau_l * t,
            dtau_m: inputs.dtau_m,
            dtau_l: inputs.dtau_l,
            span: [state.tension, inputs.span + inputs.dspan * t, inputs.dspan],
        }
    }

    /// Read from an augmented vector at a piece start.
    fn from_augmented<const N: usize>(y: &SVector<f64, N>) -> Self {
        PieceStart {
            u: std::array::from_fn(|i| y[Layout::<S>::u(i)]),
            v: std::array::from_fn(|i| y[Layout::<S>::v(i)]),
            omega_last: y[Layout::<S>::OMEGA_LAST],
            tau_m: y[Layout::<S>::TAU_M],
            tau_l: y[Layout::<S>::TAU_L],
            dtau_m: y[Layout::<S>::DTAU_M],
            dtau_l: y[Layout::<S>::DTAU_L],
            span: if N == Layout::<S>::WEB_DIM {
                [Layout::<S>::TENSION, Layout::<S>::SPAN, Layout::<S>::DSPAN].map(|j| y[j])
            } else {
                [0.0; 3]
            },
        }
    }

    /// Calls `add(j, y_j)` for the entries of the augmented vector that may be non-zero, in the
    /// column order of chain/linear.rs; the slopes of the inputs are skipped when both are 0
    /// (a zero-order hold), the span's entries without a web span (`web`).
    #[inline(always)]
    fn each_entry_of(&self, web: bool, mut add: impl FnMut(usize, f64)) {
        for i in 0..S {
            add(Layout::<S>::u(i), self.u[i]);
        }
        for i in 0..S {
            add(Layout::<S>::v(i), self.v[i]);
        }
        add(Layout::<S>::OMEGA_LAST, self.omega_last);
        add(Layout::<S>::TAU_M, self.tau_m);
        add(Layout::<S>::TAU_L, self.tau_l);
        add(Layout::<S>::ONE, 1.0);
        // Zero under a zero-order hold: skipped.
        if !((self.dtau_m == 0.0) & (self.dtau_l == 0.0)) {
            add(Layout::<S>::DTAU_M, self.dtau_m);
            add(Layout::<S>::DTAU_L, self.dtau_l);
        }
        if web {
            let [t, w, dw] = self.span;
            add(Layout::<S>::TENSION, t);
            add(Layout::<S>::SPAN, w);
            add(Layout::<S>::DSPAN, dw);
        }
    }

    /// `each_entry_of` for an augmented vector of N entries (with a web span: N = 3S + 10).
    #[inline(always)]
    fn each_entry<const N: usize>(&self, add: impl FnMut(usize, f64)) {
        self.each_entry_of(N == Layout::<S>::WEB_DIM, add)
    }
}

impl<const S: usize, const N: usize, const KO: usize> PieceKernel<S, N, KO> {
    /// The state rows: u_i, v_i, ω_S, δθ_j.
    const STATE_ROWS: usize = 3 * S + 2;
    /// With a web span (N = 3S + 10): the row of T, after the state rows.
    const WEB: bool = N == Layout::<S>::WEB_DIM;
    const TENSION_ROW: usize = Self::STATE_ROWS;
    /// u″ of each stage.
    const SECOND: usize = Self::STATE_ROWS + Self::WEB as usize;
    /// u‴ of each stage.
    const THIRD: usize = Self::SECOND + S;
    /// The growth bound of u‴ of each stage: these rows multiply |y|.
    const GROWTH: usize = Self::THIRD + S;

    fn new(phi: &SMatrix<f64, N, N>, u_rows: &[SignalRows<N>; S], remainder: &[SVector<f64, N>; S]) -> Self {
        assert!(
            KO == Self::GROWTH + S + Self::WEB as usize,
            "a kernel of {KO} outputs for {S} stages"
        );
        PieceKernel {
            cols: KernelColumn::table(|r, j| match r {
                _ if r < Self::STATE_ROWS => phi[(r, j)],
                _ if r < Self::SECOND => phi[(Layout::<S>::TENSION, j)],
                _ if r < Self::THIRD => u_rows[r - Self::SECOND].row(2)[j],
                _ if r < Self::GROWTH => u_rows[r - Self::THIRD].row(3)[j],
                _ if r < Self::GROWTH + S => remainder[r - Self::GROWTH][j],
                // Padding to an even count (with a web span).
                _ => 0.0,
            }),
        }
    }

    /// `acc += column j times x`, the growth rows times |x|. Inlined, it vectorizes across the
    /// outputs and the row test folds away.
    #[inline(always)]
    fn add(&self, acc: &mut [f64; KO], j: usize, x: f64) {
        let (col, ax) = (&self.cols[j].0, x.abs());
        for r in 0..KO {
            acc[r] += col[r] * if r >= Self::GROWTH { ax } else { x };
        }
    }

    /// The kernel's sums over a piece start, in the column order of chain/linear.rs (the sums
    /// of the matrix products they replace, skipping the terms of entries that are exactly 0,
    /// which changes nothing but the sign of a zero).
    #[inline(always)]
    fn apply(&self, start: &PieceStart<S>) -> [f64; KO] {
        let mut acc = [0.0; KO];
        start.each_entry::<N>(|j, x| self.add(&mut acc, j, x));
        acc
    }

    /// T at the piece end from `apply`'s sums (0 without a web span).
    #[inline(always)]
    fn tension(acc: &[f64; KO]) -> f64 {
        if Self::WEB {
            acc[Self::TENSION_ROW]
        } else {
            0.0
        }
    }

    /// Stage i's u″ at the piece start and its bound on |u‴| over the piece, from `apply`'s sums.
    #[inline(always)]
    fn certificate(acc: &[f64; KO], i: usize) -> (f64, f64) {
        (
            acc[Self::SECOND + i],
            acc[Self::THIRD + i].abs() + acc[Self::GROWTH + i],
        )
    }
}

/// A body's certificate over a whole piece, with friction (docs/model.md §2's cubic test on
/// its signal s: the speed while it slides, the held torque τ_h while it sticks), fused as
/// [`PieceKernel`]'s: s, s′, s″ and s‴ at the piece start, the bound on how far s‴ moves over the
/// piece (`SignalRows::remainder_row` for the piece's length) and Σ|row of s|·|y|, the scale of
/// its round-off floor; the last two multiply |y|. One pass over the piece start's non-zero
/// entries, in place of six dot products over the whole augmented vector.
#[derive(Clone, Copy, Debug)]
struct BodyKernel<const N: usize> {
    cols: [KernelColumn<BODY_OUTPUTS>; N],
}

/// [`BodyKernel`]'s outputs: s⁽ᵏ⁾ for k = 0..=3, then the rows that multiply |y|.
const BODY_OUTPUTS: usize = 6;
const BODY_ABS_ROW: usize = 4;

impl<const N: usize> BodyKernel<N> {
    fn new(rows: &SignalRows<N>, remainder: &SVector<f64, N>) -> Self {
        BodyKernel {
            cols: KernelColumn::table(|r, j| match r {
                0..=3 => rows.row(r)[j],
                BODY_ABS_ROW => rows.row(0)[j].abs(),
                _ => remainder[j],
            }),
        }
    }

    /// ([s, s′, s″] at the piece start, the bound on sup |s‴| over the piece, the floor's scale).
    #[inline(always)]
    fn apply<const S: usize>(&self, start: &PieceStart<S>) -> ([f64; 3], f64, f64) {
        let mut acc = [0.0; BODY_OUTPUTS];
        start.each_entry::<N>(|j, x| {
            let by = KernelColumn::<BODY_OUTPUTS>::multipliers_from(x, BODY_ABS_ROW, BODY_ABS_ROW);
            self.cols[j].accumulate_by(&mut acc, by);
        });
        ([acc[0], acc[1], acc[2]], acc[3].abs() + acc[5], acc[4])
    }
}

/// A located crossing of one stage's surface.
#[derive(Clone, Copy, Debug)]
struct Crossing {
    /// From the start of the span searched [s].
    offset: f64,
    to: ContactMode,
    /// On u = ±g: u there, exactly.
    u: Option<f64>,
    /// On a surface of a damper's force: u′ set from u so that the state lies on it.
    du: Option<f64>,
}

/// The exact stepper of a chain of S stages with an augmented state of N = 3S + 7 entries and
/// KO = 6S + 2 kernel outputs (stable Rust cannot write 3S + 7 as a type, so N and KO are
/// parameters checked at construction).
/// Holds the per-mode exponentials of the current step size, filled for a mode when it is
/// first entered and dropped when the step size changes; nothing is allocated per step.
#[derive(Clone, Debug)]
pub struct ChainStepper<const S: usize, const N: usize, const KO: usize> {
    chain: Chain<S>,
    /// By [`ChainMode::index`]; built when the mode is first entered (with friction there are
    /// 7^S 3^(S+1) of them, few of which a run meets).
    modes: Vec<Option<Box<ModeDynamics<S, N>>>>,
    /// Longest piece [s]: PIECE_RATE over the fastest rate.
    len_ref: f64,
    /// Longest step [s]: `MAX_PIECES` pieces.
    max_h: f64,
    /// The step size the maps are for (NaN: none yet), its pieces and their length [s].
    h: f64,
    pieces: usize,
    len: f64,
    /// By [`ChainMode::index`]; None until the mode is entered at this step size.
    maps: Vec<Option<PieceKernel<S, N, KO>>>,
    /// By [`ChainMode::index`], filled with `maps`: each body's certificate over a piece (None
    /// for a body without friction; empty without friction).
    body_maps: Vec<Box<[Option<BodyKernel<N>>]>>,
    /// Some body has Coulomb friction: its modes are certified and located besides the stages'.
    friction: bool,
}

/// One stage (docs/model.md §1's shaft or belt): 10 augmented entries, 8 kernel outputs.
pub type OneStageStepper = ChainStepper<1, 10, 8>;
/// One stage pulling a web span (docs/model.md §8's web line): 13 entries, 10 outputs.
pub type OneStageWebStepper = ChainStepper<1, 13, 10>;
/// Two stages (docs/model.md §10): 13 augmented entries, 14 kernel outputs.
pub type TwoStageStepper = ChainStepper<2, 13, 14>;

impl<const S: usize, const N: usize, const KO: usize> ChainStepper<S, N, KO> {
    pub fn new(chain: Chain<S>) -> Self {
        let (dim, outputs) = match chain.web() {
            None => (Layout::<S>::DIM, 6 * S + 2),
            Some(_) => (Layout::<S>::WEB_DIM, 6 * S + 4),
        };
        assert!(
            N == dim && KO == outputs,
            "augmented dimension {N} and {KO} kernel outputs for this chain: {dim} and {outputs}"
        );
        let len_ref = PIECE_RATE / chain.fastest_rate();
        ChainStepper {
            chain,
            modes: vec![None; ChainMode::<S>::COUNT],
            len_ref,
            max_h: MAX_PIECES as f64 * len_ref,
            h: f64::NAN,
            pieces: 0,
            len: 0.0,
            maps: vec![None; ChainMode::<S>::COUNT],
            body_maps: vec![Box::default(); ChainMode::<S>::COUNT],
            friction: chain.has_friction(),
        }
    }

    /// The dynamics of mode `index`, built on first use.
    #[cold]
    #[inline(never)]
    fn build_mode(&mut self, index: usize) {
        let mode = ChainMode::from_index(index);
        let m = mode_matrix::<S, N>(&self.chain, &mode);
        let rows = Rows::<S, N>::new(&self.chain, &mode);
        let len_ref = self.len_ref;
        let bodies = (0..=S)
            .map(|j| {
                (self.chain.body(j).friction.tau_c > 0.0).then(|| {
                    let holding = rows.holding(j);
                    let signal = match mode.body(j) {
                        BodyMode::Stuck => holding,
                        _ => rows.speed[j],
                    };
                    BodySignal {
                        rows: SignalRows::new(signal, &m, len_ref),
                        holding,
                    }
                })
            })
            .collect();
        self.modes[index] = Some(Box::new(ModeDynamics {
            m,
            sparse: Sparse::new(&m),
            u_rows: std::array::from_fn(|i| {
                let mut e_u = SVector::<f64, N>::zeros();
                e_u[Layout::<S>::u(i)] = 1.0;
                SignalRows::new(e_u, &m, len_ref)
            }),
            bodies,
        }));
    }

    /// Mode `index`'s dynamics and its maps at the current step size, built on first use.
    #[inline(always)]
    fn fill(&mut self, index: usize) {
        if self.maps[index].is_none() {
            self.fill_maps_of(index);
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
    /// web span's entries are ignored without a web span), calling `on_switch` for every switch
    /// of a stage or a body in time order. Returns the number of switches. On error `state` is
    /// left unchanged. With friction the law of stiction is applied at the step's start with
    /// these inputs first (a body at rest that they break away slides from there; not a switch
    /// inside the step).
    pub fn step(
        &mut self,
        state: &mut ChainState<S>,
        inputs: &Inputs,
        h: f64,
        on_switch: &mut dyn FnMut(ChainEvent),
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
        on_switch: &mut dyn FnMut(ChainEvent),
    ) -> Result<Option<f64>, StepError> {
        self.advance(state, inputs, h, on_switch, true).map(|(_, at)| at)
    }

    /// The law of stiction applied to `state` with `inputs` (docs/model.md §12): each body
    /// with friction slides by the sign of its speed, and at rest sticks or breaks away in the
    /// direction of the torque on it. The mode a step from `state` with these inputs starts
    /// in; the initial mode at the start time.
    pub fn apply_stiction(&mut self, state: &mut ChainState<S>, inputs: &Inputs) {
        if self.friction {
            self.stiction_at_start(state, inputs, &mut |_| {});
        }
    }

    /// τ_h of body `j` at `state` in its mode under `inputs` (docs/model.md §10): every torque on
    /// the body but its bearing's, which the bearing must cancel to hold it at rest (the viscous
    /// term vanishes at rest and is left out).
    pub fn holding(&self, state: &ChainState<S>, inputs: &Inputs, j: usize) -> f64 {
        let y = augmented::<S, N>(state, inputs, 0.0);
        Rows::<S, N>::new(&self.chain, &state.mode).holding(j).dot(&y)
    }

    /// The change of [`ChainStepper::holding`] in `mode` for a change `d` of the state (its
    /// angles, speeds, u, u′ and T) and `d_inputs` of the inputs: τ_h is linear in them within a
    /// mode (the change carries none of a flank's constant term).
    pub fn holding_change(&self, mode: &ChainMode<S>, d: &ChainState<S>, d_inputs: &Inputs, j: usize) -> f64 {
        let mut dy = augmented::<S, N>(d, d_inputs, 0.0);
        dy[Layout::<S>::ONE] = 0.0;
        Rows::<S, N>::new(&self.chain, mode).holding(j).dot(&dy)
    }

    /// The time derivative of `state` in its mode under `inputs`: [θ_0′, ω_0′, …, θ_S′, ω_S′,
    /// T′] (T′ = 0 without a web span), from the mode's rows of docs/model.md §2 (a stuck body
    /// does not accelerate).
    pub fn rates(&self, state: &ChainState<S>, inputs: &Inputs) -> Vec<f64> {
        let y = augmented::<S, N>(state, inputs, 0.0);
        let rows = Rows::<S, N>::new(&self.chain, &state.mode);
        let mut out = Vec::with_capacity(2 * S + 3);
        for j in 0..=S {
            out.push(rows.speed[j].dot(&y));
            out.push(rows.acceleration(j).dot(&y));
        }
        out.push(match self.chain.web() {
            Some(w) => {
                (w.ea * w.r_w * y[Layout::<S>::OMEGA_LAST] - w.v_ref * state.tension) / w.l_w + y[Layout::<S>::SPAN]
            }
            None => 0.0,
        });
        out
    }

    fn advance(
        &mut self,
        state: &mut ChainState<S>,
        inputs: &Inputs,
        h: f64,
        on_switch: &mut dyn FnMut(ChainEvent),
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
        if self.friction {
            switches += self.stiction_at_start(&mut next, inputs, on_switch);
        }
        for piece in 0..pieces {
            // Pieces all have length `len`; the last ends on h to round-off of the time grid.
            let start = piece as f64 * len;
            let index = next.mode.index();
            self.fill(index);
            // The whole piece in one pass, when every stage is certified clear of its
            // thresholds over it: the common case.
            if self.whole_piece(&mut next, inputs, start, index) {
                continue;
            }
            let mut y = augmented::<S, N>(&next, inputs, start);
            // Offset of y from the step start, and whether y is still at the piece start.
            let mut t = start;
            let mut whole = true;
            loop {
                let span = if whole { len } else { len - (t - start) };
                let index = next.mode.index();
                self.fill(index);
                let dynamics = self.modes[index].as_deref().expect("filled above");
                let kernel = self.maps[index].as_ref().expect("filled above");
                let start_y = y;
                if !whole && self.clear(&next.mode, dynamics, &y, span) {
                    // No stage can switch in the rest of the piece: one expansion does it.
                    y = TaylorModel::new(&dynamics.sparse, &y, span).at(span);
                    self.add_variation(&mut next, dynamics, &start_y, span, &y, &[None; S]);
                    break;
                }
                let model = TaylorModel::new(&dynamics.sparse, &y, span);
                let Some((offset, crossings, body_crossings)) =
                    self.earliest(&next.mode, dynamics, &model, &y, t, span, &mut budget)
                else {
                    let mut probe = None;
                    if whole {
                        let end = kernel.apply(&PieceStart::from_augmented(&y));
                        y.as_mut_slice()[..PieceKernel::<S, N, KO>::STATE_ROWS]
                            .copy_from_slice(&end[..PieceKernel::<S, N, KO>::STATE_ROWS]);
                        if PieceKernel::<S, N, KO>::WEB {
                            y[Layout::<S>::TENSION] = PieceKernel::<S, N, KO>::tension(&end);
                        }
                        probe = Some(end);
                    } else {
                        y = model.at(span);
                    }
                    let probe = probe
                        .as_ref()
                        .map(|end| move |i: usize| PieceKernel::<S, N, KO>::certificate(end, i));
                    self.add_variation_probed(&mut next, dynamics, &start_y, probe, span, &y, &[None; S]);
                    break;
                };
                y = model.at(offset);
                self.add_variation(&mut next, dynamics, &start_y, offset, &y, &crossings);
                t += offset;
                whole = false;
                for (i, crossing) in crossings.iter().enumerate() {
                    let Some(c) = crossing else { continue };
                    if let Some(u) = c.u {
                        y[Layout::<S>::u(i)] = u;
                    }
                    if let Some(du) = c.du {
                        y[Layout::<S>::v(i)] = du;
                    }
                    on_switch(ChainEvent::Stage(StageSwitch {
                        offset: t,
                        stage: i,
                        from: next.mode.stages[i],
                        to: c.to,
                    }));
                    next.mode.stages[i] = c.to;
                    switches += 1;
                }
                for crossing in &body_crossings {
                    let j = crossing.body;
                    let from = next.mode.body(j);
                    let to = match crossing.exit {
                        BodyExit::Breaks(to) => to,
                        BodyExit::Stops => {
                            // On ω_j = 0 exactly; what it does there is the law at rest with the
                            // torques in the modes now in force.
                            stop_body(&self.chain, &mut y, j);
                            let holding = Rows::<S, N>::new(&self.chain, &next.mode).holding(j);
                            at_rest(holding.dot(&y), self.chain.body(j).friction.breakaway())
                        }
                    };
                    if to != from {
                        on_switch(ChainEvent::Body(BodySwitch {
                            offset: t,
                            body: j,
                            from,
                            to,
                        }));
                        next.mode.set_body(j, to);
                        switches += 1;
                    }
                }
                // Inputs are functions of time: re-evaluate rather than carry round-off.
                y[Layout::<S>::TAU_M] = inputs.tau_m + inputs.dtau_m * t;
                y[Layout::<S>::TAU_L] = inputs.tau_l + inputs.dtau_l * t;
                if PieceKernel::<S, N, KO>::WEB {
                    y[Layout::<S>::SPAN] = inputs.span + inputs.dspan * t;
                }
                if stop_at_switch {
                    self.finish_piece(&mut next, y.as_slice(), tension_of::<S, N>(&y));
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
            self.finish_piece(&mut next, y.as_slice(), tension_of::<S, N>(&y));
        }
        if !next.is_finite() {
            return Err(StepError::Overflow);
        }
        *state = next;
        Ok((switches, None))
    }

    /// The piece from `start` into the step, from `next` in the mode of map `index` (filled), in
    /// one pass of its kernel, when every stage (and with friction every body) is certified to
    /// keep its mode over it: then `next` is moved to the piece end and true returned; else
    /// `next` is left as it was.
    #[inline(always)]
    fn whole_piece(&self, next: &mut ChainState<S>, inputs: &Inputs, start: f64, index: usize) -> bool {
        let kernel = self.maps[index].as_ref().expect("the mode's map is filled");
        let at_start = PieceStart::of(next, inputs, start);
        let whole_piece = kernel.apply(&at_start);
        let stages_clear = self.clear_by(&next.mode, &at_start, self.len, |i| {
            PieceKernel::<S, N, KO>::certificate(&whole_piece, i)
        });
        if !(stages_clear && (!self.friction || self.bodies_clear_over_piece(&next.mode, &at_start, index))) {
            return false;
        }
        for i in self.damped_stages() {
            let (d2, c3) = PieceKernel::<S, N, KO>::certificate(&whole_piece, i);
            let u_end = whole_piece[Layout::<S>::u(i)];
            next.variation[i] += variation(
                next.mode.stages[i],
                at_start.u[i],
                at_start.v[i],
                d2,
                c3,
                self.len,
                u_end,
            );
        }
        self.finish_piece(next, &whole_piece, PieceKernel::<S, N, KO>::tension(&whole_piece));
        true
    }

    /// The step of a co-simulation in the common case, with nothing to locate: `h` is the step
    /// size `step` last took, one piece long, the mode's map is filled, no body has friction
    /// (whose law of stiction a step applies at its start) and the piece is certified clear.
    /// Returns the state at its end if it and the inputs are finite; else `None`, and `step`
    /// does the step (or says why not).
    ///
    /// Contract: a state it returns is bit for bit the one `step` gives: it is `step`'s path
    /// through a piece certified clear (`whole_piece`, the same code on the same operands),
    /// without the step's general machinery around it, which `step` sets up before it knows
    /// whether the piece needs it.
    #[inline]
    pub fn quiet_step(&self, state: &ChainState<S>, inputs: &Inputs, h: f64) -> Option<ChainState<S>> {
        debug_assert!(state.is_finite());
        let index = state.mode.index();
        // `self.h` holds a step size `step` accepted (or NaN, with no pieces).
        let ready = (self.h.to_bits() == h.to_bits()) & (self.pieces == 1) & !self.friction;
        if !ready || self.maps[index].is_none() {
            return None;
        }
        let mut next = *state;
        let taken = self.whole_piece(&mut next, inputs, 0.0, index);
        // An infinite or NaN entry of the kernel's makes every sum it enters NaN or infinite
        // (∞·0 is NaN), so that `next` is not finite; `span` and its slope enter the kernel only
        // with a web span, and `step` refuses them non-finite in any case.
        (taken & crate::finite(inputs.span) & crate::finite(inputs.dspan) & next.is_finite()).then_some(next)
    }

    /// Refuses what the step cannot take: h not finite, ≤ 0 or longer than `max_step`,
    /// inputs or state not finite.
    #[inline(always)]
    fn check(&self, state: &ChainState<S>, inputs: &Inputs, h: f64) -> Result<(), StepError> {
        let i = inputs;
        let finite = crate::finite;
        let inputs_finite =
            finite(i.tau_m) & finite(i.tau_l) & finite(i.dtau_m) & finite(i.dtau_l) & finite(i.span) & finite(i.dspan);
        if (h > 0.0) & (h <= self.max_h) & inputs_finite & state.is_finite() {
            return Ok(());
        }
        Self::refusal(state, inputs, h, self.max_h)
    }

    /// Why `check` refuses.
    #[cold]
    #[inline(never)]
    fn refusal(state: &ChainState<S>, inputs: &Inputs, h: f64, max_h: f64) -> Result<(), StepError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(StepError::BadStepSize { h });
        }
        let named = [
            ("tau_m", inputs.tau_m),
            ("tau_L", inputs.tau_l),
            ("der(tau_m)", inputs.dtau_m),
            ("der(tau_L)", inputs.dtau_l),
            ("the web span's forcing", inputs.span),
            ("the web span's forcing rate", inputs.dspan),
        ];
        if let Some(&(name, value)) = named.iter().find(|(_, v)| !v.is_finite()) {
            return Err(StepError::NonFiniteInput { name, value });
        }
        if !state.is_finite() {
            return Err(StepError::NonFiniteState);
        }
        Err(StepError::StepTooLong { h, max_h })
    }

    /// Cuts steps of size h into equal pieces no longer than `len_ref` and drops the maps of
    /// the previous size.
    fn set_step(&mut self, h: f64) {
        let pieces = (h / self.len_ref).ceil().max(1.0);
        self.h = h;
        self.pieces = pieces as usize;
        self.len = h / pieces;
        self.maps.iter_mut().for_each(|m| *m = None);
        self.body_maps.iter_mut().for_each(|m| *m = Box::default());
    }

    #[cold]
    #[inline(never)]
    fn fill_maps_of(&mut self, index: usize) {
        if self.modes[index].is_none() {
            self.build_mode(index);
        }
        let ModeDynamics {
            m,
            sparse,
            u_rows,
            bodies,
        } = self.modes[index].as_deref().expect("built above");
        let remainder = std::array::from_fn(|i| u_rows[i].remainder_row(m, self.len));
        self.maps[index] = Some(PieceKernel::new(&exp_series(sparse, self.len), u_rows, &remainder));
        self.body_maps[index] = bodies
            .iter()
            .map(|signal| {
                let rows = &signal.as_ref()?.rows;
                Some(BodyKernel::new(rows, &rows.remainder_row(m, self.len)))
            })
            .collect();
    }

    /// True when no stage's u can leave its mode's region within `span` after y (not a whole
    /// piece: the bound on |u‴| over the span from the mode's rows).
    fn clear(&self, mode: &ChainMode<S>, dynamics: &ModeDynamics<S, N>, y: &SVector<f64, N>, span: f64) -> bool {
        self.clear_by(mode, &PieceStart::from_augmented(y), span, |i| {
            let rows = &dynamics.u_rows[i];
            (rows.derivative(2, y), rows.third_bound(y, span))
        }) && (!self.friction || bodies_clear(&self.chain, mode, dynamics, y, span))
    }

    /// The bodies' surfaces certified clear over the whole piece from its start (with friction),
    /// by the bodies' kernels of mode `index`.
    fn bodies_clear_over_piece(&self, mode: &ChainMode<S>, start: &PieceStart<S>, index: usize) -> bool {
        self.body_maps[index].iter().enumerate().all(|(j, kernel)| {
            let Some(kernel) = kernel else { return true };
            let (d, c3, scale) = kernel.apply(start);
            body_keeps_mode(
                mode.body(j),
                self.chain.body(j).friction.breakaway(),
                d,
                c3,
                scale,
                self.len,
            )
        })
    }

    /// The law of stiction at the step's start with its inputs: each body with friction slides by
    /// the sign of its speed; at rest it sticks while |τ_h| ≤ peak·τ_c, else breaks away in the
    /// direction of τ_h (not a switch inside the step: the inputs changed). A body whose speed
    /// went through 0 at the end of the last step, within round-off of it, is stopped here: set at
    /// rest and the law applied, reported as a switch at the step's start. Returns the switches.
    fn stiction_at_start(
        &mut self,
        state: &mut ChainState<S>,
        inputs: &Inputs,
        on_switch: &mut dyn FnMut(ChainEvent),
    ) -> usize {
        let index = state.mode.index();
        self.fill(index);
        let dynamics = self.modes[index].as_deref().expect("filled above");
        let mut switches = 0;
        for j in 0..=S {
            let Some(signal) = &dynamics.bodies[j] else { continue };
            let (from, omega) = (state.mode.body(j), state.body(j).omega);
            let passed = (from == BodyMode::Forward && omega < 0.0) || (from == BodyMode::Backward && omega > 0.0);
            if passed {
                rest_body(&self.chain, state, j);
            }
            let omega = state.body(j).omega;
            let to = if omega > 0.0 {
                BodyMode::Forward
            } else if omega < 0.0 {
                BodyMode::Backward
            } else {
                let y = augmented::<S, N>(state, inputs, 0.0);
                at_rest(signal.holding.dot(&y), self.chain.body(j).friction.breakaway())
            };
            if passed && to != from {
                on_switch(ChainEvent::Body(BodySwitch {
                    offset: 0.0,
                    body: j,
                    from,
                    to,
                }));
                switches += 1;
            }
            state.mode.set_body(j, to);
        }
        switches
    }

    /// The cubic test of docs/model.md §2 per stage over `span` from `start`, with each
    /// stage's u″ and bound on |u‴| over the span from `certificate`.
    #[inline(always)]
    fn clear_by(
        &self,
        mode: &ChainMode<S>,
        start: &PieceStart<S>,
        span: f64,
        certificate: impl Fn(usize) -> (f64, f64),
    ) -> bool {
        (0..S).all(|i| {
            let stage = self.chain.stage(i);
            let (u, du) = (start.u[i], start.v[i]);
            if stage.d() == 0.0 {
                if stage.g == 0.0 {
                    // No free region: both flanks carry K u.
                    return true;
                }
                let (d2, c3) = certificate(i);
                let tol = floor(u, stage.g);
                return sides(mode.stages[i], stage.g, tol)
                    .into_iter()
                    .flatten()
                    .all(|(side, _, _)| {
                        roots::cubic_clear(side.value(u), side.sign * du, side.sign * d2, c3, span, tol)
                    });
            }
            let (d2, c3) = certificate(i);
            let member = stage.damped_member();
            member.clear(&member.exits(mode.stages[i]), u, du, d2, c3, span)
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
    ) -> Option<(f64, [Option<Crossing>; S], Vec<BodyCrossing>)> {
        // The time grid's resolution here: the step time t + span to a few ulps, and the
        // search's own resolution (roots.rs: f64::EPSILON/4 of the span).
        let same_instant = 4.0 * f64::EPSILON * (t + span);
        let mut found: [Option<Crossing>; S] = [None; S];
        let mut best = f64::INFINITY;
        // The bodies' surfaces first (with friction): their earliest crossing bounds the
        // stages' searches as the stages' own do.
        let mut bodies: Vec<BodyCrossing> = Vec::new();
        if self.friction {
            for (j, signal) in dynamics.bodies.iter().enumerate() {
                let Some(signal) = signal else { continue };
                let breakaway = self.chain.body(j).friction.breakaway();
                let tol = body_floor(signal, y, breakaway);
                let mut poly = None;
                for (side, exit) in body_sides(mode.body(j), breakaway, tol).into_iter().flatten() {
                    if signal_clear(&signal.rows, side, y, span) {
                        continue;
                    }
                    let p = poly.get_or_insert_with(|| model.signal(signal.rows.row(0)));
                    let limit = span.min(best + same_instant);
                    if let Ok(Some(offset)) = roots::first_exit(p, side, limit, budget) {
                        match bodies.iter_mut().find(|c| c.body == j) {
                            Some(c) if offset < c.offset => *c = BodyCrossing { offset, body: j, exit },
                            Some(_) => {}
                            None => bodies.push(BodyCrossing { offset, body: j, exit }),
                        }
                        best = best.min(offset);
                    }
                }
            }
        }
        for (i, slot) in found.iter_mut().enumerate() {
            let stage = self.chain.stage(i);
            let g = stage.g;
            let rows = &dynamics.u_rows[i];
            let u = y[Layout::<S>::u(i)];
            if stage.d() > 0.0 {
                let (du, d2, c3) = (y[Layout::<S>::v(i)], rows.derivative(2, y), rows.third_bound(y, span));
                let member = stage.damped_member();
                for exit in member.exits(mode.stages[i]).into_iter().flatten() {
                    let (surface, sign, to) = exit;
                    if member.clear(&[Some(exit), None], u, du, d2, c3, span) {
                        continue;
                    }
                    // The surface's row on stage i's u, v and the constant 1.
                    let ([on_u, on_v, on_one], tol) = member.signal(surface, u, du);
                    let mut c = SVector::<f64, N>::zeros();
                    c[Layout::<S>::u(i)] = on_u;
                    c[Layout::<S>::v(i)] = on_v;
                    c[Layout::<S>::ONE] = on_one;
                    let p = model.signal(&c);
                    let limit = span.min(best + same_instant);
                    let side = Side { offset: 0.0, sign, tol };
                    if let Ok(Some(offset)) = roots::first_exit(&p, side, limit, budget) {
                        if slot.is_none_or(|c| offset < c.offset) {
                            let (u, du) =
                                member.crossing(surface, mode.stages[i], to, || model.at(offset)[Layout::<S>::u(i)]);
                            *slot = Some(Crossing { offset, to, u, du });
                        }
                        best = best.min(offset);
                    }
                }
                continue;
            }
            if g == 0.0 {
                continue;
            }
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
                        *slot = Some(Crossing {
                            offset,
                            to,
                            u: Some(u_cross),
                            du: None,
                        });
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
        bodies.retain(|c| c.offset <= best + same_instant);
        Some((best, found, bodies))
    }

    /// The stages with a damper.
    #[inline(always)]
    fn damped_stages(&self) -> impl Iterator<Item = usize> + '_ {
        (0..S).filter(|&i| self.chain.stage(i).d() > 0.0)
    }

    /// Adds to each damped stage's V its growth over `span` from `start` to `end` in the mode in
    /// force, u″ and the bound on |u‴| from the mode's rows; a stage that crossed u = ±g at the
    /// span's end ends exactly there.
    #[allow(clippy::too_many_arguments)]
    fn add_variation(
        &self,
        next: &mut ChainState<S>,
        dynamics: &ModeDynamics<S, N>,
        start: &SVector<f64, N>,
        span: f64,
        end: &SVector<f64, N>,
        crossings: &[Option<Crossing>; S],
    ) {
        self.add_variation_probed(
            next,
            dynamics,
            start,
            None::<fn(usize) -> (f64, f64)>,
            span,
            end,
            crossings,
        );
    }

    /// `add_variation`, with u″ and the bound on |u‴| over `span` from `probe` when the kernel
    /// computed them for this span.
    #[allow(clippy::too_many_arguments)]
    fn add_variation_probed(
        &self,
        next: &mut ChainState<S>,
        dynamics: &ModeDynamics<S, N>,
        start: &SVector<f64, N>,
        probe: Option<impl Fn(usize) -> (f64, f64)>,
        span: f64,
        end: &SVector<f64, N>,
        crossings: &[Option<Crossing>; S],
    ) {
        for i in self.damped_stages() {
            let rows = &dynamics.u_rows[i];
            let (d2, c3) = match &probe {
                Some(probe) => probe(i),
                None => (rows.derivative(2, start), rows.third_bound(start, span)),
            };
            let u_end = crossings[i].and_then(|c| c.u).unwrap_or(end[Layout::<S>::u(i)]);
            let (u, v) = (start[Layout::<S>::u(i)], start[Layout::<S>::v(i)]);
            next.variation[i] += variation(next.mode.stages[i], u, v, d2, c3, span, u_end);
        }
    }

    /// Takes the state entries of the augmented vector at the end of a piece (or at a switch;
    /// its first 3S + 2 entries) and the span's tension into the state.
    fn finish_piece(&self, next: &mut ChainState<S>, y: &[f64], tension: f64) {
        next.tension = tension;
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
            let a_omega = next.du[i] + s.c * driven;
            // x / 1 is x: the division, whose latency the step waits on, only where a ≠ 1.
            next.body_mut(i).omega = if s.a == 1.0 { a_omega } else { a_omega / s.a };
        }
        if self.friction {
            self.hold_stuck(next);
        }
    }

    /// A stuck body's speed is 0 (its rate is 0 in its mode, and round-off must not move it):
    /// set exactly, with its members' u′ from the speeds on either side.
    #[cold]
    #[inline(never)]
    fn hold_stuck(&self, next: &mut ChainState<S>) {
        for j in 0..=S {
            if self.chain.body(j).friction.tau_c > 0.0 && next.mode.body(j) == BodyMode::Stuck {
                rest_body(&self.chain, next, j);
            }
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
#[inline(always)]
fn sides(mode: ContactMode, g: f64, tol: f64) -> [Option<(Side, ContactMode, f64)>; 2] {
    let side = |offset: f64, sign: f64| Side { offset, sign, tol };
    match mode {
        ContactMode::Free => [
            Some((side(g, -1.0), ContactMode::Positive, g)),
            Some((side(g, 1.0), ContactMode::Negative, -g)),
        ],
        ContactMode::Positive => [Some((side(-g, 1.0), ContactMode::Free, g)), None],
        ContactMode::Negative => [Some((side(-g, -1.0), ContactMode::Free, -g)), None],
        _ => unreachable!("a stage without a damper is never slack or capped"),
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
    if N == Layout::<S>::WEB_DIM {
        y[Layout::<S>::TENSION] = state.tension;
        y[Layout::<S>::SPAN] = inputs.span + inputs.dspan * t;
        y[Layout::<S>::DSPAN] = inputs.dspan;
    }
    y
}

/// T of an augmented vector (0 without a web span).
fn tension_of<const S: usize, const N: usize>(y: &SVector<f64, N>) -> f64 {
    if N == Layout::<S>::WEB_DIM {
        y[Layout::<S>::TENSION]
    } else {
        0.0
    }
}

/// A located crossing of a body's surface: where it stops (sliding) or breaks away (stuck).
#[derive(Clone, Copy, Debug)]
struct BodyCrossing {
    offset: f64,
    body: usize,
    exit: BodyExit,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum BodyExit {
    /// Sliding, its speed reaches 0: the law at rest decides what follows.
    Stops,
    /// Stuck, τ_h reaches ±peak·τ_c: it slides in that direction.
    Breaks(BodyMode),
}

/// The law at rest: stuck while |τ_h| ≤ peak·τ_c (`breakaway`), else sliding in τ_h's direction.
fn at_rest(holding: f64, breakaway: f64) -> BodyMode {
    if holding > breakaway {
        BodyMode::Forward
    } else if holding < -breakaway {
        BodyMode::Backward
    } else {
        BodyMode::Stuck
    }
}

/// The surfaces a body in `mode` may cross, each as the admissible side of its signal (the
/// speed sliding, τ_h stuck) and what crossing it means.
fn body_sides(mode: BodyMode, breakaway: f64, tol: f64) -> [Option<(Side, BodyExit)>; 2] {
    let side = |offset: f64, sign: f64| Side { offset, sign, tol };
    match mode {
        BodyMode::Forward => [Some((side(0.0, 1.0), BodyExit::Stops)), None],
        BodyMode::Backward => [Some((side(0.0, -1.0), BodyExit::Stops)), None],
        BodyMode::Stuck => [
            Some((side(breakaway, -1.0), BodyExit::Breaks(BodyMode::Forward))),
            Some((side(breakaway, 1.0), BodyExit::Breaks(BodyMode::Backward))),
        ],
    }
}

/// Round-off floor of a body's signal at y: a few ulps of the magnitudes it sums, and of the
/// breakaway torque it is compared with.
fn body_floor<const N: usize>(signal: &BodySignal<N>, y: &SVector<f64, N>, breakaway: f64) -> f64 {
    floor_of(signal_scale(&signal.rows, y), breakaway)
}

/// The magnitudes a signal sums at y, Σ|row of s|·|y|: the scale of its round-off floor.
fn signal_scale<const N: usize>(rows: &SignalRows<N>, y: &SVector<f64, N>) -> f64 {
    rows.row(0).abs().dot(&y.abs())
}

/// The floor for a signal summing magnitudes of `scale`, compared with `breakaway`.
fn floor_of(scale: f64, breakaway: f64) -> f64 {
    8.0 * f64::EPSILON * (scale + breakaway)
}

/// Whether a body keeps its friction mode `mode` over `span`: its signal, with [s, s′, s″] = `d`
/// at the start, sup |s‴| ≤ `c3` and magnitudes of `scale` summed, stays off every surface of
/// the mode.
fn body_keeps_mode(mode: BodyMode, breakaway: f64, d: [f64; 3], c3: f64, scale: f64, span: f64) -> bool {
    body_sides(mode, breakaway, floor_of(scale, breakaway))
        .into_iter()
        .flatten()
        .all(|(side, _)| derivatives_clear(side, d, c3, span))
}

/// Whether the signal of `rows` stays on `side` over `span` from y (the cubic test of
/// docs/model.md §2 on its derivatives).
fn signal_clear<const N: usize>(rows: &SignalRows<N>, side: Side, y: &SVector<f64, N>, span: f64) -> bool {
    let d = [0, 1, 2].map(|k| rows.derivative(k, y));
    derivatives_clear(side, d, rows.third_bound(y, span), span)
}

/// Whether a signal with [s, s′, s″] = `d` at the start and sup |s‴| ≤ `c3` stays on `side` over
/// `span`.
fn derivatives_clear(side: Side, d: [f64; 3], c3: f64, span: f64) -> bool {
    roots::cubic_clear(side.value(d[0]), side.sign * d[1], side.sign * d[2], c3, span, side.tol)
}

/// True when no body with friction can leave its mode within `span` after y.
fn bodies_clear<const S: usize, const N: usize>(
    chain: &Chain<S>,
    mode: &ChainMode<S>,
    dynamics: &ModeDynamics<S, N>,
    y: &SVector<f64, N>,
    span: f64,
) -> bool {
    dynamics.bodies.iter().enumerate().all(|(j, signal)| {
        let Some(signal) = signal else { return true };
        let rows = &signal.rows;
        let d = [0, 1, 2].map(|k| rows.derivative(k, y));
        body_keeps_mode(
            mode.body(j),
            chain.body(j).friction.breakaway(),
            d,
            rows.third_bound(y, span),
            signal_scale(rows, y),
            span,
        )
    })
}

/// Puts body j exactly at rest in the augmented state y: its speed 0, its members' u′ from the
/// speeds on either side (the angles and u are untouched).
fn stop_body<const S: usize, const N: usize>(chain: &Chain<S>, y: &mut SVector<f64, N>, j: usize) {
    // The speeds from the load down, before the change.
    let mut omega = vec![0.0; S + 1];
    omega[S] = y[Layout::<S>::OMEGA_LAST];
    for i in (0..S).rev() {
        let s = chain.stage(i);
        omega[i] = (y[Layout::<S>::v(i)] + s.c * omega[i + 1]) / s.a;
    }
    if j == S {
        y[Layout::<S>::OMEGA_LAST] = 0.0;
    } else {
        y[Layout::<S>::v(j)] = -chain.stage(j).c * omega[j + 1];
    }
    if j > 0 {
        y[Layout::<S>::v(j - 1)] = chain.stage(j - 1).a * omega[j - 1];
    }
}

/// Puts body j of `state` at rest: its speed 0 exactly, its members' u′ from the speeds on either
/// side (angles and u untouched).
fn rest_body<const S: usize>(chain: &Chain<S>, state: &mut ChainState<S>, j: usize) {
    state.body_mut(j).omega = 0.0;
    if j < S {
        state.du[j] = -chain.stage(j).c * state.body(j + 1).omega;
    }
    if j > 0 {
        state.du[j - 1] = chain.stage(j - 1).a * state.body(j - 1).omega;
    }
}
