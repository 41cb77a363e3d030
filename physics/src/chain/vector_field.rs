//! The chain as a vector field: the right-hand side z′ = f(z, τ) over the bodies' angles and
//! speeds, its Jacobian, each stage's event indicators and the scales of the states (what an
//! importer's own solver integrates, docs/model.md §6; for one stage the single gap's
//! `crate::vector_field`, entry for entry).
//!
//! z = [θ_0, ω_0, θ_1, ω_1, …, θ_S, ω_S, T] (T, a web span's tension, 0 without one). f is a
//! pure function of the state and the bodies' friction modes: each ψ_i from u_i and u_i′
//! recomputed from the angles and speeds, so a solver that oversteps a switch is inaccurate
//! there, never inconsistent.

use super::params::Chain;
use super::state::{ChainMode, ChainState, Motion};
use crate::vector_field::{contact_surfaces, ANGLE_SCALE_WITHOUT_GAP};

impl<const S: usize> Chain<S> {
    /// The length of z: an angle and a speed per body, and T.
    pub const STATES: usize = 2 * S + 3;

    /// The state at z (its length [`Chain::STATES`]), each stage's mode and each body's friction
    /// mode by [`mode_of`].
    pub fn state_at(&self, z: &[f64]) -> ChainState<S> {
        assert_eq!(z.len(), Self::STATES, "z of a chain of {S} stages");
        let body = |j: usize| Motion {
            theta: z[2 * j],
            omega: z[2 * j + 1],
        };
        ChainState::new(self, body(0), std::array::from_fn(|i| body(i + 1))).with_tension(z[2 * S + 2])
    }

    /// The state at z with the bodies' friction modes of `mode` (Model Exchange keeps them as
    /// discrete states between events, docs/model.md §12); the stages' modes from u and u′.
    pub fn state_in(&self, z: &[f64], mode: &ChainMode<S>) -> ChainState<S> {
        let mut state = self.state_at(z);
        for j in 0..=S {
            state.mode.set_body(j, mode.body(j));
        }
        state
    }

    /// z of `state`.
    pub fn z_of(state: &ChainState<S>) -> Vec<f64> {
        let mut z: Vec<f64> = (0..=S)
            .flat_map(|j| [state.body(j).theta, state.body(j).omega])
            .collect();
        z.push(state.tension);
        z
    }

    /// How many event indicators each stage has.
    pub const STAGE_INDICATORS: usize = crate::vector_field::EVENT_INDICATORS;

    /// z′ at `state` with torques τ_m on the motor, τ_L on the load and the web span's forcing
    /// `span` (w = (v_ref T_in − EA v_in)/L_w, docs/model.md §8): θ_j′ = ω_j,
    /// J_j ω_j′ = −b_j ω_j + c_{j−1} ψ_{j−1} − a_j ψ_j (+ τ_m on the motor, + τ_L − R_w T on the
    /// load) ∓ τ_c sliding with Coulomb friction, 0 stuck; L_w T′ = EA R_w ω_S − v_ref T + L_w w.
    pub fn rates(&self, state: &ChainState<S>, tau_m: f64, tau_l: f64, span: f64) -> Vec<f64> {
        let psi = state.forces(self);
        let mut out = Vec::with_capacity(Self::STATES);
        for j in 0..=S {
            let body = self.body(j);
            let omega = state.body(j).omega;
            let mut torque = -body.b * omega;
            if j == 0 {
                torque += tau_m;
            }
            if j > 0 {
                torque += self.stage(j - 1).c * psi[j - 1];
            }
            if j < S {
                torque -= self.stage(j).a * psi[j];
            }
            if j == S {
                torque += tau_l - self.web().map_or(0.0, |w| w.r_w * state.tension);
            }
            let mode = state.mode.body(j);
            let friction = body.friction.tau_c;
            let accel = if friction > 0.0 && mode == super::BodyMode::Stuck {
                0.0
            } else if friction > 0.0 {
                (torque + mode.friction_sign() * friction) / body.j
            } else {
                torque / body.j
            };
            out.extend([omega, accel]);
        }
        out.push(self.web().map_or(0.0, |w| {
            (w.ea * w.r_w * state.body(S).omega - w.v_ref * state.tension) / w.l_w + span
        }));
        out
    }

