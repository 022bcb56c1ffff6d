//! Scalar compressed-sparse-row matrices for building the multigrid hierarchy: the
//! rest system matrix, prolongators, restrictions and coarse operators, and the
//! products that form them. Products are Gustavson's row-by-row algorithm with a
//! dense accumulator (setup only: they allocate). A built level keeps its matrices
//! as fixed-shape blocks ([`Blocks`](super::blocks::Blocks)) for the cycle.

use crate::engine::elastic::BlockMatrix;

/// A real sparse matrix, rows in order, columns ascending within each row.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Csr {
    pub rows: usize,
    pub cols: usize,
    /// `start[r]..start[r + 1]` indexes row `r`'s entries.
    pub start: Vec<usize>,
    pub col: Vec<u32>,
    pub val: Vec<f64>,
}

impl Csr {
    /// `s_M M + s_K K` as a full scalar matrix (both triangles), `M` the lumped masses
    /// (`mass[i]` on each of vertex `i`'s three unknowns). Vertices with `excluded[i]`
    /// (supports) keep only an identity diagonal block: they are not unknowns of the
    /// solve, and the hierarchy leaves them out.
    pub fn from_blocks(
        k: &BlockMatrix,
        mass: &[f64],
        mass_scale: f64,
        stiffness_scale: f64,
        excluded: &[bool],
    ) -> Csr {
        let n = k.rows();
        let mut start = Vec::with_capacity(3 * n + 1);
        let mut col = Vec::new();
        let mut val = Vec::new();
        start.push(0);
        let mut row: Vec<(u32, nalgebra::Matrix3<f64>)> = Vec::new();
        for i in 0..n {
            row.clear();
            if excluded[i] {
                row.push((i as u32, nalgebra::Matrix3::identity()));
            } else {
                k.for_each_in_row(i, |j, b| {
                    if !excluded[j] {
                        let mut b = stiffness_scale * b;
                        if j == i {
                            b += nalgebra::Matrix3::identity() * (mass_scale * mass[i]);
                        }
                        row.push((j as u32, b));
                    }
                });
            }
            row.sort_unstable_by_key(|(j, _)| *j);
            for d in 0..3 {
                for (j, b) in &row {
                    for e in 0..3 {
                        col.push(3 * j + e as u32);
                        val.push(b[(d, e)]);
                    }
                }
                start.push(col.len());
            }
        }
        Csr {
            rows: 3 * n,
            cols: 3 * n,
            start,
            col,
            val,
        }
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.val.len()
    }

    /// Row `r` as (columns, values).
    #[inline]
    pub fn row(&self, r: usize) -> (&[u32], &[f64]) {
        let (s, e) = (self.start[r], self.start[r + 1]);
        (&self.col[s..e], &self.val[s..e])
    }

    /// `out = A x`.
    #[inline]
    pub fn mul(&self, x: &[f64], out: &mut [f64]) {
        for (r, o) in out.iter_mut().enumerate().take(self.rows) {
            let (c, v) = self.row(r);
            *o = c.iter().zip(v).map(|(&c, &v)| v * x[c as usize]).sum();
        }
    }

    /// `Aᵀ`.
    pub fn transpose(&self) -> Csr {
        let mut count = vec![0usize; self.cols + 1];
        for &c in &self.col {
            count[c as usize + 1] += 1;
        }
        for c in 0..self.cols {
            count[c + 1] += count[c];
        }
        let start = count.clone();
        let mut next = count;
        let mut col = vec![0u32; self.nnz()];
        let mut val = vec![0.0; self.nnz()];
        for r in 0..self.rows {
            let (cs, vs) = self.row(r);
            for (&c, &v) in cs.iter().zip(vs) {
                let k = next[c as usize];
                col[k] = r as u32;
                val[k] = v;
                next[c as usize] += 1;
            }
        }
        Csr {
            rows: self.cols,
            cols: self.rows,
            start,
            col,
            val,
        }
    }

