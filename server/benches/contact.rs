//! Cost of the contact stage against surface size and the number of colliding edges.
//!
//! `cargo bench -p laparo-server --bench contact`
//!
//! The default scene (liver at 0.19 m held at its upper face and underside, gravity,
//! 60 Hz implicit ticks) on SOFA's liver and the liver-5k/20k/80k series, settled under
//! gravity for 1 s, then pressed on its free front (+z) face. Each tick is
//! `Simulation::tick`, timed by its stages (`TickTiming`): the contact stage is
//! `carry_held_vertices` plus `resolve_contact`, the elastic step is `elastic_step`.
//! One core.
//!
//! Every press moves at 2 cm/s (1 cm per 0.5 s): a few ticks of approach from 2 mm
//! outside the surface, then, from the first tick the stage moves a vertex, 1 cm
//! deeper over 30 ticks (0.5 s), then held still for 30 ticks. Only the ticks from
//! first contact on are timed; medians are over all timed ticks of all repeats (small
//! meshes are repeated to fill a few seconds; the simulation is deterministic, so the
//! counters are the same in every repeat).
//!
//! Table 1, one instrument ("left"), two gestures:
//! - tip: the tip presses straight in along −z (axis +z) at the front point;
//! - shaft: the axis along +x, the tip beyond the liver's −x end, the shaft in front
//!   of the front face at the front point's height, moved into −z.
//!
//! Each tick's stages are reported as `TickTiming` names them: the contact stage
//! (`carry_held_vertices` + `resolve_contact`, and each apart), `elastic_step` and
//! `local_models`. Contact share is median contact / (median contact + median elastic
//! step). Colliding
//! edges and candidate triangles per tick are medians of the per-tick deltas of the
//! stage's counters.
//!
//! `LAPARO_CONTACT_SETTLE=0` runs every case with the scene's `contact.settle` off (the
//! free tissue around the stage's jumps not settled with them; on by default), to
//! compare with the default back to back. `LAPARO_CONTACT_MODEL=linear` runs them with
//! the linear elastic model (the livers' default is corotational) and
//! `LAPARO_CONTACT_PRECONDITIONER=block-jacobi` with block Jacobi (multigrid is the
//! default from 1,000 vertices), to compare with a build from before either.
//!
//! Table 2, both instruments tip-first (axis +z) at x = −0.02 and +0.02: the whole
//! replayed tick, its contact part, share = median contact / median whole tick, and
//! the most vertices the two hold together at any timed tick.

mod common;

/// The contact tests' gestures and checks; the bench uses `front_point`.
#[path = "../tests/common/contact.rs"]
#[allow(dead_code)]
mod gestures;

use std::time::Instant;

use common::*;
use gestures::front_point;
use laparo_server::engine::contact::InstrumentPose;
use laparo_server::engine::elastic::Formulation;
use laparo_server::engine::integrate::{PreconditionerKind, StepReport};
use laparo_server::engine::scene::Scene;
use laparo_server::engine::simulation::{Simulation, TickTiming};
use nalgebra::{Point3, Unit, Vector3};

/// Press speed: 1 cm over 0.5 s, in metres per 60 Hz tick.
const PRESS_DEPTH: f64 = 0.01;
const PRESS_TICKS: usize = 30;
const HOLD_TICKS: usize = 30;
/// Distance from the surface the instrument starts at, m.
const GAP: f64 = 0.002;
/// Ticks of approach after which a press that met nothing is an error.
const MAX_APPROACH: usize = 300;
/// Wall time a case is repeated for, s.
const BUDGET: f64 = 3.0;
const MAX_REPEATS: usize = 20;

/// One tick: its stages' wall times as the simulation records them, the whole tick's,
/// s, and the integrator's report.
struct TickTimes {
    stages: TickTiming,
    whole: f64,
    step: StepReport,
}

/// One tick, with the stage timings the simulation records.
fn timed_tick(sim: &mut Simulation) -> TickTimes {
    let whole = Instant::now();
    let step = sim.tick();
    let whole = since(whole);
    TickTimes {
        stages: sim.last_timing,
        whole,
        step,
    }
}

