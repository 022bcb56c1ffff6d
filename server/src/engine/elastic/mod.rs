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
//! Storage is a symmetric block matrix ([`BlockMatrix`]) holding each vertex tensor and
//! each edge tensor once.
//!
//! A scene chooses the [`Formulation`]: these linear tensors as they are, or applied
//! in each tetrahedron's rotated frame ([`corotational`]), which is exact for rigid
//! motions of any size and so for the large rotations of tissue pushed aside.

mod assemble;
pub mod corotational;
pub mod parts;
pub mod rotation;
mod stress;
pub mod twist;
pub mod twist_tangent;

pub use assemble::{shape_gradients, tet_stiffness};
pub use corotational::{Corotated, Element, TANGENT_TURN, VertexElements};
pub use parts::{MIN_PART_VERTICES, Parts, part_count};
pub use stress::{small_strain, tet_displacements, von_mises_of_strain};

use std::ops::Range;

use nalgebra::{Matrix3, Point3, Vector3};
use serde::{Deserialize, Serialize};

use super::material::Material;
use super::mesh::TetMesh;
use super::workers::{Disjoint, Workers, share};

/// How the elastic force depends on the vertex positions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Formulation {
    /// `f = −K (x − X)`: exact for small displacements, wrong under large rotations
    /// (a rigidly turned body is strained).
    #[default]
    Linear,
    /// `f = −Σ_e R_e K_e (R_eᵀ x_e − X_e)` with each element's polar rotation
    /// ([`corotational`]): small strains, rotations of any size.
    Corotational,
}

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
    /// Linear or corotational.
    pub formulation: Formulation,
    /// Per-tetrahedron data of the corotational model (empty for the linear one).
    pub elements: Vec<Element>,
    /// The corotational elements around each vertex (empty for the linear model).
    pub vertex_elements: VertexElements,
}

/// A symmetric matrix of 3×3 blocks on the pattern of the mesh's vertex–edge graph,
/// storing each block once: the diagonal blocks `K_ii` and the upper blocks `K_ij`,
/// `i < j`, in block-row order. The lower blocks are their transposes, `K_ji = K_ijᵀ`.
///
/// Storing half the off-diagonal blocks halves the memory a product streams through:
/// a 20k-tetrahedron liver's stiffness is 2.6 MB this way, 4.8 MB in full. Row `i` of
/// the lower part is reached through `lower_*`, which index the upper blocks `(j, i)`,
/// `j < i`, so one vertex's row (its reaction) is still a short read.
#[derive(Clone, Debug)]
pub struct BlockMatrix {
    /// `row_start[i]..row_start[i + 1]` indexes the stored blocks of row `i`: first
    /// the diagonal, then the upper blocks in ascending column order.
    pub row_start: Vec<u32>,
    /// Column of each stored block.
    pub col: Vec<u32>,
    /// The stored blocks.
    pub block: Vec<Matrix3<f64>>,
    /// Index of the diagonal block of each row (`row_start[i]`).
    pub diag: Vec<u32>,
    /// `lower_start[i]..lower_start[i + 1]` indexes, in `lower_block`, the stored blocks
    /// `(j, i)` with `j < i`, whose rows are in `lower_row`.
    pub lower_start: Vec<u32>,
    pub lower_row: Vec<u32>,
    pub lower_block: Vec<u32>,
}

impl BlockMatrix {
    /// The zero matrix on the pattern of `edges` (pairs `[i, j]`, `i ≠ j`) over `n`
    /// vertices, with every diagonal block present.
    pub fn with_pattern(n: usize, edges: &[[u32; 2]]) -> Self {
        let mut upper: Vec<Vec<u32>> = (0..n as u32).map(|i| vec![i]).collect();
        let mut lower: Vec<Vec<u32>> = vec![Vec::new(); n];
        for &[a, b] in edges {
            let (i, j) = (a.min(b), a.max(b));
            upper[i as usize].push(j);
            lower[j as usize].push(i);
        }
        let (mut row_start, mut col, mut diag) = (vec![0u32], Vec::new(), Vec::with_capacity(n));
        for row in &mut upper {
            row[1..].sort_unstable();
            row.dedup();
            diag.push(col.len() as u32);
            col.extend_from_slice(row);
            row_start.push(col.len() as u32);
        }
        let nnz = col.len();
        let mut m = BlockMatrix {
            row_start,
            col,
            block: vec![Matrix3::zeros(); nnz],
            diag,
            lower_start: vec![0],
            lower_row: Vec::new(),
            lower_block: Vec::new(),
        };
        for (i, rows) in lower.iter_mut().enumerate() {
            rows.sort_unstable();
            rows.dedup();
            for &j in rows.iter() {
                let k = m.find_upper(j, i as u32).expect("pattern holds the edge");
                m.lower_row.push(j);
                m.lower_block.push(k as u32);
            }
            m.lower_start.push(m.lower_row.len() as u32);
        }
        m
    }

