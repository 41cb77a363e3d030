//! What the chain's reference integrators share (tests/chain.rs, tests/chain_friction.rs).

/// One RK4 step of length `step` taken by `rk4(length)` from the current state, kept whole when
/// the state at its end is still in the region (`inside(state, length)`); otherwise cut at the
/// first instant it leaves, located by bisection on the step length to the last bit. Returns
/// the state reached and `None` for the whole step, or the length taken up to that instant.
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
pub fn substep_ends(h: f64, substeps: usize) -> impl Iterator<Item = f64> {
    let dt = h / substeps as f64;
    (0..substeps).map(move |sub| if sub + 1 == substeps { h } else { (sub + 1) as f64 * dt })
}
