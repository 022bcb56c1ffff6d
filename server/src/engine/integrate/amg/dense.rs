//! The coarsest level's exact solve: a dense Cholesky factor `A = L Lᵀ`, packed by
//! rows, solved by forward and backward substitution in place (no allocation).

/// A dense Cholesky factor, lower triangle packed by rows (`L_ij` at `i(i+1)/2 + j`).
#[derive(Clone, Debug, Default)]
pub struct DenseCholesky {
    n: usize,
    l: Vec<f64>,
}

impl DenseCholesky {
    /// Factors the symmetric matrix given by `entry(i, j)` for `j ≤ i`; `None` if it
    /// is not positive definite (a pivot not above `1e-13` of the largest diagonal
    /// entry: round-off has then eaten the matrix's smallest eigenvalue).
    pub fn new(n: usize, entry: impl Fn(usize, usize) -> f64) -> Option<Self> {
        let mut l = vec![0.0; n * (n + 1) / 2];
        let at = |i: usize, j: usize| i * (i + 1) / 2 + j;
        let mut largest = 0.0f64;
        for i in 0..n {
            for j in 0..=i {
                l[at(i, j)] = entry(i, j);
            }
            largest = largest.max(l[at(i, i)].abs());
        }
        for i in 0..n {
            for j in 0..=i {
                let mut s = l[at(i, j)];
                let (ri, rj) = (at(i, 0), at(j, 0));
                for k in 0..j {
                    s -= l[ri + k] * l[rj + k];
                }
                if i == j {
                    let positive = s.is_finite() && s > 1e-13 * largest;
                    if !positive {
                        return None;
                    }
                    l[at(i, i)] = s.sqrt();
                } else {
                    l[at(i, j)] = s / l[at(j, j)];
                }
            }
        }
        Some(DenseCholesky { n, l })
    }

    /// Order of the matrix.
    pub fn order(&self) -> usize {
        self.n
    }

    /// `x ← A⁻¹ x`.
    pub fn solve(&self, x: &mut [f64]) {
        let n = self.n;
        let mut row = 0;
        for i in 0..n {
            let li = &self.l[row..row + i + 1];
            let s: f64 = li[..i].iter().zip(&x[..i]).map(|(a, b)| a * b).sum();
            x[i] = (x[i] - s) / li[i];
            row += i + 1;
        }
        for i in (0..n).rev() {
            row -= i + 1;
            let li = &self.l[row..row + i + 1];
            x[i] /= li[i];
            let xi = x[i];
            x[..i]
                .iter_mut()
                .zip(&li[..i])
                .for_each(|(x, l)| *x -= l * xi);
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.l.capacity() * 8
    }
}
