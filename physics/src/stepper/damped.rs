//! The stepper's part that only a damper in the compliant member needs (docs/model.md §2,
//! "With a damper"): the surfaces of the force and of law 1's cap (defined once for a member in
//! crate::damper, with the chain's stages), their certificates and their location on a piece,
//! and the variation V of u over the slack, capped and free phases that the bound takes (§3).

use super::{Exact, Exit};
use crate::damper::{variation, DampedExit, DampedMember};
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

    /// The member's damper as its surfaces see it (crate::damper).
    #[inline(always)]
    fn member(&self) -> DampedMember {
        DampedMember {
            k: self.plant.stiffness(),
            d: self.damping,
            g: self.plant.half_gap(),
            law1: self.law1,
        }
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
        let member = self.member();
        let mut best: Option<Exit> = None;
        for (surface, sign, to) in self.damped_exits(mode).into_iter().flatten() {
            if self.clear_surfaces(&[Some((surface, sign, to)), None], u, du, d2, c3, span) {
                continue;
            }
            let ([on_u, on_v, on_one], tol) = member.signal(surface, u, du);
            let mut c = AugVector::<N>::zeros();
            c[linear::U] = on_u;
            c[linear::V] = on_v;
            c[linear::ONE] = on_one;
            let sparse = &self.modes[mode.index()].sparse;
            let p = model.get_or_expand(sparse, y, span).signal(&c);
            let limit = best.map_or(span, |b| b.offset);
            let side = Side { offset: 0.0, sign, tol };
            if let Ok(Some(offset)) = roots::first_exit(&p, side, limit, budget) {
                let (u_at, du_at) = member.crossing(surface, mode, to, || {
                    model.get().expect("filled above").at(offset)[linear::U]
                });
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

    /// The surfaces that end `mode` ([`DampedMember::exits`]).
    fn damped_exits(&self, mode: ContactMode) -> [Option<DampedExit>; 2] {
        self.member().exits(mode)
    }

    /// True when none of `surfaces` can be reached within `span` ([`DampedMember::clear`]).
    /// Out of line: `clear_damped`'s common case returns before it, and inlined into the step it
    /// made both the plain and the damped event-free steps 7 to 10% slower (`taskset -c 1 cargo
    /// bench --bench physics -- damped`, its paired-damped-step line).
    #[inline(never)]
    fn clear_surfaces(&self, surfaces: &[Option<DampedExit>; 2], u: f64, du: f64, d2: f64, c3: f64, span: f64) -> bool {
        self.member().clear(surfaces, u, du, d2, c3, span)
    }
}