/// One instrument's press: its axis line moves along −z from `z` until the stage first
/// moves a vertex for it, then `PRESS_DEPTH` deeper over `PRESS_TICKS`, then holds.
struct Press {
    instrument: usize,
    /// The tip at `z = 0`; the pose's tip is `base + z·ẑ`.
    base: Point3<f64>,
    axis: Unit<Vector3<f64>>,
    z: f64,
    /// The tick (of the run) and axis height of first contact.
    contact: Option<(usize, f64)>,
    /// Ticks the press takes to go `PRESS_DEPTH` deep once in contact.
    ticks: usize,
}

impl Press {
    fn new(instrument: usize, base: [f64; 3], axis: [f64; 3], z: f64) -> Self {
        Press {
            instrument,
            base: Point3::from(base),
            axis: Unit::new_normalize(Vector3::from(axis)),
            z,
            contact: None,
            ticks: PRESS_TICKS,
        }
    }

    fn pose(&self) -> InstrumentPose {
        InstrumentPose::new(self.base + Vector3::z() * self.z, self.axis)
    }

    /// Ticks done after first contact when the press and hold are over.
    fn done(&self, tick: usize) -> bool {
        self.contact
            .is_some_and(|(c, _)| tick > c + self.ticks + HOLD_TICKS)
    }

    /// After tick `tick`: notes first contact, and sets the axis height for the next.
    fn advance(&mut self, sim: &Simulation, tick: usize) {
        let ins = &sim.instruments[self.instrument];
        if self.contact.is_none() && (ins.report.moved_vertices > 0 || !ins.held.is_empty()) {
            self.contact = Some((tick, self.z));
        }
        let speed = if self.contact.is_some() {
            PRESS_DEPTH / self.ticks as f64
        } else {
            PRESS_DEPTH / PRESS_TICKS as f64
        };
        let floor = self
            .contact
            .map_or(f64::NEG_INFINITY, |(_, z)| z - PRESS_DEPTH);
        self.z = (self.z - speed).max(floor);
    }
}

/// What a timed run measured, per timed tick.
#[derive(Default)]
struct Run {
    /// The contact stage: carrying held vertices plus resolving contact.
    contact: Vec<f64>,
    carry: Vec<f64>,
    resolve: Vec<f64>,
    elastic: Vec<f64>,
    local_models: Vec<f64>,
    whole: Vec<f64>,
    colliding: Vec<f64>,
    candidates: Vec<f64>,
    /// Vertices held by all instruments together.
    held: Vec<usize>,
    /// Held by instrument 0 at the end.
    held_end: usize,
    unconverged: usize,
}