    /// The Jacobian of [`Chain::rates`] in the mode in force at `state`: ∂z′/∂z (rows z′,
    /// columns z) and ∂z′/∂(τ_m, τ_L, w). Exact inside a mode; on a switching surface the
    /// one-sided Jacobian of the mode being entered.
    pub fn jacobian(&self, state: &ChainState<S>) -> (Vec<Vec<f64>>, Vec<[f64; 3]>) {
        let n = Self::STATES;
        let (theta, omega, tension) = (|j: usize| 2 * j, |j: usize| 2 * j + 1, 2 * S + 2);
        let mut dz = vec![vec![0.0; n]; n];
        let mut dinputs = vec![[0.0; 3]; n];
        for j in 0..=S {
            dz[theta(j)][omega(j)] = 1.0;
            let body = self.body(j);
            if body.friction.tau_c > 0.0 && state.mode.body(j) == super::BodyMode::Stuck {
                continue;
            }
            let row = &mut dz[omega(j)];
            row[omega(j)] -= body.b / body.j;
            // The members on body j: +c ψ of the stage before it, −a ψ of the stage after it;
            // ∂ψ_i/∂u_i and ∂ψ_i/∂u_i′ in the stage's mode, u_i = a_i θ_i − c_i θ_{i+1}.
            let mut member = |i: usize, lever: f64| {
                let s = self.stage(i);
                let (ks, kd) = state.mode.stages()[i].force_slopes(s.k, s.d());
                for (body_of, arm) in [(i, s.a), (i + 1, -s.c)] {
                    row[theta(body_of)] += lever * ks * arm / body.j;
                    row[omega(body_of)] += lever * kd * arm / body.j;
                }
            };
            if j > 0 {
                member(j - 1, self.stage(j - 1).c);
            }
            if j < S {
                member(j, -self.stage(j).a);
            }
            if j == 0 {
                dinputs[omega(j)][0] = 1.0 / body.j;
            }
            if j == S {
                dinputs[omega(j)][1] = 1.0 / body.j;
                if let Some(w) = self.web() {
                    dz[omega(j)][tension] = -w.r_w / body.j;
                }
            }
        }
        if let Some(w) = self.web() {
            dz[tension][omega(S)] = w.ea * w.r_w / w.l_w;
            dz[tension][tension] = -w.v_ref / w.l_w;
            dinputs[tension][2] = 1.0;
        }
        (dz, dinputs)
    }

    /// Each stage's contact surfaces at `state`, stage after stage, in the order of
    /// `Plant::event_indicators` (u_i ∓ g_i, the damped force's and law 1's cap's).
    pub fn event_indicators(&self, state: &ChainState<S>) -> Vec<f64> {
        (0..S)
            .flat_map(|i| {
                let s = self.stage(i);
                contact_surfaces(s.k, s.d(), s.g, s.damper.law, state.u[i], state.du[i])
            })
            .collect()
    }

