//! The bounds an instance reports, by model: the speed-error bound of docs/model.md §3 for the
//! drive trains, and for the web line (§8) the pair of bounds of its loop, on load speed and on
//! span tension, advanced together.

use crate::physics::chain::OneStageFrictionBound;
use crate::physics::{
    BoundError, BoundState, PiGains, Plant, SpeedErrorBound, Trajectory, Unbounded, WebSpeedBound, WebTensionBound,
};

// The drive trains' bound stays inline, out of reach of an indirection on the hot path of every
// step (as the stepper's); the web line's pair is boxed.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Bounds {
    /// `bound`, `bound_paper`, `bound_sup` of a drive train under the speed PI.
    Speed(SpeedErrorBound),
    /// The web line's: `bound`, `bound_paper`, `bound_sup` on its load speed, `bound_T`,
    /// `bound_T_sup` on its tension.
    Web(Box<WebBounds>),
    /// A drive train's with bearing friction (docs/model.md §10, §12): `bound` and `bound_sup`
    /// add each body's friction term to the speed-error bound's; `bound_paper` is the paper's.
    Friction(Box<FrictionBounds>),
}

#[derive(Clone, Debug)]
pub struct FrictionBounds {
    speed: SpeedErrorBound,
    friction: OneStageFrictionBound,
}

#[derive(Clone, Debug)]
pub struct WebBounds {
    speed: WebSpeedBound,
    tension: WebTensionBound,
}

/// The words of one saved loop-bound state: elapsed, response, integral, l1.
const fn words<const N: usize>() -> usize {
    2 * N + 4
}

fn put<const N: usize>(out: &mut Vec<f64>, s: &BoundState<N>) {
    out.push(s.elapsed);
    out.extend_from_slice(&s.response);
    out.extend_from_slice(&s.integral);
    out.push(s.l1);
    out.push(s.peak);
    out.push(s.variation);
}

fn take<const N: usize>(words: &[f64]) -> BoundState<N> {
    let mut s = BoundState::<N> {
        elapsed: words[0],
        l1: words[2 * N + 1],
        peak: words[2 * N + 2],
        variation: words[2 * N + 3],
        ..BoundState::default()
    };
    s.response.copy_from_slice(&words[1..=N]);
    s.integral.copy_from_slice(&words[N + 1..=2 * N]);
    s
}

impl Bounds {
    /// The bounds of `plant`'s loop: the speed PI `speed`, and with a web span the tension PI
    /// `tension` as well (both gains 0: no tension loop).
    pub fn new(plant: &Plant, speed: PiGains, tension: PiGains) -> Result<Bounds, BoundError> {
        Ok(match plant.web() {
            None => Bounds::Speed(SpeedErrorBound::new(plant, speed)?),
            Some(_) => Bounds::Web(Box::new(WebBounds {
                speed: WebSpeedBound::new(plant, speed, tension)?,
                tension: WebTensionBound::new(plant, speed, tension)?,
            })),
        })
    }

    /// A drive train's bounds with the friction terms `friction` (docs/model.md §10): the
    /// speed-error bound's loop is the one-stage chain's, entry for entry.
    pub fn with_friction(plant: &Plant, speed: PiGains, friction: OneStageFrictionBound) -> Result<Bounds, BoundError> {
        Ok(Bounds::Friction(Box::new(FrictionBounds {
            speed: SpeedErrorBound::new(plant, speed)?,
            friction,
        })))
    }

    /// How many numbers [`Bounds::words`] holds for a plant with (`web`) or without a web span: a
    /// drive train's speed bound and room for its two bodies' friction terms (0 without).
    pub const fn word_count(web: bool) -> usize {
        if web {
            2 * words::<{ crate::physics::closed_loop::WEB_CL }>()
        } else {
            3 * words::<{ crate::physics::closed_loop::CL }>()
        }
    }

    /// Advances every bound by `h`; on error none has changed.
    #[inline]
    pub fn advance(&mut self, h: f64) -> Result<(), BoundError> {
        match self {
            Bounds::Speed(b) => b.advance(h),
            Bounds::Web(w) => {
                let before = w.speed.state();
                w.speed.advance(h)?;
                w.tension.advance(h).inspect_err(|_| {
                    w.speed.restore(&before).expect("a state the bound had is valid");
                })
            }
            Bounds::Friction(f) => {
                let before = f.speed.state();
                f.speed.advance(h)?;
                f.friction.advance(h).inspect_err(|_| {
                    f.speed.restore(&before).expect("a state the bound had is valid");
                })
            }
        }
    }

