//! The dependencies of the model structure, computed from each model's plant (its physics
//! mapping, [`crate::Model::plant_params`]) rather than listed: the states and inputs a state
//! derivative depends on are the non-zero entries of the plant's Jacobian in contact, the states
//! ψ and the event indicators depend on are those whose change changes them, and the parameters
//! an initial unknown depends on are those whose change changes it.
//!
//! All are read at generic points: the default parameters (a parameter whose default is 0 taken
//! as 1, so that no product vanishes by a zero factor and the damper is in place), a state on the
//! positive flank with every entry non-zero, the same state moving so fast that law 1 caps the
//! damper's force (a quantity may read a parameter or a state in one mode only: ψ reads
//! `contact_law` only under the cap, the speeds only outside it), and non-zero inputs. A
//! dependency is one at any of the points. A quantity that does not read a parameter is computed
//! by the same operations on the same numbers whatever that parameter's value, so a dependency
//! shows as a changed value and independence as an identical one. A Real is changed by half its
//! value; an Integer (`contact_law`) to another admissible value.

use backlash_physics::{Chain, Plant, PlantState};

use crate::common::{depends_on_time, vr_of, CONTACT_INDICATORS, EVENT_INDICATORS};
use crate::models::{parameters, physics_of, Physics};
use crate::{Causality, Model, Range, Type, Var};

/// The plant's input lines, in the order of the model's inputs by value reference: τ_m, τ_L,
/// and on a web line v_in, T_in (docs/model.md §1, §8).
const INPUT_LINES: usize = 4;

/// The parameters of `model` at the generic point, by name.
fn generic_values(model: &Model) -> Vec<(&'static str, f64)> {
    parameters(model)
        .into_iter()
        .map(|(name, x)| (name, if x == 0.0 { 1.0 } else { x }))
        .collect()
}

