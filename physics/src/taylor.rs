//! Taylor expansions of y' = M y over one piece: the state's series, the polynomial of one
//! component, and exponentials summed from the series (entrywise accurate, unlike Padé).

use nalgebra::{SMatrix, SVector};

/// Most Taylor terms kept; over a piece (length ≤ 0.5/rate) term k is ~0.5ᵏ/k! of the first.
pub const TERMS: usize = 32;

/// A matrix kept as its non-zero entries: the augmented mode matrices have ~16 of 100, so a
/// product with them costs a sixth of a dense one. The entries are grouped by row, in column
/// order, and each row's sum is accumulated from 0 in that order: `apply` does the arithmetic of
/// the dense product with the zero terms left out, in one register per row.
#[derive(Clone, Debug)]
pub struct Sparse<const N: usize> {
    /// (column, value) of the non-zero entries, row by row.
    entries: Box<[(usize, f64)]>,
    /// Row i's entries are `entries[ends[i - 1]..ends[i]]` (from 0 for row 0).
    ends: [usize; N],
}

impl<const N: usize> Sparse<N> {
    pub fn new(m: &SMatrix<f64, N, N>) -> Self {
        let mut entries = Vec::new();
        let mut ends = [0; N];
        for (i, end) in ends.iter_mut().enumerate() {
            entries.extend((0..N).filter(|&j| m[(i, j)] != 0.0).map(|j| (j, m[(i, j)])));
            *end = entries.len();
        }
        Sparse {
            entries: entries.into_boxed_slice(),
            ends,
        }
    }

    #[inline]
    pub fn apply(&self, x: &SVector<f64, N>) -> SVector<f64, N> {
        let mut out = SVector::<f64, N>::zeros();
        self.each_row(x, |i, sum| out[i] = sum);
        out
    }

    /// Calls `row(i, (M x)_i)` for each row i in order. (A closure rather than a loop writing
    /// `out[i]` in `apply`: the switching step measured 10% faster this way.)
    #[inline(always)]
    fn each_row(&self, x: &SVector<f64, N>, mut row: impl FnMut(usize, f64)) {
        let mut begin = 0;
        for (i, &end) in self.ends.iter().enumerate() {
            let sum = self.entries[begin..end].iter().fold(0.0, |acc, &(j, v)| acc + v * x[j]);
            row(i, sum);
            begin = end;
        }
    }
}

/// The Taylor expansion y(σ) = Σ v_k σᵏ, v_k = Mᵏ y / k!, of the whole state over one piece:
/// the polynomial of any component (a switching signal) and the state at any instant of the
/// piece come from the same coefficients.
#[derive(Clone, Copy, Debug)]
pub struct TaylorModel<const N: usize> {
    v: [SVector<f64, N>; TERMS],
    terms: usize,
}

impl<const N: usize> TaylorModel<N> {
    /// Expands until two successive terms are below 1e-17 of the running magnitude of every
    /// component at σ = span (pieces are short, so this takes a dozen or so terms).
    pub fn new(m: &Sparse<N>, y: &SVector<f64, N>, span: f64) -> Self {
        let mut model = TaylorModel {
            v: [SVector::<f64, N>::zeros(); TERMS],
            terms: 0,
        };
        model.expand(m, y, span);
        model
    }

    /// `new` in place: the terms past the last kept are left as they were (none is read).
    #[inline]
    fn expand(&mut self, m: &Sparse<N>, y: &SVector<f64, N>, span: f64) {
        let v = &mut self.v;
        v[0] = *y;
        let mut magnitude = y.abs();
        let mut quiet = 0;
        let mut terms = TERMS;
        let mut power = 1.0;
        for k in 1..TERMS {
            power *= span;
            let kf = k as f64;
            // v_k = M v_{k-1} / k, and each component's term at σ = span tested against and
            // added to its running magnitude, in a loop without early exit that the compiler
            // vectorizes (the divisions are most of an expansion's cost).
            let sums = m.apply(&v[k - 1]);
            let next = &mut v[k];
            let mut negligible = true;
            for i in 0..N {
                let c = sums[i] / kf;
                next[i] = c;
                let term = c.abs() * power;
                negligible &= term <= 1e-17 * magnitude[i];
                magnitude[i] += term;
            }
            quiet = if negligible { quiet + 1 } else { 0 };
            // Keep at least the cubic: the search reads the first four coefficients.
            if quiet == 2 && k >= 3 {
                terms = k + 1;
                break;
            }
        }
        self.terms = terms;
    }

    /// The polynomial of component `i`.
    pub fn poly(&self, i: usize) -> Poly {
        let mut coef = [0.0; TERMS];
        for (c, v) in coef.iter_mut().zip(&self.v[..self.terms]) {
            *c = v[i];
        }
        Poly {
            coef,
            deg: self.terms - 1,
        }
    }

