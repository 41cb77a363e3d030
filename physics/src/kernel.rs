//! Fused kernels: a small matrix stored by column so that one pass over the input
//! produces all of a piece's outputs side by side, vectorized across them.

/// One column of a fused kernel (a matrix stored by column, its outputs side by side),
/// aligned so that each pair of outputs loads as one vector operand. Entry `abs_row` of a
/// kernel is a growth bound's row: it multiplies |x| where the others multiply x.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct KernelColumn<const OUT: usize>(pub [f64; OUT]);

impl<const OUT: usize> KernelColumn<OUT> {
    /// The N columns of a kernel with entry(r, j) in output r of column j.
    pub fn table<const N: usize>(entry: impl Fn(usize, usize) -> f64) -> [KernelColumn<OUT>; N] {
        std::array::from_fn(|j| KernelColumn(std::array::from_fn(|r| entry(r, j))))
    }

    /// This column times x: the first term of a kernel's sums, equal to `accumulate` into
    /// zeros but for the sign of a zero.
    #[inline(always)]
    pub fn product(&self, x: f64, abs_row: usize) -> [f64; OUT] {
        let by = Self::multipliers(x, abs_row);
        std::array::from_fn(|r| self.0[r] * by[r])
    }

    /// `acc += this column times x`. Inlined, it vectorizes across the outputs.
    #[inline(always)]
    pub fn accumulate(&self, acc: &mut [f64; OUT], x: f64, abs_row: usize) {
        let by = Self::multipliers(x, abs_row);
        for r in 0..OUT {
            acc[r] += self.0[r] * by[r];
        }
    }

    /// This column times `by`, entry by entry (`by` from [`KernelColumn::multipliers_from`]).
    #[inline(always)]
    pub fn product_by(&self, by: [f64; OUT]) -> [f64; OUT] {
        std::array::from_fn(|r| self.0[r] * by[r])
    }

    /// `acc += this column times by`, entry by entry.
    #[inline(always)]
    pub fn accumulate_by(&self, acc: &mut [f64; OUT], by: [f64; OUT]) {
        for r in 0..OUT {
            acc[r] += self.0[r] * by[r];
        }
    }

    /// What each output multiplies an entry x by: |x| in the growth bound's row `abs_row`, x in
    /// the others.
    #[inline(always)]
    fn multipliers(x: f64, abs_row: usize) -> [f64; OUT] {
        let mut by = [x; OUT];
        by[abs_row] = x.abs();
        by
    }

    /// As `multipliers`, and |x| in the bounds' rows from `abs_from` on too.
    #[inline(always)]
    pub fn multipliers_from(x: f64, abs_row: usize, abs_from: usize) -> [f64; OUT] {
        let mut by = Self::multipliers(x, abs_row);
        for b in by.iter_mut().skip(abs_from) {
            *b = x.abs();
        }
        by
    }
}
