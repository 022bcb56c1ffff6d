//! The contact stage of a tick: per instrument, colliding edges → confidence intervals
//! → tip → push-out → which vertices the instrument holds.
//!
//! Around the elastic step:
//! - [`ContactStage::carry_held_vertices`]: the vertices an instrument holds follow
//!   its rigid motion `R` (eq. 1) — their imposed targets become `R(x)` — and the
//!   tick's start positions are kept;
//! - the integrator advances the liver with those vertices imposed (free motion);
//! - [`ContactStage::resolve_contact`]: for each instrument in turn, the steps of
//!   §2.3–2.6 on the surface seen from the instrument, then the hold/release decision,
//!   then, unless the scene turns it off (`contact.settle`), the free tissue around the
//!   vertices the steps jumped is settled with them (`settle`: without it the
//!   first-contact tick's reaction is that of one vertex displaced against fixed
//!   neighbours, up to 49× the steady force), and what the settled tissue then pulls
//!   away from its instrument is let go and the tissue relaxed around it
//!   (`release_pulled`), then one more
//!   push-out pass for every instrument so that a vertex pushed by one, or moved by
//!   the settling, is not left inside another.
//!
//! Holding and release. A vertex the stage moved is held: imposed on the elastic model
//! at that position, so the deformation spreads into the liver. A held vertex the stage
//! did not move this tick stays held while the tissue presses it against the
//! instrument and is released when the tissue pulls it away: when its elastic reaction
//! `−(K u)_i` has a positive component along the direction from the axis to the
//! vertex. That is a unilateral contact: the instrument pushes, it never pulls, and
//! when it withdraws the tissue relaxes. The instrument's normal at a held vertex is
//! the tip's end for a vertex beyond the tip or laid on the tip plane beside the shaft,
//! else the radial direction (see `hold::contact_normal`). A held vertex moves at the
//! instrument's velocity; the stage's jumps are corrections of position, not motion.
//!
//! Friction. A held vertex dragged harder than `μ N` slides along the instrument; the
//! slide is made at the next tick, both in its imposed target and in where the contact
//! steps start it, so that it stays slid and a held instrument brings the tissue to
//! equilibrium.
//!
//! Why no marching from triangle to triangle (§2.3): the broad phase already returns
//! every triangle whose motion in the instrument's frame comes within `r` of the axis
//! segment, so every edge that can have crossed it is tested, at any speed. That is how
//! this stage does not tunnel: an instrument crossing the whole liver in one tick finds
//! every edge it crossed and stops each at its confidence interval.

use nalgebra::{Point3, Vector3};

use super::broadphase::{Box3, BroadPhase};
use super::edges::stop_colliding_edges;
use super::hold::contact_normal;
use super::instrument::Instrument;
use super::pose::{InstrumentPose, rigid_motion};
use super::push::push_out;
use super::scratch::{ContactStats, Scratch};
use super::settle::Settle;
use super::tip::{Reach, nearest_point, press_tip};
use crate::engine::elastic::{BlockMatrix, ElasticModel};
use crate::engine::integrate::{Imposed, State};
use crate::engine::mesh::Surface;
use holding::let_go;
use settling::Settled;

mod holding;
mod reaction;
mod settling;

/// The contact stage of a scene with instruments.
#[derive(Debug)]
pub struct ContactStage {
    broadphase: Vec<BroadPhase>,
    /// The three surface edges of each surface triangle.
    triangle_edges: Vec<[u32; 3]>,
    /// Surface positions at the start of the tick.
    start: Vec<Point3<f64>>,
    /// Where the elastic step put the surface vertices (the end of their free motion).
    end: Vec<Point3<f64>>,
    /// Surface positions after the last sub-move.
    current: Vec<Point3<f64>>,
    /// Bit `k` set: held by instrument `k`.
    holders: Vec<u8>,
    /// How far each held vertex slips at the next tick (Coulomb friction), m.
    slide: Vec<Vector3<f64>>,
    /// The slide being applied this tick, taken from `slide` when held vertices are
    /// carried: part of where a held vertex starts the contact steps, so that a slip
    /// stays slipped instead of being put back at the tick's start.
    slid: Vec<Vector3<f64>>,
    /// The vertices the stage jumped this tick, for the settling.
    jumped: Vec<u32>,
    /// The held vertices let go after the settling, for its relaxation.
    released: Vec<u32>,
    /// The tissue's reaction on each of an instrument's held vertices, in the order
    /// of its `held`, while the settled tissue's pull is judged (`release_pulled`).
    reactions: Vec<Vector3<f64>>,
    /// The settling's buffers, unless the scene turns it off (`contact.settle`).
    settle: Option<Settle>,
    /// Whether the tip's reactions are scaled to its own footprint (`footprint`).
    footprint: bool,
    s: Scratch,
}

