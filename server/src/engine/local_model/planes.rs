//! The direction of the shaft plane (paper §3).

use nalgebra::{Point3, Unit, Vector3};

use crate::engine::contact::Instrument;
use crate::engine::mesh::Surface;

/// The shaft plane's normal: the average of `Z × ê` over the shaft's neighbouring
/// edges (`ê` the unit edge direction), each oriented from the tissue toward the axis,
/// so that the normal points out of the tissue.
///
/// The paper's plane "contains the instrument main axis and is orthogonal to the
/// average cross product of the instrument axis with the direction of all neighboring
/// edges": `Z × ê ⟂ Z`, so the plane holds the axis. An edge of the pressed surface
/// running across the shaft gives the surface normal; an edge along the shaft gives
/// almost nothing, which is right, as it says nothing of which side the tissue is on.
/// The sign of `Z × ê` depends on how the edge is numbered; each one is turned toward
/// the axis (`w`, the part of `P − mid` orthogonal to `Z`).
///
/// When the products cancel (edges all along the axis, or symmetric), the average of
/// `w` itself, the direction from the edges to the axis, is used. `None` without shaft
/// contact, without neighbouring edges, or when both are degenerate.
pub fn shaft_normal(
    ins: &Instrument,
    surface: &Surface,
    x: &[Point3<f64>],
) -> Option<Unit<Vector3<f64>>> {
    let pose = ins.current?;
    if !ins.shaft_contact || ins.report.shaft_edges.is_empty() {
        return None;
    }
    let z = pose.axis.into_inner();
    let (mut crossed, mut toward) = (Vector3::zeros(), Vector3::zeros());
    for &e in &ins.report.shaft_edges {
        let [a, b] = surface.edges[e as usize];
        let (xa, xb) = (x[a as usize], x[b as usize]);
        let Some(dir) = (xb - xa).try_normalize(0.0) else {
            continue;
        };
        let mid = Point3::from((xa.coords + xb.coords) * 0.5);
        let to_axis = pose.tip - mid;
        let w = pose.across(&to_axis);
        let c = z.cross(&dir);
        crossed += if c.dot(&w) < 0.0 { -c } else { c };
        toward += w.try_normalize(0.0).unwrap_or_else(Vector3::zeros);
    }
    // Cancelling: less than 1e-3 of the sum of unit-length contributions survives.
    let count = ins.report.shaft_edges.len() as f64;
    let direction = if crossed.norm() > 1e-3 * count {
        crossed
    } else {
        toward
    };
    let direction = pose.across(&direction);
    Unit::try_new(direction, 1e-12 * count)
}
