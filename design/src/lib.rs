//! The design study: the paper's open question ("permissible values of compliance and backlash
//! to yield a given accuracy") answered for each model's drive train.
//!
//! - [`speed`]: the shaft and belt forms (docs/model.md §1) under a PI loop on the motor speed:
//!   the largest half gap Δ and the stiffness window that keep `bound_sup` (docs/model.md §3)
//!   within a load-speed accuracy;
//! - [`web`]: the belt drive pulling one web span (docs/model.md §8): the same for `bound_T_sup`
//!   and a tension accuracy (and the load speed's, if given);
//! - [`two_stage`]: a two-stage gearbox (docs/model.md §10): each mesh's `bound_sup` per unit
//!   of its gap, the largest gaps and the stage that dominates;
//! - [`study`]: the computations they rest on (the best-damped gain rule, Δ_max, the stiffness
//!   scan with its refined edges);
//! - [`request`]: a request from named settings (the accuracies, parameters by their FMU
//!   names), each checked: what the command line and the Python binding both build on;
//! - [`cli`]: the `backlash design` command line (also `cargo xtask design`) read into a request
//!   and its answer written as text or JSON, as strings.
//!
//! Pure computation: no printing, no files, no process exit; every failure is an `Err` with its
//! reason. The plant and its bounds come from the physics crate, the models' default parameters
//! from the interface description (their start values).

pub mod cli;
pub mod identify;
mod layout;
pub mod request;
pub mod speed;
pub mod study;
pub mod two_stage;
pub mod web;

pub use backlash_physics::{Geometry, PiGains, PlantParams};
pub use study::DesignError;

/// The drive train a design is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    Shaft,
    Belt,
    /// The belt drive pulling a web span (docs/model.md §8).
    Web,
    /// Two gear stages in series (docs/model.md §10, `BacklashTwoStage`).
    TwoStage,
}

impl Form {
    /// The form's name on the command line and in the answers.
    pub fn name(self) -> &'static str {
        match self {
            Form::Shaft => "shaft",
            Form::Belt => "belt",
            Form::Web => "web",
            Form::TwoStage => "two-stage",
        }
    }
}

/// The plant parameters at the start values of the model `identifier` (its FMU's defaults).
pub fn described_params(identifier: &'static str) -> Result<PlantParams, DesignError> {
    model_description::default_plant_params(identifier).ok_or(DesignError::NoModel { identifier })
}

/// The default drive of each single-gap form: the paper's rig (shaft, Δ = 0.775 mm read as
/// rad), BacklashBelt.fmu's parameter start values (belt), and BacklashWeb.fmu's drive (the same
/// belt drive; its span is [`web::film_line`]). The two-stage form's is BacklashTwoStage's
/// parameter start values ([`two_stage::default_values`]).
pub fn default_params(form: Form) -> Result<PlantParams, DesignError> {
    Ok(match form {
        Form::TwoStage => return Err(DesignError::NotSingleGap { form: form.name() }),
        Form::Shaft => PlantParams::paper_rig(0.775e-3),
        Form::Belt => described_params("BacklashBelt")?,
        Form::Web => PlantParams {
            damping: backlash_physics::Damping::NONE,
            web: None,
            ..described_params("BacklashWeb")?
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_are_the_fmus_start_values() {
        // BacklashBelt.fmu's start values (docs/model.md §4), read here as numbers.
        let belt = default_params(Form::Belt).unwrap();
        assert_eq!(
            belt.named_drive_train(),
            [
                ("J_m", 1e-4),
                ("J_L", 5e-3),
                ("b_m", 1e-4),
                ("b_L", 1e-3),
                ("K_b", 2e5),
                ("R_1", 0.02),
                ("R_2", 0.04),
                ("R_g1", 0.015),
                ("R_g2", 0.045),
                ("Delta", 5e-5),
            ]
        );
        assert_eq!(belt.web, None);
        // BacklashWeb.fmu drives its span with BacklashBelt's drive.
        assert_eq!(default_params(Form::Web).unwrap(), belt);
        assert_eq!(
            default_params(Form::Shaft).unwrap().named_drive_train(),
            [
                ("J_m", 2.28),
                ("J_L", 2.55),
                ("b_m", 0.05),
                ("b_L", 0.05),
                ("k", 200.0),
                ("Delta", 0.775e-3)
            ]
        );
    }

    #[test]
    fn a_model_the_description_lacks_is_an_error() {
        assert_eq!(
            described_params("BacklashGear"),
            Err(DesignError::NoModel {
                identifier: "BacklashGear"
            })
        );
    }
}
