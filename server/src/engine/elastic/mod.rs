//! Linear elasticity with the tensor-mass model (Cotin, Delingette and Ayache, 1999).
//!
//! The elastic energy of a linear tetrahedral (P1) finite element mesh is a quadratic
//! form of the vertex displacements `u_i = x_i − X_i` (current minus rest position):
//! `W = ½ Σ_ij u_iᵀ K_ij u_j`. The tensor-mass model stores the 3×3 blocks `K_ij` on the
//! mesh itself — one tensor per vertex (`K_ii`) and one per edge (`K_ij`, with
//! `K_ji = K_ijᵀ`) — each gathered from the tetrahedra sharing that vertex or edge, so the
//! elastic force on a vertex, `f_i = −Σ_j K_ij u_j`, reads only its neighbours. Each
//! tetrahedron keeps its own material, so the model is non-homogeneous.
//!
//! Storage is a block-row (BSR) matrix: row `i` lists vertex `i` itself and its edge
//! neighbours in ascending order, so the product `K u` is a gather over each row
//! (no scattered writes) and the reaction on a single vertex is one row.

mod assemble;
mod stress;

pub use assemble::{shape_gradients, tet_stiffness};
pub use stress::{tet_displacements, von_mises_stress};

use nalgebra::{Matrix3, Point3, Vector3};

use super::material::Material;
use super::mesh::TetMesh;

/// The assembled linear-elastic model of a mesh: stiffness tensors and lumped masses.
#[derive(Clone, Debug)]
pub struct ElasticModel {
    /// Rest positions `X_i`, m.
    pub rest: Vec<Point3<f64>>,
    /// Lumped mass of each vertex, kg: a quarter of the mass `ρ_T V_T` of every
    /// tetrahedron `T` that contains it.
    pub mass: Vec<f64>,
    /// The stiffness tensors `K_ij` as a symmetric block-row matrix, N/m.
    pub stiffness: BlockMatrix,
    /// The material of each tetrahedron (an index into `materials`).
    pub tet_material: Vec<u16>,
    /// The distinct materials of the mesh.
    pub materials: Vec<Material>,
}

/// A square matrix of 3×3 blocks in block-row (BSR) layout with a full (both triangles)
/// pattern: the pattern of the mesh's vertex–edge graph.
#[derive(Clone, Debug)]
pub struct BlockMatrix {
    /// `row_start[i]..row_start[i + 1]` indexes the blocks of row `i`.
    pub row_start: Vec<u32>,
    /// Column (vertex) of each block, ascending within a row.
    pub col: Vec<u32>,
    /// The blocks.
    pub block: Vec<Matrix3<f64>>,
    /// Index of the diagonal block of each row.
    pub diag: Vec<u32>,
}

impl BlockMatrix {
    /// The zero matrix on the pattern of `edges` (pairs `[i, j]`, `i ≠ j`) over `n`
    /// vertices, with every diagonal block present.
    pub fn with_pattern(n: usize, edges: &[[u32; 2]]) -> Self {
        let mut count = vec![1u32; n];
        for &[i, j] in edges {
            count[i as usize] += 1;
            count[j as usize] += 1;
        }
        let mut row_start = Vec::with_capacity(n + 1);
        row_start.push(0u32);
        for c in &count {
            row_start.push(row_start.last().unwrap() + c);
        }
        let nnz = *row_start.last().unwrap() as usize;
        let mut col = vec![0u32; nnz];
        let mut fill: Vec<u32> = row_start[..n].to_vec();
        for (i, f) in fill.iter_mut().enumerate() {
            col[*f as usize] = i as u32;
            *f += 1;
        }
        for &[i, j] in edges {
            col[fill[i as usize] as usize] = j;
            fill[i as usize] += 1;
            col[fill[j as usize] as usize] = i;
            fill[j as usize] += 1;
        }
        let mut diag = vec![0u32; n];
        for i in 0..n {
            let (s, e) = (row_start[i] as usize, row_start[i + 1] as usize);
            col[s..e].sort_unstable();
            diag[i] = s as u32 + col[s..e].binary_search(&(i as u32)).unwrap() as u32;
        }
        BlockMatrix {
            row_start,
            col,
            block: vec![Matrix3::zeros(); nnz],
            diag,
        }
    }

    /// Number of block rows.
    pub fn rows(&self) -> usize {
        self.diag.len()
    }

