use nalgebra::{Matrix3, Vector3};

use super::aggregate::{NONE, aggregate, strength};
use super::blocks::Blocks;
use super::dense::DenseCholesky;
use super::prolong::{BlockDiag, rigid_modes, smooth, spectral_radius, tentative};
use super::sparse::Csr;
use super::{Amg, THETA};
use crate::engine::integrate::PreconditionerKind;
use crate::engine::scene::Scene;
use crate::engine::simulation::Simulation;

const LIVER_5K: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/meshes/liver-5k.msh");

/// The default scene on `mesh` with the multigrid preconditioner, built.
fn scene_on(mesh: &str) -> Simulation {
    let mut scene = Scene::default_scene();
    scene.mesh.file = mesh.to_string();
    scene.mechanics.preconditioner = PreconditionerKind::Amg;
    scene.build().expect("the scene builds")
}

/// Reproducible pseudo-random block vector, zero where `mask` is set.
fn random(n: usize, seed: u64, mask: &[bool]) -> Vec<Vector3<f64>> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    (0..n)
        .map(|i| {
            let v = Vector3::new(next(), next(), next());
            if mask[i] { Vector3::zeros() } else { v }
        })
        .collect()
}

fn dot(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a.dot(b)).sum()
}

fn norm(a: &[Vector3<f64>]) -> f64 {
    dot(a, a).sqrt()
}

/// The scene's implicit operator `A = (1 + hα) M + h² K` as a product, and its
/// inverse diagonal blocks.
#[allow(clippy::type_complexity)]
fn operator(
    sim: &Simulation,
) -> (
    impl Fn(&[Vector3<f64>], &mut [Vector3<f64>]) + '_,
    Vec<Matrix3<f64>>,
) {
    let (model, h) = (&sim.model, sim.dt);
    let s_m = 1.0 + h * sim.integrator.config().damping;
    let op = move |p: &[Vector3<f64>], out: &mut [Vector3<f64>]| {
        model.stiffness.mul(p, out);
        for (i, o) in out.iter_mut().enumerate() {
            *o = s_m * model.mass[i] * p[i] + h * h * *o;
        }
    };
    let k = &model.stiffness;
    let dinv = (0..model.vertex_count())
        .map(|i| {
            (Matrix3::identity() * (s_m * model.mass[i]) + h * h * k.block[k.diag[i] as usize])
                .try_inverse()
                .unwrap()
        })
        .collect();
    (op, dinv)
}

#[test]
fn the_v_cycle_is_symmetric_positive_definite_on_the_free_vertices() {
    let sim = scene_on(LIVER_5K);
    let built: Amg = sim.integrator.amg().expect("a hierarchy was built").clone();
    let h = sim.dt;
    let s_m = 1.0 + h * sim.integrator.config().damping;
    assert_eq!(built.scales(), (s_m, h * h), "built for the scene's tick");
    let (op, dinv) = operator(&sim);
    let mask = sim.imposed.mask();
    assert!(mask.iter().any(|&m| m), "the scene has supports");
    let n = sim.model.vertex_count();
    // As built, and with its matrices rounded to f32.
    let mut rounded = built.clone();
    rounded.round_to_f32();
    assert!(!built.is_f32() && rounded.is_f32());
    for mut amg in [built, rounded] {
        let (mut bx, mut by) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]);
        for seed in 0..10 {
            let x = random(n, 2 * seed + 1, mask);
            let y = random(n, 2 * seed + 2, mask);
            amg.apply(&op, &dinv, mask, &x, &mut bx);
            amg.apply(&op, &dinv, mask, &y, &mut by);
            let (xby, bxy) = (dot(&x, &by), dot(&bx, &y));
            assert!(
                (xby - bxy).abs() <= 1e-12 * norm(&x) * norm(&by),
                "f32 {}: ⟨x, By⟩ = {xby:e}, ⟨Bx, y⟩ = {bxy:e}",
                amg.is_f32()
            );
            let xbx = dot(&x, &bx);
            assert!(xbx > 0.0, "⟨x, Bx⟩ = {xbx:e}");
            assert!(
                bx.iter()
                    .zip(mask)
                    .all(|(v, &m)| !m || *v == Vector3::zeros()),
                "zero on imposed vertices"
            );
        }
    }
}

