//! Colliding edges and confidence intervals (paper §2.3–2.4).
//!
//! In the instrument's frame every vertex moves on a straight line over the tick, from
//! `A = R(A_old)` (its previous position carried by the instrument's motion) to `A_new`
//! (where the elastic step put it). An edge that crossed the axis segment during the
//! tick is *colliding* ([`edge_crossing`], eq. 2–5). Each of its vertices gets a
//! *confidence interval* `[t_min, t_max] ⊂ [0, 1]` of its own line in which the edge is
//! still on its original side: `[0, t_c]` if the vertex's motion drove the edge toward
//! the axis ([`closer_to_axis`], eq. 6), `[t_c, 1]` otherwise. A vertex then goes to the
//! middle of the intersection of its intervals.
//!
//! Empty interval: the paper fixes the vertex at one end and recomputes the other
//! vertex's crossing. Here it is put at `t = 0`, its start in the instrument's frame.
//! That is always safe: at `t = 0` every edge is where the previous tick left it
//! relative to the instrument, and the previous tick ended with no edge through the
//! axis. The same fallback closes the stage: every candidate edge is tested again from
//! its start to its new position, and the ends of any edge that still crosses go back
//! to `t = 0`, until none does. Supports (fixed vertices) never move.

use nalgebra::Point3;

use super::crossing::{EdgeEnd, MovingEdge, closer_to_axis, edge_crossing};
use super::pose::InstrumentPose;
use super::scratch::Scratch;

/// Rounds of re-testing after the move; each round only sends vertices back to their
/// start, so it ends, and in practice one round suffices.
const MAX_ROUNDS: usize = 8;

/// The moving edge `(a, b)` from its start (instrument frame) to where it is now.
fn moving(a: u32, b: u32, start: &[Point3<f64>], x: &[Point3<f64>]) -> MovingEdge {
    let (a, b) = (a as usize, b as usize);
    MovingEdge::new(start[a], start[b], x[a] - start[a], x[b] - start[b])
}

/// Finds the colliding edges among the candidates and moves their vertices to the
/// middle of their confidence intervals. Returns the number of colliding edges.
pub(super) fn stop_colliding_edges(
    s: &mut Scratch,
    edges: &[[u32; 2]],
    pose: &InstrumentPose,
    length: f64,
    x: &mut [Point3<f64>],
) -> u32 {
    s.colliding.clear();
    for &e in &s.edges {
        let [a, b] = edges[e as usize];
        if s.fixed[a as usize] && s.fixed[b as usize] {
            continue;
        }
        s.stats.edge_tests += 1;
        if let Some(c) = edge_crossing(&moving(a, b, &s.rel_start, x), pose, length) {
            s.colliding.push((e, c));
        }
    }
    let colliding = s.colliding.len() as u32;
    s.stats.colliding_edges += colliding as u64;
    if colliding == 0 {
        return 0;
    }
    // Intersect the intervals of every vertex of a colliding edge.
    s.interval_vertices.clear();
    for k in 0..s.colliding.len() {
        let (e, c) = s.colliding[k];
        let [a, b] = edges[e as usize];
        let edge = moving(a, b, &s.rel_start, x);
        for (end, v) in [(EdgeEnd::A, a), (EdgeEnd::B, b)] {
            let vi = v as usize;
            if s.fixed[vi] {
                continue;
            }
            if s.interval_mark[vi] != s.gather_mark {
                s.interval_mark[vi] = s.gather_mark;
                s.interval[vi] = [0.0, 1.0];
                s.interval_vertices.push(v);
            }
            let iv = &mut s.interval[vi];
            if closer_to_axis(&edge, end, &c, pose) {
                iv[1] = iv[1].min(c.t);
            } else {
                iv[0] = iv[0].max(c.t);
            }
            if iv[0] > iv[1] {
                *iv = [0.0, 0.0];
            }
        }
    }
    for k in 0..s.interval_vertices.len() {
        let v = s.interval_vertices[k] as usize;
        let [lo, hi] = s.interval[v];
        let t = 0.5 * (lo + hi);
        x[v] = s.rel_start[v] + (x[v] - s.rel_start[v]) * t;
        s.touch(v as u32);
    }
    // Whatever still crosses goes back to its start in the instrument's frame.
    for _ in 0..MAX_ROUNDS {
        let mut clean = true;
        for k in 0..s.edges.len() {
            let [a, b] = edges[s.edges[k] as usize];
            if edge_crossing(&moving(a, b, &s.rel_start, x), pose, length).is_some() {
                for v in [a, b] {
                    if !s.fixed[v as usize] && x[v as usize] != s.rel_start[v as usize] {
                        x[v as usize] = s.rel_start[v as usize];
                        s.touch(v);
                        clean = false;
                    }
                }
            }
        }
        if clean {
            break;
        }
    }
    colliding
}
