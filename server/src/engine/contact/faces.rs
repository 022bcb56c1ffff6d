//! Faces out of the instrument: the interior of a surface triangle, not only its
//! vertices and edges, stays outside the capsule.
//!
//! The vertex and edge pushes of §2.6 see a triangle only through its corners and
//! sides. On a coarse mesh a triangle is larger than the instrument (11 mm edges on
//! SOFA's liver for a 5 mm shaft), so the shaft can sink into the middle of one by up
//! to its full radius with every corner and side outside; and an instrument that first
//! appears inside the liver can have its axis through a triangle whose sides are all
//! beyond its reach. Here every candidate triangle is tested whole
//! ([`closest_triangle_axis`]) and moved out when its deepest point is inside.
//!
//! The correction. The triangle's point `x = Σ wᵢ xᵢ` (barycentric `wᵢ`) closest to
//! the axis is at distance `d < r`; it must move by `δ = (r' − d) û`, `û` from the axis
//! to the point and `r' = r (1 + margin)` as for the pushes. Moving vertex `i` by
//! `wᵢ δ / Σⱼ wⱼ²` moves the point by `Σᵢ wᵢ² δ / Σⱼ wⱼ² = δ`, and among all vertex
//! moves that move the point by `δ` it is the one of least `Σ |Δxᵢ|²` (the minimum-norm
//! solution of `Σ wᵢ Δxᵢ = δ`). Supports do not move: the sums run over the free
//! vertices only, so the point still moves by `δ`, unless that would move a free
//! vertex more than [`MAX_LEVER`] times as far: then the point is all but on the
//! supports and the triangle is left. At the centroid every vertex moves
//! by `δ` (a translation); at a corner only that corner moves, as the vertex push
//! would.
//!
//! The side. When the axis passes through the triangle (`d = 0`, the instrument's
//! first pose inside the liver, or a triangle the tip press left because it is seen
//! edge-on) there is no "away from the axis". The instrument belongs on the outward
//! side of the surface (triangles are wound with their normal `n` out of the tissue)
//! and came in from its handle, outside the body; so the triangle goes to its own
//! tissue side, along `−n`, far enough that the capsule's part below its plane is
//! cleared: the axis point in the plane is at `β`, the tip is `β (n·Z)` below it and
//! the capsule reaches `r` further, so the move is `r' + β (n·Z)`. A triangle whose
//! normal faces the tip (`n·Z ≤ 0`) has the handle on its tissue side: the shaft goes
//! through a second lobe, which no push of one triangle clears (moving it `r'` a
//! pass sent it 8 cm in 16 passes); it is left as it is, and a pose that enters from
//! outside, as through a trocar, never has one.
//!
//! A triangle with a support inside the instrument (a tip pressed into a supported
//! face) stays inside whatever its free corners do; moving them would fling them pass
//! after pass, as for such an edge (`push`), so it is left as it is.
//!
//! A move tilts the triangle, and one triangle's move can bring a neighbour in, so
//! this runs inside the passes of the push-out, which repeat until nothing moves.

use nalgebra::{Point3, Vector3};

use super::closest::{closest_point_axis, closest_triangle_axis};
use super::pose::InstrumentPose;
use super::push::{ON_AXIS, PUSH_MARGIN};
use super::scratch::Scratch;
use crate::engine::mesh::Surface;

/// The largest lever of the least-norm move: how far a free vertex may move per unit
/// of the triangle point's move, `wᵢ / Σⱼ wⱼ²`. It is 1 at a free corner and at the
/// centroid of a free triangle, 3 at the centroid of a triangle with two supports,
/// and grows without bound as the point nears the supports: a point at `wᵢ = 10⁻⁶`
/// from a supported side needs its one free corner moved a million times as far.
/// An instrument whose shaft passed through the liver beside its supports and then
/// turned drove a triangle there: each push-out pass flung its free corner by the
/// lever times the radius, and the tissue went 6 km in one tick, with forces of
/// meganewtons (`tests/contact_hard_cases.rs`). Beyond this lever the point is,
/// within a tenth of the triangle, on the supports, which the tissue cannot be
/// moved off: the triangle is left as it is, as one all on supports is.
const MAX_LEVER: f64 = 10.0;

/// Moves the candidate triangles that come within `radius` of the axis out to
/// `r (1 + PUSH_MARGIN)` from it. Returns whether anything moved.
pub(super) fn push_faces(
    s: &mut Scratch,
    surface: &Surface,
    pose: &InstrumentPose,
    radius: f64,
    length: f64,
    x: &mut [Point3<f64>],
) -> bool {
    let z = pose.axis.into_inner();
    let target = radius * (1.0 + PUSH_MARGIN);
    let mut moved = false;
    for k in 0..s.triangles.len() {
        let tri = surface.triangles[s.triangles[k] as usize];
        let free = tri.map(|v| !s.fixed[v as usize]);
        if !free.iter().any(|&f| f) {
            continue;
        }
        let p = tri.map(|v| x[v as usize]);
        // Most candidates are nowhere near: every point of the triangle is within `ρ`
        // of its centroid, so one whose centroid is `r + ρ` from the axis is out.
        let centroid = Point3::from((p[0].coords + p[1].coords + p[2].coords) / 3.0);
        let rho = p
            .iter()
            .map(|q| (q - centroid).norm_squared())
            .fold(0.0, f64::max)
            .sqrt();
        if closest_point_axis(&centroid, pose, length).distance() >= radius + rho {
            continue;
        }
        let c = closest_triangle_axis(&p, pose, length);
        let d = c.distance();
        if d >= radius {
            continue;
        }
        // A support inside the instrument: left as it is (see the module notes).
        if (0..3).any(|i| !free[i] && closest_point_axis(&p[i], pose, length).distance() < radius) {
            continue;
        }
        let delta: Vector3<f64> = if d > ON_AXIS * radius {
            c.offset() * ((target - d) / d)
        } else {
            let Some(n) = (p[1] - p[0]).cross(&(p[2] - p[0])).try_normalize(0.0) else {
                // Zero area: its edges are the edge push's.
                continue;
            };
            let nz = n.dot(&z);
            if nz <= 0.0 {
                continue;
            }
            -n * (target + c.beta * nz)
        };
        let w = c.barycentric;
        let norm: f64 = (0..3).filter(|&i| free[i]).map(|i| w[i] * w[i]).sum();
        let lever = (0..3)
            .filter(|&i| free[i])
            .map(|i| w[i])
            .fold(0.0, f64::max);
        // False as well for a point all on supports (`norm = 0`) and for NaN.
        let movable = norm > 0.0 && lever <= MAX_LEVER * norm;
        if !movable {
            continue;
        }
        for i in 0..3 {
            if free[i] && w[i] > 0.0 {
                x[tri[i] as usize] += delta * (w[i] / norm);
                s.touch(tri[i]);
            }
        }
        moved = true;
    }
    moved
}
