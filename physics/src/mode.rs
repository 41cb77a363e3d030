//! Contact modes and the plant state.

use super::params::Plant;

/// The mode in force: which side of the gap the gear teeth touch (docs/model.md §4 `contact`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ContactMode {
    /// u ≤ −g: contact on the negative flank.
    Negative,
    /// |u| < g: contact lost, the load coasts.
    Free,
    /// u ≥ g: contact on the positive flank.
    Positive,
}

impl ContactMode {
    pub const ALL: [ContactMode; 3] = [ContactMode::Negative, ContactMode::Free, ContactMode::Positive];

    /// −1, 0, +1 as the FMU's `contact` output reports it.
    pub fn as_i32(self) -> i32 {
        match self {
            ContactMode::Negative => -1,
            ContactMode::Free => 0,
            ContactMode::Positive => 1,
        }
    }

    pub fn from_i32(value: i32) -> Option<ContactMode> {
        match value {
            -1 => Some(ContactMode::Negative),
            0 => Some(ContactMode::Free),
            1 => Some(ContactMode::Positive),
            _ => None,
        }
    }

    pub(crate) fn index(self) -> usize {
        (self.as_i32() + 1) as usize
    }
}

/// State of the plant: z = [θ_m, ω_m, θ_L, ω_L] (docs/model.md §1), the web span's tension T when
/// the load pulls one (docs/model.md §8), the transmission coordinate u carried alongside (so that
/// u keeps full precision when the angles grow large), and the mode.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantState {
    /// Motor angle θ_m [rad].
    pub theta_m: f64,
    /// Motor speed ω_m [rad/s].
    pub omega_m: f64,
    /// Load angle θ_L [rad].
    pub theta_l: f64,
    /// Load speed ω_L [rad/s].
    pub omega_l: f64,
    /// u = r_m θ_m − r_L θ_L, advanced exactly rather than recomputed from the angles.
    pub u: f64,
    /// u' = r_m ω_m − r_L ω_L, likewise advanced rather than recomputed from the speeds.
    pub du: f64,
    /// The mode in force at this instant (on ±g: the mode being entered).
    pub mode: ContactMode,
    /// Tension T of the web span [N]; 0 when the load pulls no web.
    pub tension: f64,
}

impl PlantState {
    /// A state from angles and speeds; the mode is the one u lies in, and exactly on ±g the
    /// one the trajectory enters given u' (docs/model.md §4 `contact`).
    pub fn new(plant: &Plant, theta_m: f64, omega_m: f64, theta_l: f64, omega_l: f64) -> PlantState {
        let u = plant.transmission(theta_m, theta_l);
        let du = plant.r_m() * omega_m - plant.r_l() * omega_l;
        PlantState {
            theta_m,
            omega_m,
            theta_l,
            omega_l,
            u,
            du,
            mode: mode_at(u, du, plant.half_gap()),
            tension: 0.0,
        }
    }

    /// This state with web tension `tension` [N].
    pub fn with_tension(self, tension: f64) -> PlantState {
        PlantState { tension, ..self }
    }

    /// All fields finite. Non-short-circuit `&`: one branch for the whole test, which runs
    /// on every step.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.theta_m.is_finite()
            & self.omega_m.is_finite()
            & self.theta_l.is_finite()
            & self.omega_l.is_finite()
            & self.u.is_finite()
            & self.du.is_finite()
            & self.tension.is_finite()
    }
}

/// The mode for transmission coordinate `u` moving at `du`, half gap `g`. Exactly on ±g it
/// is the mode being entered; with g = 0 both flanks carry the same force K·u, so any choice
/// gives the same dynamics and the sign of u (then of u') picks one.
pub fn mode_at(u: f64, du: f64, g: f64) -> ContactMode {
    if u > g || (u == g && du > 0.0) {
        ContactMode::Positive
    } else if u < -g || (u == -g && du < 0.0) {
        ContactMode::Negative
    } else if g == 0.0 {
        if u > 0.0 || (u == 0.0 && du >= 0.0) {
            ContactMode::Positive
        } else {
            ContactMode::Negative
        }
    } else {
        ContactMode::Free
    }
}

/// The FMU's `contact` output (docs/model.md §4): the mode in force, and with g = 0 the sign of u.
pub fn contact_indicator(state: &PlantState, half_gap: f64) -> i32 {
    if half_gap == 0.0 {
        if state.u > 0.0 {
            1
        } else if state.u < 0.0 {
            -1
        } else {
            0
        }
    } else {
        state.mode.as_i32()
    }
}