    /// The scale each entry of z moves on (docs/model.md §6, as `Plant::state_nominals`): a
    /// body's angle at the finest gap it must resolve, g_i/a_i of the stage it drives and
    /// g_{i}/c_{i} of the stage that drives it (1e-4 rad where neither has a gap), its speed at
    /// that angle per contact period (ω₀ = √(Σ_i K_i (a_i²/J_i + c_i²/J_{i+1}))), and a web
    /// span's tension at the force that balances on the roller the last stage's force at the
    /// load angle's scale, K c² θ_S / R_w (1 without a web).
    pub fn state_nominals(&self) -> Vec<f64> {
        let angle = |j: usize| {
            let driving = (j < S).then(|| (self.stage(j).g, self.stage(j).a));
            let driven = (j > 0).then(|| (self.stage(j - 1).g, self.stage(j - 1).c));
            driving
                .into_iter()
                .chain(driven)
                .filter(|(g, _)| *g > 0.0)
                .map(|(g, r)| g / r)
                .reduce(f64::min)
                .unwrap_or(ANGLE_SCALE_WITHOUT_GAP)
        };
        let omega0 = self.contact_frequency();
        let mut z: Vec<f64> = (0..=S).flat_map(|j| [angle(j), omega0 * angle(j)]).collect();
        let last = self.stage(S - 1);
        z.push(self.web().map_or(1.0, |w| last.k * angle(S) * last.c * last.c / w.r_w));
        z
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::{ChainParams, Coulomb};
    use crate::params::test_plants;
    use crate::{ContactLaw, Damping, Plant, WebSpan};

    fn two_stage(d: f64, law: ContactLaw) -> Chain<2> {
        let mut p = ChainParams::two_stage_rig();
        p.stages[0].damper = Damping { d, law };
        p.stages[1].damper = Damping { d: 0.5 * d, law };
        p.stages[1].c = 2.5;
        p.driven[0].friction = Coulomb { tau_c: 0.2, peak: 1.5 };
        Chain::new(p).unwrap()
    }

    /// Central differences of `rates` against `jacobian` at states inside each stage's modes
    /// (both flanks, the gap, a damped flank), away from the kinks.
    #[test]
    fn jacobian_matches_central_differences() {
        for (d, law) in [(0.0, ContactLaw::ElastoBacklash), (3.0, ContactLaw::ElastoBacklash2)] {
            let chain = two_stage(d, law);
            let g = chain.stage(0).g;
            for (u1, u2) in [(3.0 * g, -2.5 * g), (0.2 * g, 4.0 * g), (-5.0 * g, 0.1 * g)] {
                // θ_i = 0.3; θ_m and θ_L place u_1 = θ_m − θ_i and u_2 = θ_i − c θ_L.
                let z = [0.3 + u1, 0.01, 0.3, -0.004, (0.3 - u2) / 2.5, 0.002, 0.0];
                let state = chain.state_at(&z);
                let (dz, dinputs) = chain.jacobian(&state);
                let f = |z: &[f64], tau: [f64; 3]| chain.rates(&chain.state_in(z, &state.mode), tau[0], tau[1], tau[2]);
                let nominals = chain.state_nominals();
                for k in 0..Chain::<2>::STATES - 1 {
                    let h = 1e-3 * nominals[k];
                    let (mut up, mut down) = (z, z);
                    up[k] += h;
                    down[k] -= h;
                    let (fu, fd) = (f(&up, [0.0; 3]), f(&down, [0.0; 3]));
                    for r in 0..Chain::<2>::STATES {
                        let fd_entry = (fu[r] - fd[r]) / (2.0 * h);
                        // Affine within the mode: the difference is exact up to the rounding of
                        // f's entries (~1e-16 of their size) over 2h.
                        let scale = fu[r].abs().max(fd[r].abs()) + 1.0;
                        assert!(
                            (fd_entry - dz[r][k]).abs() <= 1e-12 * scale / h,
                            "d={d} u=({u1},{u2}): d f_{r}/d z_{k} = {} by the Jacobian, {fd_entry} by differences",
                            dz[r][k]
                        );
                    }
                }
                for line in 0..2 {
                    let mut tau = [0.0; 3];
                    tau[line] = 1.0;
                    let (fu, f0) = (f(&z, tau), f(&z, [0.0; 3]));
                    for r in 0..Chain::<2>::STATES {
                        let diff = fu[r] - f0[r];
                        assert!(
                            (diff - dinputs[r][line]).abs() <= 1e-12 * (f0[r].abs() + 1.0),
                            "row {r} line {line}"
                        );
                    }
                }
            }
        }
    }

    /// The stepper's own field (`ChainStepper::rates`, the mode's rows over the augmented
    /// state, chain/linear.rs) is this one, written from the equations: two stages with friction
    /// on the intermediate shaft, in every stage's modes, within 4 ulps of each rate (measured:
    /// 1; the stepper recovers the speeds from u′ and the load's speed).
    #[test]
    fn the_steppers_field_is_this_one() {
        let chain = two_stage(0.0, ContactLaw::ElastoBacklash);
        let stepper = crate::chain::TwoStageStepper::new(chain);
        let g = chain.stage(0).g;
        let inputs = crate::Inputs {
            tau_m: 0.4,
            tau_l: -0.2,
            dtau_m: 0.0,
            dtau_l: 0.0,
            span: 0.0,
            dspan: 0.0,
        };
        for (u1, u2) in [(3.0 * g, -2.5 * g), (0.2 * g, 4.0 * g), (-5.0 * g, 0.1 * g)] {
            let z = [0.3 + u1, 0.01, 0.3, -0.004, (0.3 - u2) / 2.5, 0.002, 0.0];
            let state = chain.state_at(&z);
            let ours = chain.rates(&state, inputs.tau_m, inputs.tau_l, 0.0);
            let theirs = stepper.rates(&state, &inputs);
            for (r, (a, b)) in ours.iter().zip(&theirs).enumerate() {
                assert!(
                    (a - b).abs() <= 4.0 * f64::EPSILON * a.abs().max(b.abs()),
                    "rate {r}: {a} vs {b}"
                );
            }
        }
    }

    /// One stage is the single gap: the same rates, Jacobian, indicators and nominals, bit for
    /// bit, for the shaft, a damped belt and a web line (the same formulas over the same numbers;
    /// the chain sums its members' terms in another order only where a body has two members).
    #[test]
    fn one_stage_is_the_single_gap() {
        let plants = [
            test_plants::servo_belt(None),
            test_plants::servo_belt(Some(WebSpan {
                r_w: 0.05,
                l_w: 1.2,
                ea: 4e4,
                v_ref: 0.8,
            })),
        ];
        for params in plants {
            let plant = Plant::new(params).unwrap();
            let chain = Chain::new(ChainParams::from_plant(&plant).unwrap()).unwrap();
            let nominals = plant.state_nominals();
            assert_eq!(chain.state_nominals(), nominals.to_vec());
            let g = plant.half_gap();
            for theta_m in [3.0 * g, 0.5 * g, -2.0 * g] {
                let z = [theta_m / plant.r_m(), 0.3, 0.0, -0.1, 0.7];
                let single = crate::PlantState::new(&plant, z[0], z[1], z[2], z[3]).with_tension(z[4]);
                let state = chain.state_at(&z);
                assert_eq!(chain.event_indicators(&state), plant.event_indicators(&single).to_vec());
                let rates = chain.rates(&state, 0.4, -0.2, 0.05);
                let mut expected = plant.rates(&single, 0.4, -0.2).to_vec();
                expected.push(plant.tension_rate(&single, 0.05));
                for (a, b) in rates.iter().zip(&expected) {
                    assert!(
                        (a - b).abs() <= 4.0 * f64::EPSILON * (a.abs() + b.abs()),
                        "{rates:?} vs {expected:?}"
                    );
                }
                let (dz, dinputs) = chain.jacobian(&state);
                let (pdz, pdinputs) = plant.jacobian(&single);
                for r in 0..5 {
                    for c in 0..5 {
                        let (a, b) = (dz[r][c], pdz[r][c]);
                        assert!((a - b).abs() <= 4.0 * f64::EPSILON * b.abs(), "J[{r}][{c}]: {a} vs {b}");
                    }
                    assert_eq!(dinputs[r], pdinputs[r]);
                }
            }
        }
    }
}
