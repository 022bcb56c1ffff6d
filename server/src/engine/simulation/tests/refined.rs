//! A liver refined is the same liver more finely resolved: its sag under gravity
//! converges as the mesh is refined.

use crate::engine::scene::Scene;

/// The default liver's static sag under gravity, refined `k` times: the
/// displacements of the file's vertices (the first 181 of every refinement).
fn sag(k: u32) -> Vec<nalgebra::Vector3<f64>> {
    let mut scene = Scene::default_scene();
    scene.mesh.refine = k;
    scene.mechanics.cg_tolerance = 1e-10;
    let mut sim = scene.build().unwrap();
    assert!(sim.solve_static().converged, "refined {k} times");
    (0..181)
        .map(|v| sim.state.x[v] - sim.model.rest[v])
        .collect()
}

#[test]
fn the_sag_of_the_refined_liver_converges() {
    // Linear tetrahedra converge in displacement at second order in the edge
    // length (for the smooth part of the solution): halving the edges should take
    // the change of the answer down about fourfold, and never let it grow. The
    // corners of the supports' edges and of the coarse facets are singular, which
    // slows the rate; half is asked.
    let [u0, u1, u2] = [0, 1, 2].map(sag);
    let change = |a: &[nalgebra::Vector3<f64>], b: &[nalgebra::Vector3<f64>]| {
        a.iter()
            .zip(b)
            .map(|(a, b)| (a - b).norm_squared())
            .sum::<f64>()
            .sqrt()
    };
    let scale = change(&u2, &vec![nalgebra::Vector3::zeros(); 181]);
    let (d01, d12) = (change(&u0, &u1), change(&u1, &u2));
    println!(
        "sag RMS {:.3} mm; change 0→1 refinement {:.3} mm, 1→2 {:.3} mm (ratio {:.2})",
        1e3 * scale / 181f64.sqrt(),
        1e3 * d01 / 181f64.sqrt(),
        1e3 * d12 / 181f64.sqrt(),
        d12 / d01
    );
    assert!(d12 <= 0.5 * d01, "0→1: {d01:e}, 1→2: {d12:e}");
    // A refinement changes the answer by less than the answer.
    assert!(d01 < scale, "{d01:e} against {scale:e}");
}
