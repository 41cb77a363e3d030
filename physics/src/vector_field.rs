//! The plant of docs/model.md §1 as a vector field: the right-hand side z' = f(z, τ), its
//! Jacobian, the event indicators and the scales of the states. This is what an importer's own
//! solver integrates (FMI Model Exchange, docs/model.md §6); the exact stepper does not use it.
//!
//! f is a pure function of the state: ψ = K·dz(u, g) with u = r_m θ_m − r_L θ_L recomputed from
//! the angles, so a solver that oversteps a contact switch is inaccurate there, never
//! inconsistent.

use super::mode::PlantState;
use super::params::{ContactLaw, Plant};

/// Scale of an angle state when there is no gap to measure it by [rad] (the default of the
/// Modelica Standard Library's ElastoBacklash).
pub(crate) const ANGLE_SCALE_WITHOUT_GAP: f64 = 1e-4;

/// How many event indicators every plant has ([`Plant::event_indicators`]); the descriptions
/// declare as many (a test of `fmu` ties them).
pub const EVENT_INDICATORS: usize = 6;

impl Plant {
    /// z' = d/dt [θ_m, ω_m, θ_L, ω_L] at `state` with torques τ_m, τ_L (docs/model.md §1):
    /// θ_m' = ω_m, J_m ω_m' = τ_m − b_m ω_m − r_m ψ, θ_L' = ω_L, J_L ω_L' = τ_L − b_L ω_L + r_L ψ
    /// (− R_w T when the load pulls a web span, docs/model.md §8).
    #[inline]
    pub fn rates(&self, state: &PlantState, tau_m: f64, tau_l: f64) -> [f64; 4] {
        let p = self.params();
        let psi = self.force(state.u, state.du);
        [
            state.omega_m,
            (tau_m - p.b_m * state.omega_m - self.r_m() * psi) / p.j_m,
            state.omega_l,
            (tau_l - p.b_l * state.omega_l + self.r_l() * psi - self.web_lever() * state.tension) / p.j_l,
        ]
    }

    /// T' of the web span at `state` under its forcing w = (v_ref T_in − EA v_in)/L_w
    /// (docs/model.md §8): L_w T' = EA R_w ω_L − v_ref T + L_w w. 0 without a web.
    #[inline]
    pub fn tension_rate(&self, state: &PlantState, span: f64) -> f64 {
        self.web().map_or(0.0, |w| {
            (w.ea * w.r_w * state.omega_l - w.v_ref * state.tension) / w.l_w + span
        })
    }

    /// The Jacobian of the vector field z' = d/dt [θ_m, ω_m, θ_L, ω_L, T] ([`Plant::rates`] and
    /// [`Plant::tension_rate`]) in the mode in force at `state`: ∂z'/∂z (rows z', columns θ_m,
    /// ω_m, θ_L, ω_L, T) and ∂z'/∂(τ_m, τ_L, w) with w the span's forcing. Without a web span T's
    /// row and column are 0. Exact inside a mode; on ±g, where ψ has a kink, it is the one-sided
    /// Jacobian of the mode being entered.
    pub fn jacobian(&self, state: &PlantState) -> ([[f64; 5]; 5], [[f64; 3]; 5]) {
        let p = self.params();
        let (r_m, r_l) = (self.r_m(), self.r_l());
        // ∂ψ/∂u and ∂ψ/∂u′ in the mode in force: K and D on a flank (2K and 0 where law 1 caps
        // the damper), 0 in the gap or slack; u′ = r_m ω_m − r_L ω_L.
        let (k, d) = state.mode.force_slopes(self.stiffness(), self.damping());
        // L_w T' = EA R_w ω_L − v_ref T + L_w w.
        let (pull, stretch, relax, forced) = self.web().map_or((0.0, 0.0, 0.0, 0.0), |w| {
            (w.r_w / p.j_l, w.ea * w.r_w / w.l_w, w.v_ref / w.l_w, 1.0)
        });
        let dz = [
            [0.0, 1.0, 0.0, 0.0, 0.0],
            [
                -r_m * k * r_m / p.j_m,
                -p.b_m / p.j_m - r_m * d * r_m / p.j_m,
                r_m * k * r_l / p.j_m,
                r_m * d * r_l / p.j_m,
                0.0,
            ],
            [0.0, 0.0, 0.0, 1.0, 0.0],
            [
                r_l * k * r_m / p.j_l,
                r_l * d * r_m / p.j_l,
                -r_l * k * r_l / p.j_l,
                -p.b_l / p.j_l - r_l * d * r_l / p.j_l,
                -pull,
            ],
            [0.0, 0.0, 0.0, stretch, -relax],
        ];
        let dinputs = [
            [0.0, 0.0, 0.0],
            [1.0 / p.j_m, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 1.0 / p.j_l, 0.0],
            [0.0, 0.0, forced],
        ];
        (dz, dinputs)
    }

