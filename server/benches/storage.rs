//! Whether the stiffness should be stored in f32: the product's time and error, and
//! the implicit solve's, with the blocks in f64 and in f32.
//!
//! `cargo bench -p laparo-server --bench storage`
//! (`LAPARO_MESH_DIR` for liver-20k and liver-80k; `-- liver-300k` or any labels to
//! run those meshes instead)
//!
//! For each mesh, the default scene's linear stiffness `K` (as loaded for one
//! thread) and the implicit operator of a 60 Hz tick, `A = (1 + hα) M + h² K`:
//!
//! - **the product** `K u` for a fixed pseudo-random `u`, by the engine's product on
//!   one part (`BlockMatrix::mul_shared` and `mul_shared_by`, one loop over
//!   either block type): the f64 blocks as stored, and a copy of them rounded to
//!   f32, each widened to f64 as it is read (vectors and sums stay f64). Median of
//!   [`PRODUCTS`] products each, the two kinds alternating; the
//!   relative error `‖K₃₂ u − K u‖ / ‖K u‖`. Halving the blocks halves the bytes a
//!   product streams (72 → 36 a block), which pays only if the product waits on
//!   memory;
//! - **the solve**: `A v = h M g` (the first tick's right-hand side under gravity,
//!   nothing imposed), block-Jacobi CG from zero to the scene's tolerance 1e-4 with
//!   each product, their iterations, median time of [`SOLVES`] solves, and how far
//!   the f32 solution lies from the f64 one, `‖v₃₂ − v₆₄‖ / ‖v₆₄‖`, against the
//!   error the tolerance itself leaves (the f64 solution against one to 1e-12).
//! - **the tick**: the default scene on the mesh (corotational, contact), settled
//!   for 0.5 s, then the left tip pressed straight in at the front point, 2 cm/s
//!   for [`PRESS_TICKS`] ticks (the corotational bench's gesture), with the scene's
//!   `stiffness` at `f64` and at `f32`, each preconditioner: median tick of each,
//!   the two run in turn twice in this process ([`ROUNDS`], each a fresh scene) so
//!   that the machine's drift falls on both, and the instrument's reaction at the
//!   end of each. `LAPARO_THREADS=2` runs these scenes on two threads.
//!
//! The scene setting this measures is `[mechanics] stiffness`
//! (`engine/integrate/storage.rs`, which gives the table).

mod common;

/// The contact tests' gestures; the tick part uses `front_point`.
#[path = "../tests/common/contact.rs"]
#[allow(dead_code)]
mod gestures;

use std::time::Instant;

use common::*;
use gestures::front_point;
use laparo_server::engine::contact::InstrumentPose;
use laparo_server::engine::elastic::{Formulation, Parts};
use laparo_server::engine::integrate::{
    CgWorkspace, IntegratorKind, PreconditionerKind, StiffnessStorage, Stop,
};
use nalgebra::{Matrix3, Unit, Vector3};

/// Products timed per kind and mesh.
const PRODUCTS: usize = 101;

/// Solves timed per kind and mesh.
const SOLVES: usize = 7;

/// Ticks settled before the press (0.5 s at 60 Hz), and ticks of the press, timed.
const SETTLE_TICKS: usize = 30;
const PRESS_TICKS: usize = 40;

/// Times each storage's scene is built and run, in turn.
const ROUNDS: usize = 2;

/// The tip's travel a tick (2 cm/s at 60 Hz) and its start outside the surface, m.
const STEP: f64 = 0.02 / 60.0;
const GAP: f64 = 0.002;

fn relative(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y).norm_squared()).sum();
    let n: f64 = b.iter().map(|y| y.norm_squared()).sum();
    (d / n).sqrt()
}

