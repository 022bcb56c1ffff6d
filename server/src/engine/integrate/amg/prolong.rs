//! Prolongators: the tentative one from the rigid-body modes, smoothed by one damped
//! block-Jacobi step (Vaněk, Mandel and Brezina 1996, §2–3).
//!
//! **Near-nullspace.** Linear elasticity has the six rigid-body motions as its
//! nullspace (before supports): on the fine level, vertex `i` at `X_i` (centred on
//! the mesh's centroid and divided by its radius, so that the six columns have
//! comparable size) carries the rows
//!
//! ```text
//! [1 0 0   0   z  −y]
//! [0 1 0  −z   0   x]
//! [0 0 1   y  −x   0]
//! ```
//!
//! (three translations and the rotations `ω × X` about x, y, z). A coarse space that
//! holds these modes exactly lets the coarse levels correct the smooth, nearly rigid
//! error that a local smoother cannot reduce.
//!
//! **Tentative prolongator.** For each aggregate, the rows `B_a` of the modes on its
//! unknowns are orthonormalised, `B_a = Q_a R_a` (modified Gram–Schmidt, each column
//! orthogonalised twice, "twice is enough"), and `Q_a` becomes the aggregate's block
//! of `P_tent`, its columns the aggregate's coarse unknowns; `R_a` are the modes on
//! the coarse level, so `P_tent B_coarse = B` exactly. A column whose remainder is
//! below [`DROP`] of its own size is dependent on the previous ones (a single vertex
//! carries three independent modes, two vertices five) and is dropped; the
//! aggregate's coarse node still holds six unknowns, the missing ones padding with no
//! prolongator column (so that every coarse block is 6×6, see
//! [`blocks`](super::blocks)).
//!
//! **Smoothing.** `P = (I − ω D⁻¹ A) P_tent`, with `D` the block diagonal of `A` and
//! `ω = 4 / (3 ρ(D⁻¹ A))`: the damped Jacobi step that best damps the upper two
//! thirds of the spectrum, which widens each basis function over its neighbours'
//! unknowns so that its energy drops (a piecewise-rigid function has large energy at
//! aggregate borders). `ρ` is estimated by [`POWER_ITERATIONS`] power iterations; an
//! estimate low by up to a third still keeps `ω ρ < 2`.

use nalgebra::DMatrix;

use super::aggregate::NONE;
use super::sparse::Csr;

/// A column of the modes is dropped from an aggregate when what is left of it after
/// orthogonalisation is below this fraction of its norm: far above round-off
/// (1e-16) and far below any genuinely independent mode of an aggregate of distinct
/// vertices (whose remainders are of the order of the aggregate's size over the
/// mesh's, 1e-3 and up).
pub const DROP: f64 = 1e-8;

/// Power iterations for `ρ(D⁻¹ A)`. The estimate rises monotonically towards `ρ`;
/// twenty bring it within a few percent on the livers, and the weights built on it
/// tolerate far more.
pub const POWER_ITERATIONS: usize = 20;

/// The rigid-body modes of the fine level, one row of six per unknown (vertex `i`'s
/// unknowns are `3i..3i+3`), positions centred and scaled to unit radius.
pub fn rigid_modes(positions: &[nalgebra::Point3<f64>]) -> Vec<[f64; 6]> {
    let n = positions.len().max(1) as f64;
    let centre = positions
        .iter()
        .fold(nalgebra::Vector3::zeros(), |s, p| s + p.coords)
        / n;
    let radius = positions
        .iter()
        .map(|p| (p.coords - centre).norm())
        .fold(0.0, f64::max);
    let scale = if radius > 0.0 { 1.0 / radius } else { 1.0 };
    let mut b = Vec::with_capacity(3 * positions.len());
    for p in positions {
        let q = (p.coords - centre) * scale;
        let (x, y, z) = (q.x, q.y, q.z);
        b.push([1.0, 0.0, 0.0, 0.0, z, -y]);
        b.push([0.0, 1.0, 0.0, -z, 0.0, x]);
        b.push([0.0, 0.0, 1.0, y, -x, 0.0]);
    }
    b
}

