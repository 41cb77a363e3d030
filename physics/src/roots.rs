//! Certified search for the first instant a scalar signal of a linear system leaves its
//! admissible side (docs/model.md §2: switches located to round-off, grazing contacts not missed).
//!
//! Along y' = M y a linear signal s(σ) = c·y(σ) has exact derivatives s⁽ᵏ⁾ = c Mᵏ y. A piece
//! [0, w] is cleared when the cubic lower bound f₀ + f₁σ + f₂σ²/2 − C σ³/6, with C ≥ sup|f'''|
//! from the entrywise bound |e^{Mσ} − I| ≤ e^{|M|σ} − I, stays above the round-off floor.
//! Otherwise the state's Taylor expansion over the piece gives the signal's polynomial, which is
//! searched by bisection with the same test; the first crossing is refined by safeguarded
//! Newton to round-off, and the same expansion gives the state there.

use super::taylor::{exp_nonnegative, Poly, TERMS};
use nalgebra::{SMatrix, SVector};

const FACTORIAL: [f64; TERMS] = {
    let mut f = [1.0; TERMS];
    let mut k = 1;
    while k < TERMS {
        f[k] = f[k - 1] * k as f64;
        k += 1;
    }
    f
};

/// k!/(k − 3)! as the search's bound on |f‴| divides it (entries below 3 unused), evaluated
/// once: the same quotients, bit for bit, without a division per coefficient and level.
const FALLING_CUBE: [f64; TERMS] = {
    let mut f = [0.0; TERMS];
    let mut k = 3;
    while k < TERMS {
        f[k] = FACTORIAL[k] / FACTORIAL[k - 3];
        k += 1;
    }
    f
};

/// Derivative rows of the signal s = c·y along y' = M y, and the data of its remainder bound.
#[derive(Clone, Debug)]
pub struct SignalRows<const N: usize> {
    /// rows[k] = (c Mᵏ)ᵀ, so s⁽ᵏ⁾(σ) = rows[k]·y(σ), k ≤ 3.
    rows: [SVector<f64, N>; 4],
    /// |c M³|ᵀ (e^{|M| len_ref} − I)ᵀ: sup over [0, len_ref] of |s'''(σ) − s'''(0)| ≤ this·|y(0)|.
    remainder_ref: SVector<f64, N>,
    len_ref: f64,
}

impl<const N: usize> SignalRows<N> {
    pub fn new(c: SVector<f64, N>, m: &SMatrix<f64, N, N>, len_ref: f64) -> Self {
        let mut rows = [SVector::<f64, N>::zeros(); 4];
        rows[0] = c;
        let mt = m.transpose();
        for k in 1..4 {
            rows[k] = mt * rows[k - 1];
        }
        let remainder_ref = Self::remainder_row_for(&rows[3], m, len_ref);
        SignalRows {
            rows,
            remainder_ref,
            len_ref,
        }
    }

    /// (|c M³| (e^{|M| len} − I))ᵀ for a given length.
    pub fn remainder_row(&self, m: &SMatrix<f64, N, N>, len: f64) -> SVector<f64, N> {
        Self::remainder_row_for(&self.rows[3], m, len)
    }

    fn remainder_row_for(third: &SVector<f64, N>, m: &SMatrix<f64, N, N>, len: f64) -> SVector<f64, N> {
        let grow = exp_nonnegative(&(m.abs() * len)) - SMatrix::<f64, N, N>::identity();
        grow.transpose() * third.abs()
    }

    pub fn len_ref(&self) -> f64 {
        self.len_ref
    }

    /// (c Mᵏ)ᵀ.
    pub fn row(&self, k: usize) -> &SVector<f64, N> {
        &self.rows[k]
    }

    /// s⁽ᵏ⁾ at y.
    pub fn derivative(&self, k: usize, y: &SVector<f64, N>) -> f64 {
        self.rows[k].dot(y)
    }

    /// A bound on sup |s'''| over [0, len] from y = y(0): the reference remainder row scaled by
    /// len/len_ref, valid for len ≤ len_ref because every entry of e^{|M|σ} − I is convex in σ
    /// and 0 at σ = 0. (Whole pieces get the row for their exact length from the fused kernels.)
    pub fn third_bound(&self, y: &SVector<f64, N>, len: f64) -> f64 {
        let growth = self.remainder_ref.dot(&y.abs()) * (len / self.len_ref);
        self.rows[3].dot(y).abs() + growth
    }
}

/// Which side is admissible: f = offset + sign·s ≥ 0, with a round-off floor `tol` ≥ 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Side {
    pub offset: f64,
    pub sign: f64,
    pub tol: f64,
}

