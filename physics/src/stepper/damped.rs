//! The stepper's part that only a damper in the compliant member needs (docs/model.md §2,
//! "With a damper"): the surfaces of the force and of law 1's cap, their certificates and their
//! location, and the variation V of u over the slack, capped and free phases that the bound
//! takes (§3).

use super::{Exact, Exit};
use crate::linear::{self, AugVector};
use crate::mode::ContactMode;
use crate::roots::{self, Side};
use crate::taylor::PieceModel;

impl<const N: usize, const KO: usize> Exact<N, KO> {
    /// The growth of [`PlantState::variation`](crate::mode::PlantState::variation) over a piece of length `w` in `mode` that starts
    /// at `y` (u″ = `d2` there, |u‴| ≤ `c3` over the piece) and ends with u = `u_end`: ∫|u′|
    /// over it, 0 in ordinary contact. Slack and capped, u is monotone (u′ has the sign that
    /// opens the flank: slack, D u′ ≤ −K (u ∓ g); capped, D u′ ≥ K (u ∓ g) on the positive flank),
    /// so it is |Δu|; free, |Δu| where u′ provably keeps its sign (u′(σ) ≥ u′(0) + u″(0) σ − c3 σ²/2
    /// for its sign), else the bound ∫ (|u′(0)| + |u″(0)| σ + c3 σ²/2) dσ.
    #[inline(never)]
    pub(super) fn variation(&self, mode: ContactMode, y: &AugVector<N>, d2: f64, c3: f64, w: f64, u_end: f64) -> f64 {
        variation(mode, y[linear::U], y[linear::V], d2, c3, w, u_end)
    }

    /// `variation` over the first `w` of a piece from `y` (`probe`: u″ and the bound on |u‴|
    /// when the kernel computed them for this span).
    pub(super) fn sub_variation(
        &self,
        mode: ContactMode,
        y: &AugVector<N>,
        probe: Option<(f64, f64)>,
        w: f64,
        u_end: f64,
    ) -> f64 {
        let rows = &self.modes[mode.index()].u_rows;
        let (d2, c3) = probe.unwrap_or_else(|| (rows.derivative(2, y), rows.third_bound(y, w)));
        self.variation(mode, y, d2, c3, w, u_end)
    }

