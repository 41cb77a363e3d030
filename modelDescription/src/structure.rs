//! The dependencies of the model structure, computed from each model's plant (its physics
//! mapping, [`crate::Model::plant_params`]) rather than listed: the states and inputs a state
//! derivative depends on are the non-zero entries of the plant's Jacobian in contact, and the
//! parameters an initial unknown depends on are those whose change changes it.
//!
//! Both are read at a generic point: the default parameters (a parameter whose default is 0
//! taken as 1, so that no product vanishes by a zero factor), a state on the positive flank with
//! every entry non-zero, and non-zero inputs. A quantity that does not read a parameter is
//! computed by the same operations on the same numbers whatever that parameter's value, so a
//! dependency shows as a changed value and independence as an identical one.

use backlash_physics::{Plant, PlantState};

use crate::common::{depends_on_time, output_dependencies, vr_of};
use crate::models::{parameters, plant_of};
use crate::{Causality, Model, Var};

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

/// The generic state z = [θ_m, ω_m, θ_L, ω_L, T] of `plant`: on the positive flank (u = 2.4 g),
/// every entry non-zero, in the units of the state nominals.
fn generic_state(plant: &Plant) -> [f64; 5] {
    let n = plant.state_nominals();
    [3.1 * n[0], 1.3 * n[1], 0.7 * n[2], -0.6 * n[3], 0.8 * n[4]]
}

fn state_of(plant: &Plant, z: &[f64; 5]) -> PlantState {
    PlantState::new(plant, z[0], z[1], z[2], z[3]).with_tension(z[4])
}

/// The input lines at the generic point: τ_m, τ_L, v_in, T_in.
const GENERIC_INPUTS: [f64; INPUT_LINES] = [0.37, -0.23, 0.41, 1.9];

/// What the model structure reads of a plant at a state under the generic inputs.
#[derive(Clone, Copy)]
enum Quantity {
    /// The time derivative of the state entry (docs/model.md §1, §8).
    Rate(usize),
    /// ψ = K dz(u, g).
    Force,
    /// The event indicators u ∓ g.
    Indicators,
}

impl Quantity {
    fn of(self, plant: &Plant, z: &[f64; 5]) -> Vec<f64> {
        let state = state_of(plant, z);
        let [tau_m, tau_l, v_in, t_in] = GENERIC_INPUTS;
        match self {
            Quantity::Rate(i) => {
                let span = plant.web().map_or(0.0, |w| w.forcing(v_in, t_in));
                let rates = plant.rates(&state, tau_m, tau_l);
                vec![rates
                    .get(i)
                    .copied()
                    .unwrap_or_else(|| plant.tension_rate(&state, span))]
            }
            Quantity::Force => vec![plant.force(state.u)],
            Quantity::Indicators => plant.event_indicators(&state).to_vec(),
        }
    }
}

/// The model's variables with `keep`, in value-reference order.
fn in_vr_order(model: &Model, keep: impl Fn(&Var) -> bool) -> Vec<&Var> {
    let mut vars: Vec<&Var> = model.variables.iter().filter(|v| keep(v)).collect();
    vars.sort_by_key(|v| v.vr);
    vars
}

/// The names of the parameters of `model` whose change changes `quantity` at the generic point.
fn parameter_dependencies(model: &Model, quantity: Quantity) -> Vec<&'static str> {
    let values = generic_values(model);
    let plant = plant_of(model, &values);
    let z = generic_state(&plant);
    let at_generic = quantity.of(&plant, &z);
    values
        .iter()
        .enumerate()
        .filter(|&(i, _)| {
            let mut changed = values.clone();
            changed[i].1 *= 1.5;
            // Exact: an independent quantity is the same arithmetic on the same numbers.
            quantity.of(&plant_of(model, &changed), &z) != at_generic
        })
        .map(|(_, (name, _))| *name)
        .collect()
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

/// The states and inputs the state derivative `der` depends on in Continuous-Time Mode: the
/// non-zero entries of its row of the plant's Jacobian in contact (where the compliant member
/// couples both sides), with the web span's forcing w = (v_ref T_in − EA v_in)/L_w carried to
/// v_in and T_in.
pub(crate) fn derivative_dependencies(model: &Model, der: &Var) -> Vec<&'static str> {
    let plant = plant_of(model, &generic_values(model));
    let (dz, dinputs) = plant.jacobian(&state_of(&plant, &generic_state(&plant)));
    let i = state_index(model, der);
    let (dv_in, dt_in) = plant
        .web()
        .map_or((0.0, 0.0), |w| (w.forcing(1.0, 0.0), w.forcing(0.0, 1.0)));
    let by_line = [
        dinputs[i][0],
        dinputs[i][1],
        dinputs[i][2] * dv_in,
        dinputs[i][2] * dt_in,
    ];
    let states = in_vr_order(model, Var::is_continuous_state);
    let inputs = in_vr_order(model, |v| v.causality == Causality::Input);
    assert!(
        inputs.len() <= INPUT_LINES,
        "{}: more inputs than the plant has",
        model.identifier
    );
    let states = states.iter().zip(dz[i]).filter(|(_, d)| *d != 0.0);
    let inputs = inputs.iter().zip(by_line).filter(|(_, d)| *d != 0.0);
    states.chain(inputs).map(|(v, _)| v.name).collect()
}