/// The inverse diagonal blocks of a level, one per node (any size), for the smoother
/// and the prolongator's smoothing step.
#[derive(Clone, Debug, Default)]
pub struct BlockDiag {
    /// Node `k`'s unknowns are `node_start[k]..node_start[k + 1]`.
    pub node_start: Vec<usize>,
    /// Node `k`'s inverse block, row-major, at `value_start[k]`.
    value_start: Vec<usize>,
    value: Vec<f64>,
}

impl BlockDiag {
    /// The inverses of `a`'s diagonal blocks. A block that is not invertible (a node
    /// with no stiffness: only possible in a degenerate mesh) gets the identity, so
    /// the smoother leaves it alone.
    pub fn new(a: &Csr, node_start: &[usize]) -> Self {
        let mut value_start = Vec::with_capacity(node_start.len());
        let mut value = Vec::new();
        for k in 0..node_start.len() - 1 {
            let (s, e) = (node_start[k], node_start[k + 1]);
            let m = e - s;
            let mut block = DMatrix::<f64>::zeros(m, m);
            for r in s..e {
                let (cs, vs) = a.row(r);
                for (&c, &v) in cs.iter().zip(vs) {
                    let c = c as usize;
                    if (s..e).contains(&c) {
                        block[(r - s, c - s)] = v;
                    }
                }
            }
            let inverse = block
                .clone()
                .try_inverse()
                .filter(|b| b.iter().all(|v| v.is_finite()))
                .unwrap_or_else(|| DMatrix::identity(m, m));
            value_start.push(value.len());
            for r in 0..m {
                for c in 0..m {
                    value.push(inverse[(r, c)]);
                }
            }
        }
        value_start.push(value.len());
        BlockDiag {
            node_start: node_start.to_vec(),
            value_start,
            value,
        }
    }

    /// `x += ω D⁻¹ t`.
    #[inline]
    pub fn apply_add(&self, omega: f64, t: &[f64], x: &mut [f64]) {
        for k in 0..self.node_start.len() - 1 {
            let (s, e) = (self.node_start[k], self.node_start[k + 1]);
            let m = e - s;
            let block = &self.value[self.value_start[k]..self.value_start[k + 1]];
            for r in 0..m {
                let row = &block[r * m..(r + 1) * m];
                let dot: f64 = row.iter().zip(&t[s..e]).map(|(a, b)| a * b).sum();
                x[s + r] += omega * dot;
            }
        }
    }

    /// `D⁻¹` as a sparse matrix.
    pub fn to_csr(&self) -> Csr {
        let n = *self.node_start.last().unwrap_or(&0);
        let mut start = vec![0];
        let (mut col, mut val) = (Vec::new(), Vec::new());
        for k in 0..self.node_start.len() - 1 {
            let (s, e) = (self.node_start[k], self.node_start[k + 1]);
            let m = e - s;
            let block = &self.value[self.value_start[k]..self.value_start[k + 1]];
            for r in 0..m {
                for c in 0..m {
                    col.push((s + c) as u32);
                    val.push(block[r * m + c]);
                }
                start.push(col.len());
            }
        }
        Csr {
            rows: n,
            cols: n,
            start,
            col,
            val,
        }
    }

    pub fn heap_bytes(&self) -> usize {
        (self.node_start.capacity() + self.value_start.capacity() + self.value.capacity()) * 8
    }
}