    pub fn reset(&mut self) {
        match self {
            Bounds::Speed(b) => b.reset(),
            Bounds::Web(w) => {
                w.speed.reset();
                w.tension.reset();
            }
            Bounds::Friction(f) => {
                f.speed.reset();
                f.friction.reset();
            }
        }
    }

    pub fn elapsed(&self) -> f64 {
        match self {
            Bounds::Speed(b) => b.elapsed(),
            Bounds::Web(w) => w.speed.elapsed(),
            Bounds::Friction(f) => f.speed.elapsed(),
        }
    }

    /// The longest advance accepted in one call (the web line's two bounds share their loop).
    pub fn max_advance(&self) -> f64 {
        match self {
            Bounds::Speed(b) => b.max_advance(),
            Bounds::Web(w) => w.speed.max_advance().min(w.tension.max_advance()),
            Bounds::Friction(f) => f.speed.max_advance().min(f.friction.max_advance()),
        }
    }

    /// `bound` on `trajectory` (it matters only with a damper in the compliant member).
    pub fn bound(&self, trajectory: Trajectory) -> f64 {
        match self {
            Bounds::Speed(b) => b.damped_bound(trajectory),
            Bounds::Web(w) => w.speed.damped_bound(trajectory),
            Bounds::Friction(f) => f.speed.damped_bound(trajectory) + f.friction.bound(),
        }
    }

    pub fn bound_paper(&self) -> f64 {
        match self {
            Bounds::Speed(b) => b.bound_paper(),
            Bounds::Web(w) => w.speed.bound_paper(),
            Bounds::Friction(f) => f.speed.bound_paper(),
        }
    }

    pub fn bound_rate(&self, trajectory: Trajectory) -> f64 {
        match self {
            Bounds::Speed(b) => b.damped_bound_rate(trajectory),
            Bounds::Web(w) => w.speed.damped_bound_rate(trajectory),
            Bounds::Friction(f) => f.speed.damped_bound_rate(trajectory) + f.friction.bound_rate(),
        }
    }

    pub fn bound_paper_rate(&self) -> f64 {
        match self {
            Bounds::Speed(b) => b.bound_paper_rate(),
            Bounds::Web(w) => w.speed.bound_paper_rate(),
            Bounds::Friction(f) => f.speed.bound_paper_rate(),
        }
    }

    /// `bound_T` (0 without a web span, which has no such variable).
    pub fn bound_t(&self, trajectory: Trajectory) -> f64 {
        match self {
            Bounds::Speed(_) | Bounds::Friction(_) => 0.0,
            Bounds::Web(w) => w.tension.damped_bound(trajectory),
        }
    }

    pub fn bound_t_rate(&self, trajectory: Trajectory) -> f64 {
        match self {
            Bounds::Speed(_) | Bounds::Friction(_) => 0.0,
            Bounds::Web(w) => w.tension.damped_bound_rate(trajectory),
        }
    }

    /// `bound_sup`, or why it is +∞.
    pub fn sup(&self) -> Result<f64, Unbounded> {
        match self {
            Bounds::Speed(b) => b.sup(),
            Bounds::Web(w) => w.speed.sup(),
            Bounds::Friction(f) => Ok(f.speed.sup()? + f.friction.sup()?),
        }
    }

    /// `bound_T_sup`, or why it is +∞ (0 without a web span).
    pub fn sup_t(&self) -> Result<f64, Unbounded> {
        match self {
            Bounds::Speed(_) | Bounds::Friction(_) => Ok(0.0),
            Bounds::Web(w) => w.tension.sup(),
        }
    }

    /// The largest relative slack of the suprema (see `LoopBound::sup_slack`).
    pub fn sup_slack(&self) -> f64 {
        match self {
            Bounds::Speed(b) => b.sup_slack().unwrap_or(0.0),
            Bounds::Web(w) => {
                let slack = |s: Option<f64>| s.unwrap_or(0.0);
                slack(w.speed.sup_slack()).max(slack(w.tension.sup_slack()))
            }
            Bounds::Friction(f) => f.speed.sup_slack().unwrap_or(0.0).max(f.friction.sup_slack()),
        }
    }

