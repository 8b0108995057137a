//! A Cholesky factorization that skips the zero 3 × 3 blocks of the pose solver's systems.
//!
//! The Gauss–Newton system couples two bone parameters only when their subtrees share an
//! ARAP edge, a vertex or a constraint: every joint is coupled with its ancestors, but the
//! fingers of one hand are barely coupled with the other hand, the legs or each other. With
//! the parameters ordered children before parents (the solver's order), eliminating a joint
//! fills in only among its ancestors and the few branches it touches, so a right-looking
//! factorization over 3 × 3 blocks that skips the blocks that stay zero does a fraction of the
//! dense work (52-joint humanoid: about a fifth of the block updates). The matrix stays in
//! the solver's dense row-major layout; the block structure is the blocks the system wrote
//! ([`BlockPattern::from_blocks`]), or is read off the values when effector terms added
//! blocks of their own ([`nonzero_lower_blocks`], kept while they repeat).

/// A 3 × 3 block, as rows.
type Block = [[f64; 3]; 3];

/// Where the non-zero blocks of a system's lower Cholesky factor are: the blocks non-zero in
/// the matrix and the fill its elimination adds. Made once per Gauss–Newton system (and kept
/// while the systems' blocks repeat) and shared by every damped factorization of it.
pub(crate) struct BlockPattern {
    n: usize,
    /// Per block row, its non-zero block columns `≤` it, ascending, and their slots.
    rows: Compressed,
    /// Per block column, its non-zero block rows `>` it, ascending, and their slots.
    below: Compressed,
    /// Slot of block `(i, j)` (`i ≥ j`), `usize::MAX` where it stays zero.
    slot: Vec<usize>,
    /// Each slot's block `(i, j)`.
    blocks: Vec<(usize, usize)>,
}

impl BlockPattern {
    /// The pattern of the `n × n` row-major symmetric `a` (its lower block triangle is read;
    /// the solver reads it through `HessianScratch::pattern_of`, which keeps it).
    #[cfg(test)]
    pub(crate) fn of(a: &[f64], n: usize) -> Self {
        let mut nonzero = Vec::new();
        nonzero_lower_blocks(a, n, &mut nonzero);
        Self::from_blocks(n / 3, nonzero)
    }

    /// The pattern of a matrix of `nb × nb` blocks whose non-zero lower blocks `(i, j)`,
    /// `i ≥ j`, are flagged in `nonzero[i * nb + j]` (diagonal blocks are always taken).
    pub(crate) fn from_blocks(nb: usize, mut nonzero: Vec<bool>) -> Self {
        debug_assert_eq!(nonzero.len(), nb * nb);
        let n = 3 * nb;
        for i in 0..nb {
            nonzero[i * nb + i] = true;
        }
        // Symbolic elimination: the rows below k that are non-zero in column k fill in among
        // themselves.
        let mut below_k = Vec::with_capacity(nb);
        for k in 0..nb {
            below_k.clear();
            below_k.extend((k + 1..nb).filter(|&i| nonzero[i * nb + k]));
            for (x, &i) in below_k.iter().enumerate() {
                for &j in &below_k[..x] {
                    nonzero[i * nb + j] = true;
                }
            }
        }
        let mut slot = vec![usize::MAX; nb * nb];
        let mut blocks = Vec::new();
        let mut rows = Compressed::default();
        for i in 0..nb {
            for j in 0..=i {
                if nonzero[i * nb + j] {
                    let s = blocks.len();
                    slot[i * nb + j] = s;
                    blocks.push((i, j));
                    rows.entries.push((j, s));
                }
            }
            rows.start.push(rows.entries.len());
        }
        let mut below = Compressed::default();
        for j in 0..nb {
            below.entries.extend((j + 1..nb).filter_map(|i| {
                let s = slot[i * nb + j];
                (s != usize::MAX).then_some((i, s))
            }));
            below.start.push(below.entries.len());
        }
        Self {
            n,
            rows,
            below,
            slot,
            blocks,
        }
    }
}

/// Lists of `(block index, slot)` per block row or column, one after the other.
struct Compressed {
    /// Where each list starts in `entries` (one more than lists).
    start: Vec<usize>,
    entries: Vec<(usize, usize)>,
}

impl Default for Compressed {
    fn default() -> Self {
        Self {
            start: vec![0],
            entries: Vec::new(),
        }
    }
}

