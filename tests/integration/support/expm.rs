//! Matrix exponential by scaling and squaring of a Taylor polynomial (written here, not taken
//! from the crate), and the exact ZOH/FOH step of a linear plant through an augmented matrix.

use super::taylor::inf_norm;

/// e^A by scaling and squaring of a Taylor polynomial, after a diagonal balancing
/// B = D⁻¹ A D (powers of two, exact). Every squaring doubles the relative rounding of the
/// scaled exponential (for an oscillation: its phase), so with 2^s ≈ ‖B‖ the result would
/// lose log2 ‖B‖ bits; the polynomial and the squarings are therefore done in double-double
/// arithmetic (~32 digits) and rounded once at the end.
pub fn expm<const N: usize>(a: &[[f64; N]; N]) -> [[f64; N]; N] {
    let (b, d) = balance(a);
    let nrm = inf_norm(&b);
    let s = if nrm > 0.25 {
        (nrm / 0.25).log2().ceil() as i32
    } else {
        0
    };
    let x: [[Dd; N]; N] = std::array::from_fn(|i| std::array::from_fn(|j| Dd(b[i][j] * 0.5f64.powi(s), 0.0)));
    let mut sum = [[Dd(0.0, 0.0); N]; N];
    let mut term = [[Dd(0.0, 0.0); N]; N];
    for i in 0..N {
        sum[i][i] = Dd(1.0, 0.0);
        term[i][i] = Dd(1.0, 0.0);
    }
    // ‖x‖ ≤ 1/4: the remainder after degree 40 is below 1e-72.
    for k in 1..=40 {
        term = dd_mat_mul(&term, &x);
        for row in term.iter_mut() {
            for v in row.iter_mut() {
                *v = v.div_int(k);
            }
        }
        for i in 0..N {
            for j in 0..N {
                sum[i][j] = sum[i][j].add(term[i][j]);
            }
        }
    }
    for _ in 0..s {
        sum = dd_mat_mul(&sum, &sum);
    }
    // e^A = D e^B D⁻¹ (powers of two: exact).
    std::array::from_fn(|i| std::array::from_fn(|j| (sum[i][j].0 + sum[i][j].1) * d[i] / d[j]))
}

/// A double-double number hi + lo, |lo| ≤ ulp(hi)/2.
#[derive(Clone, Copy, Debug)]
struct Dd(f64, f64);

fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bp = s - a;
    (s, (a - (s - bp)) + (b - bp))
}

fn fast_two_sum(a: f64, b: f64) -> Dd {
    let s = a + b;
    Dd(s, b - (s - a))
}

impl Dd {
    fn add(self, o: Dd) -> Dd {
        let (s, e) = two_sum(self.0, o.0);
        fast_two_sum(s, e + self.1 + o.1)
    }
    fn mul(self, o: Dd) -> Dd {
        let p = self.0 * o.0;
        let e = self.0.mul_add(o.0, -p);
        fast_two_sum(p, e + self.0 * o.1 + self.1 * o.0)
    }
    fn div_int(self, k: i32) -> Dd {
        let k = k as f64;
        let q = self.0 / k;
        let p = q * k;
        let e = q.mul_add(k, -p);
        fast_two_sum(q, ((self.0 - p) - e + self.1) / k)
    }
}

fn dd_mat_mul<const N: usize>(a: &[[Dd; N]; N], b: &[[Dd; N]; N]) -> [[Dd; N]; N] {
    let mut c = [[Dd(0.0, 0.0); N]; N];
    for i in 0..N {
        for k in 0..N {
            if a[i][k].0 == 0.0 {
                continue;
            }
            for j in 0..N {
                c[i][j] = c[i][j].add(a[i][k].mul(b[k][j]));
            }
        }
    }
    c
}

/// Parlett–Reinsch balancing with radix 2: returns B = D⁻¹ A D and diag(D).
fn balance<const N: usize>(a: &[[f64; N]; N]) -> ([[f64; N]; N], [f64; N]) {
    let mut b = *a;
    let mut d = [1.0; N];
    for _ in 0..100 {
        let mut done = true;
        for i in 0..N {
            let mut c: f64 = (0..N).filter(|&j| j != i).map(|j| b[j][i].abs()).sum();
            let r: f64 = (0..N).filter(|&j| j != i).map(|j| b[i][j].abs()).sum();
            if c == 0.0 || r == 0.0 {
                continue;
            }
            let total = c + r;
            let mut f = 1.0;
            while c < r / 2.0 {
                f *= 2.0;
                c *= 4.0;
            }
            while c >= r * 2.0 {
                f /= 2.0;
                c /= 4.0;
            }
            if (c + r) / f < 0.95 * total {
                done = false;
                d[i] *= f;
                for j in 0..N {
                    b[i][j] /= f;
                    b[j][i] *= f;
                }
            }
        }
        if done {
            break;
        }
    }
    (b, d)
}

