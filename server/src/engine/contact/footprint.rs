//! The tip's footprint: the press of the instrument's own tip, not of the patch of
//! vertices the mesh holds.
//!
//! The tip press (§2.5) lays the whole triangle under the tip on the tip plane, and
//! the push-out holds the vertices nearest the instrument: a mesh whose edges are
//! longer than the tip's radius imposes the tip's motion on a patch of surface wider
//! than the tip. The elastic reaction of that patch is the force of a wider punch.
//! For a rigid flat punch of radius `a` stuck to an elastic half-space, the force of
//! an indentation `d` is `2 E* a d` (Sneddon 1965) and that of a sideways shift `δ`
//! is `8 G a δ / (2 − ν)` (Mindlin 1949): at a given motion both grow with the
//! footprint's radius, and a body's shape adds a factor that does not depend on `a`
//! while `a` is small beside the body. So the tissue's force on the tip's end is
//! taken as the held patch's elastic reactions scaled by `min(1, r / a_h)`, where
//!
//! - `r` is the instrument's radius, the widest its hemispherical tip touches (a
//!   shallower press touches less: then the scale is too large, never too small, and
//!   on a mesh that resolves the contact, as the Hertz block does, it is 1);
//! - `a_h = √(A_h / π)` is the held patch's equivalent radius: `A_h` is the sum over
//!   the tip's held vertices of their share of surface (a third of each triangle
//!   around them, projected on the tip's plane), each counted in proportion to the
//!   normal force `N_i` it carries, up to the patch's mean `N̄`: `min(1, N_i / N̄)`.
//!   A vertex just taken carries nothing yet and widens nothing, so the force does
//!   not jump when one joins or leaves the patch;
//! - a patch narrower than the tip is the tip's own: the scale is 1.
//!
//! Both the normal and the tangential parts are scaled: the drag of a stuck patch
//! is as much too stiff as its push (pressed 15 mm, the sideways part of the held
//! patch's reaction was 0.48 N on liver-5k against 0.13 N on liver-80k, and scaling
//! the push alone left the three livers ±18% apart). What the shaft holds is its
//! reaction itself.
//!
//! The scene asks for it (`contact.footprint`, off by default): the calibrated force
//! model renders the scaled force, and its hand loop on 1 MPa tissue then falls in
//! a band of stiffness where it oscillates (found on 430–600 kPa tissue without the
//! scale; `tests/tests/haptics.rs` holds the loop to passivity at 1 and 10 MPa).
//!
//! Assumption: the force on the tip is set by the dimple under it, the tissue's
//! local response, as in a press. A gesture whose force is set by a whole lobe
//! bending (lifting one on the tip) is under-reported on a coarse mesh, by up to
//! `r / a_h`; no bench gesture does that yet.
//!
//! Checked on the default liver's free front (the convergence bench): pressed 8 and
//! 15 mm, the forces of liver-5k, liver-20k and liver-80k lie within ±7.5% and ±3.3%
//! of their mean, where the reactions themselves spread ±44% and ±60%; SOFA's coarse
//! liver lies 27% and 16% below that mean. On a block (`server/tests/
//! contact_footprint.rs`) meshed at twice the tip's radius, an 8 mm press gives
//! within 5% of the force on a block graded to 1 mm, where its own reaction is 2.7
//! times that. As the mesh is refined, `a_h` falls to the tip's own footprint and
//! the scale to 1. The deformed surface is the mesh's: the scale corrects the force
//! for what the mesh cannot resolve, not the shape.

use nalgebra::{Point3, Unit, Vector3};

use crate::engine::mesh::Surface;

/// The scale `min(1, r / a_h)` of the reactions on the tip's end, for the held vertices
/// of the tip's end (those whose contact normal is `−Z`), each with its elastic
/// reaction, N (`patch`), in positions `x`, for a tip of radius `radius` and axis
/// `axis`. 1 when nothing presses.
pub(super) fn tip_scale(
    patch: impl Iterator<Item = (u32, Vector3<f64>)> + Clone,
    surface: &Surface,
    x: &[Point3<f64>],
    axis: &Unit<Vector3<f64>>,
    radius: f64,
) -> f64 {
    // N_i: the tissue pushes the instrument along +Z, the tip's inward normal.
    let push = |f: Vector3<f64>| f.dot(axis).max(0.0);
    let (total, count) = patch
        .clone()
        .fold((0.0, 0usize), |(t, c), (_, f)| (t + push(f), c + 1));
    if total <= 0.0 {
        return 1.0;
    }
    let mean = total / count as f64;
    let area: f64 = patch
        .map(|(v, f)| (push(f) / mean).min(1.0) * projected_share(surface, v, x, axis))
        .sum();
    let a_h = (area / std::f64::consts::PI).sqrt();
    if a_h > radius { radius / a_h } else { 1.0 }
}

/// A third of the area of each surface triangle around vertex `v`, projected on the
/// plane normal to `axis`, m² (0 for a vertex off the surface).
fn projected_share(surface: &Surface, v: u32, x: &[Point3<f64>], axis: &Vector3<f64>) -> f64 {
    let Some(slot) = surface.slot(v) else {
        return 0.0;
    };
    surface
        .triangles_around(slot)
        .iter()
        .map(|&t| {
            let [a, b, c] = surface.triangles[t as usize].map(|w| x[w as usize]);
            (b - a).cross(&(c - a)).dot(axis).abs() / 6.0
        })
        .sum()
}

#[cfg(test)]
mod tests;
