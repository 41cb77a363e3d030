//! What a damper in a compliant member adds to stepping (docs/model.md §2, "With a damper"), for
//! one member: the single gap's (stepper/damped.rs) or one stage of a chain (chain/stepper.rs).
//! The surfaces that end each mode, their certificates over a span, their signals as rows on
//! (u, u′, 1), the state set on a crossing, and the growth of V over a piece (§3). Each stepper
//! places the rows in its own augmented layout.

use crate::mode::ContactMode;
use crate::roots;

/// A compliant member with a damper, as its surfaces see it (docs/model.md §1).
#[derive(Clone, Copy, Debug)]
pub(crate) struct DampedMember {
    /// Stiffness K [N·m/rad, or N/m when u is a length].
    pub k: f64,
    /// Damper D > 0 in u's units [N·m·s/rad, or N·s/m].
    pub d: f64,
    /// Half gap g in u [rad, or m].
    pub g: f64,
    /// Law 1 (`ElastoBacklash`): the capped modes and their surfaces exist.
    pub law1: bool,
}

/// A switching surface of a damped member (docs/model.md §2), on the flank `side` (±1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum DampedSurface {
    /// u = side·g.
    Gap(f64),
    /// τ_c + τ_d = K (u − side·g) + D u′ = 0: the force reaches 0 past the flank.
    Force(f64),
    /// τ_d − τ_c = D u′ − K (u − side·g) = 0: law 1's cap begins or ends.
    Cap(f64),
}

/// A surface that ends a mode, the sign that keeps the state in the mode (sign · signal ≥ 0),
/// and the mode entered across it.
pub(crate) type DampedExit = (DampedSurface, f64, ContactMode);

impl DampedMember {
    /// The surfaces that end `mode` (docs/model.md §2, "With a damper").
    #[inline(always)]
    pub fn exits(&self, mode: ContactMode) -> [Option<DampedExit>; 2] {
        use ContactMode::*;
        use DampedSurface::*;
        let law1 = self.law1;
        let gap = self.g > 0.0;
        // The mode a contact on flank `side` begins in: the damper pushes at once (law 2), or
        // its force is capped by the spring's, 0 at the flank (law 1).
        let entry = |side: f64| match (side > 0.0, law1) {
            (true, false) => Positive,
            (true, true) => CappedPositive,
            (false, false) => Negative,
            (false, true) => CappedNegative,
        };
        // Leaving a slack flank towards the other side: into the gap, or without one straight
        // onto the other flank.
        let past = |side: f64| if gap { Free } else { entry(-side) };
        match mode {
            Free => [Some((Gap(1.0), -1.0, entry(1.0))), Some((Gap(-1.0), 1.0, entry(-1.0)))],
            Positive => [
                Some((Force(1.0), 1.0, SlackPositive)),
                law1.then_some((Cap(1.0), -1.0, CappedPositive)),
            ],
            Negative => [
                Some((Force(-1.0), -1.0, SlackNegative)),
                law1.then_some((Cap(-1.0), 1.0, CappedNegative)),
            ],
            SlackPositive => [Some((Gap(1.0), 1.0, past(1.0))), Some((Force(1.0), -1.0, Positive))],
            SlackNegative => [Some((Gap(-1.0), -1.0, past(-1.0))), Some((Force(-1.0), 1.0, Negative))],
            CappedPositive => [Some((Cap(1.0), 1.0, Positive)), None],
            CappedNegative => [Some((Cap(-1.0), -1.0, Negative)), None],
        }
    }

    /// The spring's sign in a surface's signal: +K for the force, −K for law 1's cap.
    #[inline(always)]
    fn spring(&self, surface: DampedSurface) -> f64 {
        match surface {
            DampedSurface::Cap(_) => -self.k,
            _ => self.k,
        }
    }

