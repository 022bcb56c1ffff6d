//! The kept corotational tangent: the force exact, the tangent the sum of the
//! element stiffnesses at the rotations it kept, each within the allowed turn.

use nalgebra::{Point3, Rotation3, UnitQuaternion, Vector3};

use super::tests_corotational::{models, tangent_at};
use super::*;
use crate::engine::testing::liver_mesh;

/// The liver's rest points bent by an angle growing along x (`bend` rad per unit x)
/// about the y axis, with a twist: elements turn by different amounts, so small
/// increments of `bend` leave some under a given turn and take others over it.
fn bent(mesh: &TetMesh, bend: f64) -> Vec<Point3<f64>> {
    mesh.positions
        .iter()
        .map(|p| {
            let r = Rotation3::new(Vector3::new(0.2 * bend * p.z, bend * p.x, 0.0));
            r * p
        })
        .collect()
}

fn largest_entry(m: &BlockMatrix) -> f64 {
    m.block.iter().map(|b| b.abs().max()).fold(0.0, f64::max)
}

#[test]
fn a_kept_tangent_is_the_sum_at_the_rotations_it_kept() {
    // Forty small bends, then a large one: after each, the kept update's force must
    // be the full update's (the same rotations, extracted the same way), each kept
    // rotation within the turn of the extracted one, and the tangent the sum of the
    // rotated element stiffnesses at the kept rotations, to round-off (no drift from
    // the replacements), so within 2·turn of each element's stiffness of the exact
    // tangent.
    let mesh = liver_mesh();
    let (_, model) = models(&mesh, 0.45);
    let turn = 1e-3;
    // Σ ‖K_e‖_F over the elements that share each stored block.
    let rest = tangent_at(&mesh, &model, |_| nalgebra::Matrix3::identity());
    let mut share_bound = vec![0.0; rest.block.len()];
    for &t in &mesh.tets {
        let (g, v) = shape_gradients(&mesh.positions, t);
        let k = tet_stiffness(&g, v, &model.materials[0]);
        let norm = k
            .iter()
            .flatten()
            .map(|b| b.norm_squared())
            .sum::<f64>()
            .sqrt();
        for a in 0..4 {
            for b in 0..4 {
                if t[a] <= t[b] {
                    let slot = rest.find_upper(t[a], t[b]).expect("an edge");
                    share_bound[slot] += norm;
                }
            }
        }
    }
    let (mut kept, mut full) = (model.corotated().unwrap(), model.corotated().unwrap());
    let n = mesh.vertex_count();
    let (mut f_kept, mut f_full) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]);
    let (mut some_kept, mut some_reassembled) = (false, false);
    let bends = (1..=40).map(|k| 2e-4 * k as f64).chain([0.05]);
    for bend in bends {
        let x = bent(&mesh, bend);
        kept.update_tangent_within(&model, &x, &mut f_kept, turn);
        full.update(&model, &x, &mut f_full);
        let m = mesh.tets.len();
        some_kept |= kept.reassembled() < m;
        some_reassembled |= kept.reassembled() > 0;
        assert_eq!(full.reassembled(), m);
        let scale = f_full.iter().map(|f| f.norm()).fold(0.0, f64::max);
        for (a, b) in f_kept.iter().zip(&f_full) {
            assert!(
                (a - b).norm() <= 1e-12 * scale,
                "bend {bend}: force {a} vs {b}"
            );
        }
        for e in 0..m {
            let (q, qa) = (
                UnitQuaternion::from_matrix(&kept.rotation(e)),
                UnitQuaternion::from_matrix(&kept.assembled_rotation(e)),
            );
            assert!(q.angle_to(&qa) <= turn + 1e-9, "bend {bend}, element {e}");
        }
        let expected = tangent_at(&mesh, &model, |e| kept.assembled_rotation(e));
        let top = largest_entry(&expected);
        for (got, want) in kept.tangent.block.iter().zip(&expected.block) {
            assert!((got - want).abs().max() <= 1e-11 * top, "bend {bend}");
        }
        // Against the exact tangent: a block is a sum over the elements sharing it,
        // each off by at most 2·turn·‖K_e‖ (spectral, under Frobenius).
        let exact = tangent_at(&mesh, &model, |e| full.rotation(e));
        for (slot, ((a, b), bound)) in kept
            .tangent
            .block
            .iter()
            .zip(&exact.block)
            .zip(&share_bound)
            .enumerate()
        {
            let gap = (a - b).abs().max();
            assert!(
                gap <= 2.0 * turn * bound + 1e-11 * top,
                "bend {bend}, block {slot}: {gap:e} over {:e}",
                2.0 * turn * bound
            );
        }
    }
    assert!(
        some_kept && some_reassembled,
        "the bends exercise both branches"
    );
}
