//! The backlash-free loop of docs/model.md §3: the plant with a PI controller on motor speed, its
//! matrix in two coordinate systems, its spectrum, and the tail bound of ∫|h| built on it.
//!
//! θ_m and θ_L enter the dynamics only through u = r_m θ_m − r_L θ_L, so the 5-state A_cl of
//! docs/model.md §3 has the spectrum of the 4-state matrix in [u, ω_m, ω_L, x_c] plus one eigenvalue 0
//! (a rigid rotation of the whole train), which neither τ_m nor the backlash disturbance
//! excites and ω_L does not see.

use super::bound::Unbounded;
use super::params::Plant;
use nalgebra::{Complex, DMatrix, DVector, Matrix4, SMatrix};

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

/// A_cl of docs/model.md §3 (A_p with the PI loop on ω_m; with a damper in the compliant member,
/// the backlash-free twin's spring-damper K u + D u′) in θ coordinates: the loop of
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
    let d = plant.damping();
    if d != 0.0 {
        // The twin's spring-damper: ψ⁰ = K u + D u′, u′ = r_m ω_m − r_L ω_L.
        a[(1, 1)] -= d * r_m * r_m / p.j_m;
        a[(1, 3)] = d * r_m * r_l / p.j_m;
        a[(3, 1)] = d * r_m * r_l / p.j_l;
        a[(3, 3)] -= d * r_l * r_l / p.j_l;
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
    let d = plant.damping();
    if d == 0.0 {
        return a;
    }
    // The twin's damper D u′ with u′ = r_m ω_m − r_L ω_L.
    let mut a = a;
    a[(1, 1)] -= d * r_m * r_m / p.j_m;
    a[(1, 2)] = d * r_m * r_l / p.j_m;
    a[(2, 1)] = d * r_l * r_m / p.j_l;
    a[(2, 2)] -= d * r_l * r_l / p.j_l;
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

/// u = r_m θ_m − r_L θ_L over the loop state [θ_m, ω_m, θ_L, ω_L, ...].
fn gap(plant: &Plant) -> Coord {
    Coord::Gap {
        a: plant.r_m(),
        i: 0,
        c: plant.r_l(),
        j: 2,
    }
}

/// The web line's loop state [θ_m, ω_m, θ_L, ω_L, x_c, T, x_T] (docs/model.md §8): the speed
/// loop's with the span tension and the tension PI's integrator.
pub const WEB_CL: usize = 7;
/// T in the web line's loop state.
pub const TENSION: usize = 5;
/// x_T = ∫(T_ref − T) in the web line's loop state.
const X_T: usize = 6;

/// The backlash-free web line under the speed PI and the tension PI that trims its reference,
/// ω_ref += Kp_T (T_ref − T) + Ki_T x_T (docs/model.md §8), in the state [`WEB_CL`]. With zero
/// references the speed error is e = −ω_m − Kp_T T + Ki_T x_T, τ_m = Kp e + Ki x_c, x_c' = e,
/// x_T' = −T. Integrators without gain stay 0.
pub fn web_loop(plant: &Plant, speed: PiGains, tension: PiGains) -> SMatrix<f64, WEB_CL, WEB_CL> {
    let web = plant.web().expect("the web loop needs a web span");
    let p = plant.params();
    let mut a = SMatrix::<f64, WEB_CL, WEB_CL>::zeros();
    a.fixed_view_mut::<CL, CL>(0, 0).copy_from(&closed_loop(plant, speed));
    // e's dependence on T and x_T, through τ_m and x_c.
    a[(1, TENSION)] = -speed.kp * tension.kp / p.j_m;
    a[(1, X_T)] = speed.kp * tension.ki / p.j_m;
    // The tension PI acts through the speed PI only; with the speed loop open its integrator,
    // like one without gain, stays 0.
    let speed_closed = speed.kp != 0.0 || speed.ki != 0.0;
    if speed_closed {
        a[(4, TENSION)] = -tension.kp;
        a[(4, X_T)] = tension.ki;
    }
    a[(OMEGA_L, TENSION)] = -web.r_w / p.j_l;
    a[(TENSION, OMEGA_L)] = web.ea * web.r_w / web.l_w;
    a[(TENSION, TENSION)] = -web.v_ref / web.l_w;
    if speed_closed && (tension.kp != 0.0 || tension.ki != 0.0) {
        a[(X_T, TENSION)] = -1.0;
    }
    a
}

/// One coordinate of a reduced loop state, read from the full loop state v.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Coord {
    /// A gap a v[i] − c v[j] (u = r_m θ_m − r_L θ_L, or a chain stage's a θ_i − c θ_{i+1}).
    Gap { a: f64, i: usize, c: f64, j: usize },
    /// v[i] as it is.
    Entry(usize),
    /// Padding: 0.
    Zero,
}

impl Coord {
    fn of<const N: usize>(self, v: &[f64; N]) -> f64 {
        match self {
            Coord::Gap { a, i, c, j } => a * v[i] - c * v[j],
            Coord::Entry(i) => v[i],
            Coord::Zero => 0.0,
        }
    }
}

