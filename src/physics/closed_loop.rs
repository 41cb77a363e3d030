//! The backlash-free loop of docs/model.md §3: the plant with a PI controller on motor speed, its
//! matrix in two coordinate systems, its spectrum, and the tail bound of ∫|h| built on it.
//!
//! θ_m and θ_L enter the dynamics only through u = r_m θ_m − r_L θ_L, so the 5-state A_cl of
//! docs/model.md §3 has the spectrum of the 4-state matrix in [u, ω_m, ω_L, x_c] plus one eigenvalue 0
//! (a rigid rotation of the whole train), which neither τ_m nor the backlash disturbance
//! excites and ω_L does not see.

use super::bound::Unbounded;
use super::params::Plant;
use nalgebra::{Complex, DMatrix, DVector, Matrix4, SMatrix, SVector};

/// PI speed controller on ω_m: τ_m = Kp e + Ki ∫e, e = ω_ref − ω_m (docs/model.md §3).
/// Kp [N·m·s/rad], Ki [N·m/rad]; Kp = Ki = 0 means the open-loop plant.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct PiGains {
    pub kp: f64,
    pub ki: f64,
}

/// Closed-loop state [θ_m, ω_m, θ_L, ω_L, x_c] (docs/model.md §3).
pub const CL: usize = 5;
/// ω_L in the closed-loop state.
pub const OMEGA_L: usize = 3;

/// A_cl of docs/model.md §3 (A_p with the PI loop on ω_m) in θ coordinates: the loop of
/// [`reduced_loop_matrix`] with the angles kept apart. Its entries are written out rather than
/// derived from the 4×4 one: k r_m² / J_m is rounded as one product, not as (k r_m / J_m) r_m.
/// With Kp = Ki = 0 the x_c row and column are zero, so x_c stays 0 and the 5-vector norms
/// equal the open-loop 4-vector ones.
pub fn closed_loop(plant: &Plant, gains: PiGains) -> SMatrix<f64, CL, CL> {
    let p = plant.params();
    let (r_m, r_l, k) = (plant.r_m(), plant.r_l(), plant.stiffness());
    let mut a = SMatrix::<f64, CL, CL>::zeros();
    a[(0, 1)] = 1.0;
    a[(1, 0)] = -k * r_m * r_m / p.j_m;
    a[(1, 1)] = -(p.b_m + gains.kp) / p.j_m;
    a[(1, 2)] = k * r_m * r_l / p.j_m;
    a[(1, 4)] = gains.ki / p.j_m;
    a[(2, 3)] = 1.0;
    a[(3, 0)] = k * r_m * r_l / p.j_l;
    a[(3, 2)] = -k * r_l * r_l / p.j_l;
    a[(3, 3)] = -p.b_l / p.j_l;
    if gains.kp != 0.0 || gains.ki != 0.0 {
        a[(4, 1)] = -1.0;
    }
    a
}

/// The backlash-free closed loop in the minimal state x = [u, ω_m, ω_L, x_c] (see the module
/// documentation). With Ki = 0, x_c feeds nothing back and the leading 3×3 block is the loop.
pub fn reduced_loop_matrix(plant: &Plant, gains: PiGains) -> Matrix4<f64> {
    let p = plant.params();
    let (r_m, r_l, k) = (plant.r_m(), plant.r_l(), plant.stiffness());
    #[rustfmt::skip]
    let a = Matrix4::new(
        0.0,              r_m,                     -r_l,          0.0,
        -k * r_m / p.j_m, -(p.b_m + gains.kp) / p.j_m, 0.0,       gains.ki / p.j_m,
        k * r_l / p.j_l,  0.0,                     -p.b_l / p.j_l, 0.0,
        0.0,              -1.0,                    0.0,           0.0,
    );
    a
}

/// The four poles of the backlash-free closed loop (the eigenvalues of
/// [`reduced_loop_matrix`]), sorted by real part, then imaginary part.
pub fn reduced_loop_poles(plant: &Plant, gains: PiGains) -> [Complex<f64>; 4] {
    let ev = reduced_loop_matrix(plant, gains).complex_eigenvalues();
    let mut poles = [ev[0], ev[1], ev[2], ev[3]];
    poles.sort_by(|a, b| a.re.total_cmp(&b.re).then(a.im.total_cmp(&b.im)));
    poles
}

/// ρ(A) from a Schur decomposition with a capped iteration count; if that fails to converge,
/// the Frobenius norm, which bounds ρ(A) from above (pieces then come out shorter, not wrong).
pub(crate) fn spectral_radius<const N: usize>(a: &SMatrix<f64, N, N>) -> f64 {
    let d = DMatrix::from_iterator(N, N, a.iter().copied());
    match eigenvalues(&d) {
        Some(eig) => eig.iter().map(|l| l.norm()).fold(0.0, f64::max),
        None => d.norm(),
    }
}

/// Eigenvalues by a Schur decomposition of at most `SCHUR_ITERATIONS` sweeps: None if it does
/// not converge (nalgebra's default would iterate without limit).
fn eigenvalues(a: &DMatrix<f64>) -> Option<Vec<Complex<f64>>> {
    const SCHUR_ITERATIONS: usize = 10_000;
    let schur = a.clone().try_schur(f64::EPSILON, SCHUR_ITERATIONS)?;
    Some(schur.complex_eigenvalues().iter().copied().collect())
}

