//! Contact modes and the plant state.

use super::params::{ContactLaw, Plant};

/// The mode in force: which side of the gap the gear teeth touch, and with a damper in the
/// compliant member how its force is clipped (docs/model.md §1 and §4 `contact`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ContactMode {
    /// u ≤ −g: contact on the negative flank, ψ = K (u + g) + D u′ < 0.
    Negative,
    /// |u| < g: contact lost, the load coasts.
    Free,
    /// u ≥ g: contact on the positive flank, ψ = K (u − g) + D u′ > 0.
    Positive,
    /// Past −g with a damper, but K (u + g) + D u′ ≥ 0: the force would pull, so it is 0 and the
    /// bodies separate (u moves back towards the gap).
    SlackNegative,
    /// Past +g with a damper, but K (u − g) + D u′ ≤ 0: ψ = 0, the bodies separate.
    SlackPositive,
    /// Past −g, law 1 (`ElastoBacklash`) with D u′ ≤ K (u + g): the damper's force is capped by
    /// the spring's, ψ = 2 K (u + g).
    CappedNegative,
    /// Past +g, law 1 with D u′ ≥ K (u − g): ψ = 2 K (u − g).
    CappedPositive,
}

impl ContactMode {
    /// Every mode, in the order of [`ContactMode::index`].
    pub const ALL: [ContactMode; 7] = [
        ContactMode::Negative,
        ContactMode::Free,
        ContactMode::Positive,
        ContactMode::SlackNegative,
        ContactMode::SlackPositive,
        ContactMode::CappedNegative,
        ContactMode::CappedPositive,
    ];

    /// −1, 0, +1 as the FMU's `contact` output reports it: the sign of ψ in this mode.
    pub fn as_i32(self) -> i32 {
        match self {
            ContactMode::Negative | ContactMode::CappedNegative => -1,
            ContactMode::Free | ContactMode::SlackNegative | ContactMode::SlackPositive => 0,
            ContactMode::Positive | ContactMode::CappedPositive => 1,
        }
    }

    /// A number for each mode, for FMU states: −1, 0, +1 for the modes of a plant without a
    /// damper (its `contact`), ±2 for the slack and ±3 for the capped modes.
    pub fn code(self) -> i32 {
        match self {
            ContactMode::SlackNegative => -2,
            ContactMode::SlackPositive => 2,
            ContactMode::CappedNegative => -3,
            ContactMode::CappedPositive => 3,
            other => other.as_i32(),
        }
    }

    /// The mode of a [`ContactMode::code`].
    pub fn from_code(value: i32) -> Option<ContactMode> {
        ContactMode::ALL.into_iter().find(|m| m.code() == value)
    }

    /// +1 past +g, −1 past −g, 0 inside the gap.
    pub fn side(self) -> f64 {
        match self {
            ContactMode::Free => 0.0,
            ContactMode::Positive | ContactMode::SlackPositive | ContactMode::CappedPositive => 1.0,
            ContactMode::Negative | ContactMode::SlackNegative | ContactMode::CappedNegative => -1.0,
        }
    }

    /// (∂ψ/∂u, ∂ψ/∂u′) in this mode, for stiffness `k` and damping `d`: ψ = ks (u ∓ g) + kd u′.
    #[inline]
    pub fn force_slopes(self, k: f64, d: f64) -> (f64, f64) {
        match self {
            ContactMode::Free | ContactMode::SlackNegative | ContactMode::SlackPositive => (0.0, 0.0),
            ContactMode::Positive | ContactMode::Negative => (k, d),
            ContactMode::CappedPositive | ContactMode::CappedNegative => (2.0 * k, 0.0),
        }
    }

    /// Ordinary contact (ψ = K (u ∓ g) + D u′): the modes in which the bound's V does not grow.
    #[inline]
    pub fn in_contact(self) -> bool {
        matches!(self, ContactMode::Positive | ContactMode::Negative)
    }

    pub(crate) fn index(self) -> usize {
        match self {
            ContactMode::Negative => 0,
            ContactMode::Free => 1,
            ContactMode::Positive => 2,
            ContactMode::SlackNegative => 3,
            ContactMode::SlackPositive => 4,
            ContactMode::CappedNegative => 5,
            ContactMode::CappedPositive => 6,
        }
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
    /// With a damper in the compliant member: an upper bound on ∫|u′| over the time spent
    /// free, slack or capped since the start (exact where u is monotone), which the bounds
    /// of docs/model.md §3 multiply; 0 without a damper.
    pub variation: f64,
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
            mode: plant.mode_at(u, du),
            tension: 0.0,
            variation: 0.0,
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

/// The mode of a damped member (D = `d` > 0, stiffness `k`, half gap `g`, `law`) at u moving
/// at u′ = `du`: where ψ's formula of docs/model.md §1 puts the state, and on a switching surface
/// the mode being entered as far as u′ tells it (on τ_c + τ_d = 0 or τ_c = τ_d, the mode whose
/// force is the formula's value there; the stepper leaves it at once if the motion says so).
pub fn damped_mode_at(u: f64, du: f64, g: f64, k: f64, d: f64, law: ContactLaw) -> ContactMode {
    let positive = u > g || (u == g && (du > 0.0 || (g == 0.0 && du == 0.0)));
    let negative = u < -g || (u == -g && du < 0.0);
    if !(positive || negative) {
        return ContactMode::Free;
    }
    let side = if positive { 1.0 } else { -1.0 };
    let tc = k * (u - side * g);
    let td = d * du;
    let capped = law == ContactLaw::ElastoBacklash && side * td > side * tc;
    match (positive, side * (tc + td) > 0.0, capped) {
        (true, false, _) => ContactMode::SlackPositive,
        (false, false, _) => ContactMode::SlackNegative,
        (true, true, false) => ContactMode::Positive,
        (false, true, false) => ContactMode::Negative,
        (true, true, true) => ContactMode::CappedPositive,
        (false, true, true) => ContactMode::CappedNegative,
    }
}

/// The FMU's `contact` output (docs/model.md §4): the sign of ψ in the mode in force, and for a
/// plant without gap or damper (where both flanks are one spring) the sign of u.
pub fn contact_indicator(state: &PlantState, plant: &Plant) -> i32 {
    if plant.half_gap() == 0.0 && plant.damping() == 0.0 {
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