/// The loop in the coordinates an output's impulse response depends on: for the speed loop
/// [u, ω_m, ω_L] and x_c when Ki ≠ 0; for the web line also T and x_T when Ki_T ≠ 0; for a chain
/// every stage's gap, every body's speed and x_c when Ki ≠ 0. The angle translation (every gap
/// fixed) is neither excited by a backlash disturbance nor seen by a speed or T, and an
/// integrator without gain feeds nothing back, so these are exactly the modes that the response
/// excites (docs/model.md §3, and §4 `bound_sup`).
pub(crate) struct Reduced {
    a: DMatrix<f64>,
    out: DVector<f64>,
    coords: Vec<Coord>,
}

/// A bound on ∫_T^∞ |h| from the reduced state x(T). With ε = −α/2 (α the spectral abscissa),
/// Cauchy–Schwarz with the weight e^{ε(s−T)} gives
/// ∫_T^∞ |h| ≤ sqrt(1/(2ε)) · sqrt(xᵀ W x), W the observability Gramian of (A + εI, L):
/// (A + εI)ᵀ W + W (A + εI) = −Lᵀ L. It decays at half the true rate, so it is never loose
/// by more than the state's own decay. `N` is the loop state's size, `R` the most reduced
/// coordinates a loop of that size has (those a loop leaves unused are 0, with zero entries of W).
#[derive(Clone, Debug)]
pub(crate) struct TailBound<const N: usize, const R: usize> {
    /// W in the reduced coordinates, zero-padded to R×R.
    gramian: SMatrix<f64, R, R>,
    /// The reduced coordinates, padded with [`Coord::Zero`].
    coords: [Coord; R],
    epsilon: f64,
}
impl<const N: usize, const R: usize> TailBound<N, R> {
    /// The bound for the full response v (projected on the reduced coordinates).
    pub(crate) fn of(&self, v: &[f64; N]) -> f64 {
        (self.squared(v) / (2.0 * self.epsilon)).sqrt()
    }

    /// Whether `of(v)` ≤ `limit` (≥ 0), without the square root and the division: a test
    /// made after every advance until the response has decayed.
    pub(crate) fn at_most(&self, v: &[f64; N], limit: f64) -> bool {
        self.squared(v) <= 2.0 * self.epsilon * limit * limit
    }

    fn squared(&self, v: &[f64; N]) -> f64 {
        let x = SMatrix::<f64, R, 1>::from_fn(|i, _| self.coords[i].of(v));
        x.dot(&(self.gramian * x)).max(0.0)
    }
}

impl Reduced {
    /// The speed loop's: h the response of ω_L.
    pub(crate) fn new(plant: &Plant, gains: PiGains) -> Reduced {
        let n = if gains.ki != 0.0 { 4 } else { 3 };
        let full = reduced_loop_matrix(plant, gains);
        let a = DMatrix::from_fn(n, n, |i, j| full[(i, j)]);
        let mut out = DVector::zeros(n);
        out[2] = 1.0;
        // x = [r_m θ_m − r_L θ_L, ω_m, ω_L, x_c] from [θ_m, ω_m, θ_L, ω_L, x_c].
        let kept = [1, OMEGA_L, 4][..n - 1].iter().map(|&j| Coord::Entry(j));
        Reduced {
            a,
            out,
            coords: std::iter::once(gap(plant)).chain(kept).collect(),
        }
    }

    /// The map from the loop state (`cols` entries) onto the reduced coordinates.
    fn projection(&self, cols: usize) -> DMatrix<f64> {
        let mut proj = DMatrix::zeros(self.coords.len(), cols);
        for (row, coord) in self.coords.iter().enumerate() {
            match *coord {
                Coord::Gap { a, i, c, j } => {
                    proj[(row, i)] = a;
                    proj[(row, j)] = -c;
                }
                Coord::Entry(i) => proj[(row, i)] = 1.0,
                Coord::Zero => {}
            }
        }
        proj
    }

    /// The loop `full` (`cols` × `cols`) on the coordinates `coords` with the response of
    /// entry `output` (one of the `Entry` coordinates): A_r = P A P⁺ with P the projection and
    /// P⁺ a right inverse of it, which is A_r whenever P A = A_r P (the coordinates span
    /// everything A feeds back through).
    pub(crate) fn from_loop(full: &DMatrix<f64>, coords: Vec<Coord>, output: usize) -> Reduced {
        let n = coords.len();
        let mut reduced = Reduced {
            a: DMatrix::zeros(n, n),
            out: DVector::zeros(n),
            coords,
        };
        let proj = reduced.projection(full.nrows());
        let gram = &proj * proj.transpose();
        let right_inverse = proj.transpose() * gram.try_inverse().expect("independent coordinates");
        reduced.a = &proj * full * right_inverse;
        let at = reduced
            .coords
            .iter()
            .position(|&c| c == Coord::Entry(output))
            .expect("the output is a coordinate");
        reduced.out[at] = 1.0;
        reduced
    }