    /// The surfaces that end `mode` of a damped plant, with the sign that keeps the state in it
    /// (sign · signal ≥ 0) and the mode entered across each (docs/model.md §2, "With a damper").
    pub(super) fn damped_exits(&self, mode: ContactMode) -> [Option<(DampedSurface, f64, ContactMode)>; 2] {
        use ContactMode::*;
        use DampedSurface::*;
        let law1 = self.law1;
        let gap = self.plant.half_gap() > 0.0;
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

    /// A surface's signal as a row on the augmented state, and its round-off floor at `y`.
    pub(super) fn damped_signal(&self, surface: DampedSurface, y: &AugVector<N>) -> (AugVector<N>, f64) {
        let (k, d, g) = (self.plant.stiffness(), self.damping, self.plant.half_gap());
        let mut c = AugVector::<N>::zeros();
        let (u, v) = (y[linear::U], y[linear::V]);
        let tol = match surface {
            DampedSurface::Gap(side) => {
                c[linear::U] = 1.0;
                c[linear::ONE] = -side * g;
                8.0 * f64::EPSILON * (u.abs() + g)
            }
            DampedSurface::Force(side) | DampedSurface::Cap(side) => {
                // τ_c + τ_d = K (u ∓ g) + D u′, or τ_d − τ_c = D u′ − K (u ∓ g).
                let spring = if matches!(surface, DampedSurface::Force(_)) {
                    k
                } else {
                    -k
                };
                c[linear::U] = spring;
                c[linear::V] = d;
                c[linear::ONE] = -spring * side * g;
                8.0 * f64::EPSILON * (k * (u.abs() + g) + d * v.abs())
            }
        };
        (c, tol)
    }

    /// `clear` with a damper: every surface of `mode` certified out of reach within `span`.
    /// u's surfaces by the cubic of `roots`; the force's, whose third derivative involves u⁗,
    /// by the quadratic lower bound s₀ + s₁σ − C σ²/2 with C ≥ sup |s″| = sup |K u″ + D u‴|
    /// ≤ K (|u″(0)| + span c3) + D c3.
    #[inline(always)]
    pub(super) fn clear_damped(&self, mode: ContactMode, u: f64, du: f64, d2: f64, c3: f64, span: f64) -> bool {
        // The common case inline: a contact well inside its region, by the cheap test of
        // `roots::cubic_clear` on each of its surfaces (the largest fall of the quadratic).
        // Without the round-off floor (>= 0) the test is stricter, never weaker.
        let side = match mode {
            ContactMode::Positive => 1.0,
            ContactMode::Negative => -1.0,
            _ => 0.0,
        };
        if side != 0.0 {
            let (k, d, g) = (self.plant.stiffness(), self.damping, self.plant.half_gap());
            let spring = k * (u - side * g);
            let curvature = k * (d2.abs() + span * c3) + d * c3;
            let fall = |s1: f64| span * (s1.abs() + 0.5 * span * curvature);
            let force = side * (spring + d * du) > fall(k * du + d * d2);
            let cap = !self.law1 || side * (spring - d * du) > fall(d * d2 - k * du);
            if force & cap {
                return true;
            }
        }
        self.clear_surfaces(&self.damped_exits(mode), u, du, d2, c3, span)
    }

    /// `exit` with a damper: the first surface of `mode` crossed within `span`, searched on the
    /// piece's Taylor model like u = ±g without one. On u = ±g the exit sets u exactly there; on
    /// a surface of the force it sets u′ from u so that the state lies on it to round-off.
    #[cold]
    #[inline(never)]
    pub(super) fn exit_damped(
        &self,
        y: &AugVector<N>,
        mode: ContactMode,
        span: f64,
        probe: Option<(f64, f64)>,
        model: &mut PieceModel<N>,
        budget: &mut usize,
    ) -> Option<Exit> {
        let rows = &self.modes[mode.index()].u_rows;
        let (d2, c3) = probe.unwrap_or_else(|| (rows.derivative(2, y), rows.third_bound(y, span)));
        let (u, du) = (y[linear::U], y[linear::V]);
        let (k, d, g) = (self.plant.stiffness(), self.damping, self.plant.half_gap());
        let mut best: Option<Exit> = None;
        for (surface, sign, to) in self.damped_exits(mode).into_iter().flatten() {
            if self.clear_surfaces(&[Some((surface, sign, to)), None], u, du, d2, c3, span) {
                continue;
            }
            let (c, tol) = self.damped_signal(surface, y);
            let sparse = &self.modes[mode.index()].sparse;
            let p = model.get_or_expand(sparse, y, span).signal(&c);
            let limit = best.map_or(span, |b| b.offset);
            let side = Side { offset: 0.0, sign, tol };
            if let Ok(Some(offset)) = roots::first_exit(&p, side, limit, budget) {
                let (u_at, du_at) = match surface {
                    DampedSurface::Gap(side) => (Some(side * g), None),
                    DampedSurface::Force(_) | DampedSurface::Cap(_) => {
                        let at = model.get().expect("filled above").at(offset);
                        let side = mode_side(mode, to);
                        let stretch = k * (at[linear::U] - side * g);
                        // τ_c + τ_d = 0: D u′ = −K (u ∓ g); τ_d = τ_c: D u′ = K (u ∓ g).
                        let sign = if matches!(surface, DampedSurface::Force(_)) {
                            -1.0
                        } else {
                            1.0
                        };
                        (None, Some(sign * stretch / d))
                    }
                };
                best = Some(Exit {
                    offset,
                    to,
                    u: u_at,
                    du: du_at,
                });
            }
        }
        best
    }

    /// True when none of `surfaces` can be reached within `span` ([`Self::clear_damped`]).
    pub(super) fn clear_surfaces(
        &self,
        surfaces: &[Option<(DampedSurface, f64, ContactMode)>; 2],
        u: f64,
        du: f64,
        d2: f64,
        c3: f64,
        span: f64,
    ) -> bool {
        let (k, d, g) = (self.plant.stiffness(), self.damping, self.plant.half_gap());
        surfaces.iter().flatten().all(|&(surface, sign, _)| match surface {
            DampedSurface::Gap(side) => {
                let tol = 8.0 * f64::EPSILON * (u.abs() + g);
                roots::cubic_clear(sign * (u - side * g), sign * du, sign * d2, c3, span, tol)
            }
            DampedSurface::Force(side) | DampedSurface::Cap(side) => {
                let spring = if matches!(surface, DampedSurface::Force(_)) {
                    k
                } else {
                    -k
                };
                let s0 = spring * (u - side * g) + d * du;
                let s1 = spring * du + d * d2;
                let curvature = k * (d2.abs() + span * c3) + d * c3;
                let tol = 8.0 * f64::EPSILON * (k * (u.abs() + g) + d * du.abs());
                roots::cubic_clear(sign * s0, sign * s1, -curvature, 0.0, span, tol)
            }
        })
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

/// A switching surface of a damped plant (docs/model.md §2), on the flank `side` (±1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum DampedSurface {
    /// u = side·g.
    Gap(f64),
    /// τ_c + τ_d = K (u − side·g) + D u′ = 0: the force reaches 0 past the flank.
    Force(f64),
    /// τ_d − τ_c = D u′ − K (u − side·g) = 0: law 1's cap begins or ends.
    Cap(f64),
}

/// The flank of a switch on a surface of the force between `from` and `to` (one of them is past
/// it).
fn mode_side(from: ContactMode, to: ContactMode) -> f64 {
    if from.side() != 0.0 {
        from.side()
    } else {
        to.side()
    }
}