/// Rounds of the last pass over several instruments: it repeats until a round moves
/// nothing, since the last instrument's push can put a vertex back into the first.
const FINAL_ROUNDS: usize = 4;

/// Speed of a hand moving an instrument briskly, m/s: the approach reach of the tip is
/// `r` plus how far the tip goes at this speed in two ticks (the local model is used
/// until the next one arrives, one tick later, and is one tick old when it does), so
/// that a force loop has the tissue's plane before the tip reaches it.
pub const APPROACH_SPEED: f64 = 0.5;

/// Instruments a stage handles: one bit each in `holders`.
pub const MAX_INSTRUMENTS: usize = 8;

impl ContactStage {
    /// A stage for `instruments` on the surface of a mesh whose vertices `fixed` are
    /// supports.
    pub fn new(surface: &Surface, rest: &[Point3<f64>], fixed: &[u32], instruments: usize) -> Self {
        assert!(
            instruments <= MAX_INSTRUMENTS,
            "the scene checks the instrument count"
        );
        let n = rest.len();
        let edge_index = |a: u32, b: u32| {
            surface
                .edges
                .binary_search(&[a.min(b), a.max(b)])
                .expect("triangle edges are surface edges") as u32
        };
        let triangle_edges = surface
            .triangles
            .iter()
            .map(|t| {
                [
                    edge_index(t[0], t[1]),
                    edge_index(t[1], t[2]),
                    edge_index(t[2], t[0]),
                ]
            })
            .collect();
        ContactStage {
            broadphase: (0..instruments)
                .map(|_| BroadPhase::new(surface, rest))
                .collect(),
            triangle_edges,
            start: rest.to_vec(),
            end: rest.to_vec(),
            current: rest.to_vec(),
            holders: vec![0; n],
            slide: vec![Vector3::zeros(); n],
            slid: vec![Vector3::zeros(); n],
            jumped: Vec::new(),
            released: Vec::new(),
            reactions: Vec::new(),
            settle: None,
            footprint: false,
            s: Scratch::new(surface, rest, fixed),
        }
    }

    /// The stage with the settling of the tissue around its jumps on or off (off when
    /// built), for a model of `elements` corotational elements (none for the linear
    /// model; the settling's Newton passes use them).
    pub fn with_settling(mut self, on: bool, elements: usize) -> Self {
        let n = self.holders.len();
        self.settle = on.then(|| Settle::new(n, elements));
        self.jumped = Vec::with_capacity(if on { n } else { 0 });
        self.released = Vec::with_capacity(if on { n } else { 0 });
        self.reactions = Vec::with_capacity(if on { n } else { 0 });
        self
    }

    /// The stage with the tip's force scaled to its own footprint on or off (off when
    /// built; see `footprint`).
    pub fn with_footprint(mut self, on: bool) -> Self {
        self.footprint = on;
        self
    }

    /// Work counters since the stage was built.
    pub fn stats(&self) -> ContactStats {
        self.s.stats
    }

    /// Before the elastic step: held vertices follow their instrument's rigid motion,
    /// and instruments that left the body let go of everything. A held vertex from
    /// which the instrument's surface draws back, along the contact normal, by more
    /// than [`MAX_RETREAT`] radii in the tick is let go instead of carried: see there.
    pub fn carry_held_vertices(
        &mut self,
        instruments: &mut [Instrument],
        surface: &Surface,
        state: &State,
        imposed: &mut Imposed,
    ) {
        // Only the surface is read from the tick's start positions.
        for &v in &surface.vertices {
            self.start[v as usize] = state.x[v as usize];
        }
        for (k, ins) in instruments.iter_mut().enumerate() {
            match (ins.previous, ins.current) {
                (Some(prev), Some(cur)) => {
                    let r = rigid_motion(&prev, &cur);
                    let bit = 1u8 << k;
                    let (length, radius) = (ins.active_length(), ins.radius);
                    let tip_contact = ins.tip_contact;
                    let (holders, slide, slid) =
                        (&mut self.holders, &mut self.slide, &mut self.slid);
                    let (settle, fixed) = (&mut self.settle, &self.s.fixed);
                    ins.held.retain(|&v| {
                        let vi = v as usize;
                        let x = state.x[vi] + slide[vi];
                        let to = r.transform_point(&x);
                        let retreat = contact_normal(&x, &prev, length, radius, tip_contact)
                            .map_or(0.0, |(m, _)| -(to - x).dot(&m));
                        if retreat > MAX_RETREAT * radius {
                            let_go(v, bit, holders, slide, fixed, imposed, settle.as_mut());
                            return false;
                        }
                        slid[vi] = std::mem::take(&mut slide[vi]);
                        imposed.set(v, to);
                        true
                    });
                }
                _ => {
                    let bit = 1u8 << k;
                    for &v in &ins.held {
                        let (holders, slide) = (&mut self.holders, &mut self.slide);
                        let_go(v, bit, holders, slide, &self.s.fixed, imposed, None);
                    }
                    ins.held.clear();
                }
            }
        }
    }

