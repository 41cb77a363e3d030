//! BacklashTwoStage: two meshes in series, each a compliant member and a backlash, with a light
//! intermediate shaft between them (docs/model.md §10); its defaults are the paper's rig with
//! its compliance and gap split over the two meshes (`ChainParams::two_stage_rig`).
//!
//! Its own value references: z = [θ_m, ω_m, θ_i, ω_i, θ_L, ω_L] are the continuous states in
//! value-reference order (3–8). A stage's quantity is the single gap's name with the stage's
//! number (`psi_1`, `contact_2`, `u_minus_g_1`, …); a body's friction quantity the single gap's
//! with the body's letter (`tau_c_i`, `sliding_i`, `stop_i`, …).

use backlash_physics::chain::{Body, Coulomb, Stage};
use backlash_physics::{ChainParams, Damping};

use super::{
    calculated_output, contact_law, continuous_local, inputs_and_motor, load_states, parameter, shaft, sign_output,
    state_derivative, state_output, supremum, var, with_state_nominals, ModelDef,
};
use crate::{Causality, Initial, Kind, Model, Range, Type, Var, Variability};

pub(super) const MODEL: ModelDef = ModelDef {
    describe: model,
    kind: Kind::TwoStage(chain_params),
};

/// The chain of the parameters `at` reads (docs/model.md §10): stage j joins body j − 1 to
/// body j with a = 1, c = n_j, K = k_j, g = Delta_j and its damper d_j under `contact_law`;
/// each body its inertia, viscous friction and bearing friction (tau_c, peak).
pub(super) fn chain_params(at: &dyn Fn(&str) -> f64) -> ChainParams<2> {
    let body = |b: &str| Body {
        j: at(&format!("J_{b}")),
        b: at(&format!("b_{b}")),
        friction: Coulomb {
            tau_c: at(&format!("tau_c_{b}")),
            peak: at(&format!("peak_{b}")),
        },
    };
    let law = contact_law(at("contact_law"));
    let stage = |j: usize| Stage {
        a: 1.0,
        c: at(&format!("n_{j}")),
        k: at(&format!("k_{j}")),
        g: at(&format!("Delta_{j}")),
        damper: Damping {
            d: at(&format!("d_{j}")),
            law,
        },
    };
    ChainParams {
        motor: body("m"),
        driven: [body("i"), body("L")],
        stages: [stage(1), stage(2)],
        web: None,
    }
}

/// The bodies, by the letter their names carry, and their words.
const BODIES: [(&str, &str); 3] = [("m", "motor"), ("i", "intermediate shaft"), ("L", "load")];

/// The description, built once per process (its generated names are kept for the process's life).
pub(super) fn model() -> Model {
    static MODEL: std::sync::OnceLock<Model> = std::sync::OnceLock::new();
    MODEL.get_or_init(describe).clone()
}

