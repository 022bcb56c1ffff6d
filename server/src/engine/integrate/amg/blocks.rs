//! The hierarchy's matrices as a cycle applies them: dense blocks of fixed shape
//! between nodes.
//!
//! Every node of a level holds the same number of unknowns: three on the finest
//! level (a vertex), six on coarser ones (an aggregate's rigid-body modes; an
//! aggregate too small to carry six has the missing ones padded, see
//! [`tentative`](super::prolong::tentative)). So the finest prolongator is made of
//! 3×6 blocks, its restriction of 6×3 blocks and every coarser matrix of 6×6
//! blocks, with one column index per block. Fixed shapes let the compiler unroll
//! each block product, as it does for the fine stiffness's 3×3 blocks; with scalar
//! sparse rows (an index and a loop step per entry) a V-cycle cost twice as much.

use nalgebra::{SMatrix, SVector};

use super::sparse::Csr;

/// A block-sparse matrix of `M × W` blocks: row node `i` holds unknowns
/// `M i..M (i + 1)`, column node `j` the unknowns `W j..W (j + 1)`.
#[derive(Clone, Debug, Default)]
pub struct Blocks<const M: usize, const W: usize> {
    /// Row node `i`'s blocks are `start[i]..start[i + 1]`.
    start: Vec<u32>,
    /// Column node of each block.
    col: Vec<u32>,
    value: Values<M, W>,
}

/// The blocks' values, in the precision they are held in.
#[derive(Clone, Debug)]
enum Values<const M: usize, const W: usize> {
    /// As built.
    F64(Vec<SMatrix<f64, M, W>>),
    /// Rounded by [`Blocks::round_to_f32`].
    F32(Vec<SMatrix<f32, M, W>>),
}

impl<const M: usize, const W: usize> Default for Values<M, W> {
    fn default() -> Self {
        Values::F64(Vec::new())
    }
}

impl<const M: usize, const W: usize> Blocks<M, W> {
    /// `a` in blocks, every block that holds a stored entry kept whole.
    pub fn from_csr(a: &Csr) -> Self {
        assert!(
            a.rows.is_multiple_of(M) && a.cols.is_multiple_of(W),
            "whole nodes"
        );
        let (rows, cols) = (a.rows / M, a.cols / W);
        let mut slot = vec![u32::MAX; cols];
        let mut start = vec![0];
        let mut col = Vec::new();
        let mut value: Vec<SMatrix<f64, M, W>> = Vec::new();
        let mut row_blocks: Vec<u32> = Vec::new();
        for i in 0..rows {
            row_blocks.clear();
            for r in M * i..M * (i + 1) {
                for &c in a.row(r).0 {
                    let j = c / W as u32;
                    if slot[j as usize] == u32::MAX {
                        slot[j as usize] = 0;
                        row_blocks.push(j);
                    }
                }
            }
            row_blocks.sort_unstable();
            for &j in &row_blocks {
                slot[j as usize] = value.len() as u32;
                col.push(j);
                value.push(SMatrix::zeros());
            }
            for r in M * i..M * (i + 1) {
                let (cs, vs) = a.row(r);
                for (&c, &v) in cs.iter().zip(vs) {
                    let c = c as usize;
                    value[slot[c / W] as usize][(r - M * i, c % W)] = v;
                }
            }
            for &j in &row_blocks {
                slot[j as usize] = u32::MAX;
            }
            start.push(col.len() as u32);
        }
        Blocks {
            start,
            col,
            value: Values::F64(value),
        }
    }

    /// Stored values (with the zeros inside blocks).
    pub fn entries(&self) -> usize {
        self.col.len() * M * W
    }

    /// Replaces the f64 blocks by their rounding to f32: half the bytes a product
    /// streams, each entry off by at most half an ulp of f32 (6e-8 of itself).
    /// Blocks already in f32 stay as they are.
    pub fn round_to_f32(&mut self) {
        if let Values::F64(value) = &self.value {
            self.value = Values::F32(value.iter().map(|b| b.cast::<f32>()).collect());
        }
    }

    /// Whether the blocks are held in f32.
    pub fn is_f32(&self) -> bool {
        matches!(self.value, Values::F32(_))
    }

    /// `out = A x`.
    #[inline]
    pub fn mul(&self, x: &[f64], out: &mut [f64]) {
        out.iter_mut().for_each(|o| *o = 0.0);
        self.mul_add(x, out);
    }

    /// `out += A x` (sums in f64, whatever the blocks are held in).
    #[inline]
    pub fn mul_add(&self, x: &[f64], out: &mut [f64]) {
        match &self.value {
            Values::F64(value) => self.mul_add_by(value, x, out, |b| *b),
            Values::F32(value) => self.mul_add_by(value, x, out, |b| b.cast::<f64>()),
        }
    }

    #[inline]
    fn mul_add_by<B>(
        &self,
        value: &[B],
        x: &[f64],
        out: &mut [f64],
        widen: impl Fn(&B) -> SMatrix<f64, M, W>,
    ) {
        for i in 0..self.start.len() - 1 {
            let mut acc = SVector::<f64, M>::zeros();
            for b in self.start[i] as usize..self.start[i + 1] as usize {
                let j = self.col[b] as usize;
                let xj = SVector::<f64, W>::from_column_slice(&x[W * j..W * (j + 1)]);
                acc += widen(&value[b]) * xj;
            }
            for (o, a) in out[M * i..M * (i + 1)].iter_mut().zip(acc.iter()) {
                *o += a;
            }
        }
    }

    /// Bytes held.
    pub fn heap_bytes(&self) -> usize {
        (self.start.capacity() + self.col.capacity()) * 4
            + match &self.value {
                Values::F64(v) => v.capacity() * std::mem::size_of::<SMatrix<f64, M, W>>(),
                Values::F32(v) => v.capacity() * std::mem::size_of::<SMatrix<f32, M, W>>(),
            }
    }
}
