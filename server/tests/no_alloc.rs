//! A mechanics step allocates nothing: every integrator's and the contact stage's
//! buffers are allocated when they are built. A counting global allocator counts the
//! allocations of each thread (the test harness prints from its own thread meanwhile).

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use laparo_server::engine::contact::InstrumentPose;
use laparo_server::engine::elastic::Formulation;
use laparo_server::engine::integrate::{IntegratorKind, PreconditionerKind, StiffnessStorage};
use laparo_server::engine::scene::Scene;
use nalgebra::{Point3, Unit, Vector3};

struct Counting;

thread_local! {
    /// Allocations made by this thread; const-initialised, so counting allocates nothing.
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn ticks_allocate_nothing() {
    let kinds = [
        IntegratorKind::Explicit,
        IntegratorKind::Implicit,
        IntegratorKind::Static,
    ];
    let models = [Formulation::Linear, Formulation::Corotational];
    let preconditioners = [PreconditionerKind::BlockJacobi, PreconditionerKind::Amg];
    let runs = kinds
        .into_iter()
        .flat_map(|k| models.map(|m| (k, m)))
        .flat_map(|(k, m)| preconditioners.map(|p| (k, m, p)));
    for (kind, model, preconditioner) in runs {
        let mut scene = Scene::default_scene();
        scene.mechanics.integrator = kind;
        scene.material.model = model;
        scene.mechanics.preconditioner = preconditioner;
        ticks_allocate_nothing_on(scene);
    }
}

/// The same on two threads: liver-5k split into two parts, the workers taking
/// chunks of the same loops. (The count is of this thread's allocations; a chunk
/// runs the same code on whichever thread takes it.)
#[test]
fn shared_ticks_allocate_nothing() {
    for kind in [IntegratorKind::Explicit, IntegratorKind::Implicit] {
        for model in [Formulation::Linear, Formulation::Corotational] {
            let mut scene = Scene::default_scene();
            scene.mesh.file = concat!(env!("CARGO_MANIFEST_DIR"), "/meshes/liver-5k.msh").into();
            scene.mechanics.integrator = kind;
            scene.mechanics.preconditioner = PreconditionerKind::BlockJacobi;
            scene.material.model = model;
            scene.mechanics.threads = 2;
            ticks_allocate_nothing_on(scene.clone());
            // The products reading an f32 copy of the stiffness, refreshed each
            // corotational tick.
            scene.mechanics.stiffness = StiffnessStorage::F32;
            ticks_allocate_nothing_on(scene.clone());
            // And the multigrid hierarchy held in f32, on one thread (the
            // explicit step has no solve: its run above covers it).
            if kind == IntegratorKind::Implicit {
                scene.mechanics.threads = 1;
                scene.mechanics.preconditioner = PreconditionerKind::Amg;
                ticks_allocate_nothing_on(scene);
            }
        }
    }
}

/// Twenty ticks of `scene`, five vertices moved and then released, allocate nothing.
fn ticks_allocate_nothing_on(scene: Scene) {
    let (kind, model, preconditioner) = (
        scene.mechanics.integrator,
        scene.material.model,
        scene.mechanics.preconditioner,
    );
    let mut sim = scene.build().unwrap();
    assert_eq!(
        sim.integrator.used_amg(),
        kind != IntegratorKind::Explicit && preconditioner == PreconditionerKind::Amg
    );
    // Move some vertices as an instrument would, so imposed targets change too.
    let held: Vec<u32> = (0..sim.mesh.vertex_count() as u32)
        .filter(|i| !sim.fixed.contains(i))
        .take(5)
        .collect();
    sim.tick();
    let before = allocations();
    for k in 0..20 {
        for &i in &held {
            let push = Vector3::new(0.0, 0.0, -0.0002 * k as f64);
            sim.imposed.set(i, sim.model.rest[i as usize] + push);
        }
        sim.tick();
        if k == 10 {
            for &i in &held {
                sim.imposed.release(i);
            }
        }
    }
    let after = allocations();
    assert_eq!(
        after - before,
        0,
        "{kind:?} {model:?} {preconditioner:?}: {} allocations in 20 ticks",
        after - before
    );
}

#[test]
fn contact_ticks_allocate_nothing() {
    // Both instruments press the front of the liver, one with its tip and one with its
    // shaft, turning as they go (so the stage takes several sub-moves a tick); with
    // and without the settling of the tissue around the contact's jumps, the second
    // with the tip's force scaled to its footprint.
    for model in [Formulation::Linear, Formulation::Corotational] {
        for preconditioner in [PreconditionerKind::BlockJacobi, PreconditionerKind::Amg] {
            for settle in [false, true] {
                let mut scene = Scene::default_scene();
                scene.material.model = model;
                scene.mechanics.preconditioner = preconditioner;
                scene.contact.settle = settle;
                scene.contact.footprint = settle;
                contact_ticks_allocate_nothing_with(scene.build().unwrap());
            }
        }
    }
}

fn contact_ticks_allocate_nothing_with(mut sim: laparo_server::engine::simulation::Simulation) {
    let (lo, _) = sim.mesh.bounding_box();
    let front = common::contact::front_point(&sim);
    let pose = |k: usize| {
        let s = k as f64 / 20.0;
        let tip = InstrumentPose::new(
            Point3::new(front.x, front.y, front.z + 0.004 - 0.015 * s),
            Unit::new_normalize(Vector3::new(0.3 * s, 0.0, 1.0)),
        );
        let shaft = InstrumentPose::new(
            Point3::new(lo.x - 0.02, front.y, front.z + 0.004 - 0.015 * s),
            Unit::new_normalize(Vector3::new(1.0, 0.1 * s, 0.0)),
        );
        (tip, shaft)
    };
    let (a, b) = pose(0);
    sim.set_pose(0, Some(a));
    sim.set_pose(1, Some(b));
    sim.tick();
    let before = allocations();
    for k in 1..=20 {
        let (a, b) = pose(k);
        sim.set_pose(0, Some(a));
        sim.set_pose(1, Some(b));
        sim.tick();
    }
    let after = allocations();
    let held: Vec<usize> = sim.instruments.iter().map(|i| i.held.len()).collect();
    assert!(
        held.iter().all(|&h| h > 0),
        "both instruments press: held {held:?}"
    );
    assert_eq!(
        after - before,
        0,
        "{} allocations in 20 contact ticks",
        after - before
    );
}