#[test]
fn a_hierarchy_in_f32_is_the_f64_one_to_its_rounding_in_half_the_bytes() {
    let sim = scene_on(LIVER_5K);
    let mut exact: Amg = sim.integrator.amg().expect("a hierarchy was built").clone();
    let mut rounded = exact.clone();
    rounded.round_to_f32();
    // Rounding again keeps what the first rounding left.
    let mut twice = rounded.clone();
    twice.round_to_f32();
    assert_eq!(twice.matrix_bytes(), rounded.matrix_bytes());
    // The values halve (8 → 4 bytes an entry); the block indices stay.
    let (b64, b32) = (exact.matrix_bytes(), rounded.matrix_bytes());
    assert!(
        (b32 as f64) < 0.55 * b64 as f64,
        "{b32} bytes in f32 against {b64}"
    );
    let (op, dinv) = operator(&sim);
    let mask = sim.imposed.mask();
    let n = sim.model.vertex_count();
    let (mut z64, mut z32) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]);
    for seed in 0..5 {
        let r = random(n, seed + 100, mask);
        exact.apply(&op, &dinv, mask, &r, &mut z64);
        twice.apply(&op, &dinv, mask, &r, &mut z32);
        let again = z32.clone();
        rounded.apply(&op, &dinv, mask, &r, &mut z32);
        assert_eq!(
            again, z32,
            "rounded twice, the cycle is the once-rounded one"
        );
        let apart: Vec<Vector3<f64>> = z64.iter().zip(&z32).map(|(a, b)| a - b).collect();
        // Each stored entry moves by at most 2⁻²⁴ ≈ 6e-8 of itself, and the cycle
        // is a few products and a coarse solve of them: on liver-5k the two cycles
        // lie 2.0e-8 to 2.3e-8 apart; 1e-6 leaves a margin of forty.
        let relative = norm(&apart) / norm(&z64);
        assert!(relative <= 1e-6, "cycles apart by {relative:e}");
        assert!(relative > 0.0, "the rounding changed nothing: not applied?");
    }
}

