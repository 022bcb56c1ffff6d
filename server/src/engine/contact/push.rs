//! Pushing edges and vertices out of the instrument (paper §2.6).
//!
//! The instrument is the set of points within `r` of its axis segment. A vertex closer
//! than `r` goes straight away from its closest axis point to just beyond `r`: at right
//! angles to `Z` along the shaft, radially from the tip beyond it. An edge closer than
//! `r` (its closest point inside) is translated along the common perpendicular by the
//! missing distance. Then each candidate triangle whose interior is still inside is
//! moved out (`faces`). Moving one edge or face can push a neighbour in, so the passes
//! repeat until nothing moves (a few passes).
//!
//! The bound: at most `MAX_PASSES` (16) passes a tick. Every move only takes a point out
//! to `r (1 + PUSH_MARGIN)`, so a pass that moves something leaves less inside; in
//! the property tests the passes settle within a few. Should the bound be reached
//! (neighbours pushing each other in turn around a fold), the tick ends with what the
//! last pass left: every vertex it moved is held there, and the next tick's passes
//! start from it; the depth left is at most what the last pass moved, checked by the
//! invariants after every tick in the tests.
//!
//! A point exactly on the axis has no "away": a vertex at the tip goes ahead of it
//! (`−Z`), one on the shaft goes along its surface normal taken ⊥ `Z`, and an edge
//! through the axis goes along `Z × edge`. Supports never move; an edge with one fixed
//! end moves by its free end, and an edge or triangle with a fixed corner inside the
//! instrument (which no move of its free corners takes out) is left as it is.

use nalgebra::{Point3, Vector3};

use super::closest::{closest_edge_axis, closest_point_axis};
use super::faces::push_faces;
use super::pose::{InstrumentPose, perpendicular};
use super::scratch::Scratch;
use crate::engine::mesh::Surface;

/// Passes over the candidates per tick; they stop as soon as one moves nothing.
const MAX_PASSES: usize = 16;
/// Points are pushed to `r (1 + PUSH_MARGIN)`: 0.5 µm beyond a 5 mm shaft, invisible,
/// and it lets the passes settle from outside — pushing exactly to `r` leaves
/// neighbouring edges and vertices nudging each other back in by rounding and by
/// each other's moves.
pub(super) const PUSH_MARGIN: f64 = 1e-4;
/// A point nearer the axis than this fraction of `r` has no reliable direction away
/// from it and takes the fallback direction.
pub(super) const ON_AXIS: f64 = 1e-9;

/// Pushes the candidate vertices, edges and triangles out of the instrument. Returns
/// whether anything moved.
pub(super) fn push_out(
    s: &mut Scratch,
    surface: &Surface,
    pose: &InstrumentPose,
    radius: f64,
    length: f64,
    x: &mut [Point3<f64>],
) -> bool {
    let z = pose.axis.into_inner();
    let target = radius * (1.0 + PUSH_MARGIN);
    let mut any = false;
    for _ in 0..MAX_PASSES {
        let mut moved = false;
        for k in 0..s.vertices.len() {
            let v = s.vertices[k];
            let vi = v as usize;
            if s.fixed[vi] {
                continue;
            }
            let c = closest_point_axis(&x[vi], pose, length);
            let d = c.distance();
            if d >= radius {
                continue;
            }
            let dir = if d > ON_AXIS * radius {
                c.offset / d
            } else if c.beta <= 0.0 {
                -z
            } else {
                let n = surface.vertex_normal(v, x);
                pose.across(&n)
                    .try_normalize(1e-6)
                    .unwrap_or_else(|| perpendicular(&z).into_inner())
            };
            x[vi] = c.on_axis + dir * target;
            s.touch(v);
            moved = true;
        }
        for k in 0..s.edges.len() {
            let [a, b] = surface.edges[s.edges[k] as usize];
            let (ai, bi) = (a as usize, b as usize);
            if s.fixed[ai] && s.fixed[bi] {
                continue;
            }
            let c = closest_edge_axis(&x[ai], &x[bi], pose, length);
            let d = c.distance();
            if d >= radius {
                continue;
            }
            let dir: Vector3<f64> = if d > ON_AXIS * radius {
                c.offset() / d
            } else {
                z.cross(&(x[bi] - x[ai]))
                    .try_normalize(1e-12)
                    .unwrap_or_else(|| perpendicular(&z).into_inner())
            };
            // Translate the edge so its closest point reaches r; with one end fixed the
            // free end alone moves, by the missing distance over its weight there.
            let missing = target - d;
            let (wa, wb) = (1.0 - c.alpha, c.alpha);
            // A fixed end inside the instrument keeps the edge inside however far
            // the free end goes: once the free end is out, moving it on by up to
            // twice the missing clearance only flings it, pass after pass and tick
            // after tick. A tip of 1 cm radius pressed down through the default
            // liver's supported upper face threw a vertex 0.31 m; a 7 cm one pressed
            // into its front, wider than the free band between its supports, sent
            // one past 100 m within 12 ticks (`tests/contact_hard_cases.rs`). Such
            // an edge is left as it is; its free end, if inside, is the vertex
            // push's.
            let inside = |v: usize| closest_point_axis(&x[v], pose, length).distance() < radius;
            let anchored = match (s.fixed[ai], s.fixed[bi]) {
                (true, false) => inside(ai) && !inside(bi),
                (false, true) => inside(bi) && !inside(ai),
                _ => false,
            };
            if anchored {
                continue;
            }
            let (ma, mb) = match (s.fixed[ai], s.fixed[bi]) {
                (false, false) => (missing, missing),
                (true, false) => (0.0, missing / wb.max(0.5)),
                (false, true) => (missing / wa.max(0.5), 0.0),
                (true, true) => unreachable!("skipped above"),
            };
            if ma > 0.0 {
                x[ai] += dir * ma;
                s.touch(a);
            }
            if mb > 0.0 {
                x[bi] += dir * mb;
                s.touch(b);
            }
            moved = true;
        }
        moved |= push_faces(s, surface, pose, radius, length, x);
        any |= moved;
        if !moved {
            break;
        }
    }
    any
}