    /// Index of block `(i, j)`, if `j` is `i` or an edge neighbour of `i`.
    pub fn find(&self, i: u32, j: u32) -> Option<usize> {
        let (s, e) = (
            self.row_start[i as usize] as usize,
            self.row_start[i as usize + 1] as usize,
        );
        self.col[s..e].binary_search(&j).ok().map(|k| s + k)
    }

    /// Row `i` of the product: `Σ_j K_ij u_j`.
    #[inline]
    pub fn row_times(&self, i: usize, u: &[Vector3<f64>]) -> Vector3<f64> {
        let (s, e) = (self.row_start[i] as usize, self.row_start[i + 1] as usize);
        let mut acc = Vector3::zeros();
        for k in s..e {
            acc += self.block[k] * u[self.col[k] as usize];
        }
        acc
    }

    /// `out = K u`. Allocation-free.
    pub fn mul(&self, u: &[Vector3<f64>], out: &mut [Vector3<f64>]) {
        debug_assert_eq!(u.len(), self.rows());
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.row_times(i, u);
        }
    }

    /// Bytes held by the matrix (for memory reports).
    pub fn heap_bytes(&self) -> usize {
        self.row_start.capacity() * 4
            + self.col.capacity() * 4
            + self.diag.capacity() * 4
            + self.block.capacity() * std::mem::size_of::<Matrix3<f64>>()
    }
}

impl ElasticModel {
    /// Assembles the tensor-mass model of `mesh`, whose tetrahedron `t` has material
    /// `materials[tet_material[t]]`. Positions must already be in metres.
    pub fn new(mesh: &TetMesh, materials: Vec<Material>, tet_material: Vec<u16>) -> Self {
        assert_eq!(tet_material.len(), mesh.tets.len());
        let n = mesh.vertex_count();
        let mut stiffness = BlockMatrix::with_pattern(n, &mesh.edges);
        let mut mass = vec![0.0; n];
        for (t, &tet) in mesh.tets.iter().enumerate() {
            let mat = materials[tet_material[t] as usize];
            let (gradients, volume) = shape_gradients(&mesh.positions, tet);
            let k = tet_stiffness(&gradients, volume, &mat);
            for a in 0..4 {
                mass[tet[a] as usize] += mat.density * volume / 4.0;
                for b in 0..4 {
                    let idx = stiffness
                        .find(tet[a], tet[b])
                        .expect("every pair of a tetrahedron's vertices is an edge of the mesh");
                    stiffness.block[idx] += k[a][b];
                }
            }
        }
        ElasticModel {
            rest: mesh.positions.clone(),
            mass,
            stiffness,
            tet_material,
            materials,
        }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.rest.len()
    }

    /// Elastic potential energy `½ uᵀ K u` of the displacement `u`, J.
    pub fn strain_energy(&self, u: &[Vector3<f64>]) -> f64 {
        (0..u.len())
            .map(|i| 0.5 * u[i].dot(&self.stiffness.row_times(i, u)))
            .sum()
    }

    /// Upper bound on the largest eigenvalue of `M⁻¹K` (rad²/s²), by Gershgorin's
    /// theorem on the rows of `M⁻¹K`: every eigenvalue lies in a disc centred on a
    /// diagonal entry with radius the sum of the row's other absolute entries, so
    /// `λ_max ≤ max_r Σ_c |(M⁻¹K)_rc|`. The eigenvalues of `M⁻¹K` are real and
    /// non-negative (it is similar to the symmetric `M^{-½} K M^{-½}`), so this bounds
    /// the squared highest angular frequency `ω_max²` of the mesh.
    pub fn max_eigenvalue_bound(&self) -> f64 {
        let k = &self.stiffness;
        let mut bound = 0.0f64;
        for i in 0..k.rows() {
            let mut row_sums = [0.0f64; 3];
            for b in &k.block[k.row_start[i] as usize..k.row_start[i + 1] as usize] {
                for (r, sum) in row_sums.iter_mut().enumerate() {
                    *sum += b[(r, 0)].abs() + b[(r, 1)].abs() + b[(r, 2)].abs();
                }
            }
            let row_max = row_sums.iter().cloned().fold(0.0, f64::max);
            bound = bound.max(row_max / self.mass[i]);
        }
        bound
    }

    /// Bytes held by the model (for memory reports).
    pub fn heap_bytes(&self) -> usize {
        self.stiffness.heap_bytes()
            + self.rest.capacity() * 24
            + self.mass.capacity() * 8
            + self.tet_material.capacity() * 2
    }
}

#[cfg(test)]
mod tests;