/// `values` with the parameter at `i` changed: a Real by half its value, an Integer to the next
/// value its range admits (the one before at the top of the range), so that it stays admissible.
fn perturbed(model: &Model, values: &[(&'static str, f64)], i: usize) -> Vec<(&'static str, f64)> {
    let (name, x) = values[i];
    let v = model
        .variables
        .iter()
        .find(|v| v.name == name)
        .expect("a parameter is a variable");
    let changed = match (v.ty, v.range) {
        (Type::Real, _) => x * 1.5,
        (Type::Integer, Range::Integers { max, .. }) if x < max as f64 => x + 1.0,
        (Type::Integer, Range::Integers { min, .. }) if x > min as f64 => x - 1.0,
        (Type::Integer, _) => panic!(
            "{}: Integer parameter {name} has no other admissible value to change to",
            model.identifier
        ),
    };
    let mut values = values.to_vec();
    values[i].1 = changed;
    values
}

/// The generic states z of `physics`, in the units of the state nominals, each entry non-zero.
///
/// The single gap: z = [θ_m, ω_m, θ_L, ω_L, T] on the positive flank (u = 2.4 g), and where the
/// plant has a damper the same angles with the speeds scaled so that the damper's force is four
/// times the spring's, D u′ = 4 K (u − g) (where law 1 caps it).
///
/// A chain: z = [θ_0, ω_0, …, θ_S, ω_S, T] with every stage on its positive flank (u_i = 2.4 g_i
/// from the load's angle up), closing with D_i u_i′ = K_i (u_i − g_i)/2 (a damped flank) and, at
/// the second point, D_i u_i′ = 4 K_i (u_i − g_i) (capped); a stage without a damper closes at
/// u_i′ = 0.9 ω₀ g_i.
fn generic_states(physics: &Physics) -> Vec<Vec<f64>> {
    match physics {
        Physics::Gap(plant) => {
            let n = plant.state_nominals();
            let z = [3.1 * n[0], 1.3 * n[1], 0.7 * n[2], -0.6 * n[3], 0.8 * n[4]];
            if plant.damping() == 0.0 {
                return vec![z.to_vec()];
            }
            let state = gap_state(plant, &z);
            let scale = 4.0 * plant.stiffness() * (state.u - plant.half_gap()) / (plant.damping() * state.du);
            vec![z.to_vec(), vec![z[0], scale * z[1], z[2], scale * z[3], z[4]]]
        }
        Physics::TwoStage(chain) => {
            let at = |spring_over_damper: f64| chain_generic_state(chain, spring_over_damper);
            if (0..2).all(|i| chain.stage(i).d() == 0.0) {
                vec![at(0.5)]
            } else {
                vec![at(0.5), at(4.0)]
            }
        }
    }
}

/// A chain's generic state whose damped stages close with D_i u_i′ = `ratio` K_i (u_i − g_i).
fn chain_generic_state<const S: usize>(chain: &Chain<S>, ratio: f64) -> Vec<f64> {
    let n = chain.state_nominals();
    let omega0 = chain.contact_frequency();
    let (mut theta, mut omega) = (vec![0.0; S + 1], vec![0.0; S + 1]);
    theta[S] = 0.7 * n[2 * S];
    omega[S] = -0.6 * n[2 * S + 1];
    for i in (0..S).rev() {
        let s = chain.stage(i);
        let u = 2.4 * s.g;
        let du = if s.d() > 0.0 {
            ratio * s.k * (u - s.g) / s.d()
        } else {
            0.9 * omega0 * s.g
        };
        theta[i] = (u + s.c * theta[i + 1]) / s.a;
        omega[i] = (du + s.c * omega[i + 1]) / s.a;
    }
    let mut z: Vec<f64> = (0..=S).flat_map(|j| [theta[j], omega[j]]).collect();
    z.push(0.8 * n[2 * S + 2]);
    z
}

fn gap_state(plant: &Plant, z: &[f64]) -> PlantState {
    PlantState::new(plant, z[0], z[1], z[2], z[3]).with_tension(z[4])
}

/// The input lines at the generic point: τ_m, τ_L, v_in, T_in.
const GENERIC_INPUTS: [f64; INPUT_LINES] = [0.37, -0.23, 0.41, 1.9];

/// What the model structure reads of a plant at a state under the generic inputs.
#[derive(Clone, Copy)]
enum Quantity {
    /// The time derivative of the state entry (docs/model.md §1, §8).
    Rate(usize),
    /// ψ of the stage, with a damper clipped by the contact law (docs/model.md §1).
    Force(usize),
    /// The contact event indicator of that index, the stages' in turn (docs/model.md §6).
    Indicator(usize),
    /// The surfaces that decide the sign of the stage's ψ, its `contact` output: the event
    /// indicators u ∓ g and those of the damped force (not the cap, which changes ψ's size, not
    /// its sign).
    ContactSurfaces(usize),
}

impl Quantity {
    fn of(self, physics: &Physics, z: &[f64]) -> Vec<f64> {
        let [tau_m, tau_l, v_in, t_in] = GENERIC_INPUTS;
        match physics {
            Physics::Gap(plant) => {
                let state = gap_state(plant, z);
                match self {
                    Quantity::Rate(i) => {
                        let span = plant.web().map_or(0.0, |w| w.forcing(v_in, t_in));
                        let rates = plant.rates(&state, tau_m, tau_l);
                        vec![rates
                            .get(i)
                            .copied()
                            .unwrap_or_else(|| plant.tension_rate(&state, span))]
                    }
                    Quantity::Force(_) => vec![plant.force(state.u, state.du)],
                    Quantity::Indicator(i) => vec![plant.event_indicators(&state)[i]],
                    Quantity::ContactSurfaces(_) => plant.event_indicators(&state)[..4].to_vec(),
                }
            }
            Physics::TwoStage(chain) => {
                let state = chain.state_at(z);
                match self {
                    Quantity::Rate(i) => {
                        let span = chain.web().map_or(0.0, |w| w.forcing(v_in, t_in));
                        vec![chain.rates(&state, tau_m, tau_l, span)[i]]
                    }
                    Quantity::Force(stage) => vec![state.forces(chain)[stage]],
                    Quantity::Indicator(i) => vec![chain.event_indicators(&state)[i]],
                    Quantity::ContactSurfaces(stage) => {
                        let first = stage * CONTACT_INDICATORS;
                        chain.event_indicators(&state)[first..first + 4].to_vec()
                    }
                }
            }
        }
    }
}

/// The model's variables with `keep`, in value-reference order.
fn in_vr_order(model: &Model, keep: impl Fn(&Var) -> bool) -> Vec<&Var> {
    let mut vars: Vec<&Var> = model.variables.iter().filter(|v| keep(v)).collect();
    vars.sort_by_key(|v| v.vr);
    vars
}

/// The names of the continuous states of `model`, in value-reference order (z's order).
fn state_names(model: &Model) -> Vec<&'static str> {
    in_vr_order(model, Var::is_continuous_state)
        .iter()
        .map(|v| v.name)
        .collect()
}

/// The names of the parameters of `model` whose change changes `quantity` at a generic point.
fn parameter_dependencies(model: &Model, quantity: Quantity) -> Vec<&'static str> {
    let values = generic_values(model);
    let physics = physics_of(model, &values);
    let states = generic_states(&physics);
    let changed: Vec<Physics> = (0..values.len())
        .map(|i| physics_of(model, &perturbed(model, &values, i)))
        .collect();
    values
        .iter()
        .zip(&changed)
        .filter(|(_, other)| {
            // Exact: an independent quantity is the same arithmetic on the same numbers.
            states.iter().any(|z| quantity.of(other, z) != quantity.of(&physics, z))
        })
        .map(|((name, _), _)| *name)
        .collect()
}

