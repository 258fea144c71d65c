//! Symmetric matrices of block-arrowhead structure: the normal equations of a joint fit of
//! many experiments where some parameters are shared and the others belong to one
//! experiment each.
//!
//! With the columns split into the shared ones `s` (`p_s` of them) and the blocks `b`
//! (`p_b` columns each, one block per experiment), a Gram matrix `JᵀWJ` summed over
//! experiments whose Jacobian rows touch only `s` and their own block is
//!
//! ```text
//!     ⎡ D_1           C_1 ⎤
//! A = ⎢      ⋱        ⋮   ⎥      D_b = A_bb (p_b × p_b), C_b = A_bs (p_b × p_s),
//!     ⎢          D_N  C_N ⎥      F = A_ss (p_s × p_s)
//!     ⎣ C_1ᵀ  ⋯  C_Nᵀ  F  ⎦
//! ```
//!
//! and is stored as exactly those blocks: `O(N p_b (p_b + p_s) + p_s²)` numbers instead of
//! `n²` (n = `Σ p_b + p_s`). [`Arrowhead::damped_solve`] eliminates the blocks (a small
//! Cholesky each) and solves the reduced system `Σ = F − Σ_b C_bᵀ D_b⁻¹ C_b` (the Schur
//! complement, `p_s × p_s`) with `faer`; [`ArrowInverse`] gives any entry of `A⁻¹` and of
//! a sandwich `A⁻¹ B A⁻¹` without forming either (Golub & Van Loan, *Matrix
//! Computations*, 4th ed., 3.2.11 and 4.2; the arrowhead/bordered block-diagonal
//! system). Nothing here knows what the columns are.

mod inverse;
mod matrix;
mod solve;

pub use inverse::{ArrowInverse, LowRank, Sandwich};
pub use matrix::{ArrowLayout, Arrowhead};
pub use solve::{Singular, SolveTiming, solve_timing};