    /// Number of block rows.
    pub fn rows(&self) -> usize {
        self.diag.len()
    }

    /// Index of the stored block `(i, j)` for `i ≤ j`.
    pub(crate) fn find_upper(&self, i: u32, j: u32) -> Option<usize> {
        let (s, e) = (
            self.row_start[i as usize] as usize,
            self.row_start[i as usize + 1] as usize,
        );
        if j == i {
            return Some(s);
        }
        self.col[s + 1..e].binary_search(&j).ok().map(|k| s + 1 + k)
    }

    /// Block `(i, j)`, if `j` is `i` or an edge neighbour of `i`.
    pub fn get(&self, i: u32, j: u32) -> Option<Matrix3<f64>> {
        if i <= j {
            self.find_upper(i, j).map(|k| self.block[k])
        } else {
            self.find_upper(j, i).map(|k| self.block[k].transpose())
        }
    }

    /// Adds `b` to block `(i, j)` (and so `bᵀ` to block `(j, i)`), `b` seen from row
    /// `i`. Returns false if `(i, j)` is not in the pattern.
    pub fn add(&mut self, i: u32, j: u32, b: &Matrix3<f64>) -> bool {
        let found = if i <= j {
            self.find_upper(i, j).map(|k| (k, *b))
        } else {
            self.find_upper(j, i).map(|k| (k, b.transpose()))
        };
        match found {
            Some((k, b)) => {
                self.block[k] += b;
                true
            }
            None => false,
        }
    }

    /// Calls `f(j, K_ij)` for every block of row `i`, diagonal included.
    #[inline]
    pub fn for_each_in_row(&self, i: usize, mut f: impl FnMut(usize, &Matrix3<f64>)) {
        for k in self.row_start[i] as usize..self.row_start[i + 1] as usize {
            f(self.col[k] as usize, &self.block[k]);
        }
        for k in self.lower_start[i] as usize..self.lower_start[i + 1] as usize {
            f(
                self.lower_row[k] as usize,
                &self.block[self.lower_block[k] as usize].transpose(),
            );
        }
    }

    /// Row `i` of the product: `Σ_j K_ij u_j`.
    #[inline]
    pub fn row_times(&self, i: usize, u: &[Vector3<f64>]) -> Vector3<f64> {
        let (s, e) = (self.row_start[i] as usize, self.row_start[i + 1] as usize);
        let mut acc = Vector3::zeros();
        for (b, &c) in self.block[s..e].iter().zip(&self.col[s..e]) {
            acc += b * u[c as usize];
        }
        let (s, e) = (
            self.lower_start[i] as usize,
            self.lower_start[i + 1] as usize,
        );
        for (&k, &j) in self.lower_block[s..e].iter().zip(&self.lower_row[s..e]) {
            acc += self.block[k as usize].tr_mul(&u[j as usize]);
        }
        acc
    }

    /// `out = K u`, one pass over the stored blocks: each upper block `K_ij` adds
    /// `K_ij u_j` to row `i` and `K_ijᵀ u_i` to row `j`. Allocation-free.
    pub fn mul(&self, u: &[Vector3<f64>], out: &mut [Vector3<f64>]) {
        debug_assert_eq!(u.len(), self.rows());
        self.mul_rows(&self.block, 0..self.rows(), u, out);
    }