impl Compressed {
    fn len(&self) -> usize {
        self.start.len() - 1
    }

    fn list(&self, i: usize) -> &[(usize, usize)] {
        &self.entries[self.start[i]..self.start[i + 1]]
    }
}

thread_local! {
    /// The storage of this thread's last factor, reused by the next.
    static FACTOR_STORAGE: std::cell::Cell<Vec<Block>> = const { std::cell::Cell::new(Vec::new()) };
}

impl Drop for BlockCholesky<'_> {
    fn drop(&mut self) {
        let l = std::mem::take(&mut self.l);
        FACTOR_STORAGE.with(|s| s.set(l));
    }
}

/// The lower Cholesky factor of a symmetric positive definite matrix, on a [`BlockPattern`].
pub(crate) struct BlockCholesky<'p> {
    pattern: &'p BlockPattern,
    /// The factor's blocks, by slot.
    l: Vec<Block>,
}

impl<'p> BlockCholesky<'p> {
    /// Factors `a + diag(shift)` (`a` as its pattern was read from). `None` when it is
    /// not positive definite.
    pub(crate) fn factor(a: &[f64], shift: &[f64], pattern: &'p BlockPattern) -> Option<Self> {
        let n = pattern.n;
        let nb = n / 3;
        // The last factor's storage on this thread (a factorisation per damped try of every
        // iteration: no allocation each time).
        let mut l: Vec<Block> = FACTOR_STORAGE.with(|s| s.take());
        l.clear();
        l.extend(pattern.blocks.iter().map(|&(i, j)| load(a, n, i, j)));
        for k in 0..nb {
            let d = &mut l[pattern.slot[k * nb + k]];
            for r in 0..3 {
                d[r][r] += shift[3 * k + r];
            }
        }
        for k in 0..nb {
            let Some(d) = factor_diagonal(&mut l[pattern.slot[k * nb + k]]) else {
                FACTOR_STORAGE.with(|s| s.set(l));
                return None;
            };
            let below = pattern.below.list(k);
            for &(_, s) in below {
                solve_against_diagonal(&mut l[s], &d);
            }
            // Schur update of the trailing lower blocks: A_ij −= L_ik L_jkᵀ.
            for (x, &(i, si)) in below.iter().enumerate() {
                let lik = l[si];
                for &(j, sj) in &below[..=x] {
                    let ljk = l[sj];
                    subtract_product(&mut l[pattern.slot[i * nb + j]], &lik, &ljk);
                }
            }
        }
        Some(Self { pattern, l })
    }

    /// Solves `L Lᵀ x = b` in place.
    pub(crate) fn solve_in_place(&self, b: &mut [f64]) {
        // L y = b, block rows in order.
        let rows = &self.pattern.rows;
        for i in 0..rows.len() {
            for &(j, s) in rows.list(i) {
                let block = &self.l[s];
                for r in 0..3 {
                    let upto = if j == i { r } else { 3 };
                    let mut sum = 0.0;
                    for c in 0..upto {
                        sum += block[r][c] * b[3 * j + c];
                    }
                    b[3 * i + r] -= sum;
                    if j == i {
                        b[3 * i + r] /= block[r][r];
                    }
                }
            }
        }
        // Lᵀ x = y, block rows in reverse: column i of Lᵀ is row i of L.
        for i in (0..rows.len()).rev() {
            let cols = rows.list(i);
            for r in (0..3).rev() {
                let diagonal = self.l[cols.last().expect("diagonal").1][r][r];
                b[3 * i + r] /= diagonal;
                let xi = b[3 * i + r];
                for &(j, s) in cols {
                    let upto = if j == i { r } else { 3 };
                    for c in 0..upto {
                        b[3 * j + c] -= self.l[s][r][c] * xi;
                    }
                }
            }
        }
    }
}

/// Flags the non-zero lower blocks `(i, j)`, `i ≥ j`, of the row-major `n × n` matrix `a` in
/// `out[i * nb + j]` (`nb = n / 3`; `out` is resized, its allocation reused).
pub(crate) fn nonzero_lower_blocks(a: &[f64], n: usize, out: &mut Vec<bool>) {
    debug_assert_eq!(a.len(), n * n);
    debug_assert_eq!(n % 3, 0);
    let nb = n / 3;
    out.clear();
    out.resize(nb * nb, false);
    for i in 0..nb {
        for j in 0..=i {
            out[i * nb + j] = block_is_nonzero(a, n, i, j);
        }
    }
}