    /// The product `A B` (Gustavson), exact zeros dropped.
    pub fn times(&self, b: &Csr) -> Csr {
        assert_eq!(self.cols, b.rows, "inner dimensions agree");
        let mut acc = vec![0.0; b.cols];
        let mut seen = vec![usize::MAX; b.cols];
        let mut pattern: Vec<u32> = Vec::new();
        let mut start = Vec::with_capacity(self.rows + 1);
        start.push(0);
        let (mut col, mut val) = (Vec::new(), Vec::new());
        for r in 0..self.rows {
            pattern.clear();
            let (ac, av) = self.row(r);
            for (&k, &a) in ac.iter().zip(av) {
                let (bc, bv) = b.row(k as usize);
                for (&c, &v) in bc.iter().zip(bv) {
                    let c = c as usize;
                    if seen[c] != r {
                        seen[c] = r;
                        acc[c] = 0.0;
                        pattern.push(c as u32);
                    }
                    acc[c] += a * v;
                }
            }
            pattern.sort_unstable();
            for &c in &pattern {
                let v = acc[c as usize];
                if v != 0.0 {
                    col.push(c);
                    val.push(v);
                }
            }
            start.push(col.len());
        }
        Csr {
            rows: self.rows,
            cols: b.cols,
            start,
            col,
            val,
        }
    }

    /// `A + s B`, same shape, exact zeros dropped.
    pub fn add_scaled(&self, b: &Csr, s: f64) -> Csr {
        let mut start = vec![0];
        let (mut col, mut val) = (Vec::new(), Vec::new());
        for r in 0..self.rows {
            let (ac, av) = self.row(r);
            let (bc, bv) = b.row(r);
            let (mut i, mut j) = (0, 0);
            while i < ac.len() || j < bc.len() {
                let (c, v) = if j == bc.len() || (i < ac.len() && ac[i] < bc[j]) {
                    i += 1;
                    (ac[i - 1], av[i - 1])
                } else if i == ac.len() || bc[j] < ac[i] {
                    j += 1;
                    (bc[j - 1], s * bv[j - 1])
                } else {
                    i += 1;
                    j += 1;
                    (ac[i - 1], av[i - 1] + s * bv[j - 1])
                };
                if v != 0.0 {
                    col.push(c);
                    val.push(v);
                }
            }
            start.push(col.len());
        }
        Csr {
            rows: self.rows,
            cols: self.cols,
            start,
            col,
            val,
        }
    }

    /// `½ (A + Aᵀ)`: a product such as `Pᵀ A P` is symmetric only to round-off.
    pub fn symmetrised(&self) -> Csr {
        let mut s = self.add_scaled(&self.transpose(), 1.0);
        s.val.iter_mut().for_each(|v| *v *= 0.5);
        s
    }

    /// The matrix with a diagonal entry on every empty row: the coarse unknowns
    /// that pad an aggregate to six (see [`tentative`](super::prolong::tentative))
    /// have no entries, and get the mean diagonal of the matrix, so that they stay
    /// decoupled (no prolongator column reaches them) without making the level
    /// singular or changing the scale its strength of connection compares.
    pub fn with_padded_diagonal(self) -> Csr {
        let empty = (0..self.rows)
            .filter(|&r| self.start[r] == self.start[r + 1])
            .count();
        if empty == 0 {
            return self;
        }
        let (mut sum, mut count) = (0.0, 0usize);
        for r in 0..self.rows {
            let (cs, vs) = self.row(r);
            if let Some(k) = cs.iter().position(|&c| c as usize == r) {
                sum += vs[k];
                count += 1;
            }
        }
        let fill = if count > 0 { sum / count as f64 } else { 1.0 };
        let mut start = vec![0];
        let (mut col, mut val) = (Vec::new(), Vec::new());
        for r in 0..self.rows {
            let (cs, vs) = self.row(r);
            if cs.is_empty() {
                col.push(r as u32);
                val.push(fill);
            } else {
                col.extend_from_slice(cs);
                val.extend_from_slice(vs);
            }
            start.push(col.len());
        }
        Csr {
            rows: self.rows,
            cols: self.cols,
            start,
            col,
            val,
        }
    }
}