    /// After the elastic step: the contact algorithm for every instrument, then holds
    /// and releases, reactions and velocities. `tangent` is the stiffness the elastic
    /// step used (the corotational `K̂` of the tick, or the linear `K`), for the
    /// settling; `dt` is the tick, s.
    #[allow(clippy::too_many_arguments)]
    pub fn resolve_contact(
        &mut self,
        instruments: &mut [Instrument],
        surface: &Surface,
        model: &ElasticModel,
        tangent: &BlockMatrix,
        state: &mut State,
        imposed: &mut Imposed,
        dt: f64,
    ) {
        if let Some(settle) = &mut self.settle {
            settle.next_tick();
        }
        for (k, ins) in instruments.iter_mut().enumerate() {
            ins.report.clear();
            let Some(pose) = ins.current else { continue };
            self.s.stats.instrument_ticks += 1;
            let prev = ins.previous.unwrap_or(pose);
            let length = ins.active_length();
            self.s.mark = self.s.mark.wrapping_add(1);
            self.s.moved.clear();
            for &v in &surface.vertices {
                let vi = v as usize;
                self.end[vi] = state.x[vi];
                // A held vertex starts where its slide took it (zero for the others).
                self.current[vi] = self.start[vi] + self.slid[vi];
            }
            let bit = 1u8 << k;
            let moves = sub_moves(&prev, &pose);
            for i in 1..=moves {
                let from = prev.lerp(&pose, (i - 1) as f64 / moves as f64);
                let to = prev.lerp(&pose, i as f64 / moves as f64);
                let r = rigid_motion(&from, &to);
                let f = i as f64 / moves as f64;
                for &v in &surface.vertices {
                    let vi = v as usize;
                    self.s.rel_start[vi] = r.transform_point(&self.current[vi]);
                    // What this instrument holds follows it; the rest moves on its free
                    // motion, split like the instrument's.
                    let follows =
                        self.holders[vi] & bit != 0 || self.s.moved_mark[vi] == self.s.mark;
                    state.x[vi] = if follows {
                        self.s.rel_start[vi]
                    } else {
                        self.start[vi] + (self.end[vi] - self.start[vi]) * f
                    };
                }
                self.sub_move(k, ins, surface, &to, length, &mut state.x);
                self.press(ins, surface, Some(&from), &to, &mut state.x);
                push_out(&mut self.s, surface, &to, ins.radius, length, &mut state.x);
                if i < moves {
                    for &v in &surface.vertices {
                        self.current[v as usize] = state.x[v as usize];
                    }
                }
            }
            if ins.report.tip.is_none() {
                // The approach: the surface ahead of a tip that does not touch it yet,
                // for the force model's tip plane.
                let reach = ins.radius + APPROACH_SPEED * 2.0 * dt;
                let mut query = Box3::empty();
                query.cover(&pose.tip);
                self.s.triangles.clear();
                self.broadphase[k]
                    .query(&query.inflated(reach + ins.radius), &mut self.s.triangles);
                ins.report.nearest = nearest_point(&self.s, surface, &pose, &state.x)
                    .filter(|n| (n.point - pose.tip).norm() <= reach);
            }
            ins.report.moved_vertices = self.s.moved.len() as u32;
            self.hold_and_release(k, ins, surface, model, state, imposed);
            self.collect_shaft_edges(ins, surface, state);
        }
        let settled = self.settle_jumps(instruments, surface, model, tangent, state, imposed);
        if let Some(Settled {
            rings,
            past_radius: true,
        }) = settled
        {
            self.release_pulled(instruments, model, tangent, state, imposed, rings);
        }
        let settled = settled.is_some();
        // One more pass for every instrument, tip and push-out, so that what one
        // instrument moved is not left inside another or across its axis (a large
        // triangle swung back over a pressed tip has no vertex inside the instrument;
        // only the tip press sees it), nor what the settling moved inside any.
        if instruments.len() > 1 || settled {
            // Whether anything but an instrument's own steps may have moved tissue
            // since its broad phase was last refitted.
            let moved_by_others =
                settled || instruments.iter().filter(|i| i.current.is_some()).count() > 1;
            for round in 0..FINAL_ROUNDS {
                let mut moved = false;
                for (k, ins) in instruments.iter_mut().enumerate() {
                    let Some(pose) = ins.current else { continue };
                    self.s.mark = self.s.mark.wrapping_add(1);
                    self.s.moved.clear();
                    let length = ins.active_length();
                    if round == 0 && settled {
                        // The settling moves free tissue with the jumps, by up to
                        // about a radius (`SETTLE_REACH`), past an instrument as
                        // readily as away from it. Its moves are a sub-move with the
                        // instrument still, from where it started (`rel_start`, see
                        // `settle_jumps`): candidates over that sweep, and edges that
                        // crossed the axis on the way stopped where they did not
                        // (§2.3–2.4), as for any motion.
                        self.sub_move(k, ins, surface, &pose, length, &mut state.x);
                    } else {
                        // The settling and the other instruments may have moved
                        // tissue further than the query's margin from where this
                        // instrument's broad phase last saw it: its boxes are
                        // refitted to where the tissue is now (only the triangles
                        // whose vertices left their box).
                        if moved_by_others {
                            self.broadphase[k].update(surface, &state.x, &state.x);
                        }
                        self.gather(k, surface, &state.x, &pose, ins.radius, length, false);
                    }
                    self.press(ins, surface, None, &pose, &mut state.x);
                    push_out(
                        &mut self.s,
                        surface,
                        &pose,
                        ins.radius,
                        length,
                        &mut state.x,
                    );
                    if !self.s.moved.is_empty() {
                        moved = true;
                        self.hold(k, ins, state, imposed);
                    }
                }
                if !moved {
                    break;
                }
            }
        }
        for &v in &surface.vertices {
            self.slid[v as usize] = Vector3::zeros();
        }
        for ins in instruments.iter_mut() {
            self.report_reaction(ins, surface, model, state);
            // What the stage holds moves with the instrument: its velocity is the
            // instrument's at that point over the tick, `(R(x₀) − x₀)/dt`. The jumps of
            // the contact steps (a vertex put back on the instrument's surface, a tip
            // triangle laid on its plane) are corrections of position, not motion:
            // counted as velocity they were tens of metres a second at 1 kHz on a
            // coarse mesh, which a vertex kept when released and threw the tissue
            // through the instrument.
            if let (Some(prev), Some(cur)) = (ins.previous, ins.current) {
                let r = rigid_motion(&prev, &cur);
                for &v in &ins.held {
                    let x0 = self.start[v as usize];
                    state.v[v as usize] = (r.transform_point(&x0) - x0) / dt;
                }
            }
            ins.previous = ins.current;
        }
    }

