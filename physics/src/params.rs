//! Plant parameters for both drive trains and their validation (docs/model.md §1).

use super::mode::ContactMode;
use thiserror::Error;

/// Which drive train the generic plant of docs/model.md §1 describes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Geometry {
    /// Compliant shaft + gear backlash (paper eqs. 11–12): r_m = r_L = 1, K = k, g = Δ.
    Shaft {
        /// Shaft stiffness k [N·m/rad].
        k: f64,
        /// Half backlash gap Δ [rad].
        delta: f64,
    },
    /// Belt–pulley + gear backlash (paper eqs. 20–21): r_m = R_1, r_L = α_1, K = K_b, g = α_2 Δ.
    Belt {
        /// Belt stiffness K_b [N/m].
        k_b: f64,
        /// Motor pulley radius R_1 [m].
        r_1: f64,
        /// Driven pulley radius R_2 [m].
        r_2: f64,
        /// Pitch radius of gear 1 R_g1 [m].
        r_g1: f64,
        /// Pitch radius of gear 2 R_g2 [m].
        r_g2: f64,
        /// Half backlash gap Δ [m] on the pitch circle.
        delta: f64,
    },
}

/// One web span pulled out by a roller on the load shaft (docs/model.md §8): the load of a web
/// line. The span's tension T is a fifth state: L_w T' = EA (R_w ω_L − v_in) + v_ref (T_in − T),
/// and the web pulls back on the roller with R_w T.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WebSpan {
    /// Roller radius R_w [m].
    pub r_w: f64,
    /// Span length L_w [m].
    pub l_w: f64,
    /// Web stiffness EA (Young's modulus times cross-section) [N].
    pub ea: f64,
    /// Web speed the transport term is linearized at, v_ref [m/s].
    pub v_ref: f64,
}

impl WebSpan {
    /// The parameters by their names (docs/model.md §8).
    pub fn named(&self) -> [(&'static str, f64); 4] {
        [
            ("R_w", self.r_w),
            ("L_w", self.l_w),
            ("EA", self.ea),
            ("v_ref", self.v_ref),
        ]
    }

    /// The span's forcing by the upstream web, (v_ref T_in − EA v_in)/L_w [N/s]: what the
    /// inputs v_in [m/s] and T_in [N] (or their time derivatives) add to T'.
    pub fn forcing(&self, v_in: f64, t_in: f64) -> f64 {
        (self.v_ref * t_in - self.ea * v_in) / self.l_w
    }
}

/// Which of the Modelica Standard Library's laws clips the damped force of the compliant member
/// (docs/model.md §1, "Damping in the compliant member"); the FMUs' Integer `contact_law`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ContactLaw {
    /// 1, `ElastoBacklash`: the damper's force is capped by the spring's, ψ = τ_c + min(τ_c, τ_d).
    #[default]
    ElastoBacklash,
    /// 2, `ElastoBacklash2`: ψ = τ_c + τ_d, which jumps by D u′ when a contact begins.
    ElastoBacklash2,
}

impl ContactLaw {
    /// The law of the FMUs' `contact_law` value (1 or 2).
    pub fn from_code(code: i32) -> Option<ContactLaw> {
        match code {
            1 => Some(ContactLaw::ElastoBacklash),
            2 => Some(ContactLaw::ElastoBacklash2),
            _ => None,
        }
    }

    /// `contact_law`: 1 or 2.
    pub fn code(self) -> i32 {
        match self {
            ContactLaw::ElastoBacklash => 1,
            ContactLaw::ElastoBacklash2 => 2,
        }
    }
}

/// The damper in parallel with the compliant member's spring, and the law that clips their force
/// so that it never pulls (docs/model.md §1).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Damping {
    /// D in the transmission coordinate: the shaft's `d` [N·m·s/rad], the belt's `D_b` [N·s/m].
    pub d: f64,
    pub law: ContactLaw,
}

