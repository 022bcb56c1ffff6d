//! Uniform refinement: every tetrahedron split into eight, every surface triangle
//! into four, the shape unchanged.
//!
//! A new vertex goes at the midpoint of every edge. Each tetrahedron `0123` keeps
//! four corner children, `[0, m01, m02, m03]` and its like at `1`, `2`, `3`, each
//! similar to the parent at half its size; what is left is the octahedron of the six
//! midpoints, cut along one of its three diagonals `m01–m23`, `m02–m13`, `m03–m12`
//! into four tetrahedra around it. The shortest diagonal is taken, the usual choice
//! for well-shaped children; the corner children are similar to their parent. The
//! tests check that no child is worse than the worst parent, through two
//! refinements of SOFA's liver. The octahedron lies inside its parent, so each
//! tetrahedron's choice is its own and the children of neighbours still share whole
//! faces: each face of a parent is split by its three edge midpoints into the same
//! four triangles from either side.
//!
//! Every new point lies on a parent's edge, so the refined body has the parent's
//! surface exactly (each surface triangle split into four coplanar ones), its volume,
//! and on each parent the same affine fields: a coarse liver refined is the same
//! liver with more freedom, which is what a mesh-convergence study of it needs.
//!
//! Numbering: the parent's vertices keep their indices, ids and places in the file
//! (so a scene's `fixed.nodes` in file order still finds them), and edge `e` of the
//! parent's sorted [`edges`](TetMesh::edges) gives vertex `n + e`. Children keep
//! their parent's physical tag; a declared surface triangle's children keep its tag.

use nalgebra::Point3;

use super::TetMesh;
use super::assemble::{DeclaredTriangle, RawMesh};
use super::error::MeshError;

impl TetMesh {
    /// This mesh with every tetrahedron split into eight (see the module doc):
    /// `n + E` vertices for `n` vertices and `E` edges, `8 m` tetrahedra, `4 t`
    /// surface triangles.
    ///
    /// # Errors
    ///
    /// The children of a tetrahedron fill it and their boundary is its boundary
    /// split, so the result passes every check a loaded mesh passed, but one: a
    /// child's flatness `6V / L³` is at least an eighth of its parent's (`V/8`, and no
    /// edge longer than the parent's longest), so a parent within a factor 8 of
    /// `FLAT_TOLERANCE` (`topology.rs`) can have children flat by that test.
    /// Errors name a child by its parent: the parent's position among this mesh's
    /// tetrahedra, from 1.
    pub fn refined(&self) -> Result<TetMesh, MeshError> {
        let n = self.vertex_count() as u32;
        let mid = |a: u32, b: u32| -> u32 {
            let key = [a.min(b), a.max(b)];
            let e = self
                .edges
                .binary_search(&key)
                .expect("every edge of a tetrahedron is in the edge list");
            n + e as u32
        };
        let mut positions = self.positions.clone();
        positions.extend(self.edges.iter().map(|&[a, b]| {
            Point3::from(
                (self.positions[a as usize].coords + self.positions[b as usize].coords) / 2.0,
            )
        }));
        let mut tets = Vec::with_capacity(8 * self.tets.len());
        let mut tet_tags = Vec::with_capacity(8 * self.tets.len());
        for (&[v0, v1, v2, v3], &tag) in self.tets.iter().zip(&self.tet_tags) {
            let (m01, m02, m03) = (mid(v0, v1), mid(v0, v2), mid(v0, v3));
            let (m12, m13, m23) = (mid(v1, v2), mid(v1, v3), mid(v2, v3));
            tets.extend([
                [v0, m01, m02, m03],
                [m01, v1, m12, m13],
                [m02, m12, v2, m23],
                [m03, m13, m23, v3],
            ]);
            // Each diagonal with the cycle of the other four midpoints around it
            // (consecutive ones share a parent vertex, so they bound a face of the
            // octahedron together with either end of the diagonal).
            let cuts = [
                ([m01, m23], [m02, m03, m13, m12]),
                ([m02, m13], [m01, m03, m23, m12]),
                ([m03, m12], [m01, m02, m23, m13]),
            ];
            let length =
                |[a, b]: [u32; 2]| (positions[a as usize] - positions[b as usize]).norm_squared();
            let ([a, b], ring) = cuts
                .into_iter()
                .min_by(|x, y| length(x.0).total_cmp(&length(y.0)))
                .expect("three diagonals");
            for k in 0..4 {
                tets.push([a, b, ring[k], ring[(k + 1) % 4]]);
            }
            tet_tags.extend([tag; 8]);
        }
        let triangles = &self.surface.triangles;
        let declared = triangles
            .iter()
            .zip(&self.surface.triangle_tags)
            .filter(|&(_, &tag)| tag != 0)
            .flat_map(|(&[a, b, c], &tag)| {
                let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
                [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]].map(|nodes| {
                    DeclaredTriangle {
                        nodes,
                        tag,
                        element: 0,
                        line: None,
                    }
                })
            })
            .collect();
        let first_new_id = self.node_ids.iter().max().map_or(1, |&id| id + 1);
        let raw = RawMesh {
            node_ids: self
                .node_ids
                .iter()
                .copied()
                .chain((0..self.edges.len() as u64).map(|e| first_new_id + e))
                .collect(),
            // Each child is named by its parent (eight children a parent, in order).
            element_ids: (0..tets.len() as u64).map(|i| i / 8 + 1).collect(),
            tet_tags,
            positions,
            tets,
            declared,
            ..Default::default()
        };
        let mut refined = raw.into_mesh("(refined mesh)")?;
        let files = self.file_index.iter().copied().max().map_or(0, |i| i + 1);
        refined.file_index = self
            .file_index
            .iter()
            .copied()
            .chain((0..self.edges.len() as u32).map(|e| files + e))
            .collect();
        Ok(refined)
    }
}
