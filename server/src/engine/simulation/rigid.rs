//! Whether a set of fixed vertices holds a body against every rigid motion.

use nalgebra::Point3;

/// Whether holding `fixed` removes every rigid motion: three fixed vertices not on one
/// line. "On one line" is judged relative to the spread of the set (a distance from the
/// line above `1e-6` of it), so the test does not depend on units.
pub(super) fn removes_rigid_motion(positions: &[Point3<f64>], fixed: &[u32]) -> bool {
    let Some(&a) = fixed.first() else {
        return false;
    };
    let a = positions[a as usize];
    let Some(far) = fixed
        .iter()
        .map(|&i| positions[i as usize] - a)
        .max_by(|p, q| p.norm().total_cmp(&q.norm()))
    else {
        return false;
    };
    let len = far.norm();
    if len == 0.0 {
        return false;
    }
    let axis = far / len;
    fixed.iter().any(|&i| {
        let d = positions[i as usize] - a;
        (d - axis * d.dot(&axis)).norm() > 1e-6 * len
    })
}