    /// Rows `rows` of `K u` into `out` (which holds those rows), walked in order:
    /// the upper blocks of row `i` add `K_ij u_j` to row `i`, and `K_ijᵀ u_i` to row
    /// `j` when `j` is in `rows` (columns ascend, so those come first); the lower
    /// blocks `K_ji` (`j < i`) of a `j` before `rows` are read from row `i`'s side
    /// instead. Over all rows this is one pass over the stored blocks.
    ///
    /// `blocks` are the stored blocks, [`block`](Self::block) or a copy of them in
    /// another precision ([`Block`]), on this matrix's pattern.
    fn mul_rows<B: Block>(
        &self,
        blocks: &[B],
        rows: Range<usize>,
        u: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
    ) {
        let at = |i: usize| i - rows.start;
        out.iter_mut().for_each(|o| *o = Vector3::zeros());
        for i in rows.clone() {
            let (b, e) = (self.row_start[i] as usize, self.row_start[i + 1] as usize);
            let ui = u[i];
            let mut acc = blocks[b].times(&ui);
            for (k, &c) in blocks[b + 1..e].iter().zip(&self.col[b + 1..e]) {
                let c = c as usize;
                acc += k.times(&u[c]);
                if c < rows.end {
                    out[at(c)] += k.tr_times(&ui);
                }
            }
            let (b, e) = (
                self.lower_start[i] as usize,
                self.lower_start[i + 1] as usize,
            );
            for (&k, &j) in self.lower_block[b..e].iter().zip(&self.lower_row[b..e]) {
                if j as usize >= rows.start {
                    break;
                }
                acc += blocks[k as usize].tr_times(&u[j as usize]);
            }
            out[at(i)] += acc;
        }
    }

    /// `out = a ∘ u + s K u`, that is `out_i = a_i u_i + s Σ_j K_ij u_j` (the
    /// implicit step's `(1 + hα) M + h² K` is `a_i = (1 + hα) m_i`, `s = h²`), each
    /// part of `parts` computed by one of `workers` (see [`parts`]).
    ///
    /// A part computes its rows as [`mul`](Self::mul) computes all of them: with
    /// one part this is [`mul`](Self::mul)'s arithmetic in its order, to the last
    /// bit. Allocation-free.
    pub fn mul_shared(
        &self,
        workers: Option<&Workers>,
        parts: &Parts,
        a: impl Fn(usize) -> f64 + Sync,
        s: f64,
        u: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
    ) {
        self.mul_shared_by(&self.block, workers, parts, a, s, u, out);
    }

    /// [`mul_shared`](Self::mul_shared) with the blocks read from `blocks`: the
    /// stored ones, or a copy of them in another precision on this matrix's pattern,
    /// such as [`round_f32_shared`](Self::round_f32_shared)'s (each block widened
    /// to f64 as it is read, the vectors and sums in f64).
    #[allow(clippy::too_many_arguments)]
    pub fn mul_shared_by<B: Block + Sync>(
        &self,
        blocks: &[B],
        workers: Option<&Workers>,
        parts: &Parts,
        a: impl Fn(usize) -> f64 + Sync,
        s: f64,
        u: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
    ) {
        assert_eq!(blocks.len(), self.block.len());
        assert_eq!(u.len(), self.rows());
        assert_eq!(out.len(), self.rows());
        let cells = Disjoint::new(out);
        share(workers, parts.count(), &|t| {
            let rows = parts.range(t);
            // SAFETY: the parts' ranges are disjoint, and `u` is not `out`.
            let out = unsafe { cells.range(rows.clone()) };
            self.mul_rows(blocks, rows.clone(), u, out);
            for (o, i) in out.iter_mut().zip(rows.clone()) {
                *o = a(i) * u[i] + s * *o;
            }
        });
    }

    /// Writes each stored block rounded to f32 into `out` (as long as
    /// [`block`](Self::block)), the blocks of each part's rows by one of `workers`.
    /// Allocation-free.
    pub fn round_f32_shared(
        &self,
        workers: Option<&Workers>,
        parts: &Parts,
        out: &mut [Matrix3<f32>],
    ) {
        assert_eq!(out.len(), self.block.len());
        let cells = Disjoint::new(out);
        share(workers, parts.count(), &|t| {
            let rows = parts.range(t);
            let stored = self.row_start[rows.start] as usize..self.row_start[rows.end] as usize;
            // SAFETY: a part's rows hold a range of the stored blocks of their own.
            let out = unsafe { cells.range(stored.clone()) };
            for (o, b) in out.iter_mut().zip(&self.block[stored]) {
                *o = b.cast::<f32>();
            }
        });
    }

