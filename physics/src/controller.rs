//! The sampled controller of the closed loops (docs/model.md §3 and §8): a PI on the motor speed
//! and, on a web line, a PI on the span tension that trims the speed reference, with the speed
//! references of the paper's experiments. Pure arithmetic, in the order the loops closed outside
//! write it, so that a loop written elsewhere with the same operations agrees to the bit.
//!
//! At sample k (time t_k = k h since the start):
//!   e_T = T_ref − T_k,   e = r(t_k) + Kp_T e_T + Ki_T x_T − ω_k,   u_k = Kp e + Ki x_c,
//!   x_c ← x_c + h e,     x_T ← x_T + h e_T   (no anti-windup: nothing saturates the torque).

use std::f64::consts::PI;

/// The speed reference r(t) [rad/s], t the time since the start [s].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reference {
    /// `amplitude` from t = 0 on.
    Step { amplitude: f64 },
    /// From 0 up to `amplitude` in `ramp`, held for `hold`, back to 0 in `ramp`, then 0.
    Trapezoid { amplitude: f64, ramp: f64, hold: f64 },
    /// `amplitude` sin(2π `frequency` t): it reverses the drive.
    Sine { amplitude: f64, frequency: f64 },
}

impl Reference {
    /// The codes of the kinds (a controller's `reference` parameter, docs/model.md §9).
    pub const STEP: i32 = 1;
    pub const TRAPEZOID: i32 = 2;
    pub const SINE: i32 = 3;

    /// The reference of kind `code` with these amplitude [rad/s], frequency [Hz] (sine), ramp
    /// and hold times [s] (trapezoid); `None` for a code of no kind.
    pub fn from_code(code: i32, amplitude: f64, frequency: f64, ramp: f64, hold: f64) -> Option<Reference> {
        match code {
            Reference::STEP => Some(Reference::Step { amplitude }),
            Reference::TRAPEZOID => Some(Reference::Trapezoid { amplitude, ramp, hold }),
            Reference::SINE => Some(Reference::Sine { amplitude, frequency }),
            _ => None,
        }
    }

    /// r(t).
    pub fn at(&self, t: f64) -> f64 {
        match *self {
            Reference::Step { amplitude } => amplitude,
            Reference::Trapezoid { amplitude, ramp, hold } => {
                if t < ramp {
                    amplitude * t / ramp
                } else if t < ramp + hold {
                    amplitude
                } else if t < ramp + hold + ramp {
                    amplitude * (ramp + hold + ramp - t) / ramp
                } else {
                    0.0
                }
            }
            Reference::Sine { amplitude, frequency } => amplitude * (2.0 * PI * frequency * t).sin(),
        }
    }
}

/// The gains and set points of the two loops; with `kp_t` = `ki_t` = 0 the tension loop is off.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerParams {
    /// Speed PI: Kp [N.m.s/rad], Ki [N.m/rad].
    pub kp: f64,
    pub ki: f64,
    /// Tension PI: Kp_T [rad/(s.N)], Ki_T [rad/(s2.N)], set point T_ref [N].
    pub kp_t: f64,
    pub ki_t: f64,
    pub t_ref: f64,
    /// The sample period h [s] (> 0).
    pub period: f64,
    pub reference: Reference,
}

/// Why a sample is refused; nothing has changed then.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SampleError {
    /// A value of the sample left f64: the measured values, the torque or an integrator.
    Overflow { torque: f64 },
}

/// The controller between samples: its integrators, the samples taken and the torque of the last
/// one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampledPi {
    pub params: ControllerParams,
    /// The speed loop's integrator x_c [rad] and the tension loop's x_T [N.s].
    pub x_c: f64,
    pub x_t: f64,
    /// Samples taken: the next one is at t = samples · h.
    pub samples: u64,
    /// The torque u of the last sample [N.m] (`initial` before the first).
    pub torque: f64,
}

impl SampledPi {
    /// At rest: integrators 0, no sample taken, `torque` held until the first sample.
    pub fn new(params: ControllerParams, torque: f64) -> SampledPi {
        SampledPi {
            params,
            x_c: 0.0,
            x_t: 0.0,
            samples: 0,
            torque,
        }
    }

    /// The time of the next sample since the start: its count times the period, so that it does
    /// not drift with a clock summed step by step.
    pub fn next_time(&self) -> f64 {
        self.samples as f64 * self.params.period
    }