#[test]
fn the_prolongators_reproduce_the_rigid_body_modes() {
    // K of liver-5k without supports: the six rigid modes are its nullspace.
    let sim = scene_on(LIVER_5K);
    let (k, n) = (&sim.model.stiffness, sim.model.vertex_count());
    let free = vec![false; n];
    let a = Csr::from_blocks(k, &sim.model.mass, 0.0, 1.0, &free);
    let node_start: Vec<usize> = (0..=n).map(|i| 3 * i).collect();
    let b = rigid_modes(&sim.model.rest);
    let s = strength(&a, &node_start, &free, THETA);
    let (agg, count) = aggregate(&s, &free);
    assert!(agg.iter().all(|&g| g != NONE), "every vertex is aggregated");
    assert!(
        count > 0 && count < n / 5,
        "{count} aggregates of {n} vertices"
    );
    let (p_tent, coarse_b, coarse_start) = tentative(&agg, count, &node_start, &b);
    assert_eq!(*coarse_start.last().unwrap(), p_tent.cols);
    assert_eq!(coarse_b.len(), p_tent.cols);
    let dinv = BlockDiag::new(&a, &node_start);
    let omega = 4.0 / (3.0 * spectral_radius(&a, &dinv));
    let p = smooth(&a, &dinv, &p_tent, omega);
    let (mut fine, mut kb) = (vec![0.0; 3 * n], vec![0.0; 3 * n]);
    for mode in 0..6 {
        let column: Vec<f64> = b.iter().map(|r| r[mode]).collect();
        let size = column.iter().map(|v| v * v).sum::<f64>().sqrt();
        // The mode is in K's nullspace (to round-off against K's scale)…
        a.mul(&column, &mut kb);
        let k_scale = a.val.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let residual = kb.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(residual <= 1e-10 * k_scale * size, "K b = {residual:e}");
        // …and both prolongators map its coarse coefficients onto it.
        let coarse: Vec<f64> = coarse_b.iter().map(|r| r[mode]).collect();
        for (name, p) in [("tentative", &p_tent), ("smoothed", &p)] {
            p.mul(&coarse, &mut fine);
            let error = fine
                .iter()
                .zip(&column)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(error <= 1e-10 * size, "{name} P b_c − b = {error:e}");
        }
    }
    // The cycle's block form of each prolongator and restriction is the same matrix.
    let x: Vec<f64> = (0..p.cols).map(|k| (k as f64 * 0.37).sin()).collect();
    let y: Vec<f64> = (0..p.rows).map(|k| (k as f64 * 0.11).cos()).collect();
    // (Equal to the summation order: within 1e-14 of the largest entry.)
    let close = |want: &[f64], got: &[f64], what: &str| {
        let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let worst = want
            .iter()
            .zip(got)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst <= 1e-14 * scale, "{what} in blocks: off by {worst:e}");
    };
    let (mut want, mut got) = (vec![0.0; p.rows], vec![0.0; p.rows]);
    p.mul(&x, &mut want);
    Blocks::<3, 6>::from_csr(&p).mul(&x, &mut got);
    close(&want, &got, "P");
    // Rounded to f32, each entry of the product moves by at most 2⁻²⁴ of
    // Σ_j |P_ij x_j| (each stored value by half an ulp of f32; the sums stay f64).
    let mut rounded = Blocks::<3, 6>::from_csr(&p);
    rounded.round_to_f32();
    let mut got32 = vec![0.0; p.rows];
    rounded.mul(&x, &mut got32);
    let abs_x: Vec<f64> = x.iter().map(|v| v.abs()).collect();
    let mut bound = vec![0.0; p.rows];
    Csr {
        val: p.val.iter().map(|v| v.abs()).collect(),
        ..p.clone()
    }
    .mul(&abs_x, &mut bound);
    for ((w, g), b) in want.iter().zip(&got32).zip(&bound) {
        assert!(
            (w - g).abs() <= 2f64.powi(-24) * b + 1e-15 * b,
            "P in f32: {g} against {w}, bound {b:e}"
        );
    }
    assert!(
        want.iter().zip(&got32).any(|(w, g)| w != g),
        "the rounding changed nothing"
    );
    let r = p.transpose();
    let (mut want, mut got) = (vec![0.0; r.rows], vec![0.0; r.rows]);
    r.mul(&y, &mut want);
    Blocks::<6, 3>::from_csr(&r).mul(&y, &mut got);
    close(&want, &got, "Pᵀ");
    // The tentative columns are orthonormal: Pᵀ P = I.
    let ptp = p_tent.transpose().times(&p_tent);
    for r in 0..ptp.rows {
        let (cs, vs) = ptp.row(r);
        for (&c, &v) in cs.iter().zip(vs) {
            let expected = if c as usize == r { 1.0 } else { 0.0 };
            assert!((v - expected).abs() < 1e-12, "(PᵀP)[{r}, {c}] = {v}");
        }
    }
}

#[test]
fn the_dense_factor_solves_exactly() {
    let n = 30;
    // A = Gᵀ G + I with G pseudo-random: symmetric positive definite.
    let g: Vec<f64> = (0..n * n)
        .map(|k| ((k * 7919) % 101) as f64 / 101.0 - 0.5)
        .collect();
    let a = |i: usize, j: usize| {
        (0..n).map(|k| g[k * n + i] * g[k * n + j]).sum::<f64>() + if i == j { 1.0 } else { 0.0 }
    };
    let f = DenseCholesky::new(n, a).expect("positive definite");
    let x: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
    let mut b: Vec<f64> = (0..n)
        .map(|i| (0..n).map(|j| a(i, j) * x[j]).sum())
        .collect();
    f.solve(&mut b);
    for (got, want) in b.iter().zip(&x) {
        assert!((got - want).abs() < 1e-12, "{got} against {want}");
    }
    assert!(
        DenseCholesky::new(2, |i, j| if i == j { 0.0 } else { 1.0 }).is_none(),
        "an indefinite matrix has no factor"
    );
}

#[test]
fn a_singular_coarsest_level_is_an_error_not_a_panic() {
    // K alone with no supports is singular: the hierarchy cannot be built.
    let sim = scene_on(LIVER_5K);
    let m = &sim.model;
    let free = vec![false; m.vertex_count()];
    let built = Amg::new(&m.stiffness, &m.mass, 0.0, 1.0, &free, &m.rest);
    assert!(
        matches!(built, Err(super::AmgError::NotPositiveDefinite { .. })),
        "{built:?}"
    );
}
