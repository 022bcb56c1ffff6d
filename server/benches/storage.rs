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
//! - **the product** `K u` for a fixed pseudo-random `u`, by one loop written once
//!   over either block type ([`product`]): the f64 blocks as stored, and a copy of
//!   them rounded to f32, each widened to f64 as it is read (vectors and sums stay
//!   f64). Median of [`PRODUCTS`] products each, the two kinds alternating; the
//!   relative error `‖K₃₂ u − K u‖ / ‖K u‖`. Halving the blocks halves the bytes a
//!   product streams (72 → 36 a block), which pays only if the product waits on
//!   memory;
//! - **the solve**: `A v = h M g` (the first tick's right-hand side under gravity,
//!   nothing imposed), block-Jacobi CG from zero to the scene's tolerance 1e-4 with
//!   each product, their iterations, median time of [`SOLVES`] solves, and how far
//!   the f32 solution lies from the f64 one, `‖v₃₂ − v₆₄‖ / ‖v₆₄‖`, against the
//!   error the tolerance itself leaves (the f64 solution against one to 1e-12).
//!
//! The product's f64 loop is the engine's (`BlockMatrix::mul`) for one part; the
//! table also gives the engine's own product time, which the f64 row should match.

mod common;

use std::time::Instant;

use common::*;
use laparo_server::engine::elastic::{BlockMatrix, Formulation};
use laparo_server::engine::integrate::{CgWorkspace, IntegratorKind, Stop};
use nalgebra::{Matrix3, Vector3};

/// Products timed per kind and mesh.
const PRODUCTS: usize = 101;

/// Solves timed per kind and mesh.
const SOLVES: usize = 7;

/// A stored block, read as f64.
trait Block: Copy {
    fn times(&self, u: &Vector3<f64>) -> Vector3<f64>;
    fn tr_times(&self, u: &Vector3<f64>) -> Vector3<f64>;
}

impl Block for Matrix3<f64> {
    #[inline(always)]
    fn times(&self, u: &Vector3<f64>) -> Vector3<f64> {
        self * u
    }
    #[inline(always)]
    fn tr_times(&self, u: &Vector3<f64>) -> Vector3<f64> {
        self.tr_mul(u)
    }
}

impl Block for Matrix3<f32> {
    #[inline(always)]
    fn times(&self, u: &Vector3<f64>) -> Vector3<f64> {
        self.cast::<f64>() * u
    }
    #[inline(always)]
    fn tr_times(&self, u: &Vector3<f64>) -> Vector3<f64> {
        self.cast::<f64>().tr_mul(u)
    }
}

/// `out = K u` over `k`'s pattern with the blocks `blocks` (`k.block` or a copy):
/// the engine's one-part loop, each upper block adding `K_ij u_j` to row `i` and
/// `K_ijᵀ u_i` to row `j`.
fn product<B: Block>(k: &BlockMatrix, blocks: &[B], u: &[Vector3<f64>], out: &mut [Vector3<f64>]) {
    out.iter_mut().for_each(|o| *o = Vector3::zeros());
    for i in 0..k.rows() {
        let (b, e) = (k.row_start[i] as usize, k.row_start[i + 1] as usize);
        let ui = u[i];
        let mut acc = blocks[b].times(&ui);
        for (m, &c) in blocks[b + 1..e].iter().zip(&k.col[b + 1..e]) {
            let c = c as usize;
            acc += m.times(&u[c]);
            out[c] += m.tr_times(&ui);
        }
        out[i] += acc;
    }
}

/// `out = K p` by one of the two storages.
type Product<'a> = dyn Fn(&[Vector3<f64>], &mut [Vector3<f64>]) + 'a;

fn relative(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y).norm_squared()).sum();
    let n: f64 = b.iter().map(|y| y.norm_squared()).sum();
    (d / n).sqrt()
}

fn main() {
    println!(
        "| mesh | vertices | stored blocks | f64 blocks (MB) | product f64 (ms) | product f32 (ms) | f32 / f64 | engine's product (ms) | product error | CG its f64 / f32 | solve f64 (ms) | solve f32 (ms) | f32 / f64 | f32 vs f64 solution | tolerance's own error |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let labels = requested_labels(&["sofa-liver", "liver-5k", "liver-20k", "liver-80k"]);
    for case in meshes(&labels) {
        let mut scene = scene(&case.file, IntegratorKind::Implicit, 1e-4);
        scene.material.model = Formulation::Linear;
        let sim = build(&scene);
        let k = &sim.model.stiffness;
        let n = k.rows();
        let k32: Vec<Matrix3<f32>> = k.block.iter().map(|b| b.cast::<f32>()).collect();
        // A fixed pseudo-random u of unit scale (a Weyl sequence per component).
        let u: Vec<Vector3<f64>> = (0..n)
            .map(|i| {
                let f = |s: f64| ((i as f64 + 1.0) * s).fract() - 0.5;
                Vector3::new(f(0.618_033_988_7), f(0.414_213_562_4), f(0.732_050_807_6))
            })
            .collect();
        let (mut out64, mut out32, mut engine) = (
            vec![Vector3::zeros(); n],
            vec![Vector3::zeros(); n],
            vec![Vector3::zeros(); n],
        );
        let (mut t64, mut t32, mut te) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..PRODUCTS {
            let t = Instant::now();
            product(k, &k.block, &u, &mut out64);
            t64.push(since(t) * 1e3);
            let t = Instant::now();
            product(k, &k32, &u, &mut out32);
            t32.push(since(t) * 1e3);
            let t = Instant::now();
            k.mul(&u, &mut engine);
            te.push(since(t) * 1e3);
        }
        assert_eq!(out64, engine, "the bench's f64 loop is the engine's");
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
        let mut solve = |blocks: &Product, tolerance| {
            let mut v = vec![Vector3::zeros(); n];
            let apply = |p: &[Vector3<f64>], out: &mut [Vector3<f64>]| {
                blocks(p, out);
                for i in 0..n {
                    out[i] = a * mass[i] * p[i] + h * h * out[i];
                }
            };
            let t = Instant::now();
            let report = cg.solve(apply, &free, &b, &mut v, stop(tolerance));
            assert!(report.converged, "{}: CG converges", case.label);
            (v, report.iterations, since(t) * 1e3)
        };
        let f64_op = |p: &[Vector3<f64>], out: &mut [Vector3<f64>]| product(k, &k.block, p, out);
        let f32_op = |p: &[Vector3<f64>], out: &mut [Vector3<f64>]| product(k, &k32, p, out);
        let (exact, _, _) = solve(&f64_op, 1e-12);
        let (mut s64, mut s32) = (Vec::new(), Vec::new());
        let (mut v64, mut v32) = (Vec::new(), Vec::new());
        let (mut i64_, mut i32_) = (0, 0);
        for _ in 0..SOLVES {
            let (v, i, t) = solve(&f64_op, 1e-4);
            (v64, i64_) = (v, i);
            s64.push(t);
            let (v, i, t) = solve(&f32_op, 1e-4);
            (v32, i32_) = (v, i);
            s32.push(t);
        }
        let (p64, p32, pe) = (median(&mut t64), median(&mut t32), median(&mut te));
        let (m64, m32) = (median(&mut s64), median(&mut s32));
        println!(
            "| {} | {} | {} | {:.2} | {:.3} | {:.3} | {:.2} | {:.3} | {:.1e} | {} / {} | {:.2} | {:.2} | {:.2} | {:.1e} | {:.1e} |",
            case.label,
            n,
            k.block.len(),
            k.block.len() as f64 * 72.0 / 1e6,
            p64,
            p32,
            p32 / p64,
            pe,
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
}
