//! The footprint scale on flat faces, where the shares and the patch radius are
//! known exactly.

use super::*;
use crate::engine::mesh::TetMesh;
use crate::engine::mesh::generate::kuhn_box;
use nalgebra::{Rotation3, Vector3};

/// Half the width of the test block's top face, m.
const HALF: f64 = 0.02;

/// A 40 × 40 × 10 mm block of 8 × 8 × 2 cubes, top face at `z = 0`, turned by `turn`.
fn block(turn: Rotation3<f64>) -> TetMesh {
    let (positions, tets) = kuhn_box(
        [8, 8, 2],
        [2.0 * HALF, 2.0 * HALF, 0.01],
        [-HALF, -HALF, -0.01],
    );
    let positions = positions.into_iter().map(|p| turn * p).collect();
    TetMesh::from_tets(positions, tets).expect("the block is valid")
}

/// The block unturned, with its top face's vertices.
fn unturned() -> (TetMesh, Vec<u32>) {
    let mesh = block(Rotation3::identity());
    let top = top(&mesh, &Rotation3::identity());
    (mesh, top)
}

/// The top face's vertices (before the turn, `z = 0`).
fn top(mesh: &TetMesh, turn: &Rotation3<f64>) -> Vec<u32> {
    top_within(mesh, turn, HALF)
}

/// The top face's vertices within `half` of its middle in x and y.
fn top_within(mesh: &TetMesh, turn: &Rotation3<f64>, half: f64) -> Vec<u32> {
    mesh.surface
        .vertices
        .iter()
        .copied()
        .filter(|&v| {
            let p = turn.inverse() * mesh.positions[v as usize];
            p.z.abs() < 1e-12 && p.x.abs() <= half + 1e-12 && p.y.abs() <= half + 1e-12
        })
        .collect()
}

fn scale(mesh: &TetMesh, patch: &[(u32, Vector3<f64>)], axis: Vector3<f64>, r: f64) -> f64 {
    tip_scale(
        patch.iter().copied(),
        &mesh.surface,
        &mesh.positions,
        &Unit::new_normalize(axis),
        r,
    )
}

/// Every top vertex pressed equally: the shares are a partition of the top face (each
/// triangle counted a third by each of its corners), so `A_h` is the face's area and
/// the scale `r / √(4 HALF² / π)`, whatever the triangulation. The side faces, seen
/// edge-on along the axis, add nothing.
#[test]
fn a_patch_of_equal_pushes_is_as_wide_as_its_surface() {
    let (mesh, top) = unturned();
    let push = Vector3::new(0.0, 0.0, 0.3);
    let patch: Vec<_> = top.into_iter().map(|v| (v, push)).collect();
    let r = 0.005;
    let expected = r / (4.0 * HALF * HALF / std::f64::consts::PI).sqrt();
    let s = scale(&mesh, &patch, Vector3::z(), r);
    assert!(
        (s - expected).abs() <= 1e-12 * expected,
        "{s} vs {expected}"
    );
}

/// A patch of the top face's inner vertices (all their triangles on the face) seen
/// along an axis tilted by θ from the face's normal projects to `cos θ` of its area:
/// the scale grows by `1/√cos θ`. Turning the block and the axis together changes
/// nothing.
#[test]
fn the_patch_is_seen_along_the_axis_and_turns_with_the_body() {
    let r = 0.005;
    let inner = |mesh: &TetMesh, turn: &Rotation3<f64>| top_within(mesh, turn, HALF / 2.0);
    let reference = {
        let mesh = block(Rotation3::identity());
        let patch: Vec<_> = inner(&mesh, &Rotation3::identity())
            .into_iter()
            .map(|v| (v, Vector3::z()))
            .collect();
        scale(&mesh, &patch, Vector3::z(), r)
    };
    let theta = 0.4f64;
    let tilted = Rotation3::from_axis_angle(&Vector3::x_axis(), theta) * Vector3::z();
    let mesh = block(Rotation3::identity());
    let patch: Vec<_> = inner(&mesh, &Rotation3::identity())
        .into_iter()
        .map(|v| (v, tilted))
        .collect();
    let s = scale(&mesh, &patch, tilted, r);
    let expected = reference / theta.cos().sqrt();
    assert!(
        (s - expected).abs() <= 1e-12 * expected,
        "{s} vs {expected}"
    );

    let turn = Rotation3::from_euler_angles(1.1, -0.7, 2.3);
    let mesh = block(turn);
    let axis = turn * Vector3::z();
    let patch: Vec<_> = inner(&mesh, &turn).into_iter().map(|v| (v, axis)).collect();
    let s = scale(&mesh, &patch, axis, r);
    assert!(
        (s - reference).abs() <= 1e-12 * reference,
        "{s} vs {reference}"
    );
}

