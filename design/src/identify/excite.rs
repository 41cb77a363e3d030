//! An excitation that makes the gap identifiable (docs/model.md §11): a motor torque that
//! reverses at pseudo-random instants, each dwell one to three periods of the contact
//! resonance, levels alternating in sign between the full and half torque limit. Every reversal
//! carries the teeth across the gap (lost motion, which fixes Δ) and rings the contact
//! resonance (which fixes the stiffness); the random dwells keep the response from locking to one
//! frequency. A fit needs ten reversals at least: a run of ten resonance periods.

use backlash_physics::{Plant, PlantParams};

/// Reversals a run needs (docs/model.md §11).
pub const MIN_REVERSALS: usize = 10;

/// The schedule of `params`' drive: (time, tau_m) per sample of step `step` over `duration`;
/// `torque_limit` defaults to 5 r_m K g (five times the torque that closes the gap's spring
/// travel by g), enough to cross the gap quickly.
pub fn schedule(
    params: &PlantParams,
    duration: f64,
    step: f64,
    torque_limit: Option<f64>,
) -> Result<Vec<(f64, f64)>, String> {
    let plant = Plant::new(*params).map_err(|e| e.to_string())?;
    for (name, v) in [("duration", duration), ("step", step)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(format!("{name} = {v} must be finite and > 0"));
        }
    }
    let limit = torque_limit.unwrap_or(5.0 * plant.r_m() * plant.stiffness() * plant.half_gap().max(1e-6));
    if !(limit.is_finite() && limit > 0.0) {
        return Err(format!("torque limit = {limit} must be finite and > 0"));
    }
    let samples = (duration / step).round() as usize + 1;
    if samples > 50_000_000 {
        return Err(format!("{samples} samples: choose a longer step or a shorter run"));
    }
    let period = resonance_period(&plant);
    // xorshift64: the same schedule for the same drive, on every platform.
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut uniform = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut out = Vec::with_capacity(samples);
    let (mut level, mut sign, mut next) = (limit, 1.0, 0.0);
    let mut full = true;
    for i in 0..samples {
        let t = i as f64 * step;
        if t >= next {
            sign = -sign;
            full = !full;
            level = if full { limit } else { 0.5 * limit };
            next = t + (period * (0.5 + uniform())).max(5.0 * step);
        }
        out.push((t, sign * level));
    }
    Ok(out)
}

/// The contact resonance's period 2π/ω₀ [s]: the scale of a dwell.
fn resonance_period(plant: &Plant) -> f64 {
    2.0 * std::f64::consts::PI / plant.contact_frequency()
}

/// The shortest run that carries [`MIN_REVERSALS`] reversals of this schedule (dwells average
/// one resonance period) [s].
pub fn min_duration(params: &PlantParams) -> Result<f64, String> {
    let plant = Plant::new(*params).map_err(|e| e.to_string())?;
    Ok(MIN_REVERSALS as f64 * resonance_period(&plant))
}

/// The schedule as CSV: `time,tau_m`, one row per sample.
pub fn to_csv(schedule: &[(f64, f64)]) -> String {
    let mut s = String::from("time,tau_m\n");
    for (t, tau) in schedule {
        s += &format!("{t},{tau}\n");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_schedule_reverses_within_the_limit() {
        let params = PlantParams::paper_rig(0.775e-3);
        let s = schedule(&params, 10.0, 1e-3, Some(2.0)).unwrap();
        assert_eq!(s.len(), 10_001);
        assert!(s.iter().all(|(_, tau)| tau.abs() <= 2.0));
        let reversals = s.windows(2).filter(|w| w[0].1 * w[1].1 < 0.0).count();
        assert!(reversals >= MIN_REVERSALS, "{reversals}");
        // The shortest run named in the docs carries the reversals it promises.
        let short = schedule(&params, min_duration(&params).unwrap(), 1e-3, None).unwrap();
        let count = short.windows(2).filter(|w| w[0].1 * w[1].1 < 0.0).count();
        assert!(count + 3 >= MIN_REVERSALS, "{count}");
        assert!(schedule(&params, 10.0, f64::NAN, None).is_err());
        assert!(schedule(&params, 10.0, 1e-3, Some(-1.0)).is_err());
    }
}
