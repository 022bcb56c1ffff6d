//! Tick rate of the linear and the corotational model, with contact.
//!
//! `cargo bench -p laparo-server --bench corotational`
//! (`LAPARO_MESH_DIR` for liver-20k and liver-80k)
//!
//! The default scene (implicit at 60 Hz, CG tolerance 1e-4) on SOFA's liver,
//! liver-20k and liver-80k, each model built and run in the same process one after
//! the other: settled under gravity for 0.5 s (untimed), then the left instrument's
//! tip presses straight in (axis +z) at the front point from 2 mm outside, 2 cm/s for
//! 1 s, then holds for 0.25 s. Every tick of the press and hold is timed
//! (`Simulation::tick`); the table gives medians, one core unless `LAPARO_THREADS`
//! says more.
//!
//! Columns: median whole tick and ticks/s; the slowest tick; median elastic step; CG iterations per
//! tick (median); the corotational update alone, on the scene's threads (rotations of every element,
//! re-assembly of `K̂` and the offset), as a tick pays it: replayed afterwards over
//! the positions each press and hold tick started from, in order, so that each call
//! is warm-started from the rotations of the tick before (median; calling it again
//! on one state would time an already converged extraction); the
//! largest displacement at the end and the reaction on the instrument; the relative
//! error of the final state against the converged static answer of the same
//! constraints (supports and the vertices the instrument holds at the end, solved
//! with the same model to a CG tolerance of 1e-9): `max_i |x_i − x_i^static| /
//! max_i |u_i^static|`. It holds the integrator's error and what is left of the
//! physical transient after the 0.25 s hold (mass damping 10/s leaves e^{−1.25}
//! ≈ 0.29 of a mode excited at the end of the press).
//!
//! `LAPARO_THREADS=2` runs every scene on two threads (`[mechanics] threads`: the
//! mesh renumbered when loaded, the product and the update shared by parts), the
//! update's column too; the default is one.
//!
//! `LAPARO_STIFFNESS=f64` (or `f32`) sets `[mechanics] stiffness` for every scene;
//! the default, `auto`, reads liver-300k's blocks in f32 and the others' in f64,
//! and holds the multigrid hierarchies of liver-80k and 300k in f32 (the column
//! "stiffness" says which each run read: `f32 (blocks)` or `f32 (hierarchy)` when
//! only one of them was).
//!
//! `-- liver-300k` (or any labels) runs those meshes instead of the default three;
//! liver-300k's ticks take seconds, so it is not run unless asked.
//!
//! Each model runs with both CG preconditioners (`[mechanics] preconditioner`:
//! block Jacobi and smoothed-aggregation multigrid). The corotational model runs
//! twice with each: keeping an element's share of `K̂` until it has turned by
//! [`TANGENT_TURN`] (the default), then reassembling every element that turned at
//! all ("exact tangent"). For each pair the kept-tangent row adds the median share
//! of elements reassembled per tick and how far its final state lies from the exact
//! tangent's, `max_i |x_i − x_i^exact| / max_i |u_i^exact|`, and its reaction's
//! relative difference.

mod common;

/// The contact tests' gestures; the bench uses `front_point`.
#[path = "../tests/common/contact.rs"]
#[allow(dead_code)]
mod gestures;

use std::time::Instant;

use common::*;
use gestures::front_point;
use laparo_server::engine::contact::InstrumentPose;
use laparo_server::engine::elastic::{Formulation, Parts, TANGENT_TURN};
use laparo_server::engine::integrate::{
    Integrator, IntegratorKind, PreconditionerKind, StiffnessStorage,
};
use laparo_server::engine::simulation::Simulation;
use laparo_server::engine::workers::Workers;
use nalgebra::{Unit, Vector3};

const SETTLE_TICKS: usize = 30;
const PRESS_TICKS: usize = 60;
const HOLD_TICKS: usize = 15;
/// Press speed, m per 60 Hz tick (2 cm/s).
const STEP: f64 = 0.02 / 60.0;
const GAP: f64 = 0.002;