/// A vertex that carries nothing widens nothing (so the force does not jump when the
/// stage takes or lets go of one), one pulled away neither, and one pushed with half
/// the mean counts half its share: the shares are weighed by `min(1, N_i / N̄)`.
#[test]
fn a_vertex_counts_as_far_as_it_pushes() {
    let (mesh, top) = unturned();
    let r = 0.001;
    let (inner, rest) = top.split_at(top.len() / 2);
    let push = Vector3::new(0.02, -0.01, 0.4);
    let base: Vec<_> = inner.iter().map(|&v| (v, push)).collect();
    let s0 = scale(&mesh, &base, Vector3::z(), r);
    assert!(s0 < 1.0);

    for extra in [Vector3::zeros(), Vector3::new(0.1, 0.0, -0.2)] {
        let mut with = base.clone();
        with.push((rest[0], extra));
        // The mean falls to (n/(n+1)) of the push, so each pushing vertex still
        // counts in full.
        let s = scale(&mesh, &with, Vector3::z(), r);
        assert!((s - s0).abs() <= 1e-12 * s0, "{extra:?}: {s} vs {s0}");
    }

    // Half the pushing vertices at half the push: with N̄ = 3/4 of the full push, a
    // half-push vertex counts 2/3 of its share.
    let half: Vec<_> = base
        .iter()
        .enumerate()
        .map(|(i, &(v, f))| (v, if i % 2 == 0 { f } else { f * 0.5 }))
        .collect();
    let full_area = std::f64::consts::PI * (r / s0).powi(2);
    let full_only: Vec<_> = half.iter().copied().step_by(2).collect();
    let halves: Vec<_> = half.iter().copied().skip(1).step_by(2).collect();
    let area_of = |p: &[(u32, Vector3<f64>)]| {
        let s = scale(
            &mesh,
            &p.iter().map(|&(v, _)| (v, push)).collect::<Vec<_>>(),
            Vector3::z(),
            r,
        );
        std::f64::consts::PI * (r / s).powi(2)
    };
    let expected = area_of(&full_only) + 2.0 / 3.0 * area_of(&halves);
    assert!((area_of(&base) - full_area).abs() <= 1e-12 * full_area);
    let s = scale(&mesh, &half, Vector3::z(), r);
    let area = std::f64::consts::PI * (r / s).powi(2);
    assert!(
        (area - expected).abs() <= 1e-12 * expected,
        "{area} vs {expected}"
    );
}

/// A patch narrower than the tip is the tip's own, and nothing pushing is no patch.
#[test]
fn a_patch_within_the_tip_is_left_alone() {
    let (mesh, top) = unturned();
    let patch: Vec<_> = top.into_iter().map(|v| (v, Vector3::z())).collect();
    assert_eq!(scale(&mesh, &patch, Vector3::z(), 0.05), 1.0);
    let pulled: Vec<_> = patch.iter().map(|&(v, f)| (v, -f)).collect();
    assert_eq!(scale(&mesh, &pulled, Vector3::z(), 0.001), 1.0);
    assert_eq!(scale(&mesh, &[], Vector3::z(), 0.001), 1.0);
}