/// The tentative prolongator of the aggregation `agg` (aggregate of each node, or
/// [`NONE`]) with `count` aggregates, from the modes `b` (one row of six per
/// unknown): `(P_tent, coarse modes, coarse node starts)`.
pub fn tentative(
    agg: &[u32],
    count: usize,
    node_start: &[usize],
    b: &[[f64; 6]],
) -> (Csr, Vec<[f64; 6]>, Vec<usize>) {
    let rows = *node_start.last().unwrap_or(&0);
    // The unknowns of each aggregate, in order.
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); count];
    for (k, &a) in agg.iter().enumerate() {
        if a != NONE {
            members[a as usize].extend(node_start[k]..node_start[k + 1]);
        }
    }
    let mut coarse_start = vec![0usize];
    let mut coarse_b: Vec<[f64; 6]> = Vec::new();
    // Row r of P_tent: its aggregate's coarse columns, values Q_a[r].
    let mut row_values: Vec<Vec<f64>> = vec![Vec::new(); rows];
    let mut row_first: Vec<usize> = vec![0; rows];
    for unknowns in &members {
        let m = unknowns.len();
        let mut q: Vec<Vec<f64>> = Vec::with_capacity(6);
        let mut r = [[0.0f64; 6]; 6];
        for c in 0..6 {
            let mut v: Vec<f64> = unknowns.iter().map(|&u| b[u][c]).collect();
            let size = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            for _ in 0..2 {
                for (j, qj) in q.iter().enumerate() {
                    let d: f64 = qj.iter().zip(&v).map(|(a, b)| a * b).sum();
                    r[j][c] += d;
                    v.iter_mut().zip(qj).for_each(|(x, q)| *x -= d * q);
                }
            }
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            if size > 0.0 && norm > DROP * size && q.len() < m {
                r[q.len()][c] = norm;
                v.iter_mut().for_each(|x| *x /= norm);
                q.push(v);
            }
        }
        let first = *coarse_start.last().unwrap();
        for (i, &u) in unknowns.iter().enumerate() {
            row_first[u] = first;
            row_values[u] = q.iter().map(|qj| qj[i]).collect();
        }
        // Padding unknowns carry no mode.
        coarse_b.extend(r.iter().take(q.len()).copied());
        coarse_b.extend(std::iter::repeat_n([0.0; 6], 6 - q.len()));
        coarse_start.push(first + 6);
    }
    let mut start = vec![0];
    let (mut col, mut val) = (Vec::new(), Vec::new());
    for r in 0..rows {
        for (j, &v) in row_values[r].iter().enumerate() {
            col.push((row_first[r] + j) as u32);
            val.push(v);
        }
        start.push(col.len());
    }
    let p = Csr {
        rows,
        cols: *coarse_start.last().unwrap(),
        start,
        col,
        val,
    };
    (p, coarse_b, coarse_start)
}

/// `ρ(D⁻¹ A)` by [`POWER_ITERATIONS`] power iterations from a fixed pseudo-random
/// start (so that setups are reproducible).
pub fn spectral_radius(a: &Csr, dinv: &BlockDiag) -> f64 {
    let n = a.rows;
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    let mut x: Vec<f64> = (0..n)
        .map(|_| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
        .collect();
    let (mut y, mut z) = (vec![0.0; n], vec![0.0; n]);
    let mut rho = 0.0;
    for _ in 0..POWER_ITERATIONS {
        let norm = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm == 0.0 || !norm.is_finite() {
            break;
        }
        x.iter_mut().for_each(|v| *v /= norm);
        a.mul(&x, &mut y);
        z.iter_mut().for_each(|v| *v = 0.0);
        dinv.apply_add(1.0, &y, &mut z);
        rho = z.iter().map(|v| v * v).sum::<f64>().sqrt();
        std::mem::swap(&mut x, &mut z);
    }
    rho
}

/// `P = (I − ω D⁻¹ A) P_tent`.
pub fn smooth(a: &Csr, dinv: &BlockDiag, p_tent: &Csr, omega: f64) -> Csr {
    let dap = dinv.to_csr().times(&a.times(p_tent));
    p_tent.add_scaled(&dap, -omega)
}
