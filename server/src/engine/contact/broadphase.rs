//! Broad phase: which surface triangles may meet an instrument during a tick.
//!
//! A bounding-volume hierarchy (parry's [`Bvh`]) over the surface triangles, one leaf
//! per triangle, each leaf boxing the triangle at both its previous and its current
//! positions — its sweep over the tick, since the mesh moves linearly between the two
//! in the paper's model. A query with the box swept by the instrument returns every
//! triangle whose swept box meets it, so a fast instrument or a fast-moving liver cannot
//! slip between two ticks unseen.
//!
//! The leaves are loose, so that a tick does not box every triangle again. Each
//! surface vertex keeps a box `B_v` around its sweep `S_v` (the box of its previous and
//! current positions) with `S_v ⊆ B_v ⊆ S_v ⊕ 2m`, `⊕` growing a box by a margin on
//! every side and `m` a tenth of the mean surface edge ([`BroadPhase::margin`]); a
//! triangle's leaf is the union of its vertices' `B_v`. An update checks the
//! invariant vertex by vertex and, where it fails, sets `B_v = S_v ⊕ m` and refits the
//! triangles around `v` alone: tissue that did not move costs one check per vertex.
//! So a leaf holds its triangle's swept box (no triangle that meets a query is
//! missed) and lies within `2m` of it (a query returns only triangles whose swept box
//! comes within `2m` of it; the narrow phase tests the geometry itself).
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

    /// Whether `other` lies inside this box (closed boxes: touching counts; an empty
    /// `other` lies inside any box).
    pub fn contains(&self, other: &Box3) -> bool {
        (0..3).all(|a| self.min[a] <= other.min[a] && other.max[a] <= self.max[a])
    }

    fn to_parry(self) -> Aabb {
        Aabb::new(
            GVec::new(self.min.x, self.min.y, self.min.z),
            GVec::new(self.max.x, self.max.y, self.max.z),
        )
    }
}

/// The BVH over the surface triangles' swept boxes, loosened by up to `2m`.
pub struct BroadPhase {
    bvh: Bvh,
    workspace: BvhWorkspace,
    /// `m`, m.
    margin: f64,
    /// `B_v` of each vertex, by mesh index (empty boxes off the surface).
    loose: Vec<Box3>,
    /// Triangles to refit in this update, and a mark per triangle against repeats.
    refit: Vec<u32>,
    marked: Vec<bool>,
}

impl std::fmt::Debug for BroadPhase {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BroadPhase")
            .field("leaves", &self.bvh.leaf_count())
            .field("margin", &self.margin)
            .finish()
    }
}

/// The smallest box holding the three.
fn union(boxes: [Box3; 3]) -> Box3 {
    let [a, b, c] = boxes;
    Box3 {
        min: a.min.inf(&b.min).inf(&c.min),
        max: a.max.sup(&b.max).sup(&c.max),
    }
}

impl BroadPhase {
    /// Builds the hierarchy over the surface at rest.
    pub fn new(surface: &Surface, positions: &[Point3<f64>]) -> Self {
        let (mut length, mut count) = (0.0, 0usize);
        for &[a, b] in &surface.edges {
            let d = (positions[a as usize] - positions[b as usize]).norm();
            if d.is_finite() {
                length += d;
                count += 1;
            }
        }
        let margin = 0.1 * length / count.max(1) as f64;
        let mut loose = vec![Box3::empty(); positions.len()];
        for &v in &surface.vertices {
            let p = positions[v as usize];
            loose[v as usize] = Box3 { min: p, max: p }.inflated(margin);
        }
        let leaves: Vec<Aabb> = surface
            .triangles
            .iter()
            .map(|t| union(t.map(|v| loose[v as usize])).to_parry())
            .collect();
        let mut bp = BroadPhase {
            bvh: Bvh::from_leaves(BvhBuildStrategy::Binned, &leaves),
            workspace: BvhWorkspace::default(),
            margin,
            loose,
            refit: Vec::with_capacity(surface.triangles.len()),
            marked: vec![false; surface.triangles.len()],
        };
        // The first refit sizes the workspace, so later ones do not allocate.
        bp.bvh.refit(&mut bp.workspace);
        bp
    }

    /// `m`: how far a vertex's sweep may move inside its box before the triangles
    /// around it are refitted, m. A tenth of the mean surface edge, so that the extra
    /// triangles a query returns lie within a fifth of an edge of it. Measured with the
    /// bench `contact` (linear model): a quarter of an edge refitted less but gave the
    /// narrow phase a fifth more candidates, which cost more than it saved on SOFA's
    /// coarse liver (shaft 0.0158 → 0.0181 ms); a twentieth saved little more
    /// candidates and refitted more on liver-80k (shaft 0.456 → 0.533 ms).
    pub fn margin(&self) -> f64 {
        self.margin
    }

