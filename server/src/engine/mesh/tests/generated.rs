//! Generated meshes: graded coordinate lines and the grids built on them.

use crate::engine::mesh::TetMesh;
use crate::engine::mesh::generate::{graded_lines, graded_lines_symmetric, kuhn_grid};

#[test]
fn graded_lines_run_from_zero_to_the_extent_fine_then_growing() {
    for (h0, core, growth, extent) in [
        (0.25e-3, 3e-3, 1.25, 0.04),
        (1e-3, 0.0, 1.5, 0.01),
        (0.5e-3, 0.05, 1.2, 0.02), // all core: uniform to the end
        (2e-3, 1e-3, 1.1, 2.5e-3), // shorter than two steps
    ] {
        let l = graded_lines(h0, core, growth, extent);
        let case = format!("h0 {h0} core {core} growth {growth} extent {extent}: {l:?}");
        assert_eq!(l[0], 0.0, "{case}");
        assert_eq!(*l.last().unwrap(), extent, "{case}");
        let steps: Vec<f64> = l.windows(2).map(|w| w[1] - w[0]).collect();
        assert!(steps.iter().all(|&h| h > 0.0), "{case}");
        for (k, w) in steps.windows(2).enumerate() {
            // Inside the core the steps are h0; beyond it each grows by at most the
            // factor, but the last may be up to 1.5 of its step (a short tail merged).
            let last = k + 2 == steps.len();
            let bound = if last { 1.5 * growth } else { growth } * (1.0 + 1e-9);
            assert!(w[1] <= bound * w[0], "step {k}: {case}");
        }
        for (k, &h) in steps.iter().enumerate() {
            if l[k + 1] <= core && l[k + 1] < extent {
                assert!((h - h0).abs() < 1e-12, "core step {k} is {h}: {case}");
            }
        }
    }
}

#[test]
fn a_graded_grid_fills_its_box_with_valid_tetrahedra() {
    let x = graded_lines_symmetric(0.5e-3, 2e-3, 1.3, 0.02);
    let y = graded_lines_symmetric(0.5e-3, 2e-3, 1.3, 0.015);
    let z: Vec<f64> = graded_lines(0.5e-3, 2e-3, 1.3, 0.01)
        .iter()
        .map(|d| -d)
        .rev()
        .collect();
    assert_eq!(x[0], -0.02);
    assert!(x.windows(2).all(|w| w[1] > w[0]));
    let cells = (x.len() - 1) * (y.len() - 1) * (z.len() - 1);
    let (positions, tets) = kuhn_grid(&[x, y, z]);
    assert_eq!(tets.len(), 6 * cells);
    let mesh = TetMesh::from_tets(positions, tets).expect("a conforming graded grid loads");
    // Every tetrahedron positive once loaded, and together exactly the box (to
    // round-off of a sum over some 10⁴ terms).
    assert!(
        mesh.tets
            .iter()
            .all(|&t| TetMesh::six_volume(&mesh.positions, t) > 0.0)
    );
    let volume = mesh.volume(&mesh.positions);
    let exact = 0.04 * 0.03 * 0.01;
    assert!(
        (volume - exact).abs() < 1e-10 * exact,
        "{volume} vs {exact}"
    );
    // A closed box: its surface is the six faces' grid triangles, Euler characteristic 2.
    let s = &mesh.surface;
    let chi = s.vertices.len() as i64 - s.edges.len() as i64 + s.triangles.len() as i64;
    assert_eq!(chi, 2);
}