/// The names of the continuous states whose change changes `quantity` at a generic point.
fn state_dependencies(model: &Model, quantity: Quantity) -> Vec<&'static str> {
    let physics = physics_of(model, &generic_values(model));
    let states = generic_states(&physics);
    state_names(model)
        .into_iter()
        .enumerate()
        .filter(|&(j, _)| {
            states.iter().any(|z| {
                let mut moved = z.clone();
                moved[j] *= 1.5;
                quantity.of(&physics, &moved) != quantity.of(&physics, z)
            })
        })
        .map(|(_, name)| name)
        .collect()
}

/// The stage a per-stage name belongs to: `psi_2` is ψ of stage 2 (index 1); a name without a
/// stage suffix belongs to the single gap (index 0).
fn stage_of(name: &str) -> (&str, usize) {
    match name.rsplit_once('_') {
        Some((base, j)) if j.len() == 1 && j.as_bytes()[0].is_ascii_digit() && j != "0" => {
            (base, usize::from(j.as_bytes()[0] - b'1'))
        }
        _ => (name, 0),
    }
}

/// The states the output `v` depends on in Continuous-Time Mode (no output depends on an
/// input: docs/model.md §1): a state output is the state itself; ψ's and `contact`'s (a stage's
/// on a chain) are computed from the physics (`contact` is the sign of ψ: on ±g it depends on
/// the sign of u′ as well, and with a damper on the force's); the others' as listed
/// ([`crate::common::output_dependencies`]; on a chain a body's `sliding`, and the load's
/// everywhere, reads every state).
pub(crate) fn output_dependencies(model: &Model, v: &Var) -> Vec<&'static str> {
    let two_stage = matches!(model.kind, crate::Kind::TwoStage(_));
    match stage_of(v.name) {
        _ if v.is_continuous_state() => vec![v.name],
        ("psi", stage) => state_dependencies(model, Quantity::Force(stage)),
        ("contact", stage) => state_dependencies(model, Quantity::ContactSurfaces(stage)),
        // A body's friction mode: the sign of its speed sliding, the law of stiction at rest
        // (the torque on the body, from every state; on a web line the load's torque carries
        // the span's tension T).
        _ if (two_stage && v.name.starts_with("sliding_")) || v.name == "sliding_L" => state_names(model),
        _ => crate::common::output_dependencies(v.name).to_vec(),
    }
}

/// The states the event indicator `name` (one of `model`'s [`crate::common::event_indicators`])
/// depends on in Continuous-Time Mode: u ∓ g on the angles, the damped force's and the cap's on
/// the angles and the speeds (u and u′; docs/model.md §6); per stage on a chain.
pub(crate) fn event_indicator_dependencies(model: &Model, name: &str) -> Vec<&'static str> {
    // A friction surface (docs/model.md §12): a sliding body's speed, or the torque on a stuck
    // one, from every state of the drive and the body's own input (none on an intermediate
    // body).
    if let Some(body) = name.strip_prefix("stop_") {
        let speed = format!("omega_{body}");
        return state_names(model).into_iter().filter(|s| *s == speed).collect();
    }
    if let Some(body) = name.strip_prefix("breakaway_") {
        let mut names = state_names(model);
        names.extend(match body {
            "m" => Some("tau_m"),
            "L" => Some("tau_L"),
            _ => None,
        });
        return names;
    }
    let (base, stage) = stage_of(name);
    let i = EVENT_INDICATORS[..CONTACT_INDICATORS]
        .iter()
        .position(|n| *n == base)
        .unwrap_or_else(|| panic!("{name} is not an event indicator"));
    state_dependencies(model, Quantity::Indicator(stage * CONTACT_INDICATORS + i))
}

