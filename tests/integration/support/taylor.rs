//! A Taylor-series integrator for piecewise-affine ODEs with state events, written
//! independently of `src/physics` so that the crate can be checked against it.
//!
//! In mode m the system is y' = A_m y + c_m + f(s), with f given by its Taylor coefficients
//! (polynomial inputs, sinusoids). The solution over a substep is its Taylor polynomial of
//! degree `ORDER`; substeps are short enough (ρ(A)·H ≤ 1/2) that the truncation is far below
//! round-off, and the polynomial doubles as dense output. A mode is left when a guard
//! l·y + o crosses from ≤ 0 to > 0; the first such crossing is found by interval subdivision
//! with a rigorous exclusion test (so a short touch inside a substep is not missed), then
//! bisection to the last representable time.

use std::sync::OnceLock;

/// Degree of the Taylor polynomial on each substep.
pub const ORDER: usize = 30;

/// Normalised Taylor coefficients y^(n)/n!, n = 0..=ORDER.
pub type Coeffs<const N: usize> = [[f64; N]; ORDER + 1];

/// Leave the mode when `l·y + offset` crosses from ≤ 0 to > 0; then go to `to`, and set
/// `y[snap.0] = snap.1` (the boundary value, exact rather than rounded).
#[derive(Clone, Debug)]
pub struct Guard<const N: usize> {
    pub l: [f64; N],
    pub offset: f64,
    pub to: usize,
    pub snap: Option<(usize, f64)>,
}

#[derive(Clone, Debug)]
pub struct Mode<const N: usize> {
    pub a: [[f64; N]; N],
    pub c: [f64; N],
    pub guards: Vec<Guard<N>>,
}

/// The three modes of a backlash gap of half-width g > 0 on u = y[`u`]: 0 contact − (leave
/// when u + g > 0), 1 free (leave when u − g > 0 or −u − g > 0), 2 contact + (leave when
/// g − u > 0), each switch snapping u onto ±g. `build(σ, contact)` gives a mode's (A, c).
pub fn backlash_modes<const N: usize>(
    g: f64,
    u: usize,
    build: impl Fn(f64, bool) -> ([[f64; N]; N], [f64; N]),
) -> Vec<Mode<N>> {
    let mut e_u = [0.0; N];
    e_u[u] = 1.0;
    let neg_e_u = e_u.map(|x| -x);
    let guard = |l: [f64; N], offset: f64, to: usize, snap: f64| Guard {
        l,
        offset,
        to,
        snap: Some((u, snap)),
    };
    let mode = |(a, c): ([[f64; N]; N], [f64; N]), guards: Vec<Guard<N>>| Mode { a, c, guards };
    vec![
        mode(build(-1.0, true), vec![guard(e_u, g, 1, -g)]),
        mode(build(0.0, false), vec![guard(e_u, -g, 2, g), guard(neg_e_u, -g, 0, -g)]),
        mode(build(1.0, true), vec![guard(neg_e_u, g, 1, g)]),
    ]
}

/// A mode switch, `offset` measured from the start of the `advance` call.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Event {
    pub offset: f64,
    pub from: usize,
    pub to: usize,
}

/// A piece of trajectory: on [start, start + len] (offsets from the start of `advance`) the
/// state is Σ coeffs[n] σ^n, σ = t − start.
pub struct Piece<'a, const N: usize> {
    pub start: f64,
    pub len: f64,
    pub mode: usize,
    pub coeffs: &'a Coeffs<N>,
}

pub struct Hybrid<const N: usize> {
    pub modes: Vec<Mode<N>>,
    /// Upper bound on a substep (e.g. from the bandwidth of the forcing).
    pub max_substep: f64,
    /// Per-mode substep from ρ(A): 1/(2ρ).
    mode_substep: Vec<f64>,
}

fn binomials() -> &'static [[f64; ORDER + 1]; ORDER + 1] {
    static TABLE: OnceLock<[[f64; ORDER + 1]; ORDER + 1]> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut b = [[0.0; ORDER + 1]; ORDER + 1];
        for n in 0..=ORDER {
            b[n][0] = 1.0;
            for k in 1..=n {
                b[n][k] = b[n - 1][k - 1] + if k <= n - 1 { b[n - 1][k] } else { 0.0 };
            }
        }
        b
    })
}

pub fn mat_mul<const N: usize>(a: &[[f64; N]; N], b: &[[f64; N]; N]) -> [[f64; N]; N] {
    let mut c = [[0.0; N]; N];
    for i in 0..N {
        for k in 0..N {
            let aik = a[i][k];
            if aik != 0.0 {
                for j in 0..N {
                    c[i][j] += aik * b[k][j];
                }
            }
        }
    }
    c
}