    /// True when none of `surfaces` can be reached within `span` from u, u′ = `du`, u″ = `d2`
    /// with |u‴| ≤ `c3`: u = ±g by the cubic test of `roots`, the force's surfaces (whose third
    /// derivative involves u⁗) by the quadratic lower bound s₀ + s₁σ − C σ²/2 with
    /// C ≥ sup |K u″ + D u‴| ≤ K (|u″(0)| + span c3) + D c3.
    #[inline(always)]
    pub fn clear(&self, surfaces: &[Option<DampedExit>; 2], u: f64, du: f64, d2: f64, c3: f64, span: f64) -> bool {
        let (k, d, g) = (self.k, self.d, self.g);
        surfaces.iter().flatten().all(|&(surface, sign, _)| match surface {
            DampedSurface::Gap(side) => {
                let tol = 8.0 * f64::EPSILON * (u.abs() + g);
                roots::cubic_clear(sign * (u - side * g), sign * du, sign * d2, c3, span, tol)
            }
            DampedSurface::Force(side) | DampedSurface::Cap(side) => {
                let spring = self.spring(surface);
                let s0 = spring * (u - side * g) + d * du;
                let s1 = spring * du + d * d2;
                let curvature = k * (d2.abs() + span * c3) + d * c3;
                let tol = 8.0 * f64::EPSILON * (k * (u.abs() + g) + d * du.abs());
                roots::cubic_clear(sign * s0, sign * s1, -curvature, 0.0, span, tol)
            }
        })
    }

    /// A surface's signal as its coefficients on u, u′ and the constant 1, and its round-off
    /// floor at u, u′ = `v`.
    pub fn signal(&self, surface: DampedSurface, u: f64, v: f64) -> ([f64; 3], f64) {
        let (k, d, g) = (self.k, self.d, self.g);
        match surface {
            DampedSurface::Gap(side) => ([1.0, 0.0, -side * g], 8.0 * f64::EPSILON * (u.abs() + g)),
            DampedSurface::Force(side) | DampedSurface::Cap(side) => {
                // τ_c + τ_d = K (u ∓ g) + D u′, or τ_d − τ_c = D u′ − K (u ∓ g).
                let spring = self.spring(surface);
                (
                    [spring, d, -spring * side * g],
                    8.0 * f64::EPSILON * (k * (u.abs() + g) + d * v.abs()),
                )
            }
        }
    }

    /// The state set on a crossing of `surface` from `from` into `to`, as (u, u′), each `None`
    /// where the piece's own value stands: on u = ±g, u exactly there; on a surface of the
    /// force, u′ from u there (`u_at`, evaluated only then) so that the state lies on it
    /// (τ_c + τ_d = 0: D u′ = −K (u ∓ g); τ_d = τ_c: D u′ = K (u ∓ g)).
    pub fn crossing(
        &self,
        surface: DampedSurface,
        from: ContactMode,
        to: ContactMode,
        u_at: impl FnOnce() -> f64,
    ) -> (Option<f64>, Option<f64>) {
        match surface {
            DampedSurface::Gap(side) => (Some(side * self.g), None),
            DampedSurface::Force(_) | DampedSurface::Cap(_) => {
                // The flank: one of the two modes is past it.
                let side = if from.side() != 0.0 { from.side() } else { to.side() };
                let stretch = self.k * (u_at() - side * self.g);
                let sign = if matches!(surface, DampedSurface::Force(_)) {
                    -1.0
                } else {
                    1.0
                };
                (None, Some(sign * stretch / self.d))
            }
        }
    }
}

/// ∫|u′| over a piece of length `w` in `mode` that starts at u moving at u′ = `v` (u″ = `d2`
/// there, |u‴| ≤ `c3` over the piece) and ends with u = `u_end`: 0 in ordinary contact. Slack and
/// capped, u is monotone (u′ has the sign that opens the flank: slack, D u′ ≤ −K (u ∓ g); capped,
/// D u′ ≥ K (u ∓ g) on the positive flank), so it is |Δu|; free, |Δu| where u′ provably keeps its
/// sign (u′(σ) ≥ u′(0) + u″(0) σ − c3 σ²/2 for its sign), else the bound
/// ∫ (|u′(0)| + |u″(0)| σ + c3 σ²/2) dσ. The growth of V (docs/model.md §2, "With a damper"), for
/// one member or one stage of a chain.
pub(crate) fn variation(mode: ContactMode, u: f64, v: f64, d2: f64, c3: f64, w: f64, u_end: f64) -> f64 {
    match mode {
        ContactMode::Positive | ContactMode::Negative => 0.0,
        ContactMode::Free => {
            let sign = if v != 0.0 { v.signum() } else { d2.signum() };
            if v != 0.0 && roots::cubic_clear(sign * v, sign * d2, -c3, 0.0, w, 0.0) {
                (u_end - u).abs()
            } else {
                w * (v.abs() + w * (0.5 * d2.abs() + w * c3 / 6.0))
            }
        }
        _ => (u_end - u).abs(),
    }
}