/// The index in z of the state `der` is the derivative of: the continuous states in
/// value-reference order are z's entries in order.
fn state_index(model: &Model, der: &Var) -> usize {
    let of = der
        .derivative_of
        .unwrap_or_else(|| panic!("{} is not a state derivative", der.name));
    in_vr_order(model, Var::is_continuous_state)
        .iter()
        .position(|v| v.vr == of)
        .expect("a derivative's state is a continuous state")
}

/// The Jacobian of `physics`' vector field at z in the mode in force there: ∂z′/∂z and
/// ∂z′/∂(τ_m, τ_L, w), w the web span's forcing.
fn jacobian(physics: &Physics, z: &[f64]) -> (Vec<Vec<f64>>, Vec<[f64; 3]>) {
    match physics {
        Physics::Gap(plant) => {
            let (dz, dinputs) = plant.jacobian(&gap_state(plant, z));
            (dz.iter().map(|row| row.to_vec()).collect(), dinputs.to_vec())
        }
        Physics::TwoStage(chain) => chain.jacobian(&chain.state_at(z)),
    }
}

/// The states and inputs the state derivative `der` depends on in Continuous-Time Mode: the
/// non-zero entries of its row of the plant's Jacobian in contact (where the compliant member
/// couples both sides), with the web span's forcing w = (v_ref T_in − EA v_in)/L_w carried to
/// v_in and T_in.
pub(crate) fn derivative_dependencies(model: &Model, der: &Var) -> Vec<&'static str> {
    let physics = physics_of(model, &generic_values(model));
    let i = state_index(model, der);
    let (dv_in, dt_in) = physics
        .web()
        .map_or((0.0, 0.0), |w| (w.forcing(1.0, 0.0), w.forcing(0.0, 1.0)));
    let states = in_vr_order(model, Var::is_continuous_state);
    let inputs = in_vr_order(model, |v| v.causality == Causality::Input);
    assert!(
        inputs.len() <= INPUT_LINES,
        "{}: more inputs than the plant has",
        model.identifier
    );
    // The entries non-zero at any generic state (in any mode).
    let mut by_state = vec![false; states.len()];
    let mut by_input = vec![false; inputs.len()];
    for z in generic_states(&physics) {
        let (dz, dinputs) = jacobian(&physics, &z);
        let by_line = [
            dinputs[i][0],
            dinputs[i][1],
            dinputs[i][2] * dv_in,
            dinputs[i][2] * dt_in,
        ];
        by_state.iter_mut().zip(&dz[i]).for_each(|(b, d)| *b |= *d != 0.0);
        by_input.iter_mut().zip(by_line).for_each(|(b, d)| *b |= d != 0.0);
    }
    let states = states.iter().zip(by_state).filter(|(_, b)| *b);
    let inputs = inputs.iter().zip(by_input).filter(|(_, b)| *b);
    states.chain(inputs).map(|(v, _)| v.name).collect()
}