    /// Bytes held by the matrix (for memory reports).
    pub fn heap_bytes(&self) -> usize {
        (self.row_start.capacity()
            + self.col.capacity()
            + self.diag.capacity()
            + self.lower_start.capacity()
            + self.lower_row.capacity()
            + self.lower_block.capacity())
            * 4
            + self.block.capacity() * std::mem::size_of::<Matrix3<f64>>()
    }
}

impl ElasticModel {
    /// Assembles the tensor-mass model of `mesh`, whose tetrahedron `t` has material
    /// `materials[tet_material[t]]`, linear. Positions must already be in metres.
    pub fn new(mesh: &TetMesh, materials: Vec<Material>, tet_material: Vec<u16>) -> Self {
        Self::with_formulation(mesh, materials, tet_material, Formulation::Linear)
    }

    /// As [`new`](Self::new), with the given formulation.
    pub fn with_formulation(
        mesh: &TetMesh,
        materials: Vec<Material>,
        tet_material: Vec<u16>,
        formulation: Formulation,
    ) -> Self {
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
                    // Each unordered pair once: the block (a, b) with tet[a] ≤ tet[b]
                    // carries K_ab, and K_ba = K_abᵀ is implied.
                    if tet[a] <= tet[b] {
                        let added = stiffness.add(tet[a], tet[b], &k[a][b]);
                        assert!(
                            added,
                            "every pair of a tetrahedron's vertices is an edge of the mesh"
                        );
                    }
                }
            }
        }
        let elements = match formulation {
            Formulation::Linear => Vec::new(),
            Formulation::Corotational => corotational::elements(
                &mesh.positions,
                &mesh.tets,
                &stiffness,
                &materials,
                &tet_material,
            ),
        };
        let vertex_elements = VertexElements::new(n, &elements);
        ElasticModel {
            vertex_elements,
            rest: mesh.positions.clone(),
            mass,
            stiffness,
            tet_material,
            materials,
            formulation,
            elements,
        }
    }

    /// The per-tick corotational workspace, for a corotational model.
    pub fn corotated(&self) -> Option<Corotated> {
        (self.formulation == Formulation::Corotational).then(|| Corotated::new(self))
    }

    /// The small strain of tetrahedron `t` at `x`: `sym(∇u)` (linear) or
    /// `sym(Rᵀ F) − I` with `R` the polar rotation of `F` (corotational), the strain
    /// each model's forces act on. Extracts the rotation afresh (for output, not for
    /// the tick).
    pub fn tet_strain(&self, mesh_tets: &[[u32; 4]], x: &[Point3<f64>], t: usize) -> Matrix3<f64> {
        match self.formulation {
            Formulation::Linear => {
                let (g, _) = shape_gradients(&self.rest, mesh_tets[t]);
                small_strain(&g, tet_displacements(x, &self.rest, mesh_tets[t]))
            }
            Formulation::Corotational => {
                let e = &self.elements[t];
                let f = e.deformation_gradient(x);
                e.strain(&rotation::cold_rotation(&f), &f)
            }
        }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.rest.len()
    }

    /// Elastic potential energy of the configuration `x`, J: `½ uᵀ K u` with
    /// `u = x − X` (linear), or the corotated energy of
    /// [`corotational`] (rotations extracted afresh).
    pub fn strain_energy_at(&self, x: &[Point3<f64>]) -> f64 {
        match self.formulation {
            Formulation::Linear => {
                let u: Vec<_> = x.iter().zip(&self.rest).map(|(x, r)| x - r).collect();
                self.strain_energy(&u)
            }
            Formulation::Corotational => corotational::strain_energy(&self.elements, x),
        }
    }

    /// The negated elastic force at `x`, N: `K (x − X)` (linear) or
    /// `Σ_e R_e K_e (R_eᵀ x_e − X_e)` with every rotation extracted afresh
    /// (corotational). `x` is an equilibrium under loads `f` when `f − out` vanishes
    /// on the free vertices. For checks and output, not for the tick.
    pub fn negated_elastic_force_at(&self, x: &[Point3<f64>], out: &mut [Vector3<f64>]) {
        match self.formulation {
            Formulation::Linear => {
                let u: Vec<_> = x.iter().zip(&self.rest).map(|(x, r)| x - r).collect();
                self.stiffness.mul(&u, out);
            }
            Formulation::Corotational => corotational::negated_force(&self.elements, x, out),
        }
    }

    /// The negated elastic force on vertex `v` alone at `x`, N: row `v` of
    /// [`negated_elastic_force_at`](Self::negated_elastic_force_at), `(K (x − X))_v`
    /// (linear) or `Σ_{e∋v} R_e K_e (R_eᵀ x_e − X_e)` with the rotations around `v`
    /// extracted afresh (corotational). Its negation is the tissue's force on a vertex
    /// held in place: what an instrument holding it feels.
    pub fn negated_elastic_force_on(&self, v: u32, x: &[Point3<f64>]) -> Vector3<f64> {
        match self.formulation {
            Formulation::Linear => {
                let mut ku = Vector3::zeros();
                self.stiffness.for_each_in_row(v as usize, |j, kij| {
                    ku += kij * (x[j] - self.rest[j]);
                });
                ku
            }
            Formulation::Corotational => {
                corotational::negated_force_on(&self.elements, &self.vertex_elements, v, x)
            }
        }
    }

    /// Elastic potential energy `½ uᵀ K u` of the displacement `u`, J (the linear
    /// model's).
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
    ///
    /// For the corotational model the bound must hold for every rotation of the
    /// elements, which Gershgorin's on `K` does not; it is then
    /// [`corotational::max_eigenvalue_bound`]'s element-by-element bound.
    pub fn max_eigenvalue_bound(&self) -> f64 {
        if self.formulation == Formulation::Corotational {
            return corotational::max_eigenvalue_bound(&self.elements, &self.mass);
        }
        let k = &self.stiffness;
        let mut bound = 0.0f64;
        for i in 0..k.rows() {
            let mut row_sums = [0.0f64; 3];
            k.for_each_in_row(i, |_, b| {
                for (r, sum) in row_sums.iter_mut().enumerate() {
                    *sum += b[(r, 0)].abs() + b[(r, 1)].abs() + b[(r, 2)].abs();
                }
            });
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
            + self.elements.capacity() * std::mem::size_of::<Element>()
            + self.vertex_elements.heap_bytes()
    }
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_corotational;
#[cfg(test)]
mod tests_f32;
#[cfg(test)]
mod tests_shared;
#[cfg(test)]
mod tests_tangent;
#[cfg(test)]
mod tests_twist;
#[cfg(test)]
mod tests_twist_tangent;

/// A stored block of a [`BlockMatrix`] as its product reads it: `K u` and `Kᵀ u` in
/// f64, whatever the block is stored in. An f32 block is widened exactly (every
/// f32 is an f64), so the product's only extra error is the rounding of each entry
/// to f32, a relative 2⁻²⁴ ≈ 6e-8 of it.
pub trait Block: Copy {
    fn times(&self, u: &Vector3<f64>) -> Vector3<f64>;
    fn tr_times(&self, u: &Vector3<f64>) -> Vector3<f64>;
}

impl Block for Matrix3<f64> {
    #[inline(always)]
    fn times(&self, u: &Vector3<f64>) -> Vector3<f64> {
        self * u
    }
    #[inline(always)]
    fn tr_times(&self, u: &Vector3<f64>) -> Vector3<f64> {
        self.tr_mul(u)
    }
}

impl Block for Matrix3<f32> {
    #[inline(always)]
    fn times(&self, u: &Vector3<f64>) -> Vector3<f64> {
        self.cast::<f64>() * u
    }
    #[inline(always)]
    fn tr_times(&self, u: &Vector3<f64>) -> Vector3<f64> {
        self.cast::<f64>().tr_mul(u)
    }
}