    /// A sub-move of instrument `k` ending at `to`, the surface having moved from
    /// `rel_start` to `x` in the instrument's frame: the candidates over that sweep
    /// (the broad phase refitted to it), then, with shaft contact, every edge that
    /// crossed the axis stopped where it did not (§2.3–2.4).
    fn sub_move(
        &mut self,
        k: usize,
        ins: &mut Instrument,
        surface: &Surface,
        to: &InstrumentPose,
        length: f64,
        x: &mut [Point3<f64>],
    ) {
        self.gather(k, surface, x, to, ins.radius, length, true);
        if ins.shaft_contact {
            ins.report.colliding_edges +=
                stop_colliding_edges(&mut self.s, &surface.edges, to, length, x);
        }
    }

    /// Candidate triangles, edges and vertices for instrument `k`. With `refit`, the
    /// broad phase is refitted to the tick's motion in the instrument's frame; without,
    /// it is queried as it is (the caller refits it if the tissue may have moved since)
    /// with a margin of one radius for the pushes since.
    #[allow(clippy::too_many_arguments)]
    fn gather(
        &mut self,
        k: usize,
        surface: &Surface,
        x: &[Point3<f64>],
        pose: &InstrumentPose,
        radius: f64,
        length: f64,
        refit: bool,
    ) {
        self.s.gather_mark = self.s.gather_mark.wrapping_add(1);
        let s = &mut self.s;
        if refit {
            self.broadphase[k].update(surface, &s.rel_start, x);
        }
        let mut query = Box3::empty();
        query.cover(&pose.tip);
        query.cover(&pose.point_at(length));
        let query = query.inflated(if refit { radius } else { 2.0 * radius });
        s.triangles.clear();
        self.broadphase[k].query(&query, &mut s.triangles);
        s.stats.candidate_triangles += s.triangles.len() as u64;
        s.edges.clear();
        s.vertices.clear();
        for &t in &s.triangles {
            for e in self.triangle_edges[t as usize] {
                if s.edge_mark[e as usize] != s.gather_mark {
                    s.edge_mark[e as usize] = s.gather_mark;
                    s.edges.push(e);
                }
            }
            for v in surface.triangles[t as usize] {
                if s.vertex_mark[v as usize] != s.gather_mark {
                    s.vertex_mark[v as usize] = s.gather_mark;
                    s.vertices.push(v);
                }
            }
        }
    }

