//! The free vertices' Laplacian systems: assembly in elimination order and numeric
//! factorization (now, or on first use).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Par, Side};
use rayon::prelude::*;

use super::{NOT_FREE, SolveError};
use crate::deform::factor::LowerFactor;
use crate::deform::topology::{RowPiece, join_rows};

/// The cotangent and the uniform Laplacian restricted to the free vertices, in the order of
/// `free` (`free_index` maps a vertex to its position there, or [`NOT_FREE`]). Both share
/// one pattern; the upper triangle's pattern (all faer's symbolic analysis reads) is built
/// on its own, so the lower triangle with the values can be built while faer analyses it.
pub(super) struct FreeLaplacians<'a> {
    pub(super) offsets: &'a [u32],
    pub(super) nbrs: &'a [u32],
    pub(super) weights: &'a [f64],
    pub(super) free: &'a [u32],
    pub(super) free_index: &'a [u32],
    /// Added to the cotangent Laplacian's diagonal ([`super::SolverSettings::inertia`]).
    pub(super) inertia: f64,
}

/// Upper triangle pattern of the free Laplacians, compressed columns, sorted rows.
pub(super) struct UpperPattern {
    pub(super) col_ptr: Vec<u32>,
    pub(super) rows: Vec<u32>,
}

/// Lower triangle of both free Laplacians, compressed columns with sorted rows, diagonal
/// first.
pub(super) struct LowerLaplacians {
    pub(super) col_ptr: Vec<u32>,
    pub(super) rows: Vec<u32>,
    pub(super) cotangent: Vec<f64>,
    pub(super) uniform: Vec<f64>,
}

impl FreeLaplacians<'_> {
    /// Columns per parallel piece.
    const COLUMNS: usize = 4096;

    /// Free neighbours of free vertex `i` (a mesh vertex) on one side of column `col`, with
    /// their edge weights, sorted: below it (`upper`) or above it.
    pub(super) fn side(&self, i: u32, col: u32, upper: bool, out: &mut Vec<(u32, f64)>) {
        let range = self.offsets[i as usize] as usize..self.offsets[i as usize + 1] as usize;
        out.clear();
        out.extend(range.filter_map(|e| {
            let r = self.free_index[self.nbrs[e] as usize];
            (r != NOT_FREE && (r < col) == upper).then_some((r, self.weights[e]))
        }));
        out.sort_unstable_by_key(|&(r, _)| r);
    }

    pub(super) fn upper(&self) -> UpperPattern {
        let pieces: Vec<RowPiece> = self
            .free
            .par_chunks(Self::COLUMNS)
            .enumerate()
            .map(|(c, columns)| {
                let mut lengths = Vec::with_capacity(columns.len());
                let mut rows = Vec::new();
                let mut side = Vec::new();
                for (k, &i) in columns.iter().enumerate() {
                    let col = (c * Self::COLUMNS + k) as u32;
                    self.side(i, col, true, &mut side);
                    rows.extend(side.iter().map(|&(r, _)| r));
                    rows.push(col);
                    lengths.push(side.len() as u32 + 1);
                }
                (lengths, rows, Vec::new())
            })
            .collect();
        let (col_ptr, rows, _) = join_rows(&pieces);
        UpperPattern { col_ptr, rows }
    }

    pub(super) fn lower(&self) -> LowerLaplacians {
        let (pieces, uniform): (Vec<RowPiece>, Vec<Vec<f64>>) = self
            .free
            .par_chunks(Self::COLUMNS)
            .enumerate()
            .map(|(c, columns)| {
                let mut lengths = Vec::with_capacity(columns.len());
                let (mut rows, mut cotangent, mut uniform) = (Vec::new(), Vec::new(), Vec::new());
                let mut side = Vec::new();
                for (k, &i) in columns.iter().enumerate() {
                    let col = (c * Self::COLUMNS + k) as u32;
                    let range =
                        self.offsets[i as usize] as usize..self.offsets[i as usize + 1] as usize;
                    self.side(i, col, false, &mut side);
                    rows.push(col);
                    cotangent.push(self.weights[range.clone()].iter().sum::<f64>() + self.inertia);
                    uniform.push(range.len() as f64);
                    for &(r, w) in &side {
                        rows.push(r);
                        cotangent.push(-w);
                        uniform.push(-1.0);
                    }
                    lengths.push(side.len() as u32 + 1);
                }
                ((lengths, rows, cotangent), uniform)
            })
            .unzip();
        let (col_ptr, rows, cotangent) = join_rows(&pieces);
        LowerLaplacians {
            col_ptr,
            rows,
            cotangent,
            uniform: uniform.concat(),
        }
    }
}

/// A factor computed on first use, from the symbolic analysis and values kept for it.
#[derive(Default)]
pub(super) struct LazyFactor {
    pub(super) source: Option<LazySource>,
    pub(super) factor: std::sync::OnceLock<Result<LowerFactor, SolveError>>,
}

/// What a [`LazyFactor`] is computed from.
pub(super) struct LazySource {
    pub(super) symbolic: SymbolicCholesky<u32>,
    pub(super) col_ptr: Vec<u32>,
    pub(super) rows: Vec<u32>,
    pub(super) values: Vec<f64>,
    pub(super) split: Option<(usize, usize)>,
}

impl LazyFactor {
    /// The factor (an empty one for an empty system).
    pub(super) fn get(&self) -> Result<&LowerFactor, SolveError> {
        let factor = self.factor.get_or_init(|| match &self.source {
            None => Ok(LowerFactor::default()),
            Some(s) => {
                let n = s.col_ptr.len() - 1;
                let pattern = SymbolicSparseColMatRef::new_checked(n, n, &s.col_ptr, None, &s.rows);
                numeric(&s.symbolic, pattern, &s.values, s.split)
            }
        });
        factor.as_ref().map_err(Clone::clone)
    }
}

pub(super) fn numeric(
    symbolic: &SymbolicCholesky<u32>,
    pattern: SymbolicSparseColMatRef<'_, u32>,
    values: &[f64],
    split: Option<(usize, usize)>,
) -> Result<LowerFactor, SolveError> {
    let mut factor = vec![0.0f64; symbolic.len_val()];
    let mut mem = MemBuffer::try_new(
        symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
    )
    .map_err(|_| SolveError::Factorization("out of memory".into()))?;
    symbolic
        .factorize_numeric_llt(
            &mut factor,
            SparseColMatRef::new(pattern, values),
            Side::Lower,
            Default::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .map_err(|_| SolveError::NotPositiveDefinite)?;
    LowerFactor::from_faer(symbolic, factor, split).ok_or(SolveError::NotPositiveDefinite)
}