    /// Makes every leaf hold its triangle's sweep from `previous` to `current` (and
    /// lie within `2m` of it), refitting only the triangles around the vertices whose
    /// sweep left their box or shrank well inside it. Returns how many triangles it
    /// refitted.
    pub fn update(
        &mut self,
        surface: &Surface,
        previous: &[Point3<f64>],
        current: &[Point3<f64>],
    ) -> usize {
        self.refit.clear();
        for (slot, &v) in surface.vertices.iter().enumerate() {
            let vi = v as usize;
            let mut sweep = Box3::empty();
            sweep.cover(&previous[vi]);
            sweep.cover(&current[vi]);
            let b = &mut self.loose[vi];
            if b.contains(&sweep) && sweep.inflated(2.0 * self.margin).contains(b) {
                continue;
            }
            *b = sweep.inflated(self.margin);
            for &t in surface.triangles_around(slot) {
                if !self.marked[t as usize] {
                    self.marked[t as usize] = true;
                    self.refit.push(t);
                }
            }
        }
        for &t in &self.refit {
            self.marked[t as usize] = false;
            let b = union(surface.triangles[t as usize].map(|v| self.loose[v as usize]));
            self.bvh.insert_or_update_partially(b.to_parry(), t, 0.0);
        }
        if !self.refit.is_empty() {
            // The tree's shape is kept and only its boxes refitted: cheaper than
            // `refit`, which also reorders the nodes in memory.
            self.bvh.refit_without_opt();
        }
        self.refit.len()
    }

    /// Appends to `out` the triangles whose swept box meets `query`.
    pub fn query(&self, query: &Box3, out: &mut Vec<u32>) {
        let q = query.to_parry();
        out.extend(self.bvh.intersect_aabb(&q));
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;
    use crate::engine::testing::liver_mesh;

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

    #[test]
    fn a_query_finds_every_swept_triangle_and_none_beyond_twice_the_margin() {
        // Through still, slow, fast and jittered motions, a query returns every
        // triangle whose swept box meets it, and only triangles whose swept box meets
        // it grown by 2m; a motion within the margin refits nothing, a large one every
        // triangle.
        let mesh = liver_mesh();
        let rest = mesh.positions.clone();
        let mut bp = BroadPhase::new(&mesh.surface, &rest);
        let m = bp.margin();
        assert!(m > 0.0);
        let shifted =
            |d: Vector3<f64>| -> Vec<Point3<f64>> { rest.iter().map(|p| p + d).collect() };
        let jittered: Vec<_> = rest
            .iter()
            .enumerate()
            .map(|(i, p)| p + Vector3::new((i as f64).sin(), (i as f64 * 0.7).cos(), 0.3) * m)
            .collect();
        let steps = [
            (rest.clone(), rest.clone(), Some(0)),
            (
                rest.clone(),
                shifted(Vector3::new(0.3, 0.0, 0.0) * m),
                Some(0),
            ),
            (rest.clone(), shifted(Vector3::new(0.3, -0.2, 0.1)), None),
            (shifted(Vector3::new(0.3, -0.2, 0.1)), rest.clone(), None),
            (rest.clone(), jittered.clone(), None),
            (jittered, rest.clone(), None),
            (rest.clone(), rest.clone(), None),
        ];
        let (lo, hi) = mesh.bounding_box();
        for (k, (previous, current, refitted)) in steps.iter().enumerate() {
            let n = bp.update(&mesh.surface, previous, current);
            if let Some(expected) = refitted {
                assert_eq!(n, *expected, "step {k}");
            }
            if k == 2 {
                assert_eq!(n, mesh.surface.triangles.len(), "a move of many edges");
            }
            for q in 0..20 {
                let f = q as f64 / 20.0;
                let c = lo + (hi - lo) * f;
                let query = Box3 {
                    min: c,
                    max: c + Vector3::new(0.5, 0.4, 0.6),
                };
                let mut found = Vec::new();
                bp.query(&query, &mut found);
                found.sort_unstable();
                let meets = |query: &Box3, t: usize| {
                    swept_box(&mesh.surface, t, previous, current).intersects(query)
                };
                for t in 0..mesh.surface.triangles.len() {
                    if meets(&query, t) {
                        assert!(
                            found.binary_search(&(t as u32)).is_ok(),
                            "step {k}, query {q}: {t} missed"
                        );
                    }
                }
                let grown = query.inflated(2.0 * m * (1.0 + 1e-12));
                for &t in &found {
                    assert!(
                        meets(&grown, t as usize),
                        "step {k}, query {q}: {t} too far"
                    );
                }
            }
        }
    }
}