/// Variables (by value reference, sorted) whose start values and parameters the initial value
/// of `v` depends on (FMI 2.0 §2.2.8 InitialUnknowns, FMI 3.0 §2.4.8 `<InitialUnknown>`); None
/// means "all knowns".
///
/// A state derivative: its states and inputs, and the parameters of its equation. ψ and the
/// contact mode: their states, and the parameters of ψ and of the surfaces that decide its sign.
/// The bounds: none (they are 0 at the start time, docs/model.md §4). A calculated parameter
/// (the suprema of the bounds): every parameter, as they define the loop of docs/model.md §3
/// (§8).
pub(crate) fn initial_dependencies(model: &Model, v: &Var) -> Option<Vec<u32>> {
    let names: Vec<&str> = if v.derivative_of.is_some() {
        let rate = Quantity::Rate(state_index(model, v));
        let mut names = derivative_dependencies(model, v);
        names.extend(parameter_dependencies(model, rate));
        // A body's bearing friction (docs/model.md §12): its sliding torque, and its breakaway
        // for the mode it starts in.
        if let Some(speed) = v.name.strip_prefix("der(omega_") {
            let body = speed.trim_end_matches(')');
            for name in ["tau_c_", "peak_"] {
                let friction = format!("{name}{body}");
                let known = model.variables.iter().find(|p| p.name == friction);
                names.extend(known.map(|p| p.name));
            }
        }
        names
    } else if v.causality == Causality::CalculatedParameter {
        generic_values(model).iter().map(|(name, _)| *name).collect()
    } else if depends_on_time(v.name) {
        vec![]
    } else {
        let of = match stage_of(v.name) {
            ("psi", stage) => Quantity::Force(stage),
            // The mode exactly on ±g depends on the sign of u' as well (its states say so).
            ("contact", stage) => Quantity::ContactSurfaces(stage),
            _ => return None,
        };
        let mut names = output_dependencies(model, v);
        names.extend(parameter_dependencies(model, of));
        names
    };
    let mut vrs: Vec<u32> = names.iter().map(|n| vr_of(model, n)).collect();
    vrs.sort_unstable();
    vrs.dedup();
    Some(vrs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::physics_of;
    use crate::{model, model_identifiers, Kind};

    /// The plants with one gap (a two-stage gearbox's structure has its own test).
    fn single_gap_identifiers() -> Vec<&'static str> {
        model_identifiers()
            .iter()
            .copied()
            .filter(|id| matches!(model(id).kind, Kind::Plant(_)))
            .collect()
    }
    use backlash_physics::ContactMode;

    #[test]
    fn the_generic_states_are_in_contact_with_and_without_the_cap_every_entry_non_zero() {
        for id in single_gap_identifiers() {
            let m = model(id);
            let plant = crate::models::plant_of(&m, &generic_values(&m));
            assert!(plant.damping() > 0.0, "{id}: the generic point has a damper");
            let physics = Physics::Gap(plant);
            let modes: Vec<ContactMode> = generic_states(&physics)
                .iter()
                .map(|z| gap_state(&plant, z).mode)
                .collect();
            assert_eq!(modes, [ContactMode::Positive, ContactMode::CappedPositive], "{id}");
            for z in generic_states(&physics) {
                assert!(z.iter().all(|x| *x != 0.0), "{id}: {z:?}");
            }
        }
    }

    /// contact_law moves between 1 and 2 only; a Real by half its value.
    #[test]
    fn an_integer_parameter_is_changed_within_its_range() {
        let m = model("BacklashShaft");
        let values = generic_values(&m);
        let at = |values: &[(&str, f64)], name: &str| values.iter().find(|(n, _)| *n == name).unwrap().1;
        let law = values.iter().position(|(n, _)| *n == "contact_law").unwrap();
        assert_eq!(at(&values, "contact_law"), 1.0);
        let once = perturbed(&m, &values, law);
        assert_eq!(at(&once, "contact_law"), 2.0);
        assert_eq!(at(&perturbed(&m, &once, law), "contact_law"), 1.0);
        let d = values.iter().position(|(n, _)| *n == "d").unwrap();
        assert_eq!(at(&values, "d"), 1.0);
        assert_eq!(at(&perturbed(&m, &values, d), "d"), 1.5);
    }

    /// The derived structure against the equations of docs/model.md §1 and §8, written out.
    #[test]
    fn the_derived_dependencies_are_those_of_the_equations() {
        let sorted = |mut names: Vec<&'static str>| {
            names.sort_unstable();
            names
        };
        let deps = |id: &str, name: &str| {
            let m = model(id);
            let v = *m.variables.iter().find(|v| v.name == name).unwrap();
            sorted(derivative_dependencies(&m, &v))
        };
        // ψ reads u′ through the damper: each acceleration depends on both speeds.
        for id in ["BacklashShaft", "BacklashBelt", "BacklashWeb"] {
            assert_eq!(deps(id, "der(theta_m)"), ["omega_m"], "{id}");
            assert_eq!(deps(id, "der(theta_L)"), ["omega_L"], "{id}");
            assert_eq!(
                deps(id, "der(omega_m)"),
                ["omega_L", "omega_m", "tau_m", "theta_L", "theta_m"],
                "{id}"
            );
        }
        assert_eq!(
            deps("BacklashBelt", "der(omega_L)"),
            ["omega_L", "omega_m", "tau_L", "theta_L", "theta_m"]
        );
        assert_eq!(
            deps("BacklashWeb", "der(omega_L)"),
            ["T", "omega_L", "omega_m", "tau_L", "theta_L", "theta_m"]
        );
        assert_eq!(deps("BacklashWeb", "der(T)"), ["T", "T_in", "omega_L", "v_in"]);

        let params = |id: &str, q: Quantity| sorted(parameter_dependencies(&model(id), q));
        // J_m ω_m' = τ_m − b_m ω_m − r_m ψ(u, u′): the motor's inertia and friction, and the
        // transmission's stiffness, damping, contact law, lever arms and gap.
        assert_eq!(
            params("BacklashShaft", Quantity::Rate(1)),
            ["Delta", "J_m", "b_m", "contact_law", "d", "k"]
        );
        assert_eq!(
            params("BacklashBelt", Quantity::Rate(1)),
            [
                "D_b",
                "Delta",
                "J_m",
                "K_b",
                "R_1",
                "R_2",
                "R_g1",
                "R_g2",
                "b_m",
                "contact_law"
            ]
        );
        // The web pulls the load with R_w T; L_w T' = EA R_w ω_L − v_ref T + v_ref T_in − EA v_in.
        assert_eq!(
            params("BacklashWeb", Quantity::Rate(3)),
            [
                "D_b",
                "Delta",
                "J_L",
                "K_b",
                "R_1",
                "R_2",
                "R_g1",
                "R_g2",
                "R_w",
                "b_L",
                "contact_law"
            ]
        );
        assert_eq!(params("BacklashWeb", Quantity::Rate(4)), ["EA", "L_w", "R_w", "v_ref"]);
        // u ∓ g with u = r_m θ_m − r_L θ_L: the lever arms and the gap, not the stiffness; the
        // damped force's surfaces K (u ∓ g) + D u′ also K and D; the cap's also the law (it is
        // 1 under law 2); ψ all of them; its sign not the law.
        assert_eq!(params("BacklashShaft", Quantity::Indicator(0)), ["Delta"]);
        assert_eq!(params("BacklashShaft", Quantity::Indicator(3)), ["Delta", "d", "k"]);
        assert_eq!(
            params("BacklashShaft", Quantity::Indicator(4)),
            ["Delta", "contact_law", "d", "k"]
        );
        assert_eq!(
            params("BacklashShaft", Quantity::ContactSurfaces(0)),
            ["Delta", "d", "k"]
        );
        assert_eq!(
            params("BacklashShaft", Quantity::Force(0)),
            ["Delta", "contact_law", "d", "k"]
        );

        // The states: ψ and the damped surfaces read u and u′, u ∓ g the angles alone.
        for id in single_gap_identifiers() {
            let m = model(id);
            let psi = m.variables.iter().find(|v| v.name == "psi").unwrap();
            let all = ["omega_L", "omega_m", "theta_L", "theta_m"];
            assert_eq!(sorted(output_dependencies(&m, psi)), all, "{id}");
            // The friction surfaces (docs/model.md §12): a speed, or the torque on a body at
            // rest (every state of the drive, the web's T included, and its own input).
            let states: Vec<&str> = in_vr_order(&m, Var::is_continuous_state)
                .iter()
                .map(|v| v.name)
                .collect();
            let with = |input: &'static str| {
                let mut names = states.clone();
                names.push(input);
                sorted(names)
            };
            for name in EVENT_INDICATORS {
                let expected: Vec<&str> = match name {
                    "u_minus_g" | "u_plus_g" => vec!["theta_L", "theta_m"],
                    "stop_m" => vec!["omega_m"],
                    "stop_L" => vec!["omega_L"],
                    "breakaway_m" => with("tau_m"),
                    "breakaway_L" => with("tau_L"),
                    _ => all.to_vec(),
                };
                assert_eq!(sorted(event_indicator_dependencies(&m, name)), expected, "{id} {name}");
            }
        }
    }

    /// BacklashTwoStage's structure against docs/model.md §10's equations with a = 1, c = n_j,
    /// written out: J_m ω_m′ = τ_m − b_m ω_m − ψ_1, J_i ω_i′ = −b_i ω_i + n_1 ψ_1 − ψ_2,
    /// J_L ω_L′ = τ_L − b_L ω_L + n_2 ψ_2, ψ_j of u_j = θ_{j−1} − n_j θ_j and u_j′ (each body
    /// sliding with friction at the generic point, τ_c = 1 there).
    #[test]
    fn the_two_stage_dependencies_are_those_of_its_equations() {
        let m = model("BacklashTwoStage");
        let sorted = |mut names: Vec<&'static str>| {
            names.sort_unstable();
            names
        };
        let var = |name: &str| *m.variables.iter().find(|v| v.name == name).unwrap();
        let deps = |name: &str| sorted(derivative_dependencies(&m, &var(name)));
        assert_eq!(deps("der(theta_m)"), ["omega_m"]);
        assert_eq!(deps("der(theta_i)"), ["omega_i"]);
        assert_eq!(deps("der(theta_L)"), ["omega_L"]);
        assert_eq!(
            deps("der(omega_m)"),
            ["omega_i", "omega_m", "tau_m", "theta_i", "theta_m"]
        );
        assert_eq!(
            deps("der(omega_i)"),
            ["omega_L", "omega_i", "omega_m", "theta_L", "theta_i", "theta_m"]
        );
        assert_eq!(
            deps("der(omega_L)"),
            ["omega_L", "omega_i", "tau_L", "theta_L", "theta_i"]
        );

        let params = |q: Quantity| sorted(parameter_dependencies(&m, q));
        assert_eq!(
            params(Quantity::Rate(1)),
            ["Delta_1", "J_m", "b_m", "contact_law", "d_1", "k_1", "n_1", "tau_c_m"]
        );
        assert_eq!(
            params(Quantity::Rate(3)),
            [
                "Delta_1",
                "Delta_2",
                "J_i",
                "b_i",
                "contact_law",
                "d_1",
                "d_2",
                "k_1",
                "k_2",
                "n_1",
                "n_2",
                "tau_c_i"
            ]
        );
        assert_eq!(
            params(Quantity::Force(1)),
            ["Delta_2", "contact_law", "d_2", "k_2", "n_2"]
        );
        assert_eq!(params(Quantity::Indicator(0)), ["Delta_1", "n_1"]);
        assert_eq!(params(Quantity::Indicator(CONTACT_INDICATORS)), ["Delta_2", "n_2"]);
        assert_eq!(params(Quantity::ContactSurfaces(1)), ["Delta_2", "d_2", "k_2", "n_2"]);

        let outputs = |name: &str| sorted(output_dependencies(&m, &var(name)));
        assert_eq!(outputs("psi_1"), ["omega_i", "omega_m", "theta_i", "theta_m"]);
        assert_eq!(outputs("contact_2"), ["omega_L", "omega_i", "theta_L", "theta_i"]);
        let indicators = |name: &str| sorted(event_indicator_dependencies(&m, name));
        assert_eq!(indicators("u_minus_g_1"), ["theta_i", "theta_m"]);
        assert_eq!(indicators("u_plus_g_2"), ["theta_L", "theta_i"]);
        assert_eq!(indicators("cap_lower_2"), ["omega_L", "omega_i", "theta_L", "theta_i"]);
        assert_eq!(indicators("stop_i"), ["omega_i"]);
        assert_eq!(indicators("breakaway_i").len(), 6, "every state, no input");

        // The event indicators: each mesh's six contact surfaces, then the bodies' friction.
        let names: Vec<&str> = crate::common::event_indicators(&m).iter().map(|v| v.name).collect();
        let mut expected: Vec<String> = (1..=2)
            .flat_map(|j| {
                EVENT_INDICATORS[..CONTACT_INDICATORS]
                    .iter()
                    .map(move |n| format!("{n}_{j}"))
            })
            .collect();
        expected.extend(
            ["m", "i", "L"]
                .iter()
                .flat_map(|b| [format!("stop_{b}"), format!("breakaway_{b}")]),
        );
        assert_eq!(names, expected);
    }

    /// The generic points of a chain: every stage on its positive flank, damped (then capped
    /// under law 1), every entry non-zero.
    #[test]
    fn the_two_stage_generic_states_are_on_both_flanks_damped_and_capped() {
        use backlash_physics::ContactMode::{CappedPositive, Positive};
        let m = model("BacklashTwoStage");
        let Physics::TwoStage(chain) = physics_of(&m, &generic_values(&m)) else {
            panic!("a chain")
        };
        let modes: Vec<[ContactMode; 2]> = generic_states(&Physics::TwoStage(chain))
            .iter()
            .map(|z| {
                assert!(z.iter().all(|x| *x != 0.0), "{z:?}");
                *chain.state_at(z).mode.stages()
            })
            .collect();
        assert_eq!(modes, [[Positive; 2], [CappedPositive; 2]]);
    }
}