    /// The polynomial of the linear signal c·y.
    pub fn signal(&self, c: &SVector<f64, N>) -> Poly {
        let mut coef = [0.0; TERMS];
        for (k, v) in self.v[..self.terms].iter().enumerate() {
            coef[k] = c.dot(v);
        }
        Poly {
            coef,
            deg: self.terms - 1,
        }
    }

    /// The state at σ into the piece.
    pub fn at(&self, s: f64) -> SVector<f64, N> {
        let mut acc = self.v[self.terms - 1];
        for v in self.v[..self.terms - 1].iter().rev() {
            acc = acc * s + v;
        }
        acc
    }
}

/// The Taylor model of the piece being searched, expanded when a search first needs it, in
/// storage kept over a whole step: a model is ~2.5 KB, and zeroing and moving a fresh one for
/// each search cost more than its dozen terms (callgrind: a third of a switching step).
#[derive(Clone, Debug)]
pub struct PieceModel<const N: usize> {
    model: TaylorModel<N>,
    expanded: bool,
}

impl<const N: usize> PieceModel<N> {
    pub fn new() -> Self {
        PieceModel {
            model: TaylorModel {
                v: [SVector::<f64, N>::zeros(); TERMS],
                terms: 0,
            },
            expanded: false,
        }
    }

    /// Forgets the model: the next piece needs its own.
    pub fn clear(&mut self) {
        self.expanded = false;
    }

    /// The model, if expanded since the last `clear`.
    pub fn get(&self) -> Option<&TaylorModel<N>> {
        self.expanded.then_some(&self.model)
    }

    /// The model, expanded from y over `span` (by `m`) if not yet since the last `clear`: the
    /// same as `TaylorModel::new(m, y, span)`.
    pub fn get_or_expand(&mut self, m: &Sparse<N>, y: &SVector<f64, N>, span: f64) -> &TaylorModel<N> {
        if !self.expanded {
            self.model.expand(m, y, span);
            self.expanded = true;
        }
        &self.model
    }
}

impl<const N: usize> Default for PieceModel<N> {
    fn default() -> Self {
        Self::new()
    }
}

/// e^{M s} column by column from the Taylor series, for s no longer than a piece. Unlike a
/// normwise-accurate Padé exponential, every entry comes out to round-off of itself, which
/// matters here: the augmented matrices mix units, so their exponentials hold entries of very
/// different sizes (r_m s²/2J_m next to 1).
pub fn exp_series<const N: usize>(m: &Sparse<N>, s: f64) -> SMatrix<f64, N, N> {
    let mut out = SMatrix::<f64, N, N>::zeros();
    for j in 0..N {
        let mut e = SVector::<f64, N>::zeros();
        e[j] = 1.0;
        out.set_column(j, &TaylorModel::new(m, &e, s).at(s));
    }
    out
}

/// A polynomial Σ coef[k] σᵏ of degree `deg`.
#[derive(Clone, Copy, Debug)]
pub struct Poly {
    pub coef: [f64; TERMS],
    pub deg: usize,
}

impl Poly {
    pub fn eval(&self, x: f64) -> f64 {
        self.coef[..=self.deg].iter().rev().fold(0.0, |acc, &c| acc * x + c)
    }

    /// Value and first derivative.
    pub fn eval_d(&self, x: f64) -> (f64, f64) {
        let mut p = 0.0;
        let mut dp = 0.0;
        for &c in self.coef[..=self.deg].iter().rev() {
            dp = dp * x + p;
            p = p * x + c;
        }
        (p, dp)
    }

    /// The same polynomial in σ' = σ − a (Taylor shift by repeated synthetic division).
    pub fn shifted(&self, a: f64) -> Poly {
        let mut c = self.coef;
        let n = self.deg;
        if a != 0.0 {
            for i in 0..n {
                for j in (i..n).rev() {
                    c[j] += a * c[j + 1];
                }
            }
        }
        Poly { coef: c, deg: n }
    }
}

/// e^A for an entrywise non-negative A: scaling and squaring over a Taylor series. Every term
/// is non-negative, so nothing cancels and the result is accurate to round-off.
pub(crate) fn exp_nonnegative<const N: usize>(a: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    let norm = a.row_iter().map(|r| r.sum()).fold(0.0, f64::max);
    if !norm.is_finite() || norm > 1e300 {
        // Past f64: +∞ is still an upper bound, and the searches treat it as "cannot clear".
        return SMatrix::<f64, N, N>::from_element(f64::INFINITY);
    }
    let squarings = if norm > 0.5 {
        (norm / 0.5).log2().ceil() as i32
    } else {
        0
    };
    let scaled = a * 0.5f64.powi(squarings);
    let mut term = SMatrix::<f64, N, N>::identity();
    let mut sum = term;
    for k in 1..30 {
        term = term * scaled / k as f64;
        sum += term;
    }
    for _ in 0..squarings {
        sum = sum * sum;
    }
    sum
}