    /// The event indicators (docs/model.md §6): u − g and u + g, then the surfaces of a damped
    /// member's force, K (u − g) + D u′ and K (u + g) + D u′ (τ_c + τ_d on either flank), and of
    /// law 1's cap, D u′ − K (u − g) and D u′ − K (u + g) (τ_d − τ_c). A surface the plant does
    /// not have (the force's without a damper, where they are u = ±g; the cap's under law 2)
    /// reads 1, which never changes sign; so does, with a damper and no gap, each lower surface,
    /// which is then its upper one. A contact switch is a sign change of one of them while the
    /// state is on that surface's flank; elsewhere a sign change switches nothing.
    #[inline]
    pub fn event_indicators(&self, state: &PlantState) -> [f64; EVENT_INDICATORS] {
        contact_surfaces(
            self.stiffness(),
            self.damping(),
            self.half_gap(),
            self.contact_law(),
            state.u,
            state.du,
        )
    }

    /// The rate of each event indicator, from the rates of u and u′.
    pub fn event_indicator_rates(&self, du: f64, ddu: f64) -> [f64; EVENT_INDICATORS] {
        contact_surface_rates(
            self.stiffness(),
            self.damping(),
            self.half_gap(),
            self.contact_law(),
            du,
            ddu,
        )
    }

    /// The scale each state moves on (docs/model.md §6): each angle at the gap it must resolve,
    /// g/r (1e-4 rad without a gap), each speed at that angle per contact period, ω₀ g/r, and a
    /// web span's tension at the force that balances on the roller the belt force of the load
    /// angle's scale, K (θ_L r_L) r_L/R_w (1 without a web). Importers derive absolute tolerances
    /// from these.
    pub fn state_nominals(&self) -> [f64; 5] {
        let angle = |r: f64| {
            let g = self.half_gap();
            if g > 0.0 {
                g / r
            } else {
                ANGLE_SCALE_WITHOUT_GAP
            }
        };
        let (theta_m, theta_l) = (angle(self.r_m()), angle(self.r_l()));
        let omega0 = self.contact_frequency();
        let tension = self
            .web()
            .map_or(1.0, |w| self.stiffness() * theta_l * self.r_l() * self.r_l() / w.r_w);
        [theta_m, omega0 * theta_m, theta_l, omega0 * theta_l, tension]
    }
}

/// The contact surfaces of one member (stiffness `k`, damping `d`, half gap `g`, law `law`) at
/// its coordinate `u` and rate `du`, in the order of [`Plant::event_indicators`] (which says what
/// each is, and why a surface the member does not have reads 1); a chain's stages each have them
/// (`Chain::event_indicators`).
#[inline(always)]
pub(crate) fn contact_surfaces(k: f64, d: f64, g: f64, law: ContactLaw, u: f64, du: f64) -> [f64; EVENT_INDICATORS] {
    if d == 0.0 {
        return [u - g, u + g, 1.0, 1.0, 1.0, 1.0];
    }
    let damper = d * du;
    let (upper, lower) = (k * (u - g), k * (u + g));
    let (cap_upper, cap_lower) = match law {
        ContactLaw::ElastoBacklash => (damper - upper, damper - lower),
        ContactLaw::ElastoBacklash2 => (1.0, 1.0),
    };
    if g == 0.0 {
        // Without a gap each lower surface is its upper one: declared once, so that an
        // importer sees one crossing, not two at the same instant.
        return [u, 1.0, upper + damper, 1.0, cap_upper, 1.0];
    }
    [u - g, u + g, upper + damper, lower + damper, cap_upper, cap_lower]
}

