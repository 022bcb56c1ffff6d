//! Contact invariants and gestures, shared by the contact tests.

use laparo_server::engine::contact::InstrumentPose;
use laparo_server::engine::contact::closest::{closest_edge_axis, closest_point_axis};
use laparo_server::engine::simulation::Simulation;
use nalgebra::{Point3, Unit, Vector3};

/// How deep a surface vertex or edge may be inside an instrument, m.
pub const DEPTH_TOLERANCE: f64 = 1e-6;

/// How deep a point inside a surface triangle may be inside an instrument, m (the
/// issue's bound for any surface point).
pub const FACE_TOLERANCE: f64 = 1e-4;

/// Spacing of the points sampled on each triangle, m. The sampled depth falls short of
/// the true one by at most about `h²/(8 d)` where the face passes at `d` from the axis
/// (the depth is smooth there), 6 µm for `d` ≥ 5 mm; a face the axis goes through is
/// caught by the winding number of the axis points as well.
const FACE_SAMPLING: f64 = 0.5e-3;

/// The deepest point of the triangles near an instrument, sampled on a barycentric grid
/// of spacing at most [`FACE_SAMPLING`], measured by its distance to the axis segment
/// (`β` clamped to `[0, l]`): `(depth, triangle)`, depth `r − distance` (negative
/// outside). Triangles whose corners are all supports are skipped.
pub fn deepest_face_point(
    sim: &Simulation,
    pose: &InstrumentPose,
    radius: f64,
    length: f64,
) -> Option<(f64, usize)> {
    let x = &sim.state.x;
    let fixed = |v: u32| sim.fixed.binary_search(&v).is_ok();
    let (a, b) = (pose.tip, pose.point_at(length));
    let lo = a.inf(&b) - Vector3::repeat(radius);
    let hi = a.sup(&b) + Vector3::repeat(radius);
    let z = pose.axis.into_inner();
    let mut deepest: Option<(f64, usize)> = None;
    for (t, tri) in sim.mesh.surface.triangles.iter().enumerate() {
        if tri.iter().all(|&v| fixed(v)) {
            continue;
        }
        let p = tri.map(|v| x[v as usize]);
        let (tlo, thi) = (p[0].inf(&p[1]).inf(&p[2]), p[0].sup(&p[1]).sup(&p[2]));
        if (0..3).any(|k| thi[k] < lo[k] || tlo[k] > hi[k]) {
            continue;
        }
        let longest = (0..3)
            .map(|k| (p[(k + 1) % 3] - p[k]).norm())
            .fold(0.0, f64::max);
        let n = ((longest / FACE_SAMPLING).ceil() as usize).max(1);
        for i in 0..=n {
            for j in 0..=(n - i) {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                let q = p[0] + (p[1] - p[0]) * u + (p[2] - p[0]) * v;
                let beta = (q - pose.tip).dot(&z).clamp(0.0, length);
                let depth = radius - (q - pose.point_at(beta)).norm();
                if deepest.is_none_or(|(d, _)| depth > d) {
                    deepest = Some((depth, t));
                }
            }
        }
    }
    deepest
}