    /// The web line's, for the response of ω_L or of T (`output`, an index of the loop state
    /// [`WEB_CL`]): the loop of [`web_loop`] on [u, ω_m, ω_L, T] and the integrators with gain.
    pub(crate) fn web(plant: &Plant, speed: PiGains, tension: PiGains, output: usize) -> Reduced {
        let full = web_loop(plant, speed, tension);
        // The loop state's entries kept besides u: ω_m, ω_L, T, then x_c, x_T with gain.
        let mut kept = vec![1, OMEGA_L, TENSION];
        if speed.ki != 0.0 {
            kept.push(4);
        }
        // x_T feeds back only through the speed PI (see `web_loop`).
        if tension.ki != 0.0 && (speed.kp != 0.0 || speed.ki != 0.0) {
            kept.push(X_T);
        }
        let coords = std::iter::once(gap(plant))
            .chain(kept.into_iter().map(Coord::Entry))
            .collect::<Vec<_>>();
        let n = coords.len();
        let mut reduced = Reduced {
            a: DMatrix::zeros(n, n),
            out: DVector::zeros(n),
            coords,
        };
        let proj = reduced.projection(WEB_CL);
        // A_r with P A = A_r P: the θ columns of A enter only through u = r_m θ_m − r_L θ_L
        // (column θ_m of A is r_m times the u column), the others map one to one.
        let full = DMatrix::from_iterator(WEB_CL, WEB_CL, full.iter().copied());
        let pa = &proj * &full;
        for i in 0..n {
            reduced.a[(i, 0)] = pa[(i, 0)] / plant.r_m();
            for (k, coord) in reduced.coords[1..].iter().enumerate() {
                let Coord::Entry(j) = *coord else {
                    unreachable!("entries follow the gap")
                };
                reduced.a[(i, k + 1)] = pa[(i, j)];
            }
        }
        let at = reduced
            .coords
            .iter()
            .position(|&c| c == Coord::Entry(output))
            .expect("ω_L or T");
        reduced.out[at] = 1.0;
        reduced
    }

    /// The eigenvalues of the reduced loop (the poles its responses are made of), None if
    /// they cannot be computed.
    pub(crate) fn poles(&self) -> Option<Vec<Complex<f64>>> {
        eigenvalues(&self.a)
    }

    /// (P A, A_r P) for the loop `full` this was reduced from: equal when the coordinates
    /// span everything the loop feeds back through.
    #[cfg(test)]
    pub(crate) fn commutation(&self, full: &DMatrix<f64>) -> (DMatrix<f64>, DMatrix<f64>) {
        let proj = self.projection(full.nrows());
        (&proj * full, &self.a * &proj)
    }

    pub(crate) fn tail_bound<const N: usize, const R: usize>(&self) -> Result<TailBound<N, R>, Unbounded> {
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
        let inside = |c: &Coord| match *c {
            Coord::Gap { i, j, .. } => i < N && j < N,
            Coord::Entry(i) => i < N,
            Coord::Zero => true,
        };
        assert!(
            n <= R && self.coords.iter().all(inside),
            "a tail bound of {R} coordinates for a loop of {N}"
        );
        let mut gramian = SMatrix::<f64, R, R>::zeros();
        for i in 0..n {
            for j in 0..n {
                gramian[(i, j)] = 0.5 * (w[(i, j)] + w[(j, i)]);
            }
        }
        Ok(TailBound {
            gramian,
            coords: std::array::from_fn(|i| self.coords.get(i).copied().unwrap_or(Coord::Zero)),
            epsilon,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{PlantParams, WebSpan};
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

    #[test]
    fn the_web_loop_and_its_reduced_form_commute() {
        // A small servo belt drive pulling a film line's span: 50 mm roller, 1 m span, EA = 1e5 N.
        let span = WebSpan {
            r_w: 0.05,
            l_w: 1.0,
            ea: 1e5,
            v_ref: 2.0,
        };
        let plant = Plant::new(crate::params::test_plants::servo_belt(Some(span))).unwrap();
        let speed = PiGains { kp: 0.18, ki: 57.6 };
        for tension in [
            PiGains::default(),
            PiGains { kp: 0.01, ki: 0.05 },
            PiGains { kp: 2e-4, ki: 0.0 },
        ] {
            let full = web_loop(&plant, speed, tension);
            let full = DMatrix::from_iterator(WEB_CL, WEB_CL, full.iter().copied());
            for output in [OMEGA_L, TENSION] {
                let r = Reduced::web(&plant, speed, tension, output);
                let proj = r.projection(WEB_CL);
                let (lhs, rhs) = (&proj * &full, &r.a * &proj);
                let scale = lhs.abs().max();
                assert!(
                    (&lhs - &rhs).abs().max() <= 1e-14 * scale,
                    "{tension:?}: {lhs} vs {rhs}"
                );
                // The output row picks the same entry in both coordinates (exact: a sum of 1·1
                // and products with 0).
                assert_eq!((r.out.transpose() * &proj)[output], 1.0);
            }
        }
    }
}
