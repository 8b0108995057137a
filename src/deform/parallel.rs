//! The solver's data-parallel loops, run on rayon's pool for large meshes and on the calling
//! thread for small ones.
//!
//! A parallel loop called from outside rayon's pool (a Bevy task, a game's main thread) hands
//! its pieces to the pool and sleeps until they are done: tens of microseconds per loop
//! whatever the size, several loops per iteration. On a 1–2k-vertex mesh that is more than the
//! arithmetic, so below [`SERIAL_BELOW`] free vertices ([`Threading::Auto`]) every loop of a
//! solve runs on the calling thread. Both paths visit the same pieces and do the same
//! arithmetic per vertex, so they give the same positions.

use rayon::prelude::*;

/// Where a solver's loops run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Threading {
    /// On the calling thread below [`SERIAL_BELOW`] free vertices, on rayon's pool above
    /// (default).
    #[default]
    Auto,
    /// Always on the calling thread (e.g. many small meshes solved side by side, one per task).
    Serial,
    /// Always on rayon's pool.
    Parallel,
}

/// Free vertices below which [`Threading::Auto`] runs a solve on the calling thread: the size
/// where the pool's hand-off costs about what the second core saves (measured on the 2-core
/// development machine, `docs/benchmarks.md`).
pub const SERIAL_BELOW: usize = 3800;

impl Threading {
    /// Whether loops over `rows` free vertices run on rayon's pool. On the web
    /// (`wasm32`, no threads) [`Threading::Auto`] is always serial: rayon would run the pieces
    /// on the calling thread anyway, after the cost of handing them over.
    pub fn parallel_for(self, rows: usize) -> bool {
        match self {
            Self::Auto => !cfg!(target_arch = "wasm32") && rows >= SERIAL_BELOW,
            Self::Serial => false,
            Self::Parallel => true,
        }
    }
}

/// Calls `f(piece index, piece)` on `chunk`-sized pieces of `data`.
pub(crate) fn for_chunks<T: Send>(
    parallel: bool,
    data: &mut [T],
    chunk: usize,
    f: impl Fn(usize, &mut [T]) + Sync + Send,
) {
    if parallel {
        data.par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(c, piece)| f(c, piece));
    } else {
        data.chunks_mut(chunk)
            .enumerate()
            .for_each(|(c, piece)| f(c, piece));
    }
}

/// Calls `f(piece index, piece of a, piece of b)` on matching `chunk`-sized pieces of `a` and
/// `b` and sums what it returns.
pub(crate) fn sum_chunks_pair<A: Send, B: Send>(
    parallel: bool,
    a: &mut [A],
    b: &mut [B],
    chunk: usize,
    f: impl Fn(usize, &mut [A], &mut [B]) -> f64 + Sync + Send,
) -> f64 {
    if parallel {
        a.par_chunks_mut(chunk)
            .zip(b.par_chunks_mut(chunk))
            .enumerate()
            .map(|(c, (a, b))| f(c, a, b))
            .sum()
    } else {
        a.chunks_mut(chunk)
            .zip(b.chunks_mut(chunk))
            .enumerate()
            .map(|(c, (a, b))| f(c, a, b))
            .sum()
    }
}

/// Calls `f(piece of out, piece of input)` on matching `chunk`-sized pieces.
pub(crate) fn zip_chunks<A: Send, B: Sync>(
    parallel: bool,
    out: &mut [A],
    input: &[B],
    chunk: usize,
    f: impl Fn(&mut [A], &[B]) + Sync + Send,
) {
    if parallel {
        out.par_chunks_mut(chunk)
            .zip(input.par_chunks(chunk))
            .for_each(|(o, i)| f(o, i));
    } else {
        out.chunks_mut(chunk)
            .zip(input.chunks(chunk))
            .for_each(|(o, i)| f(o, i));
    }
}

/// Sums `f(piece of a, piece of b)` over matching `chunk`-sized pieces.
pub(crate) fn sum_zip<A: Sync, B: Sync>(
    parallel: bool,
    a: &[A],
    b: &[B],
    chunk: usize,
    f: impl Fn(&[A], &[B]) -> f64 + Sync + Send,
) -> f64 {
    if parallel {
        a.par_chunks(chunk)
            .zip(b.par_chunks(chunk))
            .map(|(a, b)| f(a, b))
            .sum()
    } else {
        a.chunks(chunk)
            .zip(b.chunks(chunk))
            .map(|(a, b)| f(a, b))
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_paths_visit_the_same_pieces() {
        for parallel in [false, true] {
            let mut data: Vec<usize> = vec![0; 1000];
            for_chunks(parallel, &mut data, 64, |c, piece| {
                for (k, v) in piece.iter_mut().enumerate() {
                    *v = c * 64 + k;
                }
            });
            assert!(data.iter().enumerate().all(|(i, &v)| i == v), "{parallel}");
            let total = sum_zip(parallel, &data, &data, 100, |a, b| {
                a.iter().zip(b).map(|(x, y)| (x * y) as f64).sum()
            });
            let expected: f64 = (0..1000).map(|i| (i * i) as f64).sum();
            assert_eq!(total, expected, "{parallel}");
        }
    }

    #[test]
    fn auto_is_serial_only_below_the_threshold() {
        assert!(!Threading::Auto.parallel_for(SERIAL_BELOW - 1));
        assert!(Threading::Auto.parallel_for(SERIAL_BELOW));
        assert!(!Threading::Serial.parallel_for(1 << 20));
        assert!(Threading::Parallel.parallel_for(1));
    }
}