/// Whether block `(i, j)` of the row-major `n × n` matrix has a non-zero entry.
fn block_is_nonzero(a: &[f64], n: usize, i: usize, j: usize) -> bool {
    (0..3).any(|r| a[(3 * i + r) * n + 3 * j..][..3].iter().any(|&v| v != 0.0))
}

/// Block `(i, j)` of the row-major `n × n` matrix.
fn load(a: &[f64], n: usize, i: usize, j: usize) -> Block {
    std::array::from_fn(|r| {
        let row = &a[(3 * i + r) * n + 3 * j..][..3];
        [row[0], row[1], row[2]]
    })
}

/// Factors a diagonal block in place (it becomes lower triangular `L_kk`); returns it, or
/// `None` when it is not positive definite.
fn factor_diagonal(d: &mut Block) -> Option<Block> {
    for j in 0..3 {
        let s = d[j][j] - (0..j).map(|m| d[j][m] * d[j][m]).sum::<f64>();
        if s.is_nan() || s <= 0.0 {
            return None;
        }
        d[j][j] = s.sqrt();
        for i in j + 1..3 {
            d[i][j] = (d[i][j] - (0..j).map(|m| d[i][m] * d[j][m]).sum::<f64>()) / d[j][j];
        }
        d[j][j + 1..].fill(0.0);
    }
    Some(*d)
}

/// `L_ik = A_ik L_kk⁻ᵀ` (each row of `A_ik` solved against the lower triangular `L_kk`).
fn solve_against_diagonal(a: &mut Block, d: &Block) {
    for row in a.iter_mut() {
        for c in 0..3 {
            let s = row[c] - (0..c).map(|m| row[m] * d[c][m]).sum::<f64>();
            row[c] = s / d[c][c];
        }
    }
}

/// `A −= L_ik L_jkᵀ`.
fn subtract_product(a: &mut Block, lik: &Block, ljk: &Block) {
    for r in 0..3 {
        for c in 0..3 {
            a[r][c] -= lik[r][0] * ljk[c][0] + lik[r][1] * ljk[c][1] + lik[r][2] * ljk[c][2];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block-sparse SPD matrix (an arrow: every block couples with the last one, and a few
    /// neighbours), its factorization solves the system as the dense product checks.
    #[test]
    fn solves_a_block_sparse_system() {
        let blocks = 7;
        let n = 3 * blocks;
        let mut a = vec![0.0; n * n];
        let mut set = |i: usize, j: usize, v: f64| {
            a[i * n + j] += v;
            if i != j {
                a[j * n + i] += v;
            }
        };
        for i in 0..n {
            set(i, i, 10.0 + i as f64);
        }
        for bi in 0..blocks {
            let last = blocks - 1;
            for r in 0..3 {
                for c in 0..3 {
                    let v = ((bi * 7 + r * 3 + c) % 5) as f64 * 0.3 - 0.6;
                    if bi != last {
                        set(3 * last + r, 3 * bi + c, v);
                    }
                    if bi + 2 < last {
                        set(3 * (bi + 2) + r, 3 * bi + c, 0.5 * v);
                    }
                }
            }
        }
        let x_true: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut b: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| a[i * n + j] * x_true[j]).sum())
            .collect();
        let pattern = BlockPattern::of(&a, n);
        let factor = BlockCholesky::factor(&a, &vec![0.0; n], &pattern).expect("positive definite");
        factor.solve_in_place(&mut b);
        for (x, t) in b.iter().zip(&x_true) {
            assert!((x - t).abs() < 1e-12, "{x} vs {t}");
        }
        // The fill stays where the structure says: block (2, 1) of the factor stays zero,
        // block (6, 2) fills in (both are below block 0).
        assert_eq!(pattern.slot[2 * blocks + 1], usize::MAX);
        assert_ne!(pattern.slot[6 * blocks + 2], usize::MAX);
    }

    #[test]
    fn an_indefinite_matrix_does_not_factor() {
        let mut a = vec![0.0; 9];
        a[0] = 1.0;
        a[4] = -1.0;
        a[8] = 1.0;
        let pattern = BlockPattern::of(&a, 3);
        assert!(BlockCholesky::factor(&a, &[0.0; 3], &pattern).is_none());
    }
}
