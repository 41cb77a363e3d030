//! What the physics tests share: the chain's reference integrators' steps (tests/chain.rs,
//! tests/chain_friction.rs) and plants beside the paper's rig.

use backlash_physics::{ContactLaw, Damping, Geometry, Plant, PlantParams};

/// A small servo belt drive with a gap (the belt geometry of docs/model.md §4).
#[allow(dead_code, reason = "not every test crate takes the belt")]
pub fn servo_belt() -> PlantParams {
    PlantParams {
        j_m: 1e-4,
        j_l: 5e-3,
        b_m: 1e-4,
        b_l: 1e-3,
        geometry: Geometry::Belt {
            k_b: 2e5,
            r_1: 0.02,
            r_2: 0.04,
            r_g1: 0.015,
            r_g2: 0.045,
            delta: 5e-5,
        },
        damping: Damping::NONE,
        web: None,
    }
}

/// `params` with a damper in the member at contact damping ratio ζ under `law`
/// (D = 2 ζ K / ω_0 in u).
#[allow(dead_code, reason = "not every test crate takes a damper")]
pub fn with_damper(params: PlantParams, law: ContactLaw, zeta: f64) -> PlantParams {
    let plant = Plant::new(params).unwrap();
    PlantParams {
        damping: Damping {
            d: 2.0 * zeta * plant.stiffness() / plant.contact_frequency(),
            law,
        },
        ..params
    }
}

/// One RK4 step of length `step` taken by `rk4(length)` from the current state, kept whole when
/// the state at its end is still in the region (`inside(state, length)`); otherwise cut at the
/// first instant it leaves, located by bisection on the step length to the last bit. Returns
/// the state reached and `None` for the whole step, or the length taken up to that instant.
#[allow(dead_code, reason = "not every test crate integrates")]
pub fn rk4_to_first_exit<Z>(step: f64, rk4: impl Fn(f64) -> Z, inside: impl Fn(&Z, f64) -> bool) -> (Z, Option<f64>) {
    let trial = rk4(step);
    if inside(&trial, step) {
        return (trial, None);
    }
    // Bisection for the first instant the state leaves the region.
    let (mut lo, mut hi) = (0.0, step);
    loop {
        let mid = lo + 0.5 * (hi - lo);
        if mid <= lo || mid >= hi {
            break;
        }
        if inside(&rk4(mid), mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (rk4(hi), Some(hi))
}

/// The ends of `substeps` equal parts of an interval of length `h`, the last exactly `h`.
#[allow(dead_code, reason = "not every test crate integrates")]
pub fn substep_ends(h: f64, substeps: usize) -> impl Iterator<Item = f64> {
    let dt = h / substeps as f64;
    (0..substeps).map(move |sub| if sub + 1 == substeps { h } else { (sub + 1) as f64 * dt })
}
