//! The solver's linear algebra: the block-sparse Cholesky factor over the joints' 3 × 3 blocks,
//! and low-rank parts (balance) solved beside it by the Woodbury identity.
//!
//! | question | file |
//! |---|---|
//! | the block-sparse Cholesky factor over the joints (children eliminated before parents) | `block_cholesky.rs` |
//! | rank-one parts kept beside the sparse matrix and solved with by the Woodbury identity | `low_rank.rs` |

pub(crate) mod block_cholesky;
pub(crate) mod low_rank;
