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

use nalgebra::{Matrix3, Point3, Vector3};

use super::broadphase::{Box3, BroadPhase};
use super::edges::stop_colliding_edges;
use super::hold::{
    Hold, MAX_SLIDE, MIN_SLIDE, adhesion, contact_normal, pulled_away, shaft_press, stays_held,
    tip_press,
};
use super::instrument::Instrument;
use super::pose::{InstrumentPose, rigid_motion};
use super::push::push_out;
use super::scratch::{ContactStats, Scratch};
use super::settle::{RINGS, Settle};
use super::tip::{Reach, nearest_point, press_tip};
use crate::engine::elastic::{BlockMatrix, ElasticModel, Formulation};
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

    /// Settles the free tissue around the held vertices the contact steps jumped this
    /// tick (see `settle`), when the largest jump exceeds [`SETTLE_JUMP`] of the
    /// smallest radius, unless the scene turns it off, each jump scaled down so that
    /// the largest sideways part (across its instrument's axis) is at most
    /// [`SETTLE_REACH`] radii; the region grows by a ring for every radius the largest
    /// settled jump passes one radius by, up to [`SETTLE_RINGS`]. Past a radius, on
    /// the corotational model and when no jump was scaled down, Newton passes on the
    /// model's own force follow the linear settling (see `settle`); a sweep's scaled
    /// jumps are settled linearly only (with the passes, the whole-liver sweep of
    /// `tests/contact_hard_cases.rs` left a triangle 4.9 mm inside the shaft). Returns
    /// the rings it settled, if it did, and then leaves in `rel_start` the surface as
    /// the settling found it.
    fn settle_jumps(
        &mut self,
        instruments: &[Instrument],
        surface: &Surface,
        model: &ElasticModel,
        tangent: &BlockMatrix,
        state: &mut State,
        imposed: &Imposed,
    ) -> Option<Settled> {
        let radius = instruments
            .iter()
            .filter(|i| i.current.is_some())
            .map(|i| i.radius)
            .fold(f64::INFINITY, f64::min);
        let settle = self.settle.as_mut()?;
        self.jumped.clear();
        let (mut largest, mut sideways): (f64, f64) = (0.0, 0.0);
        for &v in &surface.vertices {
            let vi = v as usize;
            let holders = self.holders[vi];
            if holders != 0 && !self.s.fixed[vi] && !settle.taken_back(v) {
                let d = state.x[vi] - self.end[vi];
                if d != Vector3::zeros() {
                    largest = largest.max(d.norm());
                    // The first instrument holding it; a vertex two hold is pressed
                    // sideways by one of them at least, which the bound then counts.
                    let across = instruments[holders.trailing_zeros() as usize]
                        .current
                        .map_or(d, |p| p.across(&d));
                    sideways = sideways.max(across.norm());
                    settle.jump[vi] = d;
                    self.jumped.push(v);
                }
            }
        }
        if largest <= SETTLE_JUMP * radius {
            for &v in &self.jumped {
                settle.jump[v as usize] = Vector3::zeros();
            }
            return None;
        }
        let scale = (SETTLE_REACH * radius / sideways).min(1.0);
        if scale < 1.0 {
            for &v in &self.jumped {
                settle.jump[v as usize] *= scale;
            }
        }
        let beyond = (largest * scale / radius - 1.0).max(0.0).ceil() as usize;
        let rings = (RINGS + beyond).min(SETTLE_RINGS);
        // Where the settling starts from: its moves are motion, which the final
        // rounds analyse as such.
        for &v in &surface.vertices {
            self.s.rel_start[v as usize] = state.x[v as usize];
        }
        let nonlinear =
            (scale == 1.0 && largest > radius && model.formulation == Formulation::Corotational)
                .then_some((model, &self.end[..]));
        settle.settle(
            tangent,
            imposed.mask(),
            &self.jumped,
            rings,
            nonlinear,
            &mut state.x,
        );
        Some(Settled {
            rings,
            past_radius: largest * scale > radius,
        })
    }

    /// After a settling whose largest jump passed the radius: lets go of the held
    /// vertices the contact steps moved this tick and the settled tissue pulls away
    /// from their instrument (the normal part of Coulomb's law, `hold::pulled_away`,
    /// on the model's force at each, with the instrument's adhesion), relaxes the
    /// tissue around them ([`Settle::relax`], over the settling's `rings`), and again,
    /// up to [`RELEASE_ROUNDS`] times, until none is let go: the held set the contact
    /// steps chose by geometry made unilateral within the tick (see `settle`, "A held
    /// set that pulls").
    fn release_pulled(
        &mut self,
        instruments: &mut [Instrument],
        model: &ElasticModel,
        tangent: &BlockMatrix,
        state: &mut State,
        imposed: &mut Imposed,
        rings: usize,
    ) {
        let Some(settle) = &mut self.settle else {
            return;
        };
        for _ in 0..RELEASE_ROUNDS {
            self.released.clear();
            for (k, ins) in instruments.iter_mut().enumerate() {
                let Some(pose) = ins.current else { continue };
                let (length, radius, tip_contact) =
                    (ins.active_length(), ins.radius, ins.tip_contact);
                let x = &state.x;
                // The tissue's reaction on each held vertex, in the order of `held`.
                self.reactions.clear();
                self.reactions.extend(
                    ins.held
                        .iter()
                        .map(|&v| -model.negated_elastic_force_on(v, x)),
                );
                let adhesion = adhesion(self.reactions.iter().map(|f| f.norm()));
                let bit = 1u8 << k;
                let (holders, slide, fixed) = (&mut self.holders, &mut self.slide, &self.s.fixed);
                let (released, end) = (&mut self.released, &self.end);
                let mut reactions = self.reactions.iter();
                ins.held.retain(|&v| {
                    let reaction = reactions.next().expect("one reaction per held vertex");
                    // Only what the contact steps moved this tick: the rest was
                    // judged by the same law after the elastic step.
                    if x[v as usize] == end[v as usize] {
                        return true;
                    }
                    let Some((m, _)) =
                        contact_normal(&x[v as usize], &pose, length, radius, tip_contact)
                    else {
                        return true;
                    };
                    if !pulled_away(-reaction.dot(&m), adhesion) {
                        return true;
                    }
                    if let_go(v, bit, holders, slide, fixed, imposed, Some(&mut *settle)) {
                        released.push(v);
                    }
                    false
                });
            }
            if self.released.is_empty() {
                break;
            }
            settle.relax(
                tangent,
                imposed.mask(),
                &self.released,
                rings,
                model,
                &mut state.x,
            );
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
        let adhesion = adhesion(ins.held.iter().map(|&v| state.reaction[v as usize].norm()));
        let ins_params = (ins.tip_contact, ins.friction, adhesion);
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
                (length, radius),
                ins_params,
                || tip_press(surface, v, &pose.tip, radius, &state.x),
                || shaft_press(surface, v, &pose, length, radius, &state.x),
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
                let_go(v, bit, holders, slide, &s.fixed, imposed, settle.as_mut());
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

/// Instrument `bit` lets go of vertex `v`: its slide is dropped, and it is freed
/// unless another instrument holds it or it is a support; `settle`, when given,
/// remembers that it was let go ([`Settle::taken_back`]). Returns whether it was
/// freed.
fn let_go(
    v: u32,
    bit: u8,
    holders: &mut [u8],
    slide: &mut [Vector3<f64>],
    fixed: &[bool],
    imposed: &mut Imposed,
    settle: Option<&mut Settle>,
) -> bool {
    let vi = v as usize;
    if let Some(settle) = settle {
        settle.let_go(v);
    }
    slide[vi] = Vector3::zeros();
    holders[vi] &= !bit;
    let freed = holders[vi] == 0 && !fixed[vi];
    if freed {
        imposed.release(v);
    }
    freed
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

/// The largest jump of a held vertex, as a fraction of the radius, below which the
/// tissue is not settled around the jumps.
const SETTLE_JUMP: f64 = 1e-3;

/// The largest sideways jump (across the instrument's axis) the tissue is settled
/// around, as a fraction of the smallest radius; larger jumps are settled as if
/// scaled down to it. The settling is a linear static correction. Around the
/// jumps of a whole-liver sweep in one tick, 10 cm across the shaft, it carried the
/// free tissue beside the swept strip 13 mm sideways across the shaft's path, so that
/// the strip's two sides crossed over the shaft (liver-5k, SOFA's liver refined once;
/// `tests/contact_hard_cases.rs`). A sideways jump larger than the instrument is a
/// gross move, which the next elastic steps carry the tissue through.
///
/// A jump along the axis is settled whole: the tip pushing tissue ahead of it into
/// the body, however far in one tick. Scaled down like a sideways one, the 3.5 cm
/// jab of `tests/explicit_chatter.rs` (ν = 0.499) left 1.04 J of strain energy in the
/// tissue around the jump, 25 times the held press's 0.042 J, and reported 78 N on
/// its tick against 2.35 N steady. The implicit step took that energy out by its own
/// dissipation; the explicit step turned it into 0.5 J of ringing that let the
/// tissue go and caught it again with 54–104 N jumps for the rest of the hold.
const SETTLE_REACH: f64 = 1.0;

/// The most rings of free nodes settled around a jump ([`RINGS`] for jumps up to a
/// radius, one more for every further radius). A jump the size of the instrument
/// moves the tissue beside it by as much, which three rings of a coarse mesh (3 cm)
/// cut off: the 3.5 cm jab settled whole within three rings left 0.14 J and rang
/// explicitly (the held set changing 9 times in a second, an 18 N retake); within
/// five rings or more it held steadily (within ten, 0.08 J left). Each three rings
/// take [`MAX_ITERATIONS`](super::settle::MAX_ITERATIONS) more iterations, so a tick
/// settles with at most four times the usual iterations, over a region up to twelve
/// rings deep (on a fine mesh up to (12/3)³ = 64 times as many nodes; never more than
/// the mesh's). Only ticks whose jumps along the axis pass a radius pay it: a jab,
/// not a press.
const SETTLE_RINGS: usize = 12;

/// What [`ContactStage::settle_jumps`] settled.
#[derive(Clone, Copy, Debug)]
struct Settled {
    /// The rings of free nodes around the jumps.
    rings: usize,
    /// Whether the largest settled jump passed the instrument's radius.
    past_radius: bool,
}

/// Rounds of letting go of what the settled tissue pulls away and relaxing around it
/// ([`ContactStage::release_pulled`]). A relaxation can leave another held vertex
/// pulled: a tip posed 1 cm into tissue of 100 kPa, ν = 0.49, let three go, then
/// one more, then none. Six rounds changed none of the first-pose figures of
/// `tests/contact_first_touch.rs`; each round costs a CG solve over the region, on
/// settled ticks only.
const RELEASE_ROUNDS: usize = 3;

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
