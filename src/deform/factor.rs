//! The Cholesky factor in the form the iterations use: compressed columns with 32-bit row
//! indices, the inverted diagonal kept apart, and the three coordinates of a right-hand side
//! interleaved, so one pass over `L` (and one over `Lᵀ`) solves for x, y and z together.
//!
//! faer computes the factor (supernodal or simplicial); once per constraint set it is
//! compacted into this layout in place (faer's value buffer becomes ours: fresh pages cost
//! more than the copy). The triangular solves are memory-bound: this layout reads 12 bytes per
//! non-zero and touches one 24-byte row of the right-hand side per entry. When the elimination
//! order has two independent halves (nested dissection), each half is solved on its own thread
//! and only the separator is solved alone.

use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use glam::DVec3;

/// Lower-triangular Cholesky factor `L` with `A = L Lᵀ`, in elimination order.
#[derive(Debug, Clone, Default)]
pub(crate) struct LowerFactor {
    /// Start of each column's strictly-lower entries (`n + 1`).
    col_ptr: Vec<u32>,
    rows: Vec<u32>,
    values: Vec<f64>,
    inv_diagonal: Vec<f64>,
    /// Columns `0..a` and `a..b` never touch each other's rows; `b..n` is the separator.
    split: Option<(usize, usize)>,
}