/// The rates of [`contact_surfaces`] from the rates of u and u′ (each surface is linear in u and
/// u′; the constant ones do not move).
#[inline(always)]
pub fn contact_surface_rates(k: f64, d: f64, g: f64, law: ContactLaw, du: f64, ddu: f64) -> [f64; EVENT_INDICATORS] {
    if d == 0.0 {
        return [du, du, 0.0, 0.0, 0.0, 0.0];
    }
    let force = k * du + d * ddu;
    let cap = match law {
        ContactLaw::ElastoBacklash => d * ddu - k * du,
        ContactLaw::ElastoBacklash2 => 0.0,
    };
    if g == 0.0 {
        return [du, 0.0, force, 0.0, cap, 0.0];
    }
    [du, du, force, force, cap, cap]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PlantParams;

    fn belt() -> Plant {
        Plant::new(crate::params::test_plants::servo_belt(None)).unwrap()
    }

    /// Central differences of `rates` against `jacobian`, away from the kinks.
    #[test]
    fn jacobian_matches_central_differences_in_every_mode() {
        let plant = belt();
        let g = plant.half_gap();
        for u_over_g in [-3.0, 0.3, 2.5] {
            let theta_m = u_over_g * g / plant.r_m();
            let state = PlantState::new(&plant, theta_m, 1.5, 0.0, -0.7);
            let (dz, dtau) = plant.jacobian(&state);
            let z = [state.theta_m, state.omega_m, state.theta_l, state.omega_l];
            let (tau_m, tau_l) = (0.02, -0.3);
            for j in 0..4 {
                let h = 1e-6 * z[j].abs().max(g);
                let at = |d: f64| {
                    let mut w = z;
                    w[j] += d;
                    plant.rates(&PlantState::new(&plant, w[0], w[1], w[2], w[3]), tau_m, tau_l)
                };
                let (plus, minus) = (at(h), at(-h));
                for i in 0..4 {
                    let fd = (plus[i] - minus[i]) / (2.0 * h);
                    let scale = dz[i].iter().fold(1.0, |m: f64, x| m.max(x.abs()));
                    assert!(
                        (fd - dz[i][j]).abs() <= 1e-6 * scale,
                        "u/g {u_over_g}: d{i}/d{j}: {fd} vs {}",
                        dz[i][j]
                    );
                }
            }
            for (j, h) in [(0, 1e-3), (1, 1e-3)] {
                let rates = |t: [f64; 2]| plant.rates(&state, t[0], t[1]);
                let mut up = [tau_m, tau_l];
                up[j] += h;
                let (a, b) = (rates(up), rates([tau_m, tau_l]));
                for i in 0..4 {
                    assert!(((a[i] - b[i]) / h - dtau[i][j]).abs() <= 1e-9 * dtau[i][j].abs().max(1.0));
                }
            }
        }
    }

    #[test]
    fn indicators_change_sign_at_the_flanks_and_nominals_scale_with_the_gap() {
        let plant = belt();
        let g = plant.half_gap();
        let on = |u: f64| plant.event_indicators(&PlantState::new(&plant, u / plant.r_m(), 0.0, 0.0, 0.0));
        assert!(on(1.5 * g)[0] > 0.0 && on(0.5 * g)[0] < 0.0 && on(0.5 * g)[1] > 0.0 && on(-1.5 * g)[1] < 0.0);
        let n = plant.state_nominals();
        assert!((n[0] * plant.r_m() / g - 1.0).abs() < 1e-15);
        assert!((n[2] * plant.r_l() / g - 1.0).abs() < 1e-15);
        assert!((n[1] / n[0] - plant.contact_frequency()).abs() < 1e-12 * plant.contact_frequency());
        let gapless = Plant::new(PlantParams::paper_rig(0.0)).unwrap();
        assert_eq!(gapless.state_nominals()[0], ANGLE_SCALE_WITHOUT_GAP);
    }
}