/// Runs the presses on `sim` (already settled) and appends the ticks from the first
/// contact on to `run`.
fn press(sim: &mut Simulation, presses: &mut [Press], label: &str, run: &mut Run) {
    let mut all = Run::default();
    let mut tick = 0;
    while !presses.iter().all(|p| p.done(tick)) {
        for p in presses.iter() {
            sim.set_pose(p.instrument, Some(p.pose()));
        }
        let before = sim.contact.as_ref().expect("scene has instruments").stats();
        let t = timed_tick(sim);
        let after = sim.contact.as_ref().unwrap().stats();
        if let Some(v) = sim
            .state
            .x
            .iter()
            .position(|p| !p.coords.iter().all(|c| c.is_finite()))
        {
            panic!("{label}: vertex {v} is not finite after run tick {tick}");
        }
        all.contact.push(t.stages.contact());
        all.carry.push(t.stages.carry_held_vertices);
        all.resolve.push(t.stages.resolve_contact);
        all.elastic.push(t.stages.elastic_step);
        all.local_models.push(t.stages.local_models);
        all.whole.push(t.whole);
        all.colliding
            .push((after.colliding_edges - before.colliding_edges) as f64);
        all.candidates
            .push((after.candidate_triangles - before.candidate_triangles) as f64);
        all.held
            .push(sim.instruments.iter().map(|i| i.held.len()).sum());
        all.unconverged += usize::from(!t.step.converged);
        for p in presses.iter_mut() {
            p.advance(sim, tick);
        }
        tick += 1;
        assert!(
            tick < MAX_APPROACH || presses.iter().all(|p| p.contact.is_some()),
            "{label}: no contact after {tick} ticks of approach"
        );
    }
    let first = presses.iter().map(|p| p.contact.unwrap().0).min().unwrap();
    run.contact.extend_from_slice(&all.contact[first..]);
    run.carry.extend_from_slice(&all.carry[first..]);
    run.resolve.extend_from_slice(&all.resolve[first..]);
    run.elastic.extend_from_slice(&all.elastic[first..]);
    run.local_models
        .extend_from_slice(&all.local_models[first..]);
    run.whole.extend_from_slice(&all.whole[first..]);
    run.colliding.extend_from_slice(&all.colliding[first..]);
    run.candidates.extend_from_slice(&all.candidates[first..]);
    run.held.extend_from_slice(&all.held[first..]);
    run.held_end = sim.instruments[0].held.len();
    run.unconverged += all.unconverged;
}

/// The default scene on `mesh`, built and settled under gravity for 1 s with the
/// instruments out of the body.
fn settled(mesh: &MeshCase) -> Simulation {
    let mut scene = Scene::default_scene();
    scene.mesh.file = mesh.file.clone();
    scene.mesh.refine = mesh.refine;
    if std::env::var_os("LAPARO_CONTACT_SETTLE").is_some_and(|v| v == "0") {
        scene.contact.settle = false;
    }
    if std::env::var_os("LAPARO_CONTACT_MODEL").is_some_and(|v| v == "linear") {
        scene.material.model = Formulation::Linear;
    }
    if std::env::var_os("LAPARO_CONTACT_PRECONDITIONER").is_some_and(|v| v == "block-jacobi") {
        scene.mechanics.preconditioner = PreconditionerKind::BlockJacobi;
    }
    let mut sim = build(&scene);
    for _ in 0..60 {
        sim.tick();
    }
    sim
}

/// Repeats `gesture` on fresh settled simulations for about `BUDGET` of wall time.
fn repeat(
    mesh: &MeshCase,
    label: &str,
    gesture: impl Fn(&Simulation) -> Vec<Press>,
) -> (Run, Simulation, usize) {
    let mut run = Run::default();
    let start = Instant::now();
    let mut repeats = 0;
    loop {
        let mut sim = settled(mesh);
        let mut presses = gesture(&sim);
        press(&mut sim, &mut presses, label, &mut run);
        repeats += 1;
        if repeats >= MAX_REPEATS || since(start) * (repeats + 1) as f64 / repeats as f64 > BUDGET {
            return (run, sim, repeats);
        }
    }
}

/// The tip pressing straight in along −z at the front point.
fn tip_gesture(sim: &Simulation) -> Vec<Press> {
    let front = front_point(sim);
    let r = sim.instruments[0].radius;
    vec![Press::new(
        0,
        [front.x, front.y, 0.0],
        [0.0, 0.0, 1.0],
        front.z + r + GAP,
    )]
}

/// The shaft along +x in front of the front face, the tip beyond the −x end.
fn shaft_gesture(sim: &Simulation) -> Vec<Press> {
    let front = front_point(sim);
    let r = sim.instruments[0].radius;
    let (lo, _) = sim.mesh.bounding_box();
    // The front of the liver along the shaft's line, over the whole width.
    let x = &sim.state.x;
    let z = sim
        .mesh
        .surface
        .vertices
        .iter()
        .map(|&v| x[v as usize])
        .filter(|p| (p.y - front.y).abs() < 0.02)
        .map(|p| p.z)
        .fold(front.z, f64::max);
    vec![Press::new(
        0,
        [lo.x - 0.03, front.y, 0.0],
        [1.0, 0.0, 0.0],
        z + r + GAP,
    )]
}