impl LowerFactor {
    /// Takes over faer's factor (`values` laid out as `symbolic` says), compacting it in
    /// place: diagonals move out, explicit zeros of relaxed supernodes are dropped. `split`
    /// is the independent-halves hint of the elimination order; it is verified against the
    /// factor's pattern and dropped if it does not hold. `None` when a diagonal entry is not
    /// finite and positive. Off-diagonal entries need no check: `|L_ij| ≤ √A_ii`, and the
    /// assembled diagonal is finite (the solve checks its output all the same).
    pub fn from_faer(
        symbolic: &SymbolicCholesky<u32>,
        mut values: Vec<f64>,
        split: Option<(usize, usize)>,
    ) -> Option<Self> {
        let n = symbolic.nrows();
        let mut out = Self {
            col_ptr: Vec::with_capacity(n + 1),
            rows: Vec::with_capacity(symbolic.len_val().saturating_sub(n)),
            values: Vec::new(),
            inv_diagonal: vec![0.0; n],
            split: None,
        };
        out.col_ptr.push(0);
        // Every value is written at or before the position it is read from, so the buffer is
        // compacted in place (fresh pages cost more than the copy).
        let len = match symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(s) => {
                // The diagonal moves out, the rest moves up.
                let (col_ptr, row_idx) = (s.col_ptr(), s.row_idx());
                let mut at = 0usize;
                for j in 0..n {
                    for k in col_ptr[j] as usize..col_ptr[j + 1] as usize {
                        let (r, v) = (row_idx[k], values[k]);
                        if r as usize == j {
                            out.inv_diagonal[j] = 1.0 / v;
                        } else {
                            values[at] = v;
                            out.rows.push(r);
                            at += 1;
                        }
                    }
                    out.col_ptr.push(at as u32);
                }
                at
            }
            SymbolicCholeskyRaw::Supernodal(s) => {
                let (begin, end) = (s.supernode_begin(), s.supernode_end());
                let (row_ptr, val_ptr, row_idx) =
                    (s.col_ptr_for_row_idx(), s.col_ptr_for_val(), s.row_idx());
                // Rows are written into a buffer sized for the worst case; dropping a zero is
                // one conditional increment, not a branch.
                out.rows.resize(values.len().saturating_sub(n), 0);
                let mut at = 0usize;
                for sn in 0..s.n_supernodes() {
                    let (b, e) = (begin[sn] as usize, end[sn] as usize);
                    let pattern = &row_idx[row_ptr[sn] as usize..row_ptr[sn + 1] as usize];
                    let width = e - b;
                    let height = width + pattern.len();
                    let block = val_ptr[sn] as usize;
                    // Column-major `height × width`: the dense diagonal block (lower part
                    // used), then the rows of `pattern`. Explicit zeros of relaxed supernodes
                    // are dropped.
                    for c in 0..width {
                        let column = block + c * height;
                        out.inv_diagonal[b + c] = 1.0 / values[column + c];
                        // Rows below the diagonal inside the supernode, then the pattern.
                        let first = column + c + 1;
                        let split = first + (e - (b + c + 1));
                        let rows = &mut out.rows[..];
                        for (k, r) in (first..split).zip((b + c + 1) as u32..) {
                            let v = values[k];
                            values[at] = v;
                            rows[at] = r;
                            at += (v != 0.0) as usize;
                        }
                        for (k, &r) in (split..column + height).zip(pattern) {
                            let v = values[k];
                            values[at] = v;
                            rows[at] = r;
                            at += (v != 0.0) as usize;
                        }
                        out.col_ptr.push(at as u32);
                    }
                }
                out.rows.truncate(at);
                at
            }
        };
        values.truncate(len);
        out.values = values;
        if !out.inv_diagonal.iter().all(|d| d.is_finite() && *d > 0.0) {
            return None;
        }
        out.split = split.filter(|&s| out.halves_are_independent(s));
        Some(out)
    }

    fn column(&self, j: usize) -> std::ops::Range<usize> {
        self.col_ptr[j] as usize..self.col_ptr[j + 1] as usize
    }

    fn halves_are_independent(&self, (a, b): (usize, usize)) -> bool {
        let n = self.inv_diagonal.len();
        if a == 0 || a >= b || b > n {
            return false;
        }
        let within = |j: usize, lo: usize, hi: usize| {
            self.rows[self.column(j)].iter().all(|&i| {
                let i = i as usize;
                i > j && (i < hi && i >= lo || i >= b)
            })
        };
        (0..a).all(|j| within(j, 0, a)) && (a..b).all(|j| within(j, a, b))
    }

    /// Dimension of the factor.
    pub fn dimension(&self) -> usize {
        self.inv_diagonal.len()
    }

    /// Stored non-zeros (diagonal included; explicit zeros of supernodal blocks dropped).
    pub fn nonzeros(&self) -> usize {
        self.rows.len() + self.inv_diagonal.len()
    }

    /// Whether the solves run on two threads.
    pub fn is_split(&self) -> bool {
        self.split.is_some()
    }

    /// Solves `L Lᵀ x = b` in place for three right-hand sides at once (`b` in elimination
    /// order); the two independent halves of a split factor on two threads when `parallel`.
    pub fn solve_in_place(&self, x: &mut [DVec3], parallel: bool) {
        let n = self.dimension();
        assert_eq!(x.len(), n, "right-hand side length");
        match self.split.filter(|_| parallel) {
            None => {
                self.forward(0..n, x, 0, n, &mut []);
                self.backward(0..n, x, 0, n, &[]);
            }
            Some((a, b)) => {
                let (xa, rest) = x.split_at_mut(a);
                let (xb, xs) = rest.split_at_mut(b - a);
                let mut acc_a = vec![DVec3::ZERO; n - b];
                let mut acc_b = vec![DVec3::ZERO; n - b];
                rayon::join(
                    || self.forward(0..a, xa, 0, b, &mut acc_a),
                    || self.forward(a..b, xb, a, b, &mut acc_b),
                );
                for ((s, da), db) in xs.iter_mut().zip(&acc_a).zip(&acc_b) {
                    *s += *da + *db;
                }
                self.forward(b..n, xs, b, n, &mut []);
                self.backward(b..n, xs, b, n, &[]);
                let xs = &*xs;
                rayon::join(
                    || self.backward(0..a, xa, 0, b, xs),
                    || self.backward(a..b, xb, a, b, xs),
                );
            }
        }
    }

    /// `L y = b` over `columns`, whose own rows live in `x` (offset `lo`); rows at or past
    /// `top` are updated in `acc` instead (offset `top`).
    #[inline(never)]
    fn forward(
        &self,
        columns: std::ops::Range<usize>,
        x: &mut [DVec3],
        lo: usize,
        top: usize,
        acc: &mut [DVec3],
    ) {
        for j in columns {
            let xj = x[j - lo] * self.inv_diagonal[j];
            x[j - lo] = xj;
            let range = self.column(j);
            for (&i, &l) in self.rows[range.clone()].iter().zip(&self.values[range]) {
                let i = i as usize;
                if i < top {
                    x[i - lo] -= l * xj;
                } else {
                    acc[i - top] -= l * xj;
                }
            }
        }
    }

    /// `Lᵀ x = y` over `columns` (descending); rows at or past `top` are read from `above`.
    #[inline(never)]
    fn backward(
        &self,
        columns: std::ops::Range<usize>,
        x: &mut [DVec3],
        lo: usize,
        top: usize,
        above: &[DVec3],
    ) {
        for j in columns.rev() {
            let mut s = x[j - lo];
            let range = self.column(j);
            for (&i, &l) in self.rows[range.clone()].iter().zip(&self.values[range]) {
                let i = i as usize;
                let v = if i < top { x[i - lo] } else { above[i - top] };
                s -= l * v;
            }
            x[j - lo] = s * self.inv_diagonal[j];
        }
    }
}