    /// Takes the sample of the measured motor speed `omega_m` [rad/s] and tension `tension` [N]:
    /// the torque u_k, then the integrators' update (module doc).
    pub fn sample(&mut self, omega_m: f64, tension: f64) -> Result<f64, SampleError> {
        let ControllerParams {
            kp,
            ki,
            kp_t,
            ki_t,
            t_ref,
            period: h,
            reference,
        } = self.params;
        let r = reference.at(self.next_time());
        let e_t = t_ref - tension;
        let e = r + kp_t * e_t + ki_t * self.x_t - omega_m;
        let torque = kp * e + ki * self.x_c;
        let (x_c, x_t) = (self.x_c + h * e, self.x_t + h * e_t);
        if !(torque.is_finite() && x_c.is_finite() && x_t.is_finite()) {
            return Err(SampleError::Overflow { torque });
        }
        *self = SampledPi {
            x_c,
            x_t,
            samples: self.samples + 1,
            torque,
            ..*self
        };
        Ok(torque)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pi(reference: Reference) -> SampledPi {
        let params = ControllerParams {
            kp: 2.0,
            ki: 3.0,
            kp_t: 0.0,
            ki_t: 0.0,
            t_ref: 0.0,
            period: 0.5,
            reference,
        };
        SampledPi::new(params, 0.25)
    }

    /// Worked by hand: r = 1, ω = 0.5, 0.25 at two samples, h = 0.5.
    #[test]
    fn two_samples_of_the_speed_loop_by_hand() {
        let mut c = pi(Reference::Step { amplitude: 1.0 });
        assert_eq!(c.torque, 0.25);
        // e = 0.5, u = 2 * 0.5 + 3 * 0 = 1, x_c = 0.25
        assert_eq!(c.sample(0.5, 0.0), Ok(1.0));
        // e = 0.75, u = 1.5 + 0.75 = 2.25, x_c = 0.625
        assert_eq!(c.sample(0.25, 0.0), Ok(2.25));
        assert_eq!((c.x_c, c.samples, c.next_time()), (0.625, 2, 1.0));
    }

    /// The tension loop trims the reference: T_ref = 10, T = 6, Kp_T = 0.5, Ki_T = 1, h = 0.5.
    #[test]
    fn the_tension_loop_trims_the_speed_reference() {
        let mut c = pi(Reference::Step { amplitude: 0.0 });
        c.params.kp_t = 0.5;
        c.params.ki_t = 1.0;
        c.params.t_ref = 10.0;
        // e_T = 4, e = 0 + 2 + 0 - 1 = 1, u = 2; x_T = 2
        assert_eq!(c.sample(1.0, 6.0), Ok(2.0));
        // e_T = 4, e = 0 + 2 + 2 - 1 = 3, u = 6 + 3 * 0.5 = 7.5
        assert_eq!(c.sample(1.0, 6.0), Ok(7.5));
        assert_eq!(c.x_t, 4.0);
    }

    #[test]
    fn the_references_by_hand() {
        let trapezoid = Reference::Trapezoid {
            amplitude: 4.0,
            ramp: 2.0,
            hold: 1.0,
        };
        let at: Vec<f64> = [0.0, 1.0, 2.0, 2.5, 3.0, 4.0, 5.0, 9.0]
            .iter()
            .map(|t| trapezoid.at(*t))
            .collect();
        assert_eq!(at, [0.0, 2.0, 4.0, 4.0, 4.0, 2.0, 0.0, 0.0]);
        let sine = Reference::Sine {
            amplitude: 2.0,
            frequency: 0.25,
        };
        assert!((sine.at(1.0) - 2.0).abs() <= 4.0 * f64::EPSILON);
        assert!(sine.at(2.0).abs() <= 4.0 * f64::EPSILON * 2.0 * PI);
    }

    #[test]
    fn an_overflowing_sample_changes_nothing() {
        let mut c = pi(Reference::Step { amplitude: 1.0 });
        let before = c;
        // e = 1 + MAX rounds to MAX; u = 2 MAX overflows.
        assert!(matches!(c.sample(-f64::MAX, 0.0), Err(SampleError::Overflow { .. })));
        assert_eq!(c, before);
    }
}