    /// The evolving state as plain numbers, [`Bounds::word_count`] of them (FMU states).
    pub fn words(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(Self::word_count(matches!(self, Bounds::Web(_))));
        let cl = words::<{ crate::physics::closed_loop::CL }>();
        match self {
            Bounds::Speed(b) => {
                put(&mut out, &b.state());
                out.resize(3 * cl, 0.0);
            }
            Bounds::Web(w) => {
                put(&mut out, &w.speed.state());
                put(&mut out, &w.tension.state());
            }
            Bounds::Friction(f) => {
                put(&mut out, &f.speed.state());
                for term in f.friction.states() {
                    match term {
                        Some(s) => put(&mut out, &s),
                        None => out.resize(out.len() + cl, 0.0),
                    }
                }
            }
        }
        out
    }

    /// Restores [`Bounds::words`] (validated; both bounds of the web line at the same time).
    pub fn restore(&mut self, saved: &[f64]) -> Result<(), BoundError> {
        if saved.len() != Self::word_count(matches!(self, Bounds::Web(_))) {
            return Err(BoundError::BadState);
        }
        let cl = words::<{ crate::physics::closed_loop::CL }>();
        // The friction terms' room is zeros where there is no term.
        let empty = |words: &[f64]| words.iter().all(|x| *x == 0.0);
        match self {
            Bounds::Speed(b) if empty(&saved[cl..]) => b.restore(&take(&saved[..cl])),
            Bounds::Speed(_) => Err(BoundError::BadState),
            Bounds::Friction(f) => {
                let bodies: Vec<Option<BoundState>> = f
                    .friction
                    .states()
                    .iter()
                    .zip(saved[cl..].chunks(cl))
                    .map(|(built, words)| built.map(|_| take(words)))
                    .collect();
                let unused = f
                    .friction
                    .states()
                    .iter()
                    .zip(saved[cl..].chunks(cl))
                    .any(|(built, words)| built.is_none() && !empty(words));
                if unused {
                    return Err(BoundError::BadState);
                }
                let speed = take(&saved[..cl]);
                if bodies.iter().flatten().any(|b| b.elapsed != speed.elapsed) {
                    return Err(BoundError::BadState);
                }
                f.speed.restore(&speed)?;
                f.friction.restore(&bodies)
            }
            Bounds::Web(w) => {
                let (speed, tension) = saved.split_at(saved.len() / 2);
                let (speed, tension) = (take(speed), take(tension));
                if speed.elapsed != tension.elapsed {
                    return Err(BoundError::BadState);
                }
                w.speed.restore(&speed)?;
                w.tension.restore(&tension)
            }
        }
    }
}

/// A two-stage gearbox's bound (docs/model.md §10) as FMU-state words: each stage's term, then
/// each body's friction term (zeros for a body without friction), each `2N + 4` words.
pub mod two_stage {
    use super::{put, take, words};
    use crate::physics::chain::TwoStageBound;
    use crate::physics::BoundError;

    /// The loop's size (the two-stage chain's loop state, docs/model.md §10).
    const N: usize = 7;

    /// How many words: two stages and three bodies.
    pub const WORDS: usize = 5 * words::<N>();

    pub fn words_of(bound: &TwoStageBound) -> Vec<f64> {
        let mut out = Vec::with_capacity(WORDS);
        for term in bound.states() {
            match term {
                Some(s) => put(&mut out, &s),
                None => out.resize(out.len() + words::<N>(), 0.0),
            }
        }
        out
    }

    /// Restores [`words_of`]: refused unless every term's room is a state where the bound has that
    /// term and zeros where it has none, all at one elapsed time.
    pub fn restore(bound: &mut TwoStageBound, saved: &[f64]) -> Result<(), BoundError> {
        if saved.len() != WORDS {
            return Err(BoundError::BadState);
        }
        let built = bound.states();
        let mut states = Vec::with_capacity(built.len());
        for (term, w) in built.iter().zip(saved.chunks(words::<N>())) {
            match term {
                Some(_) => states.push(Some(take::<N>(w))),
                None if w.iter().all(|x| *x == 0.0) => states.push(None),
                None => return Err(BoundError::BadState),
            }
        }
        let elapsed = states[0].as_ref().map(|s| s.elapsed);
        if states.iter().flatten().any(|s| Some(s.elapsed) != elapsed) {
            return Err(BoundError::BadState);
        }
        bound.restore(&states)
    }
}