fn main() {
    println!(
        "| mesh | vertices | stored blocks | f64 blocks (MB) | product f64 (ms) | product f32 (ms) | f32 / f64 | product error | CG its f64 / f32 | solve f64 (ms) | solve f32 (ms) | f32 / f64 | f32 vs f64 solution | tolerance's own error |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let labels = requested_labels(&["sofa-liver", "liver-5k", "liver-20k", "liver-80k"]);
    for case in meshes(&labels) {
        let mut scene = scene(&case, IntegratorKind::Implicit, 1e-4);
        scene.material.model = Formulation::Linear;
        let sim = build(&scene);
        let k = &sim.model.stiffness;
        let n = k.rows();
        // A fixed pseudo-random u of unit scale (a Weyl sequence per component).
        let u: Vec<Vector3<f64>> = (0..n)
            .map(|i| {
                let f = |s: f64| ((i as f64 + 1.0) * s).fract() - 0.5;
                Vector3::new(f(0.618_033_988_7), f(0.414_213_562_4), f(0.732_050_807_6))
            })
            .collect();
        let one = Parts::new(n, 1, std::iter::empty());
        let mut k32 = vec![Matrix3::<f32>::zeros(); k.block.len()];
        k.round_f32_shared(None, &one, &mut k32);
        let (mut out64, mut out32) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]);
        let (mut t64, mut t32) = (Vec::new(), Vec::new());
        for _ in 0..PRODUCTS {
            let t = Instant::now();
            k.mul_shared(None, &one, |_| 0.0, 1.0, &u, &mut out64);
            t64.push(since(t) * 1e3);
            let t = Instant::now();
            k.mul_shared_by(&k32, None, &one, |_| 0.0, 1.0, &u, &mut out32);
            t32.push(since(t) * 1e3);
        }
        let product_error = relative(&out32, &out64);

        // The first implicit tick's system under gravity, nothing imposed.
        let h = 1.0 / scene.mechanics.rate_hz;
        let a = 1.0 + h * scene.mechanics.damping;
        let mass = &sim.model.mass;
        let g = Vector3::from(scene.gravity);
        let b: Vec<Vector3<f64>> = mass.iter().map(|&m| h * m * g).collect();
        let free = vec![false; n];
        let mut cg = CgWorkspace::new(n);
        for ((p, &m), &d) in cg.precond.iter_mut().zip(mass).zip(&k.diag) {
            let a_ii = Matrix3::identity() * (a * m) + h * h * k.block[d as usize];
            *p = a_ii.try_inverse().expect("A_ii is positive definite");
        }
        let reference = b.iter().map(|v| v.norm_squared()).sum::<f64>().sqrt();
        let stop = |tolerance| Stop {
            reference,
            tolerance,
            max_iterations: 20_000,
        };
        let mut solve = |f32: bool, tolerance| {
            let mut v = vec![Vector3::zeros(); n];
            let apply = |p: &[Vector3<f64>], out: &mut [Vector3<f64>]| {
                let m = |i: usize| a * mass[i];
                if f32 {
                    k.mul_shared_by(&k32, None, &one, m, h * h, p, out);
                } else {
                    k.mul_shared(None, &one, m, h * h, p, out);
                }
            };
            let t = Instant::now();
            let report = cg.solve(apply, &free, &b, &mut v, stop(tolerance));
            assert!(report.converged, "{}: CG converges", case.label);
            (v, report.iterations, since(t) * 1e3)
        };
        let (exact, _, _) = solve(false, 1e-12);
        let (mut s64, mut s32) = (Vec::new(), Vec::new());
        let (mut v64, mut v32) = (Vec::new(), Vec::new());
        let (mut i64_, mut i32_) = (0, 0);
        for _ in 0..SOLVES {
            let (v, i, t) = solve(false, 1e-4);
            (v64, i64_) = (v, i);
            s64.push(t);
            let (v, i, t) = solve(true, 1e-4);
            (v32, i32_) = (v, i);
            s32.push(t);
        }
        let (p64, p32) = (median(&mut t64), median(&mut t32));
        let (m64, m32) = (median(&mut s64), median(&mut s32));
        println!(
            "| {} | {} | {} | {:.2} | {:.3} | {:.3} | {:.2} | {:.1e} | {} / {} | {:.2} | {:.2} | {:.2} | {:.1e} | {:.1e} |",
            case.label,
            n,
            k.block.len(),
            k.block.len() as f64 * 72.0 / 1e6,
            p64,
            p32,
            p32 / p64,
            product_error,
            i64_,
            i32_,
            m64,
            m32,
            m32 / m64,
            relative(&v32, &v64),
            relative(&v64, &exact),
        );
    }
    println!();
    println!(
        "| mesh | preconditioner | median tick f64 (ms) | median tick f32 (ms) | f32 / f64 | CG its/tick | reaction f64, f32 (N) |"
    );
    println!("|---|---|---|---|---|---|---|");
    let threads = std::env::var("LAPARO_THREADS")
        .ok()
        .and_then(|t| t.parse().ok())
        .unwrap_or(1);
    for case in meshes(&labels) {
        for preconditioner in [PreconditionerKind::BlockJacobi, PreconditionerKind::Amg] {
            let mut ticks = [Vec::new(), Vec::new()];
            let (mut its, mut reaction) = (Vec::new(), [0.0; 2]);
            for _ in 0..ROUNDS {
                for (k, storage) in [StiffnessStorage::F64, StiffnessStorage::F32]
                    .into_iter()
                    .enumerate()
                {
                    let mut scene = scene(&case, IntegratorKind::Implicit, 1e-4);
                    scene.mechanics.preconditioner = preconditioner;
                    scene.mechanics.stiffness = storage;
                    scene.mechanics.threads = threads;
                    let (t, i, f) = press(&scene);
                    ticks[k].extend(t);
                    its.extend(i);
                    reaction[k] = f;
                }
            }
            let [mut t64, mut t32] = ticks;
            let (m64, m32) = (median(&mut t64), median(&mut t32));
            println!(
                "| {} | {preconditioner:?} | {m64:.3} | {m32:.3} | {:.2} | {:.0} | {:.4}, {:.4} |",
                case.label,
                m32 / m64,
                median(&mut its),
                reaction[0],
                reaction[1],
            );
        }
    }
}

/// The press of the module comment on `scene`: each press tick's time (ms) and CG
/// iterations, and the reaction on the instrument at the end (N).
fn press(scene: &laparo_server::engine::scene::Scene) -> (Vec<f64>, Vec<f64>, f64) {
    let mut sim = build(scene);
    for _ in 0..SETTLE_TICKS {
        sim.tick();
    }
    let start = front_point(&sim) + Vector3::z() * GAP;
    let axis = Unit::new_normalize(Vector3::z());
    let (mut ticks, mut its) = (Vec::new(), Vec::new());
    for k in 0..PRESS_TICKS {
        let tip = start - Vector3::z() * STEP * (k + 1) as f64;
        sim.set_pose(0, Some(InstrumentPose::new(tip, axis)));
        let t = Instant::now();
        let report = sim.tick();
        ticks.push(since(t) * 1e3);
        its.push(report.cg_iterations as f64);
    }
    (ticks, its, sim.instruments[0].report.reaction.norm())
}
