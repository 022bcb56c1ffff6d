//! Step time of each integrator against mesh size.
//!
//! `cargo bench -p laparo-server --bench step`
//!
//! The default scene (liver at 0.19 m, E = 4.5 kPa, ν = 0.45, gravity, 60 Hz ticks,
//! held at its upper face and underside) on meshes from 596 to 309k tetrahedra,
//! explicit and implicit (CG tolerance 1e-4, the default), from rest: the ticks measured are the
//! gravity transient, the busiest part of the run for CG. Then, where the budget
//! allows (meshes up to liver-20k), the run continues to 2 s simulated and 30 ticks are
//! timed at rest. One core. Explicit runs the default scene's elastic model
//! (`[material] model`); implicit runs the linear and the corotational model, each
//! with both preconditioners (`[mechanics] preconditioner`: block Jacobi and
//! smoothed-aggregation multigrid), on the same ticks.
//! Reports per mesh: median tick times, ticks per second, substeps or CG iterations
//! per tick (median over the timed ticks, and over the first ten, which every mesh
//! times), the achieved bytes per second, the memory the model and
//! integrator hold, the multigrid setup (the hierarchy built once more, timed alone:
//! seconds, and unknowns per level), and the median of each stage of the transient ticks as
//! `TickTiming` names them (`carry_held_vertices`, `elastic_step`, `resolve_contact`,
//! `local_models`; the instruments stay out of the body, so the contact stages do
//! almost nothing).
//!
//! `-- liver-300k` (or any labels) runs those meshes instead of all five.
//!
//! Achieved bytes per second: the bytes one tick streams, each array counted once per
//! pass that reads or writes it, over the median tick. A product `K p` reads the
//! stiffness blocks (in f32 where the scene's `[mechanics] stiffness` reads them so:
//! liver-300k under `auto`) and indices, the masses and `p` and writes its result; a CG
//! iteration adds ten block vectors for its updates and dot products and the inverse
//! diagonal blocks of block Jacobi, or a V-cycle: two products of the tick's
//! operator and what `Amg::cycle_bytes` counts (the prolongators, restrictions and
//! coarse operators as held, their vectors, the coarsest factor read twice); a
//! corotational tick first reads every element and
//! the positions and writes `K̂` twice (zeroed, then summed into) and the offset; an
//! explicit substep is a force evaluation (the product, or the element pass when
//! corotational) and four vector passes for positions and velocities. Cache reuse is
//! not credited: it is what the solver moves, not what memory delivered.

mod common;

use std::time::Instant;

use common::*;
use laparo_server::engine::elastic::{Element, Formulation};
use laparo_server::engine::integrate::amg::Amg;
use laparo_server::engine::integrate::{IntegratorKind, PreconditionerKind};
use laparo_server::engine::simulation::Simulation;

/// The ticks every mesh times, from rest: the CG iterations over these compare the
/// meshes at the same instants of the gravity transient (the column "CG its/tick"
/// is over all timed ticks, fewer on the large meshes, whose budget ends sooner).
const FIRST_TICKS: usize = 10;

