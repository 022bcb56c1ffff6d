//! Broad phase: which surface triangles may meet an instrument during a tick.
//!
//! A bounding-volume hierarchy (parry's [`Bvh`]) over the surface triangles, one leaf
//! per triangle, each leaf boxing the triangle at both its previous and its current
//! positions — its sweep over the tick, since the mesh moves linearly between the two
//! in the paper's model. A query with the box swept by the instrument returns every
//! triangle whose swept box meets it, so a fast instrument or a fast-moving liver cannot
//! slip between two ticks unseen.
//!
//! parry speaks glam; positions are converted here, at the module's edge.

use nalgebra::Point3;
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector as GVec;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy, BvhWorkspace};

use crate::engine::mesh::Surface;

/// An axis-aligned box in nalgebra terms, m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Box3 {
    pub min: Point3<f64>,
    pub max: Point3<f64>,
}

impl Box3 {
    /// The empty box (grows to cover the first point added).
    pub fn empty() -> Self {
        Box3 {
            min: Point3::from([f64::INFINITY; 3]),
            max: Point3::from([f64::NEG_INFINITY; 3]),
        }
    }

    /// Grows the box to cover `p`.
    pub fn cover(&mut self, p: &Point3<f64>) {
        self.min = self.min.inf(p);
        self.max = self.max.sup(p);
    }

    /// The box grown by `margin` on every side.
    pub fn inflated(&self, margin: f64) -> Self {
        let m = nalgebra::Vector3::repeat(margin);
        Box3 {
            min: self.min - m,
            max: self.max + m,
        }
    }

    /// Whether two boxes overlap (closed boxes: touching counts).
    pub fn intersects(&self, other: &Box3) -> bool {
        (0..3).all(|a| self.min[a] <= other.max[a] && other.min[a] <= self.max[a])
    }

    fn to_parry(self) -> Aabb {
        Aabb::new(
            GVec::new(self.min.x, self.min.y, self.min.z),
            GVec::new(self.max.x, self.max.y, self.max.z),
        )
    }
}

/// The BVH over the surface triangles' swept boxes.
pub struct BroadPhase {
    bvh: Bvh,
    workspace: BvhWorkspace,
}

impl std::fmt::Debug for BroadPhase {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BroadPhase")
            .field("leaves", &self.bvh.leaf_count())
            .finish()
    }
}

/// The box swept by triangle `t` between two position sets.
fn swept_box(
    surface: &Surface,
    t: usize,
    previous: &[Point3<f64>],
    current: &[Point3<f64>],
) -> Box3 {
    let mut b = Box3::empty();
    for &v in &surface.triangles[t] {
        b.cover(&previous[v as usize]);
        b.cover(&current[v as usize]);
    }
    b
}

impl BroadPhase {
    /// Builds the hierarchy over the surface at rest.
    pub fn new(surface: &Surface, positions: &[Point3<f64>]) -> Self {
        let leaves: Vec<Aabb> = (0..surface.triangles.len())
            .map(|t| swept_box(surface, t, positions, positions).to_parry())
            .collect();
        let mut bp = BroadPhase {
            bvh: Bvh::from_leaves(BvhBuildStrategy::Binned, &leaves),
            workspace: BvhWorkspace::default(),
        };
        // The first refit sizes the workspace, so later ones do not allocate.
        bp.bvh.refit(&mut bp.workspace);
        bp
    }

    /// Refits every leaf to its triangle's sweep from `previous` to `current`.
    pub fn update(&mut self, surface: &Surface, previous: &[Point3<f64>], current: &[Point3<f64>]) {
        for t in 0..surface.triangles.len() {
            let b = swept_box(surface, t, previous, current).to_parry();
            self.bvh.insert_or_update_partially(b, t as u32, 0.0);
        }
        // The tree's shape is kept and only its boxes refitted: cheaper than `refit`,
        // which also reorders the nodes in memory.
        self.bvh.refit_without_opt();
    }

    /// Appends to `out` the triangles whose swept box meets `query`.
    pub fn query(&self, query: &Box3, out: &mut Vec<u32>) {
        let q = query.to_parry();
        out.extend(self.bvh.intersect_aabb(&q));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::testing::liver_mesh;

    #[test]
    fn query_finds_exactly_the_triangles_whose_swept_box_meets_it() {
        let mesh = liver_mesh();
        let rest = mesh.positions.clone();
        let moved: Vec<_> = rest
            .iter()
            .map(|p| p + nalgebra::Vector3::new(0.3, -0.2, 0.1))
            .collect();
        let mut bp = BroadPhase::new(&mesh.surface, &rest);
        bp.update(&mesh.surface, &rest, &moved);
        let (lo, hi) = mesh.bounding_box();
        for k in 0..20 {
            let f = k as f64 / 20.0;
            let c = lo + (hi - lo) * f;
            let query = Box3 {
                min: c,
                max: c + nalgebra::Vector3::new(0.5, 0.4, 0.6),
            };
            let mut found = Vec::new();
            bp.query(&query, &mut found);
            found.sort_unstable();
            let brute: Vec<u32> = (0..mesh.surface.triangles.len())
                .filter(|&t| swept_box(&mesh.surface, t, &rest, &moved).intersects(&query))
                .map(|t| t as u32)
                .collect();
            assert_eq!(found, brute, "query {k}");
        }
    }
}
