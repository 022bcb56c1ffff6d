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
//!   neighbours, up to 49× the steady force), then one more
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
//! else the radial direction (see `contact_normal`). A held vertex moves at the
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

use nalgebra::{Matrix3, Point3, Vector3};

use super::broadphase::{Box3, BroadPhase};
use super::closest::{TrianglePoint, closest_point_triangle};
use super::edges::stop_colliding_edges;
use super::instrument::Instrument;
use super::pose::{InstrumentPose, rigid_motion};
use super::push::push_out;
use super::scratch::{ContactStats, Scratch};
use super::settle::Settle;
use super::tip::{nearest_point, press_tip};
use crate::engine::elastic::{BlockMatrix, ElasticModel};
use crate::engine::integrate::{Imposed, State};
use crate::engine::mesh::Surface;

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
            settle: None,
            footprint: false,
            s: Scratch::new(surface, rest, fixed),
        }
    }

    /// The stage with the settling of the tissue around its jumps on or off (off when
    /// built).
    pub fn with_settling(mut self, on: bool) -> Self {
        let n = self.holders.len();
        self.settle = on.then(|| Settle::new(n));
        self.jumped = Vec::with_capacity(if on { n } else { 0 });
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
    /// and instruments that left the body let go of everything.
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
                    for &v in &ins.held {
                        let vi = v as usize;
                        self.slid[vi] = std::mem::take(&mut self.slide[vi]);
                        imposed.set(v, r.transform_point(&(state.x[vi] + self.slid[vi])));
                    }
                }
                _ => {
                    let bit = 1u8 << k;
                    for &v in &ins.held {
                        self.slide[v as usize] = Vector3::zeros();
                        self.holders[v as usize] &= !bit;
                        if self.holders[v as usize] == 0 && !self.s.fixed[v as usize] {
                            imposed.release(v);
                        }
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
                self.gather(k, surface, &state.x, &to, ins.radius, length, true);
                if ins.shaft_contact {
                    ins.report.colliding_edges += stop_colliding_edges(
                        &mut self.s,
                        &surface.edges,
                        &to,
                        length,
                        &mut state.x,
                    );
                }
                self.press(ins, surface, &from, &to, &mut state.x);
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
        let settled = self.settle_jumps(instruments, surface, tangent, state, imposed);
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
                        self.gather(k, surface, &state.x, &pose, ins.radius, length, true);
                        if ins.shaft_contact {
                            ins.report.colliding_edges += stop_colliding_edges(
                                &mut self.s,
                                &surface.edges,
                                &pose,
                                length,
                                &mut state.x,
                            );
                        }
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
                    self.press(ins, surface, &pose, &pose, &mut state.x);
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

    /// Settles the free tissue around the held vertices the contact steps jumped this
    /// tick (see `settle`), when the largest jump exceeds [`SETTLE_JUMP`] of the
    /// smallest radius, unless the scene turns it off, each jump scaled down so that
    /// the largest is at most [`SETTLE_REACH`] radii. Returns whether it did, and
    /// then leaves in `rel_start` the surface as the settling found it.
    fn settle_jumps(
        &mut self,
        instruments: &[Instrument],
        surface: &Surface,
        tangent: &BlockMatrix,
        state: &mut State,
        imposed: &Imposed,
    ) -> bool {
        let radius = instruments
            .iter()
            .filter(|i| i.current.is_some())
            .map(|i| i.radius)
            .fold(f64::INFINITY, f64::min);
        let Some(settle) = &mut self.settle else {
            return false;
        };
        self.jumped.clear();
        let mut largest: f64 = 0.0;
        for &v in &surface.vertices {
            let vi = v as usize;
            if self.holders[vi] != 0 && !self.s.fixed[vi] && !settle.taken_back(v) {
                let d = state.x[vi] - self.end[vi];
                if d != Vector3::zeros() {
                    largest = largest.max(d.norm());
                    settle.jump[vi] = d;
                    self.jumped.push(v);
                }
            }
        }
        if largest <= SETTLE_JUMP * radius {
            for &v in &self.jumped {
                settle.jump[v as usize] = Vector3::zeros();
            }
            return false;
        }
        if largest > SETTLE_REACH * radius {
            let scale = SETTLE_REACH * radius / largest;
            for &v in &self.jumped {
                settle.jump[v as usize] *= scale;
            }
        }
        // Where the settling starts from: its moves are motion, which the final
        // rounds analyse as such.
        for &v in &surface.vertices {
            self.s.rel_start[v as usize] = state.x[v as usize];
        }
        settle.settle(tangent, imposed.mask(), &self.jumped, &mut state.x);
        true
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

    /// The tip press (§2.5) for an instrument that moved from `from` to `to`; the
    /// report keeps the latest contact. Without a shaft the tip can only have gone
    /// through the surface along its own path, so it reaches that far (and 2r) only.
    fn press(
        &mut self,
        ins: &mut Instrument,
        surface: &Surface,
        from: &InstrumentPose,
        to: &InstrumentPose,
        x: &mut [Point3<f64>],
    ) {
        if !ins.tip_contact {
            return;
        }
        let reach = if ins.shaft_contact {
            ins.length
        } else {
            (to.tip - from.tip).norm() + 2.0 * ins.radius
        };
        let tip = press_tip(&mut self.s, surface, to, ins.radius, reach, x);
        ins.report.tip = tip.or(ins.report.tip);
    }

    /// Holds the vertices moved for instrument `k`; slides those the tissue drags
    /// harder than friction allows, and releases those it pulls away.
    fn hold_and_release(
        &mut self,
        k: usize,
        ins: &mut Instrument,
        surface: &Surface,
        model: &ElasticModel,
        state: &State,
        imposed: &mut Imposed,
    ) {
        let bit = 1u8 << k;
        let pose = ins.current.expect("only instruments in the body hold");
        let length = ins.active_length();
        // Adhesion: a pull-away below a tenth of the mean force on the instrument's
        // held vertices does not release (see `stays_held`).
        let mean = ins
            .held
            .iter()
            .map(|&v| state.reaction[v as usize].norm())
            .sum::<f64>()
            / ins.held.len().max(1) as f64;
        let ins_params = (ins.tip_contact, ins.friction, ADHESION * mean);
        let radius = ins.radius;
        let holders = &mut self.holders;
        let slide = &mut self.slide;
        let settle = &mut self.settle;
        let s = &self.s;
        ins.held.retain(|&v| {
            let vi = v as usize;
            if s.moved_mark[vi] == s.mark {
                return true;
            }
            let hold = stays_held(
                &state.x[vi],
                &state.reaction[vi],
                &pose,
                length,
                radius,
                ins_params,
                || tip_press(surface, v, &pose.tip, radius, &state.x),
            );
            let keep = match hold {
                Hold::Stick => true,
                Hold::Slip(tangent, excess) => {
                    // Slide along the instrument until the drag is back on the
                    // friction cone: the tissue's pull changes by −K_ii δ, so a step
                    // δ = excess / (t̂·K_ii·t̂) along t̂ takes the excess away (to first
                    // order; the vertex's neighbours do not move with it).
                    // The slide is applied with the next tick's rigid motion, before
                    // the contact steps, so that they keep the surface out of the
                    // instrument as for any other move.
                    // A slide longer than half the radius is no small creep along
                    // the instrument but the tissue tearing away from it: let go.
                    let kii = model.stiffness.get(v, v).unwrap_or_else(Matrix3::zeros);
                    let stiffness = tangent.dot(&(kii * tangent.into_inner()));
                    let step = excess / stiffness;
                    if stiffness > 0.0 && step <= MAX_SLIDE * radius {
                        if step >= MIN_SLIDE * radius {
                            slide[vi] = tangent.into_inner() * step;
                        }
                        true
                    } else {
                        false
                    }
                }
                Hold::Release => false,
            };
            if !keep {
                if let Some(settle) = settle.as_mut() {
                    settle.let_go(v);
                }
                slide[vi] = Vector3::zeros();
                holders[vi] &= !bit;
                if holders[vi] == 0 && !s.fixed[vi] {
                    imposed.release(v);
                }
            }
            keep
        });
        self.hold(k, ins, state, imposed);
    }

    /// Holds the vertices moved for instrument `k`, where they are now.
    fn hold(&mut self, k: usize, ins: &mut Instrument, state: &State, imposed: &mut Imposed) {
        let bit = 1u8 << k;
        for &v in &self.s.moved {
            let vi = v as usize;
            if self.holders[vi] & bit == 0 {
                self.holders[vi] |= bit;
                ins.held.push(v);
            }
            imposed.set(v, state.x[vi]);
        }
    }

    /// The tissue's force on the instrument: the elastic reactions on what it holds,
    /// from the elastic model's own force (corotational: the rotations around each
    /// held vertex extracted afresh; the linear `K u` would count the turn of tissue
    /// pushed aside as strain, and the calibrated force model would render it). With
    /// the scene's `contact.footprint`, the reactions on the tip's end are scaled to
    /// the tip's own footprint, and those on the shaft's side to the strip the shaft
    /// presses (see `footprint`).
    fn report_reaction(
        &self,
        ins: &mut Instrument,
        surface: &Surface,
        model: &ElasticModel,
        state: &State,
    ) {
        let mut total = Vector3::zeros();
        ins.report.held_reactions.clear();
        for &v in &ins.held {
            let ku = model.negated_elastic_force_on(v, &state.x);
            ins.report.held_reactions.push(-ku);
            total -= ku;
        }
        ins.report.reaction = total;
        let Some(pose) = ins.current.filter(|_| self.footprint) else {
            return;
        };
        let (length, radius, tip_contact) = (ins.active_length(), ins.radius, ins.tip_contact);
        let z = pose.axis.into_inner();
        let on_tip = |v: u32| {
            tip_contact
                && contact_normal(&state.x[v as usize], &pose, length, radius, true)
                    .is_some_and(|(m, _)| m == -z)
        };
        let held = &ins.held;
        let report = &mut ins.report;
        let patch = |tip: bool| {
            held.iter()
                .zip(&report.held_reactions)
                .filter(move |(v, _)| on_tip(**v) == tip)
                .map(|(&v, &f)| (v, f))
        };
        // The shaft's side, then the tip's end.
        let scales = [
            super::footprint::shaft_scale(
                patch(false),
                surface,
                &state.x,
                (&pose.tip, &pose.axis),
                radius,
            ),
            super::footprint::tip_scale(patch(true), surface, &state.x, &pose.axis, radius),
        ];
        if scales.iter().all(|&s| s >= 1.0) {
            return;
        }
        let mut cut_total = Vector3::zeros();
        for (&v, f) in held.iter().zip(report.held_reactions.iter_mut()) {
            let cut = (1.0 - scales[usize::from(on_tip(v))]) * *f;
            *f -= cut;
            cut_total += cut;
        }
        report.reaction -= cut_total;
    }

    /// The shaft's neighbouring edges (§3): candidate edges with a held end that lie
    /// along the shaft, within 1.5 r of it.
    fn collect_shaft_edges(&self, ins: &mut Instrument, surface: &Surface, state: &State) {
        let Some(pose) = ins.current else { return };
        if !ins.shaft_contact {
            return;
        }
        for &e in &self.s.edges {
            let [a, b] = surface.edges[e as usize];
            let held = |v: u32| self.holders[v as usize] != 0;
            if held(a) || held(b) {
                let c = super::closest::closest_edge_axis(
                    &state.x[a as usize],
                    &state.x[b as usize],
                    &pose,
                    ins.length,
                );
                if c.beta > 0.0 && c.distance() <= 1.5 * ins.radius {
                    ins.report.shaft_edges.push(e);
                }
            }
        }
    }
}

/// The largest jump of a held vertex, as a fraction of the radius, below which the
/// tissue is not settled around the jumps.
const SETTLE_JUMP: f64 = 1e-3;

/// The largest jump the tissue is settled around, as a fraction of the smallest
/// radius; larger jumps are settled as if scaled down to it. The settling is a
/// linear static correction for the dimple of a first contact, a jump of a
/// millimetre or two. Around the jumps of a whole-liver sweep in one tick, 10 cm, it
/// carried the free tissue beside the swept strip 13 mm sideways across the shaft's
/// path, so that the strip's two sides crossed over the shaft (liver-5k, SOFA's
/// liver refined once; `tests/contact_hard_cases.rs`). A jump larger than the
/// instrument is a gross move, which the next elastic steps carry the tissue through.
const SETTLE_REACH: f64 = 1.0;

/// The pull-away a held vertex withstands, as a fraction of the mean force on its
/// instrument's held vertices. Without it, vertices on the flanks of a shaft pushed
/// sideways — where the push-out puts them back on the cylinder with the tissue
/// pulling them very slightly away — were released and re-taken every other tick,
/// and the force flickered by 12%. Wet tissue sticks that much; a withdrawing
/// instrument pulls far harder.
const ADHESION: f64 = 0.1;

/// The longest slide of a held vertex in one tick, as a fraction of the radius.
const MAX_SLIDE: f64 = 0.5;

/// The shortest slide made, as a fraction of the radius (5 µm on a 5 mm shaft). The
/// slide is a step of the excess drag over the vertex's own stiffness `K_ii`, stiffer
/// than the tissue around it, so successive slides close in on the friction cone
/// geometrically and never quite reach it; each moves the held vertex off the chords
/// the push-out left its edges on, and the push-out puts them back. Below this the
/// slides only stirred those margins (10 µm of push-out every other tick, a residual
/// of a millinewton that never died out); the drag they leave is `K_ii` times 5 µm,
/// a few hundredths of a percent of the force.
const MIN_SLIDE: f64 = 1e-3;

/// What becomes of a held vertex this tick.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Hold {
    /// Pressed on and within friction: it stays where it is on the instrument.
    Stick,
    /// Pressed on but dragged harder than friction allows: it slides along the
    /// instrument's surface in direction `t̂` until the drag falls by the excess, N.
    Slip(nalgebra::Unit<Vector3<f64>>, f64),
    /// Pulled away: the tissue takes it back.
    Release,
}

/// Coulomb's law on the instrument's surface for a held vertex at `x` on which the
/// tissue exerts `reaction`.
///
/// `m` is the instrument's outward surface normal at the vertex: `−Z` for a vertex at
/// or beyond the tip of an instrument whose tip presses (§2.5 lays the tip triangle on
/// the plane ⊥ Z ahead of the tip: a flat end), else the radial direction from the
/// axis. The tissue pushes the vertex onto the instrument with `N = −reaction·m`; the
/// rest, `T`, is tangential. `N < −adhesion`: pulled away, released, the tissue
/// relaxes.
/// `|T| ≤ μ N`: it sticks. Otherwise it slips along `T` (the return mapping of
/// friction: slide until the drag is on the cone). Without the friction bound a held
/// vertex followed the instrument whatever the tissue's pull, so that a slid or
/// withdrawn instrument kept dragging tissue it no longer pressed; releasing a
/// slipping vertex instead of sliding it made it flip between held and free every
/// other tick under a steady sideways push.
///
/// Off the instrument's body — on the tip's end further than [`OFF_SHAFT`]·r from
/// the axis — a vertex touches no part of the instrument: it lies on the tip plane
/// only because the tip press laid its whole triangle there (a coarse mesh cannot
/// bend around the tip). It stays held only while the tip still presses on that
/// triangle or another of the vertex's triangles: one of them within
/// [`OFF_SHAFT`]·r of the tip `P` (a triangle laid on the tip plane is at `r`).
/// Without this a tip withdrawn after a slide kept tissue it had dragged sideways,
/// six radii from its axis and a centimetre out of the liver, with 0.7 N: on the
/// unbounded tip plane, whose normal is `−Z`, the tissue's sideways pull counted as
/// a push on the tip's end.
///
/// Such a vertex slides in the plane it was laid on. The tip press laid its triangle
/// on the plane through `P − r·n_prox` normal to `n_prox` (see `tip`), at distance
/// `r` from `P`; while the tip's nearest point `c` on the nearest of the vertex's
/// triangles lies inside that triangle (the triangle flat against the tip,
/// [`TipPress::flat`]), the slide loses its component along `ĉ = (c − P)/|c − P|`
/// (`= −n_prox` while the triangle lies on that plane). Coulomb's law itself keeps
/// `−Z`. Without the projection, slides perpendicular to `Z` moved the triangle off
/// its plane, away from the tip when the axis is tilted to the surface: after a
/// 20 mm slide on SOFA's liver, a withdrawal at 60 Hz slid the held triangle from
/// 5.00 to 5.21 mm from the tip in six ticks, past [`OFF_SHAFT`]·r, and let all three
/// vertices go while the tissue still pressed one of them with 1.5 N; the tissue
/// sprang back 7 mm and was caught again the next tick with a 0.3 N spike, at a time
/// set by the tick (the workspace's `tests/tests/reaction_rate.rs`). Taking `ĉ` for
/// the normal of the law instead upset the frictionless tip in the Hertz blocks
/// (`tests/contact_footprint.rs`): for the vertices off the body only, the contact
/// set still shifted after 40 passes; for those on the tip's end too, the coarse
/// block's force rose to 1.31× the fine one's.
fn stays_held(
    x: &Point3<f64>,
    reaction: &Vector3<f64>,
    pose: &InstrumentPose,
    length: f64,
    radius: f64,
    (tip_contact, friction, adhesion): (bool, f64, f64),
    pressed_by_tip: impl FnOnce() -> Option<TipPress>,
) -> Hold {
    let Some((m, on_body)) = contact_normal(x, pose, length, radius, tip_contact) else {
        return Hold::Release;
    };
    let flat = if on_body {
        None
    } else {
        match pressed_by_tip() {
            Some(press) => press.flat,
            None => return Hold::Release,
        }
    };
    let normal = -reaction.dot(&m);
    if normal < -adhesion || (normal <= 0.0 && adhesion == 0.0) {
        return Hold::Release;
    }
    let normal = normal.max(0.0);
    let tangential = reaction + m * normal;
    let excess = tangential.norm() - friction * normal;
    let along = match flat {
        Some(c) => tangential - c * tangential.dot(&c),
        None => tangential,
    };
    match nalgebra::Unit::try_new(along, 0.0) {
        Some(t) if excess > 0.0 => Hold::Slip(t, excess),
        _ => Hold::Stick,
    }
}

/// The instrument's outward surface normal `m` at a held vertex `x`: `−Z` on the
/// tip's flat end, else the radial direction from the axis; `None` on the axis. With
/// it, whether `x` is on the instrument's body: not on the tip's end further than
/// [`OFF_SHAFT`]·r from the axis.
///
/// The tip's end is where the vertex lies at or beyond the tip (`β ≤ 0`), and, with
/// a pressing tip, also where it lies off the shaft's surface (beyond
/// [`OFF_SHAFT`]·r from the axis) level with the tip (`(x − P)·Z ≤ r`, the split of
/// the local model): the tip press lays the whole triangle under the tip on its
/// plane, so on a coarse mesh it holds vertices a centimetre or two beside the
/// shaft. Those touch no part of the shaft; taking the radial direction for them
/// made a withdrawal along the axis look like a slide along the shaft, and they
/// crept toward the tip a few hundred microns a tick, held for half a second.
fn contact_normal(
    x: &Point3<f64>,
    pose: &InstrumentPose,
    length: f64,
    radius: f64,
    tip_contact: bool,
) -> Option<(Vector3<f64>, bool)> {
    let c = super::closest::closest_point_axis(x, pose, length);
    let level = (x - pose.tip).dot(&pose.axis);
    let off_shaft = c.distance() > OFF_SHAFT * radius;
    let at_tip = (c.beta <= 0.0 && level <= 0.0) || (off_shaft && level <= radius);
    if at_tip && tip_contact {
        Some((-pose.axis.into_inner(), !off_shaft))
    } else {
        c.offset.try_normalize(0.0).map(|m| (m, true))
    }
}

/// How the tip presses on a triangle of a held vertex ([`tip_press`]).
#[derive(Clone, Copy, Debug, PartialEq)]
struct TipPress {
    /// `ĉ = (c − P)/|c − P|`, from the tip `P` to `c`, the nearest point of the nearest
    /// of the vertex's triangles, when `c` lies inside that triangle: the triangle lies
    /// flat against the tip, normal to `ĉ`. `None` when `c` is on one of its sides or
    /// corners, where `ĉ` is no normal of the triangle and turns as the vertex moves.
    flat: Option<Vector3<f64>>,
}

/// Whether the tip `P` still presses on one of surface vertex `v`'s triangles: one
/// of them within [`OFF_SHAFT`]·r of it; if so, how.
fn tip_press(
    surface: &Surface,
    v: u32,
    tip: &Point3<f64>,
    radius: f64,
    x: &[Point3<f64>],
) -> Option<TipPress> {
    let slot = surface.slot(v)?;
    let nearest = surface
        .triangles_around(slot)
        .iter()
        .map(|&t| {
            let tri = surface.triangles[t as usize].map(|w| x[w as usize]);
            closest_point_triangle(tip, &tri)
        })
        .min_by(|a, b| {
            let d = |c: &TrianglePoint| (c.point - tip).norm_squared();
            d(a).total_cmp(&d(b))
        })?;
    let offset = nearest.point - tip;
    (offset.norm() <= OFF_SHAFT * radius).then(|| TipPress {
        flat: nearest
            .barycentric
            .iter()
            .all(|&w| w > FLAT_MARGIN)
            .then(|| offset.try_normalize(0.0))
            .flatten(),
    })
}

/// Smallest barycentric coordinate of the tip's nearest point for a triangle to lie
/// flat against the tip ([`TipPress::flat`]). `closest_point_triangle` gives exact
/// zeros on a side or corner; the margin (a thousandth of the triangle) keeps a
/// nearest point that lies on a side up to round-off from counting as inside.
const FLAT_MARGIN: f64 = 1e-3;

/// Distance from the axis, in radii, beyond which a held vertex is off the shaft's
/// surface: the push-out leaves vertices at `r (1 + 10⁻⁴)` and an edge pushed out
/// leaves its ends a little further; 1.05 r is well clear of both.
const OFF_SHAFT: f64 = 1.05;

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
