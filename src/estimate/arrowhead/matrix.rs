//! The arrowhead matrix and its layout: storage by blocks, entries, products.

use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};
use std::sync::Arc;

/// Which block each of the n columns of an arrowhead matrix belongs to (`None`: shared),
/// and the inverse map. Columns of a block, and the shared ones, keep their order.
#[derive(Clone, Debug, PartialEq)]
pub struct ArrowLayout {
    pub(super) owner: Vec<Option<usize>>,
    pub(super) pos: Vec<usize>,
    pub(super) shared: Vec<usize>,
    pub(super) blocks: Vec<Vec<usize>>,
}

impl ArrowLayout {
    /// The layout of `owner.len()` columns: column g belongs to block `owner[g]`, or is
    /// shared when `None`; `n_blocks` blocks (a block may have no column).
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (option `layout`) when a block index is `≥ n_blocks`.
    pub fn try_new(owner: Vec<Option<usize>>, n_blocks: usize) -> Result<Self> {
        let mut shared = Vec::new();
        let mut blocks = vec![Vec::new(); n_blocks];
        let mut pos = Vec::with_capacity(owner.len());
        for (g, o) in owner.iter().enumerate() {
            match *o {
                None => {
                    pos.push(shared.len());
                    shared.push(g);
                }
                Some(b) if b < n_blocks => {
                    pos.push(blocks[b].len());
                    blocks[b].push(g);
                }
                Some(b) => {
                    return Err(Error::InvalidOption {
                        option: "layout".into(),
                        reason: format!("column {g} in block {b} of {n_blocks}"),
                    });
                }
            }
        }
        Ok(Self { owner, pos, shared, blocks })
    }
    /// Number of columns n.
    pub fn n(&self) -> usize {
        self.owner.len()
    }
    /// Number of blocks.
    pub fn n_blocks(&self) -> usize {
        self.blocks.len()
    }
    /// The shared columns, in order (length p_s).
    pub fn shared(&self) -> &[usize] {
        &self.shared
    }
    /// The columns of block b, in order (length p_b).
    ///
    /// # Panics
    /// If `b ≥ n_blocks`.
    pub fn block(&self, b: usize) -> &[usize] {
        &self.blocks[b]
    }
    /// The block of column g (`None`: shared).
    ///
    /// # Panics
    /// If `g ≥ n`.
    pub fn owner(&self, g: usize) -> Option<usize> {
        self.owner[g]
    }
    /// Where entry (r, c) is stored.
    fn slot(&self, r: usize, c: usize) -> Slot {
        match (self.owner[r], self.owner[c]) {
            (None, None) => Slot::Shared(self.pos[r], self.pos[c]),
            (Some(a), Some(b)) if a == b => Slot::Own(a, self.pos[r], self.pos[c]),
            (Some(a), None) => Slot::Coupling(a, self.pos[r], self.pos[c]),
            (None, Some(b)) => Slot::Coupling(b, self.pos[c], self.pos[r]),
            _ => Slot::Zero,
        }
    }
}

/// Where an entry of an arrowhead matrix lives.
#[derive(Clone, Copy, Debug)]
enum Slot {
    Shared(usize, usize),
    Own(usize, usize, usize),
    /// Block, row in the block, shared column.
    Coupling(usize, usize, usize),
    Zero,
}

/// A symmetric n × n matrix of block-arrowhead structure (the `arrowhead` module's documentation), stored
/// by its blocks.
#[derive(Clone, Debug, PartialEq)]
pub struct Arrowhead {
    pub(super) layout: Arc<ArrowLayout>,
    /// F, p_s × p_s.
    pub(super) shared: DMatrix<f64>,
    /// D_b, p_b × p_b each.
    pub(super) own: Vec<DMatrix<f64>>,
    /// C_b, p_b × p_s each.
    pub(super) coupling: Vec<DMatrix<f64>>,
}

impl Arrowhead {
    /// The zero matrix of `layout`.
    pub fn zeros(layout: Arc<ArrowLayout>) -> Self {
        let ps = layout.shared.len();
        let own = layout.blocks.iter().map(|b| DMatrix::zeros(b.len(), b.len())).collect();
        let coupling = layout.blocks.iter().map(|b| DMatrix::zeros(b.len(), ps)).collect();
        Self { shared: DMatrix::zeros(ps, ps), own, coupling, layout }
    }

    /// The arrowhead part of a dense symmetric matrix `a` (n × n): entries outside the
    /// structure are dropped.
    ///
    /// # Panics
    /// If `a` is not n × n.
    pub fn from_dense(layout: Arc<ArrowLayout>, a: &DMatrix<f64>) -> Self {
        let mut m = Self::zeros(layout);
        let n = m.layout.n();
        assert_eq!(a.shape(), (n, n), "arrowhead of a {:?} matrix, layout of {n}", a.shape());
        for r in 0..n {
            for c in 0..n {
                match m.layout.slot(r, c) {
                    Slot::Shared(i, j) => m.shared[(i, j)] = a[(r, c)],
                    Slot::Own(b, i, j) => m.own[b][(i, j)] = a[(r, c)],
                    Slot::Coupling(b, i, j) if m.layout.owner[r].is_some() => {
                        m.coupling[b][(i, j)] = a[(r, c)]
                    }
                    _ => {}
                }
            }
        }
        m
    }