fn describe() -> Model {
    use Range::*;
    let mut v = inputs_and_motor().to_vec();
    v.extend([
        state_output(
            "theta_i",
            "ThetaI",
            5,
            "rad",
            "Angle",
            "Intermediate shaft angle; its start value is the initial state",
        ),
        state_output(
            "omega_i",
            "OmegaI",
            6,
            "rad/s",
            "AngularVelocity",
            "Intermediate shaft speed; its start value is the initial state",
        ),
    ]);
    v.extend(load_states(7));
    v.extend([
        calculated_output("psi_1", "Psi1", 9, "N.m", "Torque", "Torque psi_1 in the first mesh's compliant member: k_1*dz(theta_m - n_1*theta_i, Delta_1), with a damper (d_1 > 0) clipped by contact_law so that it never pulls"),
        calculated_output("psi_2", "Psi2", 10, "N.m", "Torque", "Torque psi_2 in the second mesh's compliant member: k_2*dz(theta_i - n_2*theta_L, Delta_2), with a damper (d_2 > 0) clipped by contact_law so that it never pulls"),
        sign_output("contact_1", "Contact1", 11, "Contact of the first mesh at the communication point, the sign of psi_1: +1 positive flank, 0 free, -1 negative flank"),
        sign_output("contact_2", "Contact2", 12, "Contact of the second mesh at the communication point, the sign of psi_2: +1 positive flank, 0 free, -1 negative flank"),
        calculated_output("bound", "Bound", 13, "rad/s", "AngularVelocity", "Rigorous bound on |omega_L with backlash - omega_L without backlash| since the start time: sum over the meshes of k_j*Delta_j*integral of |h_j|"),
        supremum("bound_sup", "BoundSup", 14, "rad/s", "AngularVelocity", "Supremum of bound over all times; +inf (with a warning) if the loop is not asymptotically stable"),
    ]);
    let mut vr = 15;
    let mut next = || {
        vr += 1;
        vr - 1
    };
    for (b, word) in BODIES {
        let (j, bb) = (leak(format!("J_{b}")), leak(format!("b_{b}")));
        let j_default = match b {
            "m" => 2.28,
            "i" => 0.1,
            _ => 2.55,
        };
        v.push(parameter(
            j,
            leak(format!("J{}", b.to_uppercase())),
            next(),
            j_default,
            Positive,
            "kg.m2",
            "MomentOfInertia",
            leak(format!("Inertia of the {word} (> 0)")),
        ));
        let b_default = if b == "i" { 0.01 } else { 0.05 };
        v.push(parameter(
            bb,
            leak(format!("B{}", b.to_uppercase())),
            next(),
            b_default,
            NonNegative,
            "N.m.s/rad",
            "RotationalDampingConstant",
            leak(format!("Viscous friction of the {word} (>= 0)")),
        ));
    }
    for j in 1..=2 {
        let stage = if j == 1 {
            "first mesh (motor to intermediate shaft)"
        } else {
            "second mesh (intermediate shaft to load)"
        };
        v.push(parameter(
            leak(format!("n_{j}")),
            leak(format!("N{j}")),
            next(),
            1.0,
            Positive,
            "",
            "",
            leak(format!(
                "Reduction ratio of the {stage}: input turns per output turn (> 0)"
            )),
        ));
        v.push(parameter(
            leak(format!("k_{j}")),
            leak(format!("K{j}")),
            next(),
            400.0,
            Positive,
            "N.m/rad",
            "RotationalSpringConstant",
            leak(format!("Stiffness of the {stage}, on its input side (> 0)")),
        ));
        v.push(parameter(
            leak(format!("Delta_{j}")),
            leak(format!("Delta{j}")),
            next(),
            0.3875e-3,
            NonNegative,
            "rad",
            "Angle",
            leak(format!("Half backlash gap of the {stage}, on its input side (>= 0)")),
        ));
        v.push(parameter(
            leak(format!("d_{j}")),
            leak(format!("D{j}")),
            next(),
            0.0,
            NonNegative,
            "N.m.s/rad",
            "RotationalDampingConstant",
            leak(format!(
                "Damping of the {stage}, in parallel with its stiffness (>= 0; 0: no damper)"
            )),
        ));
    }
    v.push(var(
        "contact_law",
        "ContactLaw",
        next(),
        Type::Integer,
        Causality::Parameter,
        Variability::Fixed,
        Initial::Exact,
        Some(backlash_physics::ContactLaw::ElastoBacklash.code() as f64),
        Range::Integers {
            min: backlash_physics::ContactLaw::ElastoBacklash.code(),
            max: backlash_physics::ContactLaw::ElastoBacklash2.code(),
        },
        "",
        "",
        "Both meshes' dampers: 1: Modelica ElastoBacklash (damper force capped by the spring force), 2: ElastoBacklash2",
    ));
    v.push(parameter(
        "Kp",
        "Kp",
        next(),
        0.0,
        Finite,
        "N.m.s/rad",
        "",
        "Proportional gain of the PI loop on omega_m used by the bounds only (0 with Ki = 0: open loop)",
    ));
    v.push(parameter(
        "Ki",
        "Ki",
        next(),
        0.0,
        Finite,
        "N.m/rad",
        "",
        "Integral gain of the PI loop on omega_m used by the bounds only",
    ));
    for (b, word) in BODIES {
        v.push(parameter(
            leak(format!("tau_c_{b}")),
            leak(format!("TauC{}", b.to_uppercase())),
            next(),
            0.0,
            NonNegative,
            "N.m",
            "Torque",
            leak(format!(
                "Coulomb friction torque in the {word}'s bearing while it slides (>= 0; 0: no friction)"
            )),
        ));
        v.push(parameter(
            leak(format!("peak_{b}")),
            leak(format!("Peak{}", b.to_uppercase())),
            next(),
            1.0,
            AtLeastOne,
            "",
            "",
            leak(format!(
                "Breakaway torque of the {word}'s bearing over its tau_c (>= 1)"
            )),
        ));
    }
    // The derivatives of z's entries, in z's order.
    let states: Vec<Var> = v.iter().filter(|w| w.is_continuous_state()).copied().collect();
    for s in &states {
        let (unit, quantity) = if s.name.starts_with("theta") {
            ("rad/s", "AngularVelocity")
        } else {
            ("rad/s2", "AngularAcceleration")
        };
        let name = leak(format!("der({})", s.name));
        v.push(state_derivative(
            name,
            leak(format!("Der{}", s.symbol)),
            next(),
            s,
            unit,
            quantity,
        ));
    }
    for (b, word) in BODIES {
        v.push(sign_output(leak(format!("sliding_{b}")), leak(format!("Sliding{}", b.to_uppercase())), next(), leak(format!("Friction mode of the {word} at the communication point: +1 sliding forward, 0 stuck, -1 sliding backward (without friction the sign of its speed)"))));
    }
    // The event indicators: each mesh's contact surfaces, then each body's friction surfaces.
    for j in 1..=2 {
        for (base, symbol, unit, text) in [
            ("u_minus_g", "UMinusG", "rad", "u_j - Delta_j (u_j the mesh's coordinate): positive in contact on the positive flank"),
            ("u_plus_g", "UPlusG", "rad", "u_j + Delta_j: negative in contact on the negative flank"),
            ("force_upper", "ForceUpper", "N.m", "k_j*(u_j - Delta_j) + d_j*u_j': with a damper, contact on the positive flank holds while it is positive; 1 without a damper"),
            ("force_lower", "ForceLower", "N.m", "k_j*(u_j + Delta_j) + d_j*u_j': with a damper, contact on the negative flank holds while it is negative; 1 without a damper"),
            ("cap_upper", "CapUpper", "N.m", "d_j*u_j' - k_j*(u_j - Delta_j): with contact_law = 1 the damper force is capped on the positive flank while it is positive; 1 otherwise"),
            ("cap_lower", "CapLower", "N.m", "d_j*u_j' - k_j*(u_j + Delta_j): with contact_law = 1 the damper force is capped on the negative flank while it is negative; 1 otherwise"),
        ] {
            let quantity = if unit == "rad" { "" } else { "Torque" };
            v.push(continuous_local(leak(format!("{base}_{j}")), leak(format!("{symbol}{j}")), next(), unit, quantity, leak(format!("Event indicator of mesh {j}: {text}"))));
        }
    }
    for (b, word) in BODIES {
        let upper = b.to_uppercase();
        v.push(continuous_local(leak(format!("stop_{b}")), leak(format!("Stop{upper}")), next(), "rad/s", "AngularVelocity", leak(format!("Event indicator: the {word}'s speed while it slides with friction (it stops where this crosses 0); 1 stuck or without friction"))));
        v.push(continuous_local(leak(format!("breakaway_{b}")), leak(format!("Breakaway{upper}")), next(), "N.m", "Torque", leak(format!("Event indicator: peak*tau_c - |tau_h| while the {word} is stuck (tau_h: every other torque on it); it breaks away where this crosses 0; 1 sliding or without friction"))));
    }
    with_state_nominals(Model {
        identifier: "BacklashTwoStage",
        kind: Kind::TwoStage(chain_params),
        description: "Two gear meshes in series, each a compliant member and a backlash, with an intermediate shaft between them; exact stepping with the switches of both meshes located; defaults are the paper's rig with its compliance and gap split over the two meshes",
        // The shaft's: the motor torque reverses every second, so both meshes cross their gaps
        // again and again; a load torque from t = 5 s.
        default_experiment: shaft::EXPERIMENT,
        reference_inputs: shaft::REFERENCE_INPUTS,
        variables: v,
    })
}

/// A name made at description time, kept for the process's life (the description is built once,
/// [`model`]; its variables' names are `&'static str`).
fn leak(name: String) -> &'static str {
    Box::leak(name.into_boxed_str())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::parameters;

    /// At its start values the mapping gives the chain the physics documents as the two-stage
    /// rig (docs/model.md §10), field for field.
    #[test]
    fn the_defaults_are_the_two_stage_rig() {
        let m = describe();
        let values = parameters(&m);
        let at = |name: &str| values.iter().find(|(n, _)| *n == name).unwrap().1;
        assert_eq!(chain_params(&at), ChainParams::two_stage_rig());
    }
}