impl Damping {
    /// No damper (D = 0): the plant of the paper, whichever law.
    pub const NONE: Damping = Damping {
        d: 0.0,
        law: ContactLaw::ElastoBacklash,
    };
}

/// Parameters as a user gives them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantParams {
    /// Motor inertia J_m [kg·m²].
    pub j_m: f64,
    /// Load inertia J_L [kg·m²].
    pub j_l: f64,
    /// Motor viscous friction b_m [N·m·s/rad].
    pub b_m: f64,
    /// Load viscous friction b_L [N·m·s/rad].
    pub b_l: f64,
    pub geometry: Geometry,
    /// The damper in the compliant member (D = 0: none).
    pub damping: Damping,
    /// The web span the load pulls, if any (docs/model.md §8); None: the load is an inertia.
    pub web: Option<WebSpan>,
}

impl PlantParams {
    /// These parameters with half gap Δ = `delta` [rad (shaft) or m (belt)].
    pub fn with_half_gap(mut self, delta: f64) -> Self {
        match &mut self.geometry {
            Geometry::Shaft { delta: d, .. } | Geometry::Belt { delta: d, .. } => *d = delta,
        }
        self
    }

    /// The drive train's parameters by their names (docs/model.md §4): J_m, J_L, b_m, b_L, then
    /// the geometry's (k, Delta or K_b, R_1, R_2, R_g1, R_g2, Delta), then with a damper `d` or
    /// `D_b` and `contact_law`; the web span's are [`WebSpan::named`].
    pub fn named_drive_train(&self) -> Vec<(&'static str, f64)> {
        let mut named = vec![
            ("J_m", self.j_m),
            ("J_L", self.j_l),
            ("b_m", self.b_m),
            ("b_L", self.b_l),
        ];
        match self.geometry {
            Geometry::Shaft { k, delta } => named.extend([("k", k), ("Delta", delta)]),
            Geometry::Belt {
                k_b,
                r_1,
                r_2,
                r_g1,
                r_g2,
                delta,
            } => named.extend([
                ("K_b", k_b),
                ("R_1", r_1),
                ("R_2", r_2),
                ("R_g1", r_g1),
                ("R_g2", r_g2),
                ("Delta", delta),
            ]),
        }
        // The damper, when there is one: `d` or `D_b`, and `contact_law`.
        if self.damping.d > 0.0 {
            let name = match self.geometry {
                Geometry::Shaft { .. } => "d",
                Geometry::Belt { .. } => "D_b",
            };
            named.extend([(name, self.damping.d), ("contact_law", self.damping.law.code() as f64)]);
        }
        named
    }

    /// The paper's rectilinear rig (docs/model.md §4) in shaft form, with half gap `delta`.
    pub fn paper_rig(delta: f64) -> Self {
        PlantParams {
            j_m: 2.28,
            j_l: 2.55,
            b_m: 0.05,
            b_l: 0.05,
            geometry: Geometry::Shaft { k: 200.0, delta },
            damping: Damping::NONE,
            web: None,
        }
    }
}