fn main() {
    let labels = requested_labels(&[
        "sofa-liver",
        "liver-5k",
        "liver-20k",
        "liver-80k",
        "liver-300k",
    ]);
    println!(
        "| mesh | vertices | tets | model | integrator | preconditioner | median tick, transient (ms) | ticks/s | substeps/tick | CG its/tick | CG its/tick, ticks 1–10 | achieved GB/s | median tick at rest (ms) | ticks/s at rest | memory (MB) | multigrid setup (s) | multigrid levels (unknowns) | ticks timed | stages, transient: carry / elastic / resolve / local models (ms) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for case in meshes(&labels) {
        let mut runs = vec![(
            IntegratorKind::Explicit,
            None,
            PreconditionerKind::BlockJacobi,
        )];
        for model in [Formulation::Linear, Formulation::Corotational] {
            for preconditioner in [PreconditionerKind::BlockJacobi, PreconditionerKind::Amg] {
                runs.push((IntegratorKind::Implicit, Some(model), preconditioner));
            }
        }
        for (integrator, model, preconditioner) in runs {
            let mut scene = scene(&case, integrator, 1e-4);
            if let Some(model) = model {
                scene.material.model = model;
            }
            scene.mechanics.preconditioner = preconditioner;
            let mut sim = build(&scene);
            let (setup, levels) = multigrid_setup(&sim);
            let memory = sim.model.heap_bytes()
                + sim.integrator.heap_bytes()
                + 3 * 24 * sim.mesh.vertex_count();
            // Time up to 60 ticks (1 s simulated) or about 8 s of wall time.
            let (mut times, mut substeps, mut cg, mut bytes) =
                (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            let mut stages: [Vec<f64>; 4] = Default::default();
            let budget = Instant::now();
            // Implicit runs time at least FIRST_TICKS; explicit ones, which have no CG
            // and take seconds a tick on liver-300k, at least 3.
            let least = if integrator == IntegratorKind::Explicit {
                3
            } else {
                FIRST_TICKS
            };
            while times.len() < 60 && (times.len() < least || since(budget) < 8.0) {
                let t = Instant::now();
                let r = sim.tick();
                let elapsed = since(t);
                times.push(elapsed);
                bytes.push(tick_bytes(&sim, r.substeps, r.cg_iterations) / elapsed);
                substeps.push(r.substeps as f64);
                cg.push(r.cg_iterations as f64);
                let t = sim.last_timing;
                let parts = [
                    t.carry_held_vertices,
                    t.elastic_step,
                    t.resolve_contact,
                    t.local_models,
                ];
                for (stage, part) in stages.iter_mut().zip(parts) {
                    stage.push(part);
                }
            }
            let n = times.len();
            let mut first = cg[..FIRST_TICKS.min(n)].to_vec();
            let first_cg = median(&mut first);
            let tick = median(&mut times);
            let at_rest = if sim.mesh.tets.len() <= 25_000 {
                while sim.time < 2.0 {
                    sim.tick();
                }
                let mut rest: Vec<f64> = (0..30)
                    .map(|_| {
                        let t = Instant::now();
                        sim.tick();
                        since(t)
                    })
                    .collect();
                let m = median(&mut rest);
                format!("{:.3} | {:.0}", m * 1e3, 1.0 / m)
            } else {
                "— | —".to_string()
            };
            let [carry, elastic, resolve, local] = stages.map(|mut v| median(&mut v) * 1e3);
            let precond = match integrator {
                IntegratorKind::Explicit => "—",
                _ if sim.integrator.used_amg() => "amg",
                _ => "block-jacobi",
            };
            let gbs = format!("{:.2}", median(&mut bytes) / 1e9);
            println!(
                "| {} | {} | {} | {:?} | {:?} | {precond} | {:.3} | {:.0} | {:.0} | {:.0} | {first_cg:.0} | {gbs} | {} | {:.1} | {setup} | {levels} | {} | {carry:.4} / {elastic:.3} / {resolve:.4} / {local:.4} |",
                case.label,
                sim.mesh.vertex_count(),
                sim.mesh.tets.len(),
                sim.model.formulation,
                integrator,
                tick * 1e3,
                1.0 / tick,
                median(&mut substeps),
                median(&mut cg),
                at_rest,
                memory as f64 / 1e6,
                n
            );
        }
    }
}

/// The multigrid hierarchy of `sim`'s implicit matrix built once more, timed alone
/// (seconds), and its unknowns per level, finest first; dashes without multigrid.
fn multigrid_setup(sim: &Simulation) -> (String, String) {
    if !sim.integrator.used_amg() {
        return ("—".to_string(), "—".to_string());
    }
    let (m, h) = (&sim.model, sim.dt);
    let s_m = 1.0 + h * sim.integrator.config().damping;
    let t = Instant::now();
    let amg = Amg::new(
        &m.stiffness,
        &m.mass,
        s_m,
        h * h,
        sim.imposed.mask(),
        &m.rest,
    )
    .expect("the hierarchy builds");
    let seconds = since(t);
    let sizes = amg.coarse_sizes();
    let mut levels = vec![format!(
        "{} (P {:.1} M)",
        3 * m.vertex_count(),
        sizes.prolongator_nonzeros[0] as f64 / 1e6
    )];
    for (k, (n, nnz)) in sizes.unknowns.iter().zip(&sizes.nonzeros).enumerate() {
        let p = sizes
            .prolongator_nonzeros
            .get(k + 1)
            .map_or(String::new(), |p| format!(", P {:.2} M", *p as f64 / 1e6));
        levels.push(format!("{n} (A {:.2} M{p})", *nnz as f64 / 1e6));
    }
    (format!("{seconds:.2}"), levels.join(" / "))
}

/// Bytes one tick streams, each array counted once per pass (see the module comment).
fn tick_bytes(sim: &Simulation, substeps: u32, cg_iterations: u32) -> f64 {
    let n = sim.mesh.vertex_count() as f64;
    let vector = 24.0 * n;
    let k = sim.model.stiffness.heap_bytes() as f64;
    let product = k + 8.0 * n + 2.0 * vector;
    let corotational = sim.model.formulation == Formulation::Corotational;
    // Elements and positions read; K̂ zeroed and summed into; offset and force written.
    let elements = (sim.model.elements.len() * std::mem::size_of::<Element>()) as f64;
    let update = elements + vector + 2.0 * k + 2.0 * vector;
    if sim.integrator.config().kind == IntegratorKind::Explicit {
        let force = if corotational {
            elements + 2.0 * vector
        } else {
            product
        };
        return f64::from(substeps) * (force + 4.0 * vector);
    }
    let multigrid = sim.integrator.amg().filter(|_| sim.integrator.used_amg());
    // The solve's products read the f32 copy of the blocks when the scene's
    // `stiffness` says so (liver-300k under `auto`): half the blocks' bytes, and
    // the corotational K̂ read once more and the copy written each tick.
    let blocks = (sim.model.stiffness.block.len() * 72) as f64;
    let (solve_product, rounding) = if sim.integrator.reads_f32() {
        let rounding = if corotational { 1.5 * blocks } else { 0.0 };
        (product - 0.5 * blocks, rounding)
    } else {
        (product, 0.0)
    };
    // The update (corotational) or a product for the right-hand side, the first
    // residual, then per iteration a product, the updates and the preconditioner.
    let start = if corotational { update } else { product };
    let its = f64::from(cg_iterations);
    // One application of the preconditioner: block Jacobi's z = D⁻¹ r, once at the
    // start and once an iteration; or a V-cycle, its own traffic and its products
    // of the operator (`Amg::cycle_bytes`), once at the start and once an iteration
    // but the last (a converged solve skips it).
    let (precond, applications) = match multigrid {
        None => (72.0 * n + 2.0 * vector, its + 1.0),
        Some(amg) => (
            amg.cycle_bytes() as f64 + amg.operator_products() as f64 * solve_product,
            its.max(1.0),
        ),
    };
    start
        + rounding
        + solve_product
        + its * (solve_product + 10.0 * vector)
        + applications * precond
}