impl Side {
    pub fn value(&self, s: f64) -> f64 {
        self.offset + self.sign * s
    }
}

/// True when f₀ + f₁σ + f₂σ²/2 − c₃σ³/6 > −tol for all σ in (0, w] and f₀ ≥ −tol: then f
/// (with |f'''| ≤ c₃) cannot leave the admissible side on [0, w]. A start on the floor itself
/// (f₀ = −tol, as after a located crossing with tol = 0) is admissible: the search asks where
/// f goes below it.
#[inline]
pub fn cubic_clear(f0: f64, f1: f64, f2: f64, c3: f64, w: f64, tol: f64) -> bool {
    // Sufficient and cheap: f₀ exceeds the largest possible drop over [0, w].
    if f0 - largest_drop(f1, f2, c3, w) > -tol {
        return true;
    }
    cubic_clear_exactly(f0, f1, f2, c3, w, tol)
}

/// The most f₀ + f₁σ + f₂σ²/2 − c₃σ³/6 can fall below f₀ over [0, w] (c₃ ≥ 0), by the
/// triangle inequality: the cheap test of `cubic_clear`, the same for f and −f.
#[inline(always)]
pub fn largest_drop(f1: f64, f2: f64, c3: f64, w: f64) -> f64 {
    w * (f1.abs() + w * (0.5 * f2.abs() + w * c3 * (1.0 / 6.0)))
}

/// `cubic_clear` past its cheap test: the cubic's minimum over [0, w].
#[allow(clippy::neg_cmp_op_on_partial_ord, reason = "a NaN must fail each test, not pass it")]
#[inline(never)]
fn cubic_clear_exactly(f0: f64, f1: f64, f2: f64, c3: f64, w: f64, tol: f64) -> bool {
    let floor = -tol;
    let lower = |x: f64| f0 + x * (f1 + x * (0.5 * f2 - x * c3 / 6.0));
    if !(f0 >= floor) || !(lower(w) > floor) {
        return false;
    }
    // On the floor at the start, f must leave it upwards.
    if f0 == floor && !(f1 > 0.0 || (f1 == 0.0 && f2 > 0.0)) {
        return false;
    }
    // Interior minima: roots of f₁ + f₂σ − c₃σ²/2.
    let mut ok = true;
    let mut check = |x: f64| {
        if x > 0.0 && x < w && !(lower(x) > floor) {
            ok = false;
        }
    };
    if c3 == 0.0 {
        if f2 != 0.0 {
            check(-f1 / f2);
        }
    } else {
        let disc = f2 * f2 + 2.0 * c3 * f1;
        if disc >= 0.0 {
            let sq = disc.sqrt();
            check((f2 - sq) / c3);
            check((f2 + sq) / c3);
        }
    }
    ok
}

/// Upper bound of the work in one search: intervals examined. A search for one or two
/// crossings descends ~50 levels at most (to `RESOLUTION`), with one sibling per level.
const MAX_INTERVALS: usize = 512;

/// A search that spent its work budget without certifying either way: the signal hovers
/// within round-off of the threshold over much of the span.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Undecided;

/// Pieces whose searches get an allowance in [`work_budget`]; a step, advance or supremum of
/// more pieces gets no more. An interval costs about a microsecond (extreme parameters), so
/// the whole budget is a fraction of a second however many pieces there are.
pub const SEARCH_PIECES: usize = 1 << 12;

/// The intervals all searches of one step or advance of `pieces` pieces may examine together:
/// plenty for the few crossings per piece a real motion has, and a cap on the work when the
/// signal hovers at its threshold through a long step (each piece then gives up early). The
/// allowance stops growing at `SEARCH_PIECES` pieces: a signal hovering through a million
/// pieces would otherwise search for minutes.
#[inline]
pub fn work_budget(pieces: usize) -> usize {
    4 * MAX_INTERVALS + 64 * pieces.min(SEARCH_PIECES)
}

/// First σ in [0, w] at which `side.value(p(σ))` leaves [−tol, ∞), located as the root of
/// side.value(p) = 0 (σ = 0 when it is already outside). `Ok(None)` when it provably stays;
/// `Err(Undecided)` when the work ran out (`MAX_INTERVALS`, or what is left of `budget`,
/// which is charged with the intervals examined) before either was certified.
pub fn first_exit(p: &Poly, side: Side, w: f64, budget: &mut usize) -> Result<Option<f64>, Undecided> {
    let allowed = MAX_INTERVALS.min(*budget);
    let mut left = allowed;
    // Depth first, left to right: a crossing found before the work ran out is the first.
    // p.shifted(0) is p.
    let found = search(p, Some(p), side, 0.0, w, RESOLUTION * w, &mut left);
    *budget -= allowed - left;
    match found {
        None if left == 0 => Err(Undecided),
        found => Ok(found),
    }
}

