//! Tetrahedral meshes: reading Gmsh files, normalising orientation, and the derived
//! topology (edges and the outward boundary surface) that the elastic model and the
//! contact stage work on.
//!
//! Conventions:
//! - Vertices are indexed `0..n` in file order (the order of the `$NOD`/`$Nodes` block),
//!   whatever ids the file gives them, until [`TetMesh::renumbered`] gives them an order
//!   with locality (`order`). `node_ids[i]` keeps the file's id and `file_index[i]`
//!   the place in the file.
//! - Every tetrahedron `[a, b, c, d]` is positively oriented after loading:
//!   `(b − a) · ((c − a) × (d − a)) > 0`, i.e. six times its signed volume is positive.
//! - Coordinates are in the file's units until [`TetMesh::scale`] maps them to metres.
//!
//! Loading repairs what is only a listing convention — a tetrahedron listed with
//! negative volume gets its last two vertices swapped — and rejects what would break
//! the simulation, naming the file, line and ids ([`MeshErrorKind`]): flat tetrahedra,
//! tetrahedra that overlap across a shared face, faces shared by three or more, open or
//! non-manifold boundaries, declared surface triangles that differ from the boundary,
//! and nodes no tetrahedron uses.
//!
//! Files: `gmsh` parses the text, `topology` orients and builds edges and the surface
//! (in indices), `assemble` runs the checks in order and names faults by file ids and
//! lines, `error` defines the errors, `surface` the boundary surface and its normals,
//! `order` a vertex numbering with locality, `refine` uniform refinement (every
//! tetrahedron into eight, the shape kept).

mod assemble;
mod error;
pub mod generate;
mod gmsh;
mod order;
mod refine;
mod surface;
mod topology;

#[cfg(test)]
mod tests;

pub use error::{BoundaryGap, MeshError, MeshErrorKind, NonManifold, OutOfRange, Syntax};
pub use gmsh::{read_gmsh, read_gmsh_file};
pub use order::reverse_cuthill_mckee;
pub use surface::Surface;

use nalgebra::Point3;

/// A tetrahedral volume mesh with positively oriented elements.
#[derive(Clone, Debug, PartialEq)]
pub struct TetMesh {
    /// Rest positions, one per vertex.
    pub positions: Vec<Point3<f64>>,
    /// The file's id of each vertex (Gmsh node number).
    pub node_ids: Vec<u64>,
    /// Each vertex's index in the file's node list: `0..n` in order as read, another
    /// permutation after [`TetMesh::renumbered`] (how scenes' `fixed.nodes`, given in
    /// file order, find their vertices).
    pub file_index: Vec<u32>,
    /// Tetrahedra as vertex indices, each positively oriented.
    pub tets: Vec<[u32; 4]>,
    /// The physical tag of each tetrahedron (Gmsh "reg-phys" in v1, first tag in v2.2);
    /// scenes use it to give regions their own material.
    pub tet_tags: Vec<i32>,
    /// Unique undirected edges of the tetrahedra, each stored `[i, j]` with `i < j`,
    /// sorted lexicographically.
    pub edges: Vec<[u32; 2]>,
    /// The outward boundary surface.
    pub surface: Surface,
}

impl TetMesh {
    /// Builds a mesh from vertex positions and tetrahedra given in memory (e.g. a
    /// generated test body), with the same checks and orientation normalisation as a
    /// file. Node ids are `1..=n` and element ids `1..=m` in the given order (errors
    /// name them so); tags are 0.
    ///
    /// # Errors
    ///
    /// As [`read_gmsh`] (without line numbers), plus
    /// [`OutOfRange::VertexIndex`] for a vertex index past `positions`.
    pub fn from_tets(positions: Vec<Point3<f64>>, tets: Vec<[u32; 4]>) -> Result<Self, MeshError> {
        const SOURCE: &str = "(mesh in memory)";
        let raw = assemble::RawMesh {
            node_ids: (1..=positions.len() as u64).collect(),
            element_ids: (1..=tets.len() as u64).collect(),
            tet_tags: vec![0; tets.len()],
            positions,
            tets,
            ..Default::default()
        };
        raw.check_indices_and_coordinates(SOURCE)?;
        raw.into_mesh(SOURCE)
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Multiplies every coordinate by `factor` (file units → metres) and recomputes the
    /// surface normals. `factor` must be finite and positive; callers validate it.
    pub fn scale(&mut self, factor: f64) {
        for p in &mut self.positions {
            *p = Point3::from(p.coords * factor);
        }
        self.surface.update_normals(&self.positions);
    }

    /// Six times the signed volume of tetrahedron `t` at the given positions.
    pub fn six_volume(positions: &[Point3<f64>], t: [u32; 4]) -> f64 {
        let [a, b, c, d] = t.map(|i| positions[i as usize]);
        (b - a).dot(&(c - a).cross(&(d - a)))
    }

    /// Volume of the mesh at the given positions (the sum of the signed tetrahedron
    /// volumes).
    pub fn volume(&self, positions: &[Point3<f64>]) -> f64 {
        self.tets
            .iter()
            .map(|&t| Self::six_volume(positions, t))
            .sum::<f64>()
            / 6.0
    }

    /// Axis-aligned bounding box `(min, max)` of the rest positions.
    pub fn bounding_box(&self) -> (Point3<f64>, Point3<f64>) {
        let mut lo = Point3::from([f64::INFINITY; 3]);
        let mut hi = Point3::from([f64::NEG_INFINITY; 3]);
        for p in &self.positions {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        (lo, hi)
    }
}
