//! Shared by the engine's integration tests.
#![allow(dead_code)]

pub mod contact;
pub mod hertz;
pub mod process;

use laparo_server::engine::integrate::{IntegratorKind, mechanical_energy};
use laparo_server::engine::scene::Scene;
use laparo_server::engine::simulation::Simulation;

pub const SCENES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
pub const LIVER_5K: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/meshes/liver-5k.msh");

/// The default scene with its material, tick, integrator and mesh replaced, and a CG
/// tolerance of 1e-6 (the settling checks compare with the static answer at 1e-3).
pub fn default_variant(
    mesh_file: &str,
    e: f64,
    nu: f64,
    tick_s: f64,
    integrator: &str,
) -> Simulation {
    let mut scene = Scene::default_scene();
    scene.mesh.file = mesh_file.to_string();
    scene.material.young_modulus = e;
    scene.material.poisson_ratio = nu;
    scene.mechanics.rate_hz = 1.0 / tick_s;
    scene.mechanics.integrator = integrator_kind(integrator);
    scene.mechanics.cg_tolerance = 1e-6;
    scene.build().expect("variant builds")
}

/// The default scene made nearly incompressible (ν = 0.499), stepped by `integrator`,
/// its left instrument's friction replaced when `friction` is given.
pub fn nearly_incompressible(integrator: &str, friction: Option<f64>) -> Simulation {
    let mut scene = Scene::default_scene();
    scene.material.poisson_ratio = 0.499;
    scene.mechanics.integrator = integrator_kind(integrator);
    if let Some(mu) = friction {
        scene.instruments[0].friction = mu;
    }
    scene
        .build()
        .expect("the default scene at ν = 0.499 builds")
}

/// An integrator by its scene name.
pub fn integrator_kind(name: &str) -> IntegratorKind {
    match name {
        "explicit" => IntegratorKind::Explicit,
        "implicit" => IntegratorKind::Implicit,
        "static" => IntegratorKind::Static,
        other => panic!("no integrator {other}"),
    }
}

/// Largest vertex distance between two position sets, m.
pub fn max_distance(a: &[nalgebra::Point3<f64>], b: &[nalgebra::Point3<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max)
}

/// What a run to rest saw.
#[derive(Debug)]
pub struct Run {
    pub finite: bool,
    /// Largest total mechanical energy over the run, J (it starts at 0).
    pub max_energy: f64,
    /// Energy of the static equilibrium (its minimum), J.
    pub static_energy: f64,
    /// `max |x_T − x_static| / max |x_static − X|` at the end.
    pub settle_error: f64,
    /// How far the end state is from being an equilibrium itself:
    /// `‖(M g − f(x_T))_free‖ / ‖(M g)_free‖`, with `f(x)` the negated elastic force of
    /// [`ElasticModel::negated_elastic_force_at`](laparo_server::engine::elastic::ElasticModel::negated_elastic_force_at)
    /// (rotations extracted afresh), over the vertices not held.
    pub static_residual: f64,
    /// Ticks run.
    pub ticks: usize,
    pub substeps: u32,
    pub cg_iterations: u64,
}

/// Runs `sim` from rest for `seconds`, then compares with its static equilibrium.
pub fn run_to_rest(sim: Simulation, seconds: f64) -> Run {
    let ticks = (seconds / sim.dt).round() as usize;
    run_ticks_to_rest(sim, ticks)
}

/// Runs `sim` from rest for `ticks` ticks, then compares with its static equilibrium.
pub fn run_ticks_to_rest(mut sim: Simulation, ticks: usize) -> Run {
    let g = sim.gravity;
    let mut run = Run {
        finite: true,
        max_energy: 0.0,
        static_energy: 0.0,
        settle_error: 0.0,
        static_residual: 0.0,
        substeps: 0,
        cg_iterations: 0,
        ticks,
    };
    for _ in 0..ticks {
        let r = sim.tick();
        run.substeps = run.substeps.max(r.substeps);
        run.cg_iterations += r.cg_iterations as u64;
        let e = mechanical_energy(&sim.model, &sim.state, g);
        run.finite &= e.is_finite()
            && sim
                .state
                .x
                .iter()
                .all(|p| p.coords.iter().all(|c| c.is_finite()));
        if !run.finite {
            return run;
        }
        run.max_energy = run.max_energy.max(e);
    }
    run.static_residual = static_residual(&sim);
    let dynamic = sim.state.x.clone();
    let mut reference = sim.scene.build().expect("scene rebuilds");
    let report = reference.solve_static();
    assert!(
        report.converged,
        "static reference did not converge: {report:?}"
    );
    run.static_energy = mechanical_energy(&reference.model, &reference.state, g);
    run.settle_error = max_distance(&dynamic, &reference.state.x) / reference.max_displacement();
    run
}

/// `‖(M g − f(x))_free‖ / ‖(M g)_free‖` at the current state of `sim` (see
/// [`Run::static_residual`]): zero at an equilibrium under gravity and still supports.
pub fn static_residual(sim: &Simulation) -> f64 {
    let n = sim.model.vertex_count();
    let mut f = vec![nalgebra::Vector3::zeros(); n];
    sim.model.negated_elastic_force_at(&sim.state.x, &mut f);
    let mask = sim.imposed.mask();
    let (mut residual, mut load) = (0.0, 0.0);
    for i in (0..n).filter(|&i| !mask[i]) {
        let weight = sim.model.mass[i] * sim.gravity;
        residual += (weight - f[i]).norm_squared();
        load += weight.norm_squared();
    }
    (residual / load).sqrt()
}