/// An upper bound on ∫_0^w |p(σ)| dσ: Σ |c_k| w^(k+1)/(k+1), for spans the search gave up on.
pub fn abs_integral_bound(p: &Poly, w: f64) -> f64 {
    let mut wp = w;
    let mut total = 0.0;
    for (k, c) in p.coef[..=p.deg].iter().enumerate() {
        total += c.abs() * wp / (k + 1) as f64;
        wp *= w;
    }
    total
}

/// Intervals narrower than this fraction of the searched span are not split: offsets that
/// small vanish when added to the span's start time, and halving on down to the subnormal
/// range would take ~1000 levels of slow arithmetic per search.
const RESOLUTION: f64 = f64::EPSILON / 4.0;

/// The first crossing in [lo, hi], depth first; `shifted` is p.shifted(lo) when the caller has it
/// (the left half of a split starts where its parent did, so it reads the parent's: the same
/// coefficients, not computed twice).
fn search(
    p: &Poly,
    shifted: Option<&Poly>,
    side: Side,
    lo: f64,
    hi: f64,
    resolution: f64,
    budget: &mut usize,
) -> Option<f64> {
    if *budget == 0 {
        return None;
    }
    *budget -= 1;
    let w = hi - lo;
    let own;
    let q = match shifted {
        Some(q) => q,
        None => {
            own = p.shifted(lo);
            &own
        }
    };
    let s = side.sign;
    let f0 = side.value(q.coef[0]);
    if f0 < -side.tol {
        return Some(lo);
    }
    let f1 = s * q.coef[1];
    let f2 = 2.0 * s * q.coef[2];
    // sup |f'''| on [lo, hi] from the shifted polynomial's higher coefficients.
    let mut c3 = 0.0;
    let mut wp = 1.0;
    for (c, falling) in q.coef.iter().zip(FALLING_CUBE).take(q.deg + 1).skip(3) {
        c3 += c.abs() * falling * wp;
        wp *= w;
    }
    if cubic_clear(f0, f1, f2, c3, w, side.tol) {
        return None;
    }
    let f_hi = side.value(q.eval(w));
    if f_hi < -side.tol {
        // f' ≤ f₁ + f₂σ + c₃σ²/2, convex: if negative at both ends, f falls through one root.
        let slope_end = f1 + w * (f2 + 0.5 * c3 * w);
        if f1 < 0.0 && slope_end < 0.0 {
            return Some(lo + refine(q, side, w, f_hi));
        }
    }
    let mid = lo + 0.5 * w;
    if w <= resolution || mid <= lo || mid >= hi {
        // At the resolution of the span: the crossing, if any, is here.
        return if f_hi < -side.tol {
            Some(lo + refine(q, side, w, f_hi))
        } else {
            None
        };
    }
    search(p, Some(q), side, lo, mid, resolution, budget).or_else(|| search(p, None, side, mid, hi, resolution, budget))
}

