//! Closed-form solutions of the plant in the two regimes where it is linear and simple:
//! no contact (each inertia alone) and permanent undamped contact (one oscillator plus a
//! rigid-body motion). Inputs are τ(t) = τ0 + dτ·t (zero-order hold when dτ = 0).

/// φ_k(x) = Σ_j x^j / (j+k)!  (φ_0 = e^x, φ_{k+1} = (φ_k − 1/k!)/x).
pub fn phi(k: usize, x: f64) -> f64 {
    if x.abs() < 1.0 {
        let mut fact = 1.0; // k!
        for i in 1..=k {
            fact *= i as f64;
        }
        let mut term = 1.0 / fact;
        let mut sum = term;
        for j in 1..60 {
            term *= x / (j + k) as f64;
            sum += term;
            if term.abs() < 1e-18 * sum.abs() {
                break;
            }
        }
        sum
    } else {
        let mut p = x.exp();
        let mut fact = 1.0;
        for i in 0..k {
            if i > 0 {
                fact *= i as f64;
            }
            p = (p - 1.0 / fact) / x;
        }
        p
    }
}

/// One inertia alone: J ω' = τ0 + dτ t − b ω. Returns (θ(t), ω(t)).
pub fn single_inertia(j: f64, b: f64, theta0: f64, omega0: f64, tau0: f64, dtau: f64, t: f64) -> (f64, f64) {
    let (dtheta, omega) = single_inertia_increment(j, b, omega0, tau0, dtau, t);
    (theta0 + dtheta, omega)
}

/// As [`single_inertia`], but returns (θ(t) − θ(0), ω(t)).
pub fn single_inertia_increment(j: f64, b: f64, omega0: f64, tau0: f64, dtau: f64, t: f64) -> (f64, f64) {
    let x = -b / j * t;
    let (f0, f1) = (tau0 / j, dtau / j);
    let omega = x.exp() * omega0 + t * phi(1, x) * f0 + t * t * phi(2, x) * f1;
    let dtheta = t * phi(1, x) * omega0 + t * t * phi(2, x) * f0 + t * t * t * phi(3, x) * f1;
    (dtheta, omega)
}

/// F_n(t) = Σ_k (−Ω²)^k t^(2k+n) / (2k+n)!, n = 0..=5: F_0 = cos Ωt, F_1 = sin Ωt / Ω, and
/// each next pair is an iterated integral of the previous one.
pub fn oscillator_kernels(omega: f64, t: f64) -> [f64; 6] {
    let x = omega * t;
    let mut out = [0.0; 6];
    if x.abs() < 3.0 {
        for (n, o) in out.iter_mut().enumerate() {
            let mut fact = 1.0;
            for i in 1..=n {
                fact *= i as f64;
            }
            let mut term = t.powi(n as i32) / fact;
            let mut sum = term;
            for k in 1..80 {
                term *= -x * x / (((2 * k + n - 1) * (2 * k + n)) as f64);
                sum += term;
                if term.abs() < 1e-19 * sum.abs() {
                    break;
                }
            }
            *o = sum;
        }
    } else {
        let w2 = omega * omega;
        out[0] = x.cos();
        out[1] = x.sin() / omega;
        let mut fact = 1.0;
        for n in 0..4 {
            if n > 0 {
                fact *= n as f64;
            }
            out[n + 2] = (t.powi(n as i32) / fact - out[n]) / w2;
        }
    }
    out
}

/// Permanent contact on flank σ = ±1 with b_m = b_L = 0 (docs/model.md §1 with ψ = K (u − σ g)).
/// q = u − σg obeys q'' + Ω² q = F(t), Ω² = K (r_m²/J_m + r_L²/J_L),
/// F = r_m τ_m/J_m − r_L τ_L/J_L; the speeds follow by integrating the torques.
/// Returns [θ_m, ω_m, θ_L, ω_L, u] at t. Valid while σ q ≥ 0 on [0, t].
#[allow(clippy::too_many_arguments)]
pub fn undamped_contact(
    j_m: f64,
    j_l: f64,
    r_m: f64,
    r_l: f64,
    k: f64,
    sigma_g: f64,
    z0: [f64; 4],
    u0: f64,
    tau: [f64; 2],
    dtau: [f64; 2],
    t: f64,
) -> [f64; 5] {
    let [theta_m0, omega_m0, theta_l0, omega_l0] = z0;
    let w2 = k * (r_m * r_m / j_m + r_l * r_l / j_l);
    let f0 = r_m * tau[0] / j_m - r_l * tau[1] / j_l;
    let f1 = r_m * dtau[0] / j_m - r_l * dtau[1] / j_l;
    let q0 = u0 - sigma_g;
    let dq0 = r_m * omega_m0 - r_l * omega_l0;
    let f = oscillator_kernels(w2.sqrt(), t);
    let q = q0 * f[0] + dq0 * f[1] + f0 * f[2] + f1 * f[3];
    let iq = q0 * f[1] + dq0 * f[2] + f0 * f[3] + f1 * f[4];
    let iiq = q0 * f[2] + dq0 * f[3] + f0 * f[4] + f1 * f[5];
    let (t2, t3) = (t * t / 2.0, t * t * t / 6.0);
    let omega_m = omega_m0 + (tau[0] * t + dtau[0] * t2 - r_m * k * iq) / j_m;
    let theta_m = theta_m0 + omega_m0 * t + (tau[0] * t2 + dtau[0] * t3 - r_m * k * iiq) / j_m;
    let omega_l = omega_l0 + (tau[1] * t + dtau[1] * t2 + r_l * k * iq) / j_l;
    let theta_l = theta_l0 + omega_l0 * t + (tau[1] * t2 + dtau[1] * t3 + r_l * k * iiq) / j_l;
    [theta_m, omega_m, theta_l, omega_l, sigma_g + q]
}
