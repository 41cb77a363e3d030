//! Parameter sets shared by the physics tests, and the FMUs' test rigs (tests/fixtures/rigs.toml).

use std::path::Path;

use backlash_fmu::fmu::adapter;
use backlash_fmu::physics::{Damping, Geometry, PiGains, PlantParams};

/// The reader of tests/fixtures/rigs.toml that the cross-platform test and the bench use.
#[path = "../../../xtask/src/rigs.rs"]
mod fixture;

/// The PI gains (Kp, Ki) of the FMU rig of the model `id` in tests/fixtures/rigs.toml, which the
/// cross-platform test, the bench and the Python tests read too.
pub fn fmu_gains(id: &str) -> PiGains {
    let rig = fixture::rig(Path::new(env!("CARGO_MANIFEST_DIR")), id, "parameters").unwrap_or_else(|e| panic!("{e}"));
    let gain = |name: &str| {
        rig.iter()
            .find(|(n, _)| n == name)
            .map(|&(_, value)| value)
            .unwrap_or_else(|| panic!("the rig of {id} in tests/fixtures/rigs.toml has no {name}"))
    };
    PiGains {
        kp: gain("Kp"),
        ki: gain("Ki"),
    }
}

/// The paper's rig (docs/model.md §4) with both viscous coefficients set to `b`.
pub fn rig(delta: f64, b: f64) -> PlantParams {
    PlantParams {
        b_m: b,
        b_l: b,
        ..PlantParams::paper_rig(delta)
    }
}

/// A small geared belt drive (r_m = 0.05 m, r_L = α₁ = 0.3 m) with viscous coefficients b_m, b_L.
pub fn belt_damped(delta: f64, b_m: f64, b_l: f64) -> PlantParams {
    PlantParams {
        j_m: 0.02,
        j_l: 0.5,
        b_m,
        b_l,
        geometry: Geometry::Belt {
            k_b: 2.0e4,
            r_1: 0.05,
            r_2: 0.1,
            r_g1: 0.03,
            r_g2: 0.09,
            delta,
        },
        damping: Damping::NONE,
        web: None,
    }
}

/// The belt drive lightly damped (b_m = 0.002, b_L = 0.01).
pub fn belt(delta: f64) -> PlantParams {
    belt_damped(delta, 0.002, 0.01)
}

/// Undamped plants (b = 0) for the closed forms of permanent contact: the rig and the belt,
/// without gap and with one.
pub fn undamped() -> [PlantParams; 4] {
    [
        rig(0.0, 0.0),
        rig(2e-3, 0.0),
        belt_damped(0.0, 0.0, 0.0),
        belt_damped(1e-4, 0.0, 0.0),
    ]
}

/// The belt drive of BacklashBelt's start values pulling the film line's web span (docs/model.md
/// §8).
pub fn web_line(delta: f64) -> PlantParams {
    adapter::default_plant_params("BacklashWeb").with_half_gap(delta)
}