/// The root of side.value(q(σ)) on [0, w], given f(0) ≥ −tol and f(w) = `f_w` < −tol (the
/// search has it: `q.eval(w)` is the value `q.eval_d(w)` computes, operation for operation):
/// Newton safeguarded by the bracket, until the step is below one ulp. σ = 0 when f(0) ≤ 0.
fn refine(q: &Poly, side: Side, w: f64, f_w: f64) -> f64 {
    let f = |x: f64| {
        let (v, d) = q.eval_d(x);
        (side.value(v), side.sign * d)
    };
    let (mut a, mut b) = (0.0, w);
    let (fa, _) = f(a);
    if fa <= 0.0 {
        return 0.0;
    }
    let mut x = a + (b - a) * (fa / (fa - f_w)).clamp(0.0, 1.0);
    for _ in 0..200 {
        let (fx, dx) = f(x);
        if fx == 0.0 {
            return x;
        }
        if fx > 0.0 {
            a = x;
        } else {
            b = x;
        }
        let step = fx / dx;
        if b - a <= 2.0 * f64::EPSILON * b || step.abs() <= f64::EPSILON * x {
            return x;
        }
        let newton = x - step;
        x = if newton > a && newton < b {
            newton
        } else {
            a + 0.5 * (b - a)
        };
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    fn poly(coefs: &[f64]) -> Poly {
        let mut coef = [0.0; TERMS];
        coef[..coefs.len()].copy_from_slice(coefs);
        Poly {
            coef,
            deg: coefs.len() - 1,
        }
    }

    /// Intervals one search examines, and what it found.
    fn work(p: &Poly, side: Side, w: f64) -> (Option<f64>, usize) {
        let mut budget = MAX_INTERVALS;
        let found = search(p, Some(p), side, 0.0, w, RESOLUTION * w, &mut budget);
        (found, MAX_INTERVALS - budget)
    }

    #[test]
    fn a_signal_on_its_threshold_throughout_is_undecided_within_the_budget() {
        // f ≡ 0 with a floor of 0 and a non-zero cubic bound from round-off-sized higher
        // coefficients: nothing can be certified anywhere; the search must give up, not hang.
        let p = poly(&[0.0, 0.0, 0.0, 1e-300, -1e-300]);
        let side = Side {
            offset: 0.0,
            sign: 1.0,
            tol: 0.0,
        };
        let (_, intervals) = work(&p, side, 0.5);
        assert!(intervals <= MAX_INTERVALS);
        let mut budget = 3 * MAX_INTERVALS;
        assert!(matches!(
            first_exit(&p, side, 0.5, &mut budget),
            Err(Undecided) | Ok(None)
        ));
        assert_eq!(budget, 3 * MAX_INTERVALS - intervals, "the shared budget is charged");
        // With the shared budget spent, a search gives up at once.
        let mut spent = 0;
        assert_eq!(first_exit(&p, side, 0.5, &mut spent), Err(Undecided));
    }

    #[test]
    fn the_fallback_integral_bounds_the_absolute_integral() {
        // p = 1 − 3σ + σ² changes sign on [0, 1]; ∫|p| by fine midpoint sums stays below.
        let p = poly(&[1.0, -3.0, 1.0]);
        let n = 100_000;
        let exact: f64 = (0..n)
            .map(|i| p.eval((i as f64 + 0.5) / n as f64).abs() / n as f64)
            .sum();
        let bound = abs_integral_bound(&p, 1.0);
        assert!(bound >= exact, "{bound} < {exact}");
        assert!((bound - (1.0 + 1.5 + 1.0 / 3.0)).abs() < 1e-15);
    }

    #[test]
    fn a_start_on_the_floor_heading_inside_is_clear_at_once() {
        // h = σ − 2σ² + σ³ on a located root with a zero round-off floor: the state the
        // bound's sign-change search restarts from after each crossing.
        let p = poly(&[0.0, 1.0, -2.0, 1.0]);
        let side = Side {
            offset: 0.0,
            sign: 1.0,
            tol: 0.0,
        };
        let (found, intervals) = work(&p, side, 0.5);
        assert_eq!(found, None);
        assert!(intervals <= 4, "{intervals} intervals");
        assert!(cubic_clear(0.0, 1.0, -4.0, 6.0, 0.25, 0.0));
        // Heading out of the admissible side, or flat with nothing to lift it: not clear.
        assert!(!cubic_clear(0.0, -1.0, 0.0, 0.0, 0.5, 0.0));
        assert!(!cubic_clear(0.0, 0.0, 0.0, 1.0, 0.5, 0.0));
    }

    #[test]
    fn bisection_stops_at_the_resolution_of_the_span() {
        // f touches the floor at σ = 0 from inside with f1 = 0 and f2 = 0; c3 > 0 keeps every
        // interval starting at 0 from being cleared, so only the resolution ends the descent.
        let p = poly(&[0.0, 0.0, 0.0, 1.0, -1.0]);
        let side = Side {
            offset: 0.0,
            sign: 1.0,
            tol: 0.0,
        };
        let (found, intervals) = work(&p, side, 0.5);
        // ~f64::EPSILON / 4 of the span in halvings, and one sibling per level.
        assert!(intervals <= 2 * 60, "{intervals} intervals");
        // The only exit of f = σ³ − σ⁴ from [0, ∞) in (0, 0.5] would be at σ = 1: none.
        assert!(found.is_none_or(|x| x <= RESOLUTION * 0.5), "{found:?}");
    }

    #[test]
    fn a_crossing_is_still_located_to_the_last_bit() {
        // f = 0.3 − σ crosses 0 at 0.3: the resolution floor does not coarsen the root.
        let p = poly(&[0.3, -1.0, 0.0, 1e-3]);
        let side = Side {
            offset: 0.0,
            sign: 1.0,
            tol: 0.0,
        };
        let (found, _) = work(&p, side, 0.5);
        let root = found.expect("a crossing");
        assert!(p.eval(root).abs() <= 4.0 * f64::EPSILON, "f({root}) = {}", p.eval(root));
    }
}