pub fn mat_vec<const N: usize>(a: &[[f64; N]; N], x: &[f64; N]) -> [f64; N] {
    let mut y = [0.0; N];
    for i in 0..N {
        y[i] = (0..N).map(|j| a[i][j] * x[j]).sum();
    }
    y
}

pub fn scaled<const N: usize>(a: &[[f64; N]; N], t: f64) -> [[f64; N]; N] {
    let mut b = *a;
    for row in b.iter_mut() {
        for v in row.iter_mut() {
            *v *= t;
        }
    }
    b
}

/// A_p of docs/model.md §3 (the backlash-free plant, z = [θ_m, ω_m, θ_L, ω_L]).
#[allow(clippy::too_many_arguments)]
pub fn a_p(j_m: f64, j_l: f64, b_m: f64, b_l: f64, r_m: f64, r_l: f64, k: f64) -> [[f64; 4]; 4] {
    [
        [0.0, 1.0, 0.0, 0.0],
        [-k * r_m * r_m / j_m, -b_m / j_m, k * r_m * r_l / j_m, 0.0],
        [0.0, 0.0, 0.0, 1.0],
        [k * r_m * r_l / j_l, 0.0, -k * r_l * r_l / j_l, -b_l / j_l],
    ]
}

/// Exact step of z' = A z + B τ(t), τ(t) = τ0 + dτ t, B = [0, 1/J_m, 0, 0; 0, 0, 0, 1/J_L]ᵀ,
/// through e^{M t} of the 8×8 matrix that also carries τ and dτ as states (Van Loan).
pub fn linear_plant_step(
    a: &[[f64; 4]; 4],
    j_m: f64,
    j_l: f64,
    z0: [f64; 4],
    tau: [f64; 2],
    dtau: [f64; 2],
    t: f64,
) -> [f64; 4] {
    let mut m = [[0.0; 8]; 8];
    for i in 0..4 {
        m[i][..4].copy_from_slice(&a[i]);
    }
    m[1][4] = 1.0 / j_m;
    m[3][5] = 1.0 / j_l;
    m[4][6] = 1.0;
    m[5][7] = 1.0;
    let e = expm(&scaled(&m, t));
    let x = mat_vec(&e, &[z0[0], z0[1], z0[2], z0[3], tau[0], tau[1], dtau[0], dtau[1]]);
    [x[0], x[1], x[2], x[3]]
}

/// u(t) of the backlash-free plant (ψ = K u) in gap coordinates [u, v, ω_m, ω_L], v = u':
/// u is advanced through v, not recovered as r_m θ_m − r_L θ_L, which would cancel when the
/// angles are large. Same augmented-matrix construction as [`linear_plant_step`].
#[allow(clippy::too_many_arguments)]
pub fn linear_gap_step(
    j_m: f64,
    j_l: f64,
    b_m: f64,
    b_l: f64,
    r_m: f64,
    r_l: f64,
    k: f64,
    y0: [f64; 4],
    tau: [f64; 2],
    dtau: [f64; 2],
    t: f64,
) -> f64 {
    let mu = r_m * r_m / j_m + r_l * r_l / j_l;
    let mut m = [[0.0; 8]; 8];
    m[0][1] = 1.0;
    m[1] = [
        -mu * k,
        0.0,
        -r_m * b_m / j_m,
        r_l * b_l / j_l,
        r_m / j_m,
        -r_l / j_l,
        0.0,
        0.0,
    ];
    m[2] = [-r_m * k / j_m, 0.0, -b_m / j_m, 0.0, 1.0 / j_m, 0.0, 0.0, 0.0];
    m[3] = [r_l * k / j_l, 0.0, 0.0, -b_l / j_l, 0.0, 1.0 / j_l, 0.0, 0.0];
    m[4][6] = 1.0;
    m[5][7] = 1.0;
    let e = expm(&scaled(&m, t));
    mat_vec(&e, &[y0[0], y0[1], y0[2], y0[3], tau[0], tau[1], dtau[0], dtau[1]])[0]
}
