//! Uniform refinement: counts, the shape kept exactly, children inside their parent,
//! numbering and tags carried over.

use super::*;

/// The smallest radius ratio `3 r_in / r_circ`-like measure used here: `6√2 V /
/// l_max³`, 1 for a regular tetrahedron and 0 for a flat one.
fn shape(mesh: &TetMesh, t: [u32; 4]) -> f64 {
    let p = t.map(|v| mesh.positions[v as usize]);
    let longest = (0..4)
        .flat_map(|i| (i + 1..4).map(move |j| (i, j)))
        .map(|(i, j)| (p[i] - p[j]).norm())
        .fold(0.0, f64::max);
    6.0 * std::f64::consts::SQRT_2 * (TetMesh::six_volume(&mesh.positions, t) / 6.0)
        / longest.powi(3)
}

fn surface_area(mesh: &TetMesh) -> f64 {
    mesh.surface
        .triangles
        .iter()
        .map(|tri| {
            let p = tri.map(|v| mesh.positions[v as usize]);
            (p[1] - p[0]).cross(&(p[2] - p[0])).norm() / 2.0
        })
        .sum()
}

#[test]
fn refinement_multiplies_the_counts_and_keeps_volume_surface_and_topology() {
    for (name, text) in [("liver", LIVER), ("liver-5k", LIVER_5K)] {
        let coarse = load(text);
        let fine = coarse.refined().expect("a loaded mesh refines");
        let (n, e) = (coarse.vertex_count(), coarse.edges.len());
        assert_eq!(fine.vertex_count(), n + e, "{name}");
        assert_eq!(fine.tets.len(), 8 * coarse.tets.len(), "{name}");
        assert_eq!(
            fine.surface.triangles.len(),
            4 * coarse.surface.triangles.len(),
            "{name}"
        );
        // Each tetrahedron has six edges, each face three; an edge is split in two
        // and each face and tetrahedron adds its inner edges (3 a face, 1 the
        // octahedron's diagonal): E' = 2E + 3F + T.
        let faces = (4 * coarse.tets.len() + coarse.surface.triangles.len()) / 2;
        assert_eq!(
            fine.edges.len(),
            2 * e + 3 * faces + coarse.tets.len(),
            "{name}"
        );
        // The same closed surface of the same genus, the same volume and area.
        assert_eq!(check_surface(&fine), check_surface(&coarse), "{name}");
        let (v0, v1) = (total_volume(&coarse), total_volume(&fine));
        assert!((v1 - v0).abs() <= 1e-12 * v0, "{name}: volume {v0} → {v1}");
        assert!(
            (divergence_volume(&fine) - v0).abs() <= 1e-12 * v0,
            "{name}"
        );
        let (a0, a1) = (surface_area(&coarse), surface_area(&fine));
        assert!((a1 - a0).abs() <= 1e-12 * a0, "{name}: area {a0} → {a1}");
        check_normals(&fine);
    }
}

#[test]
fn children_fill_their_parent_and_keep_its_vertices_and_tag() {
    let coarse = load(LIVER);
    let fine = coarse.refined().unwrap();
    let n = coarse.vertex_count();
    // The parent's vertices first, unchanged; then one midpoint per sorted edge.
    assert_eq!(&fine.positions[..n], &coarse.positions[..]);
    assert_eq!(&fine.node_ids[..n], &coarse.node_ids[..]);
    assert_eq!(&fine.file_index[..n], &coarse.file_index[..]);
    for (e, &[a, b]) in coarse.edges.iter().enumerate() {
        let mid = (coarse.positions[a as usize].coords + coarse.positions[b as usize].coords) / 2.0;
        assert_eq!(fine.positions[n + e].coords, mid);
    }
    // file_index stays a permutation (what `fixed.nodes` is looked up through).
    let mut files = fine.file_index.clone();
    files.sort_unstable();
    assert!(files.iter().enumerate().all(|(i, &f)| f as usize == i));
    for (t, parent) in coarse.tets.iter().enumerate() {
        let children = &fine.tets[8 * t..8 * t + 8];
        let v: f64 = children
            .iter()
            .map(|&c| TetMesh::six_volume(&fine.positions, c))
            .sum();
        let v0 = TetMesh::six_volume(&coarse.positions, *parent);
        assert!((v - v0).abs() <= 1e-12 * v0, "tet {t}: {v0} → {v}");
        // Each child's vertices lie in the parent (barycentric coordinates in [0, 1]).
        let p = parent.map(|i| coarse.positions[i as usize]);
        let m = nalgebra::Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
        let inverse = m.try_inverse().unwrap();
        for &c in children {
            assert!(TetMesh::six_volume(&fine.positions, c) > 0.0);
            for w in c {
                let b = inverse * (fine.positions[w as usize] - p[0]);
                let l = [1.0 - b.sum(), b.x, b.y, b.z];
                assert!(
                    l.iter().all(|&x| (-1e-12..=1.0 + 1e-12).contains(&x)),
                    "{l:?}"
                );
            }
        }
        assert!(
            fine.tet_tags[8 * t..8 * t + 8]
                .iter()
                .all(|&g| g == coarse.tet_tags[t])
        );
    }
}

#[test]
fn corner_children_are_the_parent_halved_and_no_child_is_worse_than_the_worst_parent() {
    // The corner children are the parent at half size, so they keep its shape; the
    // octahedron's four, cut along its shortest diagonal, are never the worst: the
    // worst shape of the mesh stays its coarsest's through two refinements.
    let coarse = load(LIVER);
    let once = coarse.refined().unwrap();
    let twice = once.refined().unwrap();
    for (t, &parent) in coarse.tets.iter().enumerate() {
        let corner = once.tets[8 * t];
        assert!((shape(&once, corner) - shape(&coarse, parent)).abs() <= 1e-9);
    }
    let worst = |m: &TetMesh| m.tets.iter().map(|&t| shape(m, t)).fold(1.0, f64::min);
    let (w0, w1, w2) = (worst(&coarse), worst(&once), worst(&twice));
    assert!(w1 >= (1.0 - 1e-9) * w0, "first refinement: {w0} → {w1}");
    assert!(w2 >= (1.0 - 1e-9) * w1, "second refinement: {w1} → {w2}");
}

#[test]
fn declared_surface_tags_pass_to_the_children() {
    let text = cube_v1(&cube_tets());
    let mut mesh = load(&text);
    // Tag the surface as a file would declare it: each triangle by its face's axis.
    let tags: Vec<i32> = mesh
        .surface
        .triangles
        .iter()
        .map(|tri| {
            let p = tri.map(|v| mesh.positions[v as usize]);
            let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
            1 + n.iamax() as i32
        })
        .collect();
    mesh.surface.triangle_tags = tags;
    let fine = mesh.refined().unwrap();
    for (tri, &tag) in fine
        .surface
        .triangles
        .iter()
        .zip(&fine.surface.triangle_tags)
    {
        let p = tri.map(|v| fine.positions[v as usize]);
        let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
        assert_eq!(tag, 1 + n.iamax() as i32);
    }
}