/// The shaft gesture, but 1 cm deep within one tick once in contact (0.6 m/s): edges
/// cross the axis and the confidence intervals stop them.
fn fast_shaft_gesture(sim: &Simulation) -> Vec<Press> {
    let mut presses = shaft_gesture(sim);
    presses[0].ticks = 1;
    presses
}

/// Both instruments tip-first at x = −0.02 and +0.02.
fn two_tips(sim: &Simulation) -> Vec<Press> {
    let front = front_point(sim);
    [(0, -0.02), (1, 0.02)]
        .into_iter()
        .map(|(k, x)| {
            let r = sim.instruments[k].radius;
            Press::new(k, [x, front.y, 0.0], [0.0, 0.0, 1.0], front.z + r + GAP)
        })
        .collect()
}

fn ms(v: &mut [f64]) -> f64 {
    median(v) * 1e3
}

fn main() {
    let mut notes = Vec::new();
    println!("Contact time per tick against surface size and colliding edges (one instrument)");
    println!();
    println!(
        "| mesh | surface triangles | gesture | median contact (ms) | carry held vertices / resolve contact (ms) | median elastic step (ms) | median local models (ms) | contact share (%) | colliding edges/tick (median / max) | candidate triangles/tick | held at end | ticks timed |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for case in meshes(&["sofa-liver", "liver-5k", "liver-20k", "liver-80k"]) {
        type Gesture = fn(&Simulation) -> Vec<Press>;
        for (name, gesture) in [
            ("tip", tip_gesture as Gesture),
            ("shaft", shaft_gesture),
            ("shaft, fast", fast_shaft_gesture),
        ] {
            let label = format!("{} {name}", case.label);
            let (mut run, sim, repeats) = repeat(&case, &label, gesture);
            let contact = ms(&mut run.contact);
            let elastic = ms(&mut run.elastic);
            let (carry, resolve) = (ms(&mut run.carry), ms(&mut run.resolve));
            let local_models = ms(&mut run.local_models);
            if run.unconverged > 0 {
                notes.push(format!(
                    "{label}: CG hit its iteration cap on {} ticks",
                    run.unconverged
                ));
            }
            println!(
                "| {} | {} | {name} | {:.4} | {:.4} / {:.4} | {:.3} | {:.4} | {:.1} | {:.0} / {:.0} | {:.0} | {} | {} × {} |",
                case.label,
                sim.mesh.surface.triangles.len(),
                contact,
                carry,
                resolve,
                elastic,
                local_models,
                100.0 * contact / (contact + elastic),
                median(&mut run.colliding),
                run.colliding.iter().cloned().fold(0.0, f64::max),
                median(&mut run.candidates),
                run.held_end,
                repeats,
                run.contact.len() / repeats,
            );
        }
    }
    println!();
    println!("Whole tick with two instruments pressing (tips at x = ±0.02)");
    println!();
    println!(
        "| mesh | median whole tick (ms) | median contact (ms) | contact share (%) | ticks/s | max held vertices | ticks timed |"
    );
    println!("|---|---|---|---|---|---|---|");
    for case in meshes(&["sofa-liver", "liver-20k"]) {
        let label = format!("{} two tips", case.label);
        let (mut run, _, repeats) = repeat(&case, &label, two_tips);
        let whole = ms(&mut run.whole);
        let contact = ms(&mut run.contact);
        if run.unconverged > 0 {
            notes.push(format!(
                "{label}: CG hit its iteration cap on {} ticks",
                run.unconverged
            ));
        }
        println!(
            "| {} | {:.3} | {:.4} | {:.1} | {:.0} | {} | {} × {} |",
            case.label,
            whole,
            contact,
            100.0 * contact / whole,
            1e3 / whole,
            run.held.iter().max().unwrap(),
            repeats,
            run.contact.len() / repeats,
        );
    }
    for n in notes {
        println!();
        println!("{n}");
    }
}
