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
    let id = |c: [usize; 3]| (c[0] + (n[0] + 1) * (c[1] + (n[1] + 1) * c[2])) as u32;
    let mut positions = Vec::with_capacity((n[0] + 1) * (n[1] + 1) * (n[2] + 1));
    for k in 0..=n[2] {
        for j in 0..=n[1] {
            for i in 0..=n[0] {
                let c = [i, j, k];
                positions.push(Point3::from(
                    [0, 1, 2].map(|a| origin[a] + size[a] * c[a] as f64 / n[a] as f64),
                ));
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
