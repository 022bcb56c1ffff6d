//! The boundary surface of a tetrahedral mesh.

use nalgebra::{Point3, Vector3};

/// The outward boundary surface of a [`super::TetMesh`]: the tetrahedron faces that
/// belong to exactly one tetrahedron, oriented so that their normals point out of the
/// volume. Indices are *volume* vertex indices, so surface positions are read directly
/// from the simulation state.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Surface {
    /// Boundary triangles `[a, b, c]`, counter-clockwise seen from outside:
    /// `(b − a) × (c − a)` points out of the volume.
    pub triangles: Vec<[u32; 3]>,
    /// Volume indices of the vertices on the surface, sorted ascending.
    pub vertices: Vec<u32>,
    /// Unit outward normal at each surface vertex (same order as `vertices`): the
    /// angle-weighted average of the adjacent triangle normals.
    pub vertex_normals: Vec<Vector3<f64>>,
    /// Unique surface edges `[i, j]` with `i < j` (volume indices), sorted.
    pub edges: Vec<[u32; 2]>,
    /// For each triangle, the triangle across each of its edges: entry `k` is the
    /// neighbour across edge `(tri[k], tri[(k + 1) % 3])`.
    pub triangle_neighbours: Vec<[u32; 3]>,
    /// Triangles around each surface vertex (same order as `vertices`), as a CSR list:
    /// the triangles of surface vertex `s` are
    /// `vertex_triangles[vertex_triangle_offsets[s]..vertex_triangle_offsets[s + 1]]`,
    /// listed in fan order: counter-clockwise around the vertex seen from outside, each
    /// triangle sharing an edge with the next (and the last with the first).
    pub vertex_triangle_offsets: Vec<u32>,
    pub vertex_triangles: Vec<u32>,
    /// For each *volume* vertex, its slot in `vertices` (and so in `vertex_normals` and
    /// the CSR lists), or `u32::MAX` for an interior vertex.
    pub surface_index: Vec<u32>,
    /// For each triangle, the index of the tetrahedron it is a face of.
    pub triangle_tets: Vec<u32>,
    /// For each triangle, the physical tag of the surface triangle the file declares
    /// for it (Gmsh type 2 elements, e.g. a "fixed" patch), or 0 when the file declares
    /// no surface triangles.
    pub triangle_tags: Vec<i32>,
}

impl Surface {
    /// Recomputes `vertex_normals` from the given volume positions (the rest positions,
    /// or the deformed ones of the current tick).
    ///
    /// Each vertex normal is the normalised sum of the unit normals of its triangles,
    /// each weighted by the triangle's corner angle at the vertex. Angle weights make the
    /// normal a property of the surface's shape, independent of how it is triangulated
    /// (area or uniform weights are not). A triangle of zero area adds nothing; a vertex
    /// whose triangles all have zero area gets a zero normal.
    ///
    /// Allocation-free, so it can run every tick. `positions` must cover every vertex
    /// index used by the triangles.
    pub fn update_normals(&mut self, positions: &[Point3<f64>]) {
        self.vertex_normals.fill(Vector3::zeros());
        for tri in &self.triangles {
            if let Some((normal, angles)) = corner_weights(tri, positions) {
                for k in 0..3 {
                    let slot = self.surface_index[tri[k] as usize] as usize;
                    self.vertex_normals[slot] += normal * angles[k];
                }
            }
        }
        for n in &mut self.vertex_normals {
            let length = n.norm();
            if length > 0.0 {
                *n /= length;
            }
        }
    }

    /// The slot of volume vertex `v` in `vertices` (and `vertex_normals`), if it is on
    /// the surface.
    /// The unit outward normal at surface vertex `v` for the given positions (the
    /// angle-weighted average over its fan, as [`Self::update_normals`]), computed
    /// from its own triangles only; zero if `v` is not on the surface or its fan is
    /// degenerate.
    pub fn vertex_normal(&self, v: u32, positions: &[Point3<f64>]) -> Vector3<f64> {
        let Some(s) = self.slot(v) else {
            return Vector3::zeros();
        };
        let mut n = Vector3::zeros();
        for &t in self.triangles_around(s) {
            let tri = &self.triangles[t as usize];
            if let Some((normal, angles)) = corner_weights(tri, positions) {
                let k = tri
                    .iter()
                    .position(|&w| w == v)
                    .expect("a fan triangle holds its vertex");
                n += normal * angles[k];
            }
        }
        n.try_normalize(0.0).unwrap_or_else(Vector3::zeros)
    }

    pub fn slot(&self, v: u32) -> Option<usize> {
        match self.surface_index.get(v as usize) {
            Some(&s) if s != u32::MAX => Some(s as usize),
            _ => None,
        }
    }

    /// The triangles around surface slot `s`, in fan order.
    pub fn triangles_around(&self, s: usize) -> &[u32] {
        let range =
            self.vertex_triangle_offsets[s] as usize..self.vertex_triangle_offsets[s + 1] as usize;
        &self.vertex_triangles[range]
    }
}

/// The unit normal of a triangle and the angle at each of its corners, or `None` if it
/// is degenerate. Weighting by the corner angle makes a vertex normal independent of
/// how its fan is triangulated.
fn corner_weights(tri: &[u32; 3], positions: &[Point3<f64>]) -> Option<(Vector3<f64>, [f64; 3])> {
    let p = tri.map(|v| positions[v as usize]);
    let cross = (p[1] - p[0]).cross(&(p[2] - p[0]));
    let double_area = cross.norm();
    if !(double_area.is_finite() && double_area > 0.0) {
        return None;
    }
    // |u × w| is twice the area at every corner, so the corner angle is
    // atan2(2A, u · w): accurate for small and obtuse angles alike.
    let angles =
        [0, 1, 2].map(|k| double_area.atan2((p[(k + 1) % 3] - p[k]).dot(&(p[(k + 2) % 3] - p[k]))));
    Some((cross / double_area, angles))
}