/// The loop in the coordinates h depends on: [u, ω_m, ω_L] and x_c when Ki ≠ 0. The angle
/// translation (u fixed) is neither excited by D_1 nor seen by ω_L, and x_c without Ki feeds
/// nothing back, so these are exactly the modes that h excites (docs/model.md §3, and §4 `bound_sup`).
pub(crate) struct Reduced {
    a: DMatrix<f64>,
    out: DVector<f64>,
    r_m: f64,
    r_l: f64,
}

/// A bound on ∫_T^∞ |h| from the reduced state x(T). With ε = −α/2 (α the spectral abscissa),
/// Cauchy–Schwarz with the weight e^{ε(s−T)} gives
/// ∫_T^∞ |h| ≤ sqrt(1/(2ε)) · sqrt(xᵀ W x), W the observability Gramian of (A + εI, L):
/// (A + εI)ᵀ W + W (A + εI) = −Lᵀ L. It decays at half the true rate, so it is never loose
/// by more than the state's own decay.
#[derive(Clone, Debug)]
pub(crate) struct TailBound {
    /// W in the reduced coordinates, zero-padded to 4×4 when x_c is not among them.
    gramian: SMatrix<f64, 4, 4>,
    epsilon: f64,
    r_m: f64,
    r_l: f64,
    with_xc: bool,
}

impl TailBound {
    /// The bound for the full response v (projected on the reduced coordinates).
    pub(crate) fn of(&self, v: &[f64; CL]) -> f64 {
        (self.squared(v) / (2.0 * self.epsilon)).sqrt()
    }

    /// Whether `of(v)` ≤ `limit` (≥ 0), without the square root and the division: a test
    /// made after every advance until the response has decayed.
    pub(crate) fn at_most(&self, v: &[f64; CL], limit: f64) -> bool {
        self.squared(v) <= 2.0 * self.epsilon * limit * limit
    }

    fn squared(&self, v: &[f64; CL]) -> f64 {
        let xc = if self.with_xc { v[4] } else { 0.0 };
        let x = SVector::<f64, 4>::new(self.r_m * v[0] - self.r_l * v[2], v[1], v[OMEGA_L], xc);
        x.dot(&(self.gramian * x)).max(0.0)
    }
}

impl Reduced {
    pub(crate) fn new(plant: &Plant, gains: PiGains) -> Reduced {
        let n = if gains.ki != 0.0 { 4 } else { 3 };
        let full = reduced_loop_matrix(plant, gains);
        let a = DMatrix::from_fn(n, n, |i, j| full[(i, j)]);
        let mut out = DVector::zeros(n);
        out[2] = 1.0;
        Reduced {
            a,
            out,
            r_m: plant.r_m(),
            r_l: plant.r_l(),
        }
    }

    pub(crate) fn tail_bound(&self) -> Result<TailBound, Unbounded> {
        let n = self.a.nrows();
        let eig = eigenvalues(&self.a).ok_or(Unbounded::Indeterminate)?;
        let radius = eig.iter().map(|l| l.norm()).fold(0.0, f64::max);
        let abscissa = eig.iter().map(|l| l.re).fold(f64::NEG_INFINITY, f64::max);
        if abscissa >= -1e-12 * radius {
            return Err(if abscissa.abs() <= 1e-12 * radius {
                Unbounded::Undamped
            } else {
                Unbounded::Unstable { abscissa }
            });
        }
        let epsilon = -0.5 * abscissa;
        // (A + εI)ᵀ W + W (A + εI) = −Lᵀ L as (I ⊗ Bᵀ + Bᵀ ⊗ I) vec(W) = −vec(Lᵀ L), B = A + εI.
        let eye = DMatrix::<f64>::identity(n, n);
        let bt = (&self.a + &eye * epsilon).transpose();
        let kron = eye.kronecker(&bt) + bt.kronecker(&eye);
        let rhs = -DVector::from_iterator(n * n, (&self.out * self.out.transpose()).iter().copied());
        let vec_w = kron.lu().solve(&rhs).ok_or(Unbounded::Undamped)?;
        let w = DMatrix::from_iterator(n, n, vec_w.iter().copied());
        let mut gramian = SMatrix::<f64, 4, 4>::zeros();
        for i in 0..n {
            for j in 0..n {
                gramian[(i, j)] = 0.5 * (w[(i, j)] + w[(j, i)]);
            }
        }
        Ok(TailBound {
            gramian,
            epsilon,
            r_m: self.r_m,
            r_l: self.r_l,
            with_xc: n == 4,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::PlantParams;
    use nalgebra::SMatrix;

    #[test]
    fn the_five_and_four_state_matrices_are_the_same_loop() {
        // x = P y maps [θ_m, ω_m, θ_L, ω_L, x_c] to [u, ω_m, ω_L, x_c]; the loop commutes with it.
        let plant = Plant::new(PlantParams::paper_rig(1e-3)).unwrap();
        let gains = PiGains { kp: 7.0, ki: 30.0 };
        let (r_m, r_l) = (plant.r_m(), plant.r_l());
        let mut proj = SMatrix::<f64, 4, CL>::zeros();
        proj[(0, 0)] = r_m;
        proj[(0, 2)] = -r_l;
        proj[(1, 1)] = 1.0;
        proj[(2, OMEGA_L)] = 1.0;
        proj[(3, 4)] = 1.0;
        let lhs = proj * closed_loop(&plant, gains);
        let rhs = reduced_loop_matrix(&plant, gains) * proj;
        let scale = lhs.abs().max();
        assert!((lhs - rhs).abs().max() <= 1e-14 * scale, "{lhs} vs {rhs}");
    }
}