pub fn inf_norm<const N: usize>(a: &[[f64; N]; N]) -> f64 {
    a.iter()
        .map(|row| row.iter().map(|x| x.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

/// Spectral-radius estimate ‖A^32‖^(1/32) (Gelfand), with rescaling against overflow.
pub fn spectral_radius_estimate<const N: usize>(a: &[[f64; N]; N]) -> f64 {
    let mut m = *a;
    let mut log_scale = 0.0;
    for _ in 0..5 {
        let nm = inf_norm(&m);
        if nm == 0.0 {
            return 0.0;
        }
        for row in m.iter_mut() {
            for x in row.iter_mut() {
                *x /= nm;
            }
        }
        log_scale = 2.0 * (log_scale + nm.ln());
        m = mat_mul(&m, &m);
    }
    let nm = inf_norm(&m);
    if nm == 0.0 {
        0.0
    } else {
        ((nm.ln() + log_scale) / 32.0).exp()
    }
}

/// Value of the polynomial Σ p[n] s^n.
pub fn horner(p: &[f64], s: f64) -> f64 {
    p.iter().rev().fold(0.0, |acc, &c| acc * s + c)
}

/// Coefficients of p re-expanded about c: q_k = Σ_n C(n,k) p_n c^(n−k).
fn shift(p: &[f64; ORDER + 1], c: f64) -> [f64; ORDER + 1] {
    let b = binomials();
    let mut pow = [1.0; ORDER + 1];
    for i in 1..=ORDER {
        pow[i] = pow[i - 1] * c;
    }
    let mut q = [0.0; ORDER + 1];
    for (k, qk) in q.iter_mut().enumerate() {
        let mut acc = 0.0;
        for n in (k..=ORDER).rev() {
            acc += b[n][k] * p[n] * pow[n - k];
        }
        *qk = acc;
    }
    q
}

/// Last s in [a, b] with p(s) ≤ 0, given p(a) ≤ 0 < p(b): bisection to adjacent doubles.
fn bisect(p: &[f64; ORDER + 1], mut a: f64, mut b: f64) -> f64 {
    loop {
        let m = 0.5 * (a + b);
        if m <= a || m >= b {
            return b;
        }
        if horner(p, m) <= 0.0 {
            a = m;
        } else {
            b = m;
        }
    }
}

/// First s in [a, b] where p crosses from ≤ 0 to > 0 (a touch with p > 0 on an interval of
/// any representable length counts).
fn first_crossing(p: &[f64; ORDER + 1], a: f64, b: f64, depth: u32) -> Option<f64> {
    let c = 0.5 * (a + b);
    let r = 0.5 * (b - a);
    let q = shift(p, c);
    let mut spread = 0.0;
    let mut slope_spread = 0.0;
    let mut rp = r;
    for n in 1..=ORDER {
        spread += q[n].abs() * rp;
        if n >= 2 {
            slope_spread += n as f64 * q[n].abs() * rp / r;
        }
        rp *= r;
    }
    // Rounding in the shifted coefficients: a few ulps of the largest term.
    let fuzz = 8.0 * f64::EPSILON * (q[0].abs() + spread);
    if q[0] < -(spread + fuzz) {
        return None; // p < 0 on the whole interval
    }
    let pa = horner(p, a);
    let pb = horner(p, b);
    if pa > 0.0 {
        // Only reachable through rounding right at a crossing already passed on the left.
        return Some(a);
    }
    if q[1].abs() > slope_spread * (1.0 + 1e-12) + fuzz / r.max(f64::MIN_POSITIVE) {
        // Monotone: at most one crossing, upward only if increasing.
        return if q[1] > 0.0 && pb > 0.0 {
            Some(bisect(p, a, b))
        } else {
            None
        };
    }
    if depth >= 64 || c <= a || c >= b {
        return if pb > 0.0 { Some(bisect(p, a, b)) } else { None };
    }
    first_crossing(p, a, c, depth + 1).or_else(|| first_crossing(p, c, b, depth + 1))
}

impl<const N: usize> Hybrid<N> {
    pub fn new(modes: Vec<Mode<N>>, max_substep: f64) -> Hybrid<N> {
        let mode_substep = modes
            .iter()
            .map(|m| {
                let rho = spectral_radius_estimate(&m.a);
                if rho > 0.0 {
                    0.5 / rho
                } else {
                    f64::INFINITY
                }
            })
            .collect();
        Hybrid {
            modes,
            max_substep,
            mode_substep,
        }
    }

    /// Taylor coefficients of the solution through y at the expansion point.
    fn coefficients(&self, mode: usize, y: &[f64; N], forcing: &Coeffs<N>) -> Coeffs<N> {
        let m = &self.modes[mode];
        let mut out = [[0.0; N]; ORDER + 1];
        out[0] = *y;
        for n in 0..ORDER {
            let mut d = forcing[n];
            if n == 0 {
                for i in 0..N {
                    d[i] += m.c[i];
                }
            }
            for i in 0..N {
                let mut acc = d[i];
                for j in 0..N {
                    acc += m.a[i][j] * out[n][j];
                }
                out[n + 1][i] = acc / (n + 1) as f64;
            }
        }
        out
    }

    /// Truncation test: the last two terms are negligible in every component.
    fn converged(coeffs: &Coeffs<N>, h: f64) -> bool {
        (0..N).all(|i| {
            let mut total = 0.0;
            let mut hp = 1.0;
            let mut terms = [0.0; ORDER + 1];
            for n in 0..=ORDER {
                terms[n] = coeffs[n][i].abs() * hp;
                total += terms[n];
                hp *= h;
            }
            terms[ORDER] + terms[ORDER - 1] <= 1e-18 * total
        })
    }

    pub fn eval(coeffs: &Coeffs<N>, s: f64) -> [f64; N] {
        let mut y = [0.0; N];
        for i in 0..N {
            let mut acc = 0.0;
            for n in (0..=ORDER).rev() {
                acc = acc * s + coeffs[n][i];
            }
            y[i] = acc;
        }
        y
    }

    /// Advances (mode, y) by `h`. `forcing(s, out)` writes the normalised Taylor coefficients
    /// of f at offset s (out is zeroed first). Switches are appended to `events`; every piece
    /// of trajectory is passed to `on_piece` in time order.
    pub fn advance(
        &self,
        mode: &mut usize,
        y: &mut [f64; N],
        h: f64,
        forcing: &dyn Fn(f64, &mut Coeffs<N>),
        events: &mut Vec<Event>,
        on_piece: &mut dyn FnMut(Piece<N>),
    ) {
        // Elapsed time kept exactly as s + s_lo (error-free sums): a rounded running sum of
        // ~10⁴ substeps would shift the end of the step by ~1e-13 s, i.e. ω·1e-13 in θ.
        let (mut s, mut s_lo) = (0.0, 0.0);
        let mut zero_length_switches = 0;
        loop {
            let remaining = (h - s) - s_lo;
            if remaining <= 0.0 {
                break;
            }
            let mut f = [[0.0; N]; ORDER + 1];
            forcing(s, &mut f);
            let mut len = remaining.min(self.max_substep).min(self.mode_substep[*mode]);
            let coeffs = loop {
                let cf = self.coefficients(*mode, y, &f);
                if Self::converged(&cf, len) {
                    break cf;
                }
                len *= 0.5;
                assert!(len > 1e-300, "Taylor series does not converge");
            };
            let mut first: Option<(f64, usize)> = None;
            for (gi, g) in self.modes[*mode].guards.iter().enumerate() {
                let mut p = [0.0; ORDER + 1];
                for n in 0..=ORDER {
                    p[n] = (0..N).map(|j| g.l[j] * coeffs[n][j]).sum();
                }
                p[0] += g.offset;
                let limit = first.map_or(len, |(t, _)| t);
                if let Some(t) = first_crossing(&p, 0.0, limit, 0) {
                    if first.is_none_or(|(t0, _)| t < t0) {
                        first = Some((t, gi));
                    }
                }
            }
            match first {
                Some((t, gi)) => {
                    *y = Self::eval(&coeffs, t);
                    on_piece(Piece {
                        start: s,
                        len: t,
                        mode: *mode,
                        coeffs: &coeffs,
                    });
                    let g = &self.modes[*mode].guards[gi];
                    if let Some((idx, value)) = g.snap {
                        y[idx] = value;
                    }
                    events.push(Event {
                        offset: s + t,
                        from: *mode,
                        to: g.to,
                    });
                    *mode = g.to;
                    (s, s_lo) = add_exact(s, s_lo, t);
                    zero_length_switches = if t == 0.0 { zero_length_switches + 1 } else { 0 };
                    assert!(zero_length_switches < 4, "chattering at s = {s}");
                }
                None => {
                    *y = Self::eval(&coeffs, len);
                    on_piece(Piece {
                        start: s,
                        len,
                        mode: *mode,
                        coeffs: &coeffs,
                    });
                    if len == remaining {
                        break;
                    }
                    (s, s_lo) = add_exact(s, s_lo, len);
                }
            }
        }
    }
}

/// (s + s_lo) + t as a renormalised pair (TwoSum, then FastTwoSum).
fn add_exact(s: f64, s_lo: f64, t: f64) -> (f64, f64) {
    let sum = s + t;
    let bp = sum - s;
    let err = (s - (sum - bp)) + (t - bp);
    let lo = s_lo + err;
    let hi = sum + lo;
    (hi, lo - (hi - sum))
}

/// ∫_0^len Σ p[n] σ^n dσ.
pub fn integrate_poly(p: &[f64], len: f64) -> f64 {
    let mut acc = 0.0;
    for n in (0..p.len()).rev() {
        acc = acc * len + p[n] / (n + 1) as f64;
    }
    acc * len
}

/// Coefficients of the product of two polynomials.
pub fn poly_mul(p: &[f64], q: &[f64]) -> Vec<f64> {
    let mut r = vec![0.0; p.len() + q.len() - 1];
    for (i, a) in p.iter().enumerate() {
        for (j, b) in q.iter().enumerate() {
            r[i + j] += a * b;
        }
    }
    r
}

/// Column `i` of a coefficient array as a polynomial.
pub fn component<const N: usize>(coeffs: &Coeffs<N>, i: usize) -> [f64; ORDER + 1] {
    let mut p = [0.0; ORDER + 1];
    for n in 0..=ORDER {
        p[n] = coeffs[n][i];
    }
    p
}
