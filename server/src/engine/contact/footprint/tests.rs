//! The footprint scale on flat faces, where the shares and the patch radius are
//! known exactly.

use super::*;
use crate::engine::mesh::TetMesh;
use crate::engine::mesh::generate::kuhn_box;
use nalgebra::{Point3, Rotation3, Vector3};

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

/// Gauss's mean against his integral `∫₀^{π/2} dθ / √(a² cos²θ + b² sin²θ) = π / (2
/// AGM(a, b))`, summed by the trapezoid rule (the integrand is smooth and periodic:
/// 4,000 points are exact to rounding down to `b/a = 10⁻²`), and against the known
/// `AGM(1, √2) = 1.198140234735592207…`.
#[test]
fn the_mean_of_gauss_is_his_elliptic_integral() {
    let integral = |a: f64, b: f64| {
        let n = 4000;
        let h = std::f64::consts::FRAC_PI_2 / n as f64;
        let f = |t: f64| 1.0 / (a * a * t.cos().powi(2) + b * b * t.sin().powi(2)).sqrt();
        h * ((f(0.0) + f(std::f64::consts::FRAC_PI_2)) / 2.0
            + (1..n).map(|k| f(k as f64 * h)).sum::<f64>())
    };
    for (a, b) in [
        (1.0, 1.0),
        (1.0, 0.5),
        (0.03, 0.005),
        (2.0, 0.02),
        (1.0, 0.01),
    ] {
        let expected = std::f64::consts::FRAC_PI_2 / integral(a, b);
        for m in [agm(a, b), agm(b, a)] {
            assert!(
                (m - expected).abs() <= 1e-12 * expected,
                "AGM({a}, {b}) = {m}, the integral gives {expected}"
            );
        }
    }
    let gauss = 1.198_140_234_735_592_2;
    assert!((agm(1.0, 2f64.sqrt()) - gauss).abs() <= 1e-15 * gauss);
}

/// The scale of `patch` under a shaft of radius `r` along `axis` through `on_axis`.
fn strip_scale(
    mesh: &TetMesh,
    patch: &[(u32, Vector3<f64>)],
    (on_axis, axis): (Point3<f64>, Vector3<f64>),
    r: f64,
) -> f64 {
    shaft_scale(
        patch.iter().copied(),
        &mesh.surface,
        &mesh.positions,
        (&on_axis, &Unit::new_normalize(axis)),
        r,
    )
}

/// A shaft of radius `r` lying on the top face along x, turned by `turn`: a point of
/// its axis and the axis.
fn shaft(turn: &Rotation3<f64>, r: f64) -> (Point3<f64>, Vector3<f64>) {
    (turn * Point3::new(0.0, 0.0, r), turn * Vector3::x())
}

/// The top face's rows within `half_width` of its middle line `y = 0`, each pushing
/// the shaft `(on_axis, axis)` toward its axis with 0.3 N (a strip along x).
fn strip(
    mesh: &TetMesh,
    turn: &Rotation3<f64>,
    half_width: f64,
    (on_axis, axis): (Point3<f64>, Vector3<f64>),
) -> Vec<(u32, Vector3<f64>)> {
    top(mesh, turn)
        .into_iter()
        .filter(|&v| (turn.inverse() * mesh.positions[v as usize]).y.abs() <= half_width + 1e-12)
        .map(|v| {
            let d = mesh.positions[v as usize] - on_axis;
            (v, 0.3 * (d.dot(&axis) * axis - d).normalize())
        })
        .collect()
}

/// A strip of three rows (y = −5, 0, 5 mm) along the whole face under a shaft along
/// x: its shares make a band 15 mm wide and 40 mm long, `A = 600 mm²` exactly (each
/// triangle between the last row and the next has one or two corners in it, half of
/// its square). Taken as a uniform rectangle, the equivalent ellipse has `a = L/√3`
/// (the rectangle's second moment `L²/12 = a²/4`) and `b = A/(π a)`; the scale is
/// `AGM(a, r)/AGM(a, b)`. The point shares sum the second moment by the trapezoid
/// rule with each share's own spread, 4.5% above the rectangle's: the scale,
/// logarithmic in `a`, within 1.5% of the rectangle's.
/// Turning the block with the shaft changes nothing.
#[test]
fn a_strip_is_scaled_as_an_elliptical_punch() {
    let r = 0.005;
    let mesh = block(Rotation3::identity());
    let line = shaft(&Rotation3::identity(), r);
    let patch = strip(&mesh, &Rotation3::identity(), 0.005, line);
    let s = strip_scale(&mesh, &patch, line, r);
    let (length, area) = (2.0 * HALF, 2.0 * HALF * 0.015);
    let a = length / 3f64.sqrt();
    let b = area / (std::f64::consts::PI * a);
    let expected = agm(a, r) / agm(a, b);
    assert!(expected < 0.95, "the case should scale: {expected}");
    assert!(
        (s - expected).abs() <= 1.5e-2 * expected,
        "{s} vs the rectangle's {expected}"
    );

    let turn = Rotation3::from_euler_angles(1.1, -0.7, 2.3);
    let mesh = block(turn);
    let line = shaft(&turn, r);
    let patch = strip(&mesh, &turn, 0.005, line);
    let turned = strip_scale(&mesh, &patch, line, r);
    assert!((turned - s).abs() <= 1e-12 * s, "{turned} vs {s}");
}

/// The wider the strip, the smaller the scale, and always milder than the tip's rule
/// would be for the same width (`r / b`): a line contact's force grows with its width
/// only through a logarithm. A strip no wider than the shaft (one row, 5 mm of band
/// for a 5 mm radius) is left alone, and nothing pushing is no strip.
#[test]
fn a_wider_strip_is_scaled_more_but_less_than_its_width() {
    let r = 0.005;
    let mesh = block(Rotation3::identity());
    let line = shaft(&Rotation3::identity(), r);
    let mut last = 1.0;
    for rows in 1..=3 {
        let half_width = 0.005 * f64::from(rows);
        let patch = strip(&mesh, &Rotation3::identity(), half_width, line);
        let s = strip_scale(&mesh, &patch, line, r);
        let a = 2.0 * HALF / 3f64.sqrt();
        let b = 2.0 * HALF * (2.0 * half_width + 0.005) / (std::f64::consts::PI * a);
        assert!(s < last, "{rows} rows each side: {s} after {last}");
        assert!(
            s > r / b,
            "{rows} rows each side: {s} against the width's {}",
            r / b
        );
        last = s;
    }
    let one_row = strip(&mesh, &Rotation3::identity(), 0.0, line);
    assert_eq!(strip_scale(&mesh, &one_row, line, r), 1.0);
    let wide = strip(&mesh, &Rotation3::identity(), 0.01, line);
    let pulled: Vec<_> = wide.iter().map(|&(v, f)| (v, -f)).collect();
    assert!(strip_scale(&mesh, &wide, line, r) < 1.0);
    assert_eq!(strip_scale(&mesh, &pulled, line, r), 1.0);
    assert_eq!(strip_scale(&mesh, &[], line, r), 1.0);
}
