//! Contact invariants and gestures, shared by the contact tests.

use laparo_server::engine::contact::InstrumentPose;
use laparo_server::engine::contact::closest::{closest_edge_axis, closest_point_axis};
use laparo_server::engine::simulation::Simulation;
use nalgebra::{Point3, Unit, Vector3};

/// How deep a surface vertex or edge may be inside an instrument, m.
pub const DEPTH_TOLERANCE: f64 = 1e-6;

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
/// with a free end inside it deeper than [`DEPTH_TOLERANCE`], and its axis (sampled
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