/// An invalid parameter: names it and gives the offending value.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum ParamError {
    #[error("parameter {name} = {value} must be finite")]
    NotFinite { name: &'static str, value: f64 },
    #[error("parameter {name} = {value} must be > 0")]
    NotPositive { name: &'static str, value: f64 },
    #[error("parameter {name} = {value} must be >= 0")]
    Negative { name: &'static str, value: f64 },
    #[error(
        "parameter {name} = {value:e} is outside the range this model integrates: 0 or 1e-100 ..= 1e100 in magnitude"
    )]
    OutOfScale { name: &'static str, value: f64 },
    #[error("{name} = {value:e}, derived from the parameters, is outside 1e-200 ..= 1e200: the time scales of the plant are too far apart to integrate")]
    DerivedOutOfScale { name: &'static str, value: f64 },
}

/// Non-zero parameters must lie within [1/SCALE_LIMIT, SCALE_LIMIT] in magnitude: past it
/// products of two or three of them leave f64, and the plant's time scales drift so far apart
/// that no step could resolve them.
pub const SCALE_LIMIT: f64 = 1e100;

/// Checks the magnitude of a finite parameter (0 is always admissible).
pub(crate) fn in_scale(name: &'static str, value: f64) -> Result<f64, ParamError> {
    let a = value.abs();
    if a != 0.0 && !(1.0 / SCALE_LIMIT..=SCALE_LIMIT).contains(&a) {
        Err(ParamError::OutOfScale { name, value })
    } else {
        Ok(value)
    }
}

/// `value` as a parameter that must be finite, > 0 and within the range the plant integrates.
pub fn positive(name: &'static str, value: f64) -> Result<f64, ParamError> {
    if !value.is_finite() {
        Err(ParamError::NotFinite { name, value })
    } else if value <= 0.0 {
        Err(ParamError::NotPositive { name, value })
    } else {
        in_scale(name, value)
    }
}

fn non_negative(name: &'static str, value: f64) -> Result<f64, ParamError> {
    if !value.is_finite() {
        Err(ParamError::NotFinite { name, value })
    } else if value < 0.0 {
        Err(ParamError::Negative { name, value })
    } else {
        in_scale(name, value)
    }
}

/// A validated plant in the generic form of docs/model.md §1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plant {
    params: PlantParams,
    /// Lever arm of the motor in the transmission coordinate, r_m.
    r_m: f64,
    /// Lever arm of the load, r_L.
    r_l: f64,
    /// Stiffness K of the compliant member.
    stiffness: f64,
    /// Half gap g in the transmission coordinate u.
    half_gap: f64,
    /// Damping D of the compliant member in u (0: none).
    damping: f64,
}

impl Plant {
    /// Validates `params` (J > 0, b ≥ 0, K > 0, Δ ≥ 0, radii > 0, the web's R_w, L_w, EA, v_ref > 0,
    /// all finite).
    pub fn new(params: PlantParams) -> Result<Plant, ParamError> {
        positive("J_m", params.j_m)?;
        positive("J_L", params.j_l)?;
        non_negative("b_m", params.b_m)?;
        non_negative("b_L", params.b_l)?;
        let (r_m, r_l, stiffness, half_gap) = match params.geometry {
            Geometry::Shaft { k, delta } => (1.0, 1.0, positive("k", k)?, non_negative("Delta", delta)?),
            Geometry::Belt {
                k_b,
                r_1,
                r_2,
                r_g1,
                r_g2,
                delta,
            } => {
                let k_b = positive("K_b", k_b)?;
                let r_1 = positive("R_1", r_1)?;
                let r_2 = positive("R_2", r_2)?;
                let r_g1 = positive("R_g1", r_g1)?;
                let r_g2 = positive("R_g2", r_g2)?;
                let delta = non_negative("Delta", delta)?;
                // α_1 = R_2 R_g2 / R_g1, α_2 = R_2 / R_g1 (paper eq. 15).
                (r_1, r_2 * r_g2 / r_g1, k_b, r_2 / r_g1 * delta)
            }
        };
        let damping_name = match params.geometry {
            Geometry::Shaft { .. } => "d",
            Geometry::Belt { .. } => "D_b",
        };
        let damping = non_negative(damping_name, params.damping.d)?;
        for (name, value) in params.web.iter().flat_map(WebSpan::named) {
            positive(name, value)?;
        }
        let plant = Plant {
            params,
            r_m,
            r_l,
            stiffness,
            half_gap,
            damping,
        };
        // The rates and forces the integration works with, all from parameters in scale: a
        // square rate K·r²/J, a damping rate b/J, an input acceleration r/J, the gap force K·g
        // and the lever ratio r_L/r_m. Outside 1e±200 they over- or underflow in products.
        let p = &params;
        let derived = [
            ("K*r_m^2/J_m", stiffness * r_m * r_m / p.j_m),
            ("K*r_L^2/J_L", stiffness * r_l * r_l / p.j_l),
            ("r_m/J_m", r_m / p.j_m),
            ("r_L/J_L", r_l / p.j_l),
            ("b_m/J_m", p.b_m / p.j_m),
            ("b_L/J_L", p.b_l / p.j_l),
            ("K*g", stiffness * half_gap),
            ("g", half_gap),
            ("r_L/r_m", r_l / r_m),
            // The damper's rate D (r_m²/J_m + r_L²/J_L), and its ratio to the stiffness.
            ("D*r_m^2/J_m", damping * r_m * r_m / p.j_m),
            ("D*r_L^2/J_L", damping * r_l * r_l / p.j_l),
            ("D/K", damping / stiffness),
        ];
        // The span's rates: its stiffness against the load inertia, EA R_w²/(L_w J_L), its
        // relaxation v_ref/L_w, the pull's lever R_w/J_L and the speed gain EA R_w/L_w.
        let web = params.web.into_iter().flat_map(|w| {
            [
                ("EA*R_w^2/(L_w*J_L)", w.ea * w.r_w * w.r_w / (w.l_w * p.j_l)),
                ("v_ref/L_w", w.v_ref / w.l_w),
                ("R_w/J_L", w.r_w / p.j_l),
                ("EA*R_w/L_w", w.ea * w.r_w / w.l_w),
            ]
        });
        for (name, value) in derived.into_iter().chain(web) {
            if value != 0.0 && !(value.abs() >= 1e-200 && value.abs() <= 1e200) {
                return Err(ParamError::DerivedOutOfScale { name, value });
            }
        }
        Ok(plant)
    }

    pub fn params(&self) -> &PlantParams {
        &self.params
    }
    /// The web span the load pulls, if any.
    pub fn web(&self) -> Option<&WebSpan> {
        self.params.web.as_ref()
    }
    /// The web's lever on the load, R_w [m]; 0 without a web (the pull R_w T then vanishes).
    pub fn web_lever(&self) -> f64 {
        self.params.web.map_or(0.0, |w| w.r_w)
    }
    pub fn r_m(&self) -> f64 {
        self.r_m
    }
    pub fn r_l(&self) -> f64 {
        self.r_l
    }
    /// Stiffness K [N·m/rad (shaft) or N/m (belt)].
    pub fn stiffness(&self) -> f64 {
        self.stiffness
    }
    /// Half gap g in u [rad (shaft) or m (belt)].
    pub fn half_gap(&self) -> f64 {
        self.half_gap
    }
    /// Damping D of the compliant member in u [N·m·s/rad (shaft) or N·s/m (belt)]; 0: none.
    pub fn damping(&self) -> f64 {
        self.damping
    }
    /// The law that clips the damped force (it matters only when D > 0).
    pub fn contact_law(&self) -> ContactLaw {
        self.params.damping.law
    }
    /// The mode at u moving at u′ = `du` ([`super::mode_at`]; with a damper
    /// [`super::mode::damped_mode_at`]).
    pub fn mode_at(&self, u: f64, du: f64) -> ContactMode {
        if self.damping == 0.0 {
            super::mode::mode_at(u, du, self.half_gap)
        } else {
            super::mode::damped_mode_at(
                u,
                du,
                self.half_gap,
                self.stiffness,
                self.damping,
                self.params.damping.law,
            )
        }
    }
    /// Transmission coordinate u = r_m θ_m − r_L θ_L.
    pub fn transmission(&self, theta_m: f64, theta_l: f64) -> f64 {
        self.r_m * theta_m - self.r_l * theta_l
    }
    /// Contact natural frequency ω₀ = sqrt(K (r_m²/J_m + r_L²/J_L)) [rad/s]: the undamped
    /// oscillation of u on a flank, the fastest motion of an undamped plant.
    pub fn contact_frequency(&self) -> f64 {
        let p = &self.params;
        (self.stiffness * (self.r_m * self.r_m / p.j_m + self.r_l * self.r_l / p.j_l)).sqrt()
    }
    /// dψ/dt in the mode in force (at a switch: the mode entered), from the rates of the angles
    /// and of the speeds: ∂ψ/∂u u′ + ∂ψ/∂u′ u″ (docs/model.md §1); K u′ in contact without a
    /// damper, 0 when the force is 0.
    pub fn force_rate(&self, mode: ContactMode, angle_rates: [f64; 2], speed_rates: [f64; 2]) -> f64 {
        let (ks, kd) = mode.force_slopes(self.stiffness, self.damping);
        if ks == 0.0 && kd == 0.0 {
            return 0.0;
        }
        let du = self.transmission(angle_rates[0], angle_rates[1]);
        if kd == 0.0 {
            ks * du
        } else {
            ks * du + kd * self.transmission(speed_rates[0], speed_rates[1])
        }
    }
    /// Force in the compliant member ψ at transmission coordinate u moving at u′ (docs/model.md
    /// §1): K·dz(u, g) without a damper; with one, the spring's and the damper's force clipped
    /// by the contact law so that it never pulls.
    #[inline]
    pub fn force(&self, u: f64, du: f64) -> f64 {
        if self.damping == 0.0 {
            return self.stiffness * dead_zone(u, self.half_gap);
        }
        damped_force(
            self.stiffness,
            self.damping,
            self.half_gap,
            self.params.damping.law,
            u,
            du,
        )
    }
}

/// ψ of a damped member (docs/model.md §1): past +g, with τ_c = K (u − g) and τ_d = D u′, law 2
/// gives τ_c + τ_d and law 1 τ_c + min(τ_c, τ_d) while τ_c + τ_d > 0, else 0; mirrored past −g;
/// 0 inside the gap.
#[inline(never)]
pub(crate) fn damped_force(k: f64, d: f64, g: f64, law: ContactLaw, u: f64, du: f64) -> f64 {
    let td = d * du;
    if u >= g {
        let tc = k * (u - g);
        if tc + td > 0.0 {
            return match law {
                ContactLaw::ElastoBacklash2 => tc + td,
                ContactLaw::ElastoBacklash => tc + tc.min(td),
            };
        }
    } else if u <= -g {
        let tc = k * (u + g);
        if tc + td < 0.0 {
            return match law {
                ContactLaw::ElastoBacklash2 => tc + td,
                ContactLaw::ElastoBacklash => tc + tc.max(td),
            };
        }
    }
    0.0
}

/// dz(u, g) of docs/model.md §1: zero inside the gap, shifted identity outside.
pub fn dead_zone(u: f64, g: f64) -> f64 {
    if u >= g {
        u - g
    } else if u <= -g {
        u + g
    } else {
        0.0
    }
}

/// Plants for the crate's own tests.
#[cfg(test)]
pub(crate) mod test_plants {
    use super::{Damping, Geometry, PlantParams, WebSpan};

    /// A small servo belt drive with a gap (r_m = 0.02 m, r_L = 0.12 m, g = 0.133 mm), pulling
    /// `web` if given.
    pub(crate) fn servo_belt(web: Option<WebSpan>) -> PlantParams {
        let geometry = Geometry::Belt {
            k_b: 2e5,
            r_1: 0.02,
            r_2: 0.04,
            r_g1: 0.015,
            r_g2: 0.045,
            delta: 5e-5,
        };
        PlantParams {
            j_m: 1e-4,
            j_l: 5e-3,
            b_m: 1e-4,
            b_l: 1e-3,
            geometry,
            damping: Damping::NONE,
            web,
        }
    }
}