fn main() {
    println!(
        "| mesh | tetrahedra | model | preconditioner | stiffness | tangent | median tick (ms) | ticks/s | max tick (ms) | median elastic step (ms) | CG its/tick | corotational update (ms) | shares reassembled per tick | max displacement (mm) | instrument force (N) | relative error vs static | vs exact tangent: state, force |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let labels = requested_labels(&["sofa-liver", "liver-20k", "liver-80k"]);
    let threads = threads();
    let stiffness = stiffness();
    for case in meshes(&labels) {
        let runs = [PreconditionerKind::BlockJacobi, PreconditionerKind::Amg]
            .into_iter()
            .flat_map(|p| {
                [
                    (Formulation::Linear, p, None),
                    (Formulation::Corotational, p, Some(0.0)),
                    (Formulation::Corotational, p, Some(kept_turn())),
                ]
            });
        // The exact tangent's final positions and reaction, for the kept-tangent run
        // that follows it.
        let mut exact = None;
        for (model, preconditioner, turn) in runs {
            let mut scene = scene(&case, IntegratorKind::Implicit, 1e-4);
            scene.material.model = model;
            scene.mechanics.preconditioner = preconditioner;
            scene.mechanics.threads = threads;
            scene.mechanics.stiffness = stiffness;
            let mut sim = build(&scene);
            if let Some(turn) = turn {
                sim.integrator.set_tangent_turn(turn);
            }
            for _ in 0..SETTLE_TICKS {
                sim.tick();
            }
            let start = front_point(&sim) + Vector3::z() * GAP;
            let axis = Unit::new_normalize(Vector3::z());
            let (mut ticks, mut elastic, mut cg) = (Vec::new(), Vec::new(), Vec::new());
            let mut shares = Vec::new();
            let mut starts = Vec::new();
            for k in 0..PRESS_TICKS + HOLD_TICKS {
                starts.push(sim.state.x.clone());
                let depth = STEP * (k.min(PRESS_TICKS) + 1) as f64;
                let tip = start - Vector3::z() * depth;
                sim.set_pose(0, Some(InstrumentPose::new(tip, axis)));
                let t = Instant::now();
                let report = sim.tick();
                ticks.push(since(t) * 1e3);
                elastic.push(sim.last_timing.elastic_step * 1e3);
                cg.push(report.cg_iterations as f64);
                shares
                    .push(sim.integrator.tangent_reassembled() as f64 / sim.mesh.tets.len() as f64);
            }
            let update = match sim.model.corotated() {
                Some(mut c) => {
                    let n = sim.model.vertex_count();
                    // The parts and threads the scene's tick used.
                    let parts = sim.integrator.parts();
                    let tets = sim.model.elements.iter().map(|e| e.tet);
                    c.set_parts(Parts::new(n, parts, tets));
                    let crew = (parts > 1).then(|| Workers::new(parts).expect("1 to 64 parts"));
                    let mut out = vec![Vector3::zeros(); n];
                    // The first call starts from rest rotations: not timed.
                    let turn = turn.unwrap_or(0.0);
                    c.update_shared(&sim.model, &starts[0], &mut out, turn, crew.as_ref());
                    let mut times: Vec<f64> = starts[1..]
                        .iter()
                        .map(|x| {
                            let t = Instant::now();
                            c.update_shared(&sim.model, x, &mut out, turn, crew.as_ref());
                            since(t) * 1e3
                        })
                        .collect();
                    format!("{:.3}", median(&mut times))
                }
                None => "—".to_string(),
            };
            let slowest = ticks.iter().cloned().fold(0.0, f64::max);
            let tick = median(&mut ticks);
            let error = error_against_static(&sim);
            let reaction = sim.instruments[0].report.reaction;
            let (tangent, shares, versus) = match turn {
                None => ("—".to_string(), "—".to_string(), "—".to_string()),
                Some(0.0) => {
                    exact = Some((sim.state.x.clone(), reaction));
                    ("exact".to_string(), "—".to_string(), "—".to_string())
                }
                Some(t) => {
                    let versus = exact.take().map_or("—".to_string(), |(x, f)| {
                        let scale = x
                            .iter()
                            .zip(&sim.model.rest)
                            .map(|(x, r)| (x - r).norm())
                            .fold(0.0, f64::max);
                        format!(
                            "{:.1e}, {:.1e}",
                            max_distance(&sim.state.x, &x) / scale,
                            (reaction - f).norm() / f.norm()
                        )
                    });
                    (
                        format!("kept to {t:.0e} rad"),
                        format!("{:.1}%", 100.0 * median(&mut shares)),
                        versus,
                    )
                }
            };
            println!(
                "| {} | {} | {:?} | {preconditioner:?} | {} | {tangent} | {:.3} | {:.0} | {slowest:.3} | {:.3} | {:.0} | {} | {shares} | {:.2} | {:.3} | {:.1e} | {versus} |",
                case.label,
                sim.mesh.tets.len(),
                model,
                match (
                    sim.integrator.reads_f32(),
                    sim.integrator
                        .amg()
                        .is_some_and(|h| h.is_f32() && sim.integrator.used_amg()),
                ) {
                    (true, true) => "f32",
                    (true, false) => "f32 (blocks)",
                    (false, true) => "f32 (hierarchy)",
                    (false, false) => "f64",
                },
                tick,
                1e3 / tick,
                median(&mut elastic),
                median(&mut cg),
                update,
                sim.max_displacement() * 1e3,
                reaction.norm(),
                error,
            );
        }
    }
}

/// `LAPARO_THREADS` (the scene's `[mechanics] threads`), 1 unless set.
fn threads() -> usize {
    std::env::var("LAPARO_THREADS")
        .ok()
        .and_then(|t| t.parse().ok())
        .unwrap_or(1)
}

/// `LAPARO_STIFFNESS` (the scene's `[mechanics] stiffness`: `auto`, `f64` or
/// `f32`), `auto` unless set.
fn stiffness() -> StiffnessStorage {
    match std::env::var("LAPARO_STIFFNESS").as_deref() {
        Ok("f64") => StiffnessStorage::F64,
        Ok("f32") => StiffnessStorage::F32,
        Ok("auto") | Err(_) => StiffnessStorage::Auto,
        Ok(other) => panic!("LAPARO_STIFFNESS is auto, f64 or f32, not {other}"),
    }
}

/// [`TANGENT_TURN`], or `LAPARO_TANGENT_TURN` (rad) to measure another.
fn kept_turn() -> f64 {
    std::env::var("LAPARO_TANGENT_TURN")
        .ok()
        .and_then(|t| t.parse().ok())
        .unwrap_or(TANGENT_TURN)
}

/// `max_i |x_i − x_i^static| / max_i |u_i^static|` of `sim`'s state against the
/// static equilibrium of its current constraints, solved to a CG tolerance of 1e-9.
fn error_against_static(sim: &Simulation) -> f64 {
    let mut config = *sim.integrator.config();
    config.kind = IntegratorKind::Static;
    config.cg_tolerance = 1e-9;
    config.cg_max_iterations = 100_000;
    let mut static_solver = Integrator::new(config, &sim.model);
    let mut reference = sim.state.clone();
    let report = static_solver.solve_static(&sim.model, &mut reference, &sim.imposed, sim.gravity);
    if !report.converged {
        eprintln!(
            "{}: static reference not converged: {report:?}",
            sim.scene.name
        );
    }
    let scale = reference
        .x
        .iter()
        .zip(&sim.model.rest)
        .map(|(x, r)| (x - r).norm())
        .fold(0.0, f64::max);
    max_distance(&sim.state.x, &reference.x) / scale
}