    /// The tip press (§2.5) for an instrument that moved from `from` to `to` in a
    /// sub-move (`None`: a final pass, the instrument still); the report keeps the
    /// latest contact. Without a shaft the tip can only have gone through the surface
    /// along its own path, so it reaches that far (and 2r) only. In a sub-move, back
    /// faces the tip went through on that path are pressed ahead too (`tip`).
    fn press(
        &mut self,
        ins: &mut Instrument,
        surface: &Surface,
        from: Option<&InstrumentPose>,
        to: &InstrumentPose,
        x: &mut [Point3<f64>],
    ) {
        if !ins.tip_contact {
            return;
        }
        let from_tip = from.unwrap_or(to).tip;
        let travel = (to.tip - from_tip).norm() + 2.0 * ins.radius;
        let reach = Reach {
            front: if ins.shaft_contact {
                ins.length
            } else {
                travel
            },
            back: from.map(|_| (from_tip - to.tip).dot(&to.axis)),
        };
        let tip = press_tip(&mut self.s, surface, to, ins.radius, reach, x);
        ins.report.tip = tip.or(ins.report.tip);
    }
}

/// How far the instrument's surface may draw back from a held vertex in one tick,
/// along the contact normal `m` of `hold::contact_normal` (the instrument's outward
/// normal there), as a fraction of the radius, before the vertex is let go instead
/// of carried.
///
/// Held vertices follow the instrument's rigid motion before the elastic step
/// (eq. 1), and the pull-away that releases them is read from the reaction after
/// it: a vertex carried back with a withdrawal is released only once it has been
/// dragged the whole way. Withdrawn 14 cm in one tick, the tip carried four
/// vertices of the coarse liver with it and released them 13 cm out of the body:
/// after a press of 35 mm the liver was flung to 142 mm of displacement at 60 Hz
/// (358 mm at 1 kHz, where the flung tissue came back into the shaft with 328 N).
/// Let go before the step, a vertex goes where the elastic step takes it, and one
/// that springs back faster than the instrument retreats is caught by the contact
/// steps as any other.
///
/// Why two radii (10 mm a tick for the default instruments): the tissue follows a
/// retreat it is faster than, and there the carry is right. Released from a 35 mm
/// press on the coarse liver at 60 Hz, it springs back 6–13 mm a tick; with half a
/// radius as the bound, a withdrawal at 0.34 m/s (5.7 mm a tick) let it go every
/// tick and caught it again a tick later, and the force on the retreating tip rose
/// from 0.7 to 2.7 N. So slower retreats are decided by the reaction as before, and
/// a retreat of two radii or more carries the tissue at most that far past where it
/// would go.
pub(super) const MAX_RETREAT: f64 = 2.0;

/// Largest turn of the axis per sub-move, rad (2°). Over a sub-move each vertex moves
/// on a straight line in the instrument's frame while the instrument turns about its
/// tip; a point at distance `L` from the tip really sweeps an arc that leaves that
/// chord by `L θ²/8`, 46 µm at the end of a 0.3 m shaft for θ = 2°: far below `r`, so
/// no crossing is missed. A translation alone is exact in one move.
const MAX_TURN: f64 = 2.0 * std::f64::consts::PI / 180.0;

/// How many sub-moves the motion from `a` to `b` needs.
fn sub_moves(a: &InstrumentPose, b: &InstrumentPose) -> usize {
    let angle = a.axis.angle(&b.axis);
    (angle / MAX_TURN).ceil().max(1.0) as usize
}