/// Variables (by value reference, sorted) whose start values and parameters the initial value
/// of `v` depends on (FMI 2.0 §2.2.8 InitialUnknowns, FMI 3.0 §2.4.8 `<InitialUnknown>`); None
/// means "all knowns".
///
/// A state derivative: its states and inputs, and the parameters of its equation. ψ and the
/// contact mode: their states, and the parameters of ψ and of u ∓ g. The bounds: none (they are
/// 0 at the start time, docs/model.md §4). A calculated parameter (the suprema of the bounds):
/// every parameter, as they define the loop of docs/model.md §3 (§8).
pub(crate) fn initial_dependencies(model: &Model, v: &Var) -> Option<Vec<u32>> {
    let names: Vec<&str> = if v.derivative_of.is_some() {
        let rate = Quantity::Rate(state_index(model, v));
        let mut names = derivative_dependencies(model, v);
        names.extend(parameter_dependencies(model, rate));
        names
    } else if v.causality == Causality::CalculatedParameter {
        generic_values(model).iter().map(|(name, _)| *name).collect()
    } else if depends_on_time(v.name) {
        vec![]
    } else {
        let of = match v.name {
            "psi" => Quantity::Force,
            // The mode exactly on ±g depends on the sign of u' as well (its states say so).
            "contact" => Quantity::Indicators,
            _ => return None,
        };
        let mut names = output_dependencies(v.name).to_vec();
        names.extend(parameter_dependencies(model, of));
        names
    };
    let mut vrs: Vec<u32> = names.iter().map(|n| vr_of(model, n)).collect();
    vrs.sort_unstable();
    Some(vrs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{model, model_identifiers};

    #[test]
    fn the_generic_state_is_in_contact_with_every_entry_non_zero() {
        for id in model_identifiers() {
            let m = model(id);
            let plant = plant_of(&m, &generic_values(&m));
            let z = generic_state(&plant);
            let state = state_of(&plant, &z);
            assert_eq!(state.mode, backlash_physics::ContactMode::Positive, "{id}");
            assert!(z.iter().all(|x| *x != 0.0), "{id}: {z:?}");
        }
    }

    /// The derived structure against the equations of docs/model.md §1 and §8, written out.
    #[test]
    fn the_derived_dependencies_are_those_of_the_equations() {
        let deps = |id: &str, name: &str| {
            let m = model(id);
            let v = *m.variables.iter().find(|v| v.name == name).unwrap();
            let mut d = derivative_dependencies(&m, &v);
            d.sort_unstable();
            d
        };
        for id in ["BacklashShaft", "BacklashBelt", "BacklashWeb"] {
            assert_eq!(deps(id, "der(theta_m)"), ["omega_m"], "{id}");
            assert_eq!(deps(id, "der(theta_L)"), ["omega_L"], "{id}");
            assert_eq!(
                deps(id, "der(omega_m)"),
                ["omega_m", "tau_m", "theta_L", "theta_m"],
                "{id}"
            );
        }
        assert_eq!(
            deps("BacklashBelt", "der(omega_L)"),
            ["omega_L", "tau_L", "theta_L", "theta_m"]
        );
        assert_eq!(
            deps("BacklashWeb", "der(omega_L)"),
            ["T", "omega_L", "tau_L", "theta_L", "theta_m"]
        );
        assert_eq!(deps("BacklashWeb", "der(T)"), ["T", "T_in", "omega_L", "v_in"]);

        let params = |id: &str, q: Quantity| {
            let mut p = parameter_dependencies(&model(id), q);
            p.sort_unstable();
            p
        };
        // J_m ω_m' = τ_m − b_m ω_m − r_m K dz(u, g): the motor's inertia and friction, and the
        // transmission's stiffness, lever arms and gap.
        assert_eq!(params("BacklashShaft", Quantity::Rate(1)), ["Delta", "J_m", "b_m", "k"]);
        assert_eq!(
            params("BacklashBelt", Quantity::Rate(1)),
            ["Delta", "J_m", "K_b", "R_1", "R_2", "R_g1", "R_g2", "b_m"]
        );
        // The web pulls the load with R_w T; L_w T' = EA R_w ω_L − v_ref T + v_ref T_in − EA v_in.
        assert_eq!(
            params("BacklashWeb", Quantity::Rate(3)),
            ["Delta", "J_L", "K_b", "R_1", "R_2", "R_g1", "R_g2", "R_w", "b_L"]
        );
        assert_eq!(params("BacklashWeb", Quantity::Rate(4)), ["EA", "L_w", "R_w", "v_ref"]);
        // u ∓ g with u = r_m θ_m − r_L θ_L: the lever arms and the gap, not the stiffness.
        assert_eq!(params("BacklashShaft", Quantity::Indicators), ["Delta"]);
        assert_eq!(params("BacklashShaft", Quantity::Force), ["Delta", "k"]);
    }
}
