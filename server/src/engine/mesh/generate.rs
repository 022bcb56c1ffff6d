//! Meshes made rather than read: for tests, benchmarks and simple scenes.

use nalgebra::Point3;

/// A box of `n[0]·n[1]·n[2]` cubes of size `size / n` each, its minimum corner at
/// `origin` (m), every cube split into six tetrahedra around its main diagonal (Kuhn's
/// subdivision: conforming, all tetrahedra congruent). Vertex `(i, j, k)` of the grid
/// has index `i + (n₀+1)(j + (n₁+1) k)`. Tetrahedra come from the six permutations of
/// the axes, so half of them are listed negatively oriented; loading repairs that.
pub fn kuhn_box(
    n: [usize; 3],
    size: [f64; 3],
    origin: [f64; 3],
) -> (Vec<Point3<f64>>, Vec<[u32; 4]>) {
    let lines = [0, 1, 2].map(|a| {
        (0..=n[a])
            .map(|c| origin[a] + size[a] * c as f64 / n[a] as f64)
            .collect::<Vec<_>>()
    });
    kuhn_grid(&lines)
}

/// The grid whose vertices are the products of the coordinate lines `lines[0] ×
/// lines[1] × lines[2]` (each strictly increasing, m), every box between neighbouring
/// lines split into six tetrahedra as in [`kuhn_box`] (same numbering). With unequal
/// spacings the boxes are not cubes and the tetrahedra not congruent, but the split
/// stays conforming: a mesh graded towards where it must resolve a detail.
pub fn kuhn_grid(lines: &[Vec<f64>; 3]) -> (Vec<Point3<f64>>, Vec<[u32; 4]>) {
    let n = [0, 1, 2].map(|a| lines[a].len().saturating_sub(1));
    let id = |c: [usize; 3]| (c[0] + (n[0] + 1) * (c[1] + (n[1] + 1) * c[2])) as u32;
    let mut positions = Vec::with_capacity((n[0] + 1) * (n[1] + 1) * (n[2] + 1));
    for &z in &lines[2] {
        for &y in &lines[1] {
            for &x in &lines[0] {
                positions.push(Point3::new(x, y, z));
            }
        }
    }
    let mut tets = Vec::with_capacity(6 * n[0] * n[1] * n[2]);
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                for perm in [
                    [0, 1, 2],
                    [0, 2, 1],
                    [1, 0, 2],
                    [1, 2, 0],
                    [2, 0, 1],
                    [2, 1, 0],
                ] {
                    let mut c = [i, j, k];
                    let mut t = [id(c); 4];
                    for (s, axis) in perm.into_iter().enumerate() {
                        c[axis] += 1;
                        t[s + 1] = id(c);
                    }
                    tets.push(t);
                }
            }
        }
    }
    (positions, tets)
}

/// Coordinate lines from `0` to `extent` (m): uniform steps of `h0` up to `core`, then
/// steps growing by the factor `growth` (> 1) until `extent`, the last one cut to land
/// on it exactly (merged into the one before if it would be under half a step). Fine
/// where a contact patch must be resolved, coarse where the field is smooth.
pub fn graded_lines(h0: f64, core: f64, growth: f64, extent: f64) -> Vec<f64> {
    let mut lines = vec![0.0];
    let mut h = h0;
    let mut x = 0.0;
    while x + 1e-12 < extent {
        if x + 1e-12 >= core {
            h *= growth;
        }
        let next = (x + h).min(extent);
        if extent - next < 0.5 * h && next < extent {
            x = extent;
        } else {
            x = next;
        }
        lines.push(x);
    }
    lines
}

/// `graded_lines` mirrored about `0`: from `−extent` to `extent`, finest at the middle.
pub fn graded_lines_symmetric(h0: f64, core: f64, growth: f64, extent: f64) -> Vec<f64> {
    let half = graded_lines(h0, core, growth, extent);
    let mut lines: Vec<f64> = half.iter().rev().map(|x| -x).collect();
    lines.extend_from_slice(&half[1..]);
    lines
}