/// Generalised winding number of the closed surface around `p` (Van Oosterom and
/// Strackee's solid angle per triangle, summed over 4π): 1 inside, 0 outside.
pub fn winding_number(sim: &Simulation, p: &Point3<f64>) -> f64 {
    let x = &sim.state.x;
    let mut total = 0.0;
    for t in &sim.mesh.surface.triangles {
        let [a, b, c] = t.map(|v| x[v as usize] - p);
        let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
        let num = a.dot(&b.cross(&c));
        let den = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
        total += 2.0 * num.atan2(den);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// Checks, for every instrument in the body: no free surface vertex and no surface edge
/// with a free end inside it deeper than [`DEPTH_TOLERANCE`], no point of a triangle
/// deeper than [`FACE_TOLERANCE`] ([`deepest_face_point`]), and its axis (sampled
/// every 2 mm, tip included) outside the liver. Supports never move, so a
/// vertex or edge that is all support is not the stage's to keep out.
pub fn check_invariants(sim: &Simulation) -> Result<(), String> {
    let x = &sim.state.x;
    let fixed = |v: u32| sim.fixed.binary_search(&v).is_ok();
    for ins in &sim.instruments {
        let Some(pose) = ins.current else { continue };
        let len = ins.active_length();
        for &v in &sim.mesh.surface.vertices {
            let d = closest_point_axis(&x[v as usize], &pose, len).distance();
            if !fixed(v) && d < ins.radius - DEPTH_TOLERANCE {
                return Err(format!(
                    "tick {}: vertex {v} is {:.3e} m inside `{}`",
                    sim.tick,
                    ins.radius - d,
                    ins.name
                ));
            }
        }
        for &[a, b] in &sim.mesh.surface.edges {
            let d = closest_edge_axis(&x[a as usize], &x[b as usize], &pose, len).distance();
            if !(fixed(a) && fixed(b)) && d < ins.radius - DEPTH_TOLERANCE {
                return Err(format!(
                    "tick {}: edge {a}-{b} is {:.3e} m inside `{}`",
                    sim.tick,
                    ins.radius - d,
                    ins.name
                ));
            }
        }
        if let Some((depth, t)) = deepest_face_point(sim, &pose, ins.radius, len)
            && depth > FACE_TOLERANCE
        {
            return Err(format!(
                "tick {}: a point of triangle {t} is {depth:.3e} m inside `{}`",
                sim.tick, ins.name
            ));
        }
        let samples = (len / 2e-3).ceil() as usize;
        for k in 0..=samples {
            let p = pose.point_at(len * k as f64 / samples.max(1) as f64);
            let w = winding_number(sim, &p);
            if w > 0.5 {
                return Err(format!(
                    "tick {}: `{}` axis point at {:.4} m from the tip is inside the liver (winding {w:.3})",
                    sim.tick,
                    ins.name,
                    (p - pose.tip).norm()
                ));
            }
        }
    }
    Ok(())
}

/// A pose from a tip and an axis direction.
pub fn pose(tip: [f64; 3], axis: [f64; 3]) -> InstrumentPose {
    InstrumentPose::new(Point3::from(tip), Unit::new_normalize(Vector3::from(axis)))
}

/// The surface vertex of the default liver's free front (+z) face nearest the middle.
pub fn front_point(sim: &Simulation) -> Point3<f64> {
    let x = &sim.state.x;
    sim.mesh
        .surface
        .vertices
        .iter()
        .map(|&v| x[v as usize])
        .filter(|p| p.x.abs() < 0.03 && p.y.abs() < 0.02)
        .max_by(|a, b| a.z.total_cmp(&b.z))
        .expect("the default liver has a front face")
}

/// The end of a press of the default liver's free front, past [`front_point`] by
/// `depth` (m), for an instrument of radius `r`: with the tip, the axis along +z
/// through the front point and the instrument's foremost point `P − r Z` `depth` past
/// it; with the shaft, the axis along −x level with the front point, the tip 6 cm
/// beyond it in +x and the shaft's underside `depth` past it.
pub fn front_press(sim: &Simulation, shaft: bool, depth: f64, r: f64) -> InstrumentPose {
    let f = front_point(sim);
    if shaft {
        InstrumentPose::new(
            Point3::new(f.x + 0.06, f.y, f.z - depth + r),
            Unit::new_normalize(-Vector3::x()),
        )
    } else {
        InstrumentPose::new(
            Point3::new(f.x, f.y, f.z - depth + r),
            Unit::new_normalize(Vector3::z()),
        )
    }
}

/// The index of the vertex [`front_point`] returns.
pub fn front_vertex(sim: &Simulation) -> u32 {
    let p = front_point(sim);
    *sim.mesh
        .surface
        .vertices
        .iter()
        .find(|&&v| sim.state.x[v as usize] == p)
        .unwrap()
}

/// The tip's path of a slide and withdrawal on the default liver, at time `t` (s),
/// from `start` (1 cm in front of the free front, 1 cm to −x of its middle): in
/// 18 mm along −z over `[0, 1]`, slid 2 cm along +x over `[1.25, 2.25]`, back out
/// along +z over `[2.5, 3]`, then still.
pub fn slide_and_withdraw(start: Point3<f64>, t: f64) -> Point3<f64> {
    let ramp = |a: f64, b: f64| ((t - a) / (b - a)).clamp(0.0, 1.0);
    let z = -0.018 * (ramp(0.0, 1.0) - ramp(2.5, 3.0));
    start + Vector3::new(0.02 * ramp(1.25, 2.25), 0.0, z)
}
