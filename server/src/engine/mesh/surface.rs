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
            let p = tri.map(|v| positions[v as usize]);
            let cross = (p[1] - p[0]).cross(&(p[2] - p[0]));
            let double_area = cross.norm();
            if !(double_area.is_finite() && double_area > 0.0) {
                continue;
            }
            let normal = cross / double_area;
            for k in 0..3 {
                let u = p[(k + 1) % 3] - p[k];
                let w = p[(k + 2) % 3] - p[k];
                // |u × w| is twice the area at every corner, so the corner angle is
                // atan2(2A, u · w): accurate for small and obtuse angles alike.
                let angle = double_area.atan2(u.dot(&w));
                let slot = self.surface_index[tri[k] as usize] as usize;
                self.vertex_normals[slot] += normal * angle;
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
