//! Error against run time for the elastic liver.
//!
//! `cargo bench -p laparo-server --bench error_vs_time`
//!
//! The default scene (gravity on, 60 Hz ticks) on SOFA's liver and liver-20k, run
//! from rest for 3 s of simulated time — long enough for the physical transient to
//! die out (mass damping 10/s leaves e^{−15} ≈ 3e-7 of it) — and compared with the
//! static equilibrium solved to a CG tolerance of 1e-12. What is left is the
//! integrator's own error at rest: the explicit run's, and the implicit run's at each
//! CG tolerance. Error is max_i |x_i − x_i^static| / max_i |u_i^static|; cost is wall
//! time per simulated second (median of the repeats), on one core. Each elastic model
//! (linear, corotational) is compared with its own static equilibrium.

mod common;

use std::time::Instant;

use common::*;
use laparo_server::engine::elastic::Formulation;
use laparo_server::engine::integrate::IntegratorKind;
use laparo_server::engine::scene::Scene;

const SIMULATED: f64 = 3.0;

fn main() {
    println!(
        "| mesh | model | integrator | CG tolerance | relative error | wall s per simulated s | real-time factor | CG its/tick | repeats |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for case in meshes(&["sofa-liver", "liver-20k"]) {
        for model in [Formulation::Linear, Formulation::Corotational] {
            let scene = |case: &MeshCase, integrator, tol| -> Scene {
                let mut s = scene(case, integrator, tol);
                s.material.model = model;
                s
            };
            let mut reference = build(&scene(&case, IntegratorKind::Static, 1e-12));
            let r = reference.solve_static();
            assert!(r.converged, "static reference: {r:?}");
            let scale = reference.max_displacement();
            let repeats = if case.label == "sofa-liver" { 5 } else { 1 };
            let runs: Vec<(IntegratorKind, f64)> =
                std::iter::once((IntegratorKind::Explicit, 1e-6))
                    .chain([1e-2, 1e-3, 1e-4, 1e-6, 1e-8].map(|t| (IntegratorKind::Implicit, t)))
                    .collect();
            for (integrator, tol) in runs {
                let scene = scene(&case, integrator, tol);
                let (mut walls, mut error, mut cg) = (Vec::new(), 0.0, 0u64);
                for _ in 0..repeats {
                    let mut sim = build(&scene);
                    let ticks = (SIMULATED / sim.dt).round() as u64;
                    cg = 0;
                    let t = Instant::now();
                    for _ in 0..ticks {
                        cg += sim.tick().cg_iterations as u64;
                    }
                    walls.push(since(t) / SIMULATED);
                    error = sim
                        .state
                        .x
                        .iter()
                        .zip(&reference.state.x)
                        .map(|(a, b)| (a - b).norm())
                        .fold(0.0, f64::max)
                        / scale;
                    cg /= ticks;
                }
                let wall = median(&mut walls);
                let tol_col = if integrator == IntegratorKind::Explicit {
                    "—".to_string()
                } else {
                    format!("{tol:.0e}")
                };
                println!(
                    "| {} | {:?} | {:?} | {} | {:.2e} | {:.4} | {:.0}x | {} | {} |",
                    case.label,
                    model,
                    integrator,
                    tol_col,
                    error,
                    wall,
                    1.0 / wall,
                    cg,
                    repeats
                );
            }
        }
    }
}