    /// The layout.
    pub fn layout(&self) -> &Arc<ArrowLayout> {
        &self.layout
    }
    /// Number of rows and columns n.
    pub fn n(&self) -> usize {
        self.layout.n()
    }

    /// Entry (r, c); 0 outside the structure.
    ///
    /// # Panics
    /// If r or c is ≥ n.
    pub fn get(&self, r: usize, c: usize) -> f64 {
        match self.layout.slot(r, c) {
            Slot::Shared(i, j) => self.shared[(i, j)],
            Slot::Own(b, i, j) => self.own[b][(i, j)],
            Slot::Coupling(b, i, j) => self.coupling[b][(i, j)],
            Slot::Zero => 0.0,
        }
    }

    /// A reference to entry (r, c), `None` outside the structure.
    pub(crate) fn get_ref(&self, r: usize, c: usize) -> Option<&f64> {
        match self.layout.slot(r, c) {
            Slot::Shared(i, j) => Some(&self.shared[(i, j)]),
            Slot::Own(b, i, j) => Some(&self.own[b][(i, j)]),
            Slot::Coupling(b, i, j) => Some(&self.coupling[b][(i, j)]),
            Slot::Zero => None,
        }
    }

    /// Adds v to entries (r, c) and (c, r) (once on the diagonal).
    ///
    /// # Panics
    /// If (r, c) lies outside the structure (two different blocks), or r or c is ≥ n.
    pub fn add_symmetric(&mut self, r: usize, c: usize, v: f64) {
        match self.layout.slot(r, c) {
            Slot::Shared(i, j) => {
                self.shared[(i, j)] += v;
                if i != j {
                    self.shared[(j, i)] += v;
                }
            }
            Slot::Own(b, i, j) => {
                self.own[b][(i, j)] += v;
                if i != j {
                    self.own[b][(j, i)] += v;
                }
            }
            Slot::Coupling(b, i, j) => self.coupling[b][(i, j)] += v,
            Slot::Zero => panic!("entry ({r}, {c}) couples two blocks"),
        }
    }

    /// `self += f · other` (the same layout).
    ///
    /// # Panics
    /// If the layouts differ in shape.
    pub fn add_scaled(&mut self, other: &Self, f: f64) {
        self.shared += &other.shared * f;
        for (a, b) in self.own.iter_mut().zip(&other.own) {
            *a += b * f;
        }
        for (a, b) in self.coupling.iter_mut().zip(&other.coupling) {
            *a += b * f;
        }
    }

    /// The diagonal (length n).
    pub fn diagonal(&self) -> DVector<f64> {
        DVector::from_fn(self.n(), |g, _| self.get(g, g))
    }

    /// `A x` (x of length n).
    ///
    /// # Panics
    /// If x is not of length n.
    pub fn mul(&self, x: &DVector<f64>) -> DVector<f64> {
        let l = &self.layout;
        assert_eq!(x.len(), l.n(), "arrowhead of {} times a vector of {}", l.n(), x.len());
        let xs = DVector::from_iterator(l.shared.len(), l.shared.iter().map(|&g| x[g]));
        let mut ys = &self.shared * &xs;
        let mut y = DVector::zeros(l.n());
        for (b, cols) in l.blocks.iter().enumerate() {
            if cols.is_empty() {
                continue;
            }
            let xb = DVector::from_iterator(cols.len(), cols.iter().map(|&g| x[g]));
            let yb = &self.own[b] * &xb + &self.coupling[b] * &xs;
            ys += self.coupling[b].tr_mul(&xb);
            for (&g, v) in cols.iter().zip(yb.iter()) {
                y[g] = *v;
            }
        }
        for (&g, v) in l.shared.iter().zip(ys.iter()) {
            y[g] = *v;
        }
        y
    }

    /// The dense n × n matrix (for tests and small problems).
    pub fn to_dense(&self) -> DMatrix<f64> {
        let n = self.n();
        DMatrix::from_fn(n, n, |r, c| self.get(r, c))
    }

    /// The matrix with the rows and columns where `mask` is true replaced by those of the
    /// identity (a system solved with those components held at zero).
    ///
    /// # Panics
    /// If `mask` is shorter than n.
    pub fn with_identity_at(&self, mask: &[bool]) -> Self {
        let l = &self.layout;
        let mut a = self.clone();
        for g in (0..l.n()).filter(|&g| mask[g]) {
            let i = l.pos[g];
            match l.owner[g] {
                None => {
                    a.shared.row_mut(i).fill(0.0);
                    a.shared.column_mut(i).fill(0.0);
                    a.shared[(i, i)] = 1.0;
                    a.coupling.iter_mut().for_each(|c| c.column_mut(i).fill(0.0));
                }
                Some(b) => {
                    a.own[b].row_mut(i).fill(0.0);
                    a.own[b].column_mut(i).fill(0.0);
                    a.own[b][(i, i)] = 1.0;
                    a.coupling[b].row_mut(i).fill(0.0);
                }
            }
        }
        a
    }

    /// Whether every stored entry is finite.
    pub fn is_finite(&self) -> bool {
        let fin = |m: &DMatrix<f64>| m.iter().all(|v| v.is_finite());
        fin(&self.shared) && self.own.iter().all(fin) && self.coupling.iter().all(fin)
    }
}
