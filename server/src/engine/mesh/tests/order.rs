//! The vertex numbering with locality: reverse Cuthill–McKee, and a renumbered mesh
//! being the same mesh.

use std::collections::BTreeSet;

use super::super::generate::kuhn_box;
use super::super::topology::edges;
use super::super::{TetMesh, read_gmsh, reverse_cuthill_mckee};
use super::{LIVER, LIVER_5K};

/// The largest `|new[a] − new[b]|` over the tetrahedra's edges: the bandwidth of the
/// vertex graph in that numbering.
fn bandwidth(tets: &[[u32; 4]], new: impl Fn(u32) -> u32) -> u32 {
    tets.iter()
        .flat_map(|t| (0..4).flat_map(move |a| (a + 1..4).map(move |b| (t[a], t[b]))))
        .map(|(a, b)| new(a).abs_diff(new(b)))
        .max()
        .unwrap_or(0)
}

fn assert_permutation(new: &[u32]) {
    let set: BTreeSet<u32> = new.iter().copied().collect();
    assert_eq!(set.len(), new.len(), "two vertices share a new index");
    assert!(new.iter().all(|&k| (k as usize) < new.len()));
}

#[test]
fn reverse_cuthill_mckee_narrows_a_shuffled_grid_to_its_natural_bandwidth() {
    // 9 × 9 × 9 vertices; in the grid's own numbering `i + 9 (j + 9 k)` an edge along
    // the cube's diagonal spans 1 + 9 + 81 = 91.
    let (_, tets) = kuhn_box([8, 8, 8], [1.0; 3], [0.0; 3]);
    let n = 729u32;
    assert_eq!(bandwidth(&tets, |v| v), 91);
    // Scatter the numbering (383 is prime to 729 = 3⁶, so this is a permutation).
    let shuffle = |v: u32| (v * 383) % n;
    let shuffled: Vec<[u32; 4]> = tets.iter().map(|t| t.map(shuffle)).collect();
    assert!(bandwidth(&shuffled, |v| v) > 600);
    let new = reverse_cuthill_mckee(n as usize, &edges(&shuffled));
    assert_permutation(&new);
    // Cuthill–McKee numbers level by level, so an edge spans at most two levels; on
    // a grid that is no wider than the grid's own numbering (82 here).
    let b = bandwidth(&shuffled, |v| new[v as usize]);
    assert!(b <= 91, "bandwidth {b}");
}

#[test]
fn reverse_cuthill_mckee_numbers_each_component_in_one_block() {
    // Two separate tetrahedra and a vertex that none uses, interleaved.
    let tets = [[0, 2, 4, 6], [1, 3, 5, 7]];
    let new = reverse_cuthill_mckee(9, &edges(&tets));
    assert_permutation(&new);
    for t in tets {
        let k: BTreeSet<u32> = t.iter().map(|&v| new[v as usize]).collect();
        let (lo, hi) = (*k.first().unwrap(), *k.last().unwrap());
        assert_eq!(hi - lo, 3, "component {t:?} numbered {k:?}");
    }
    // Deterministic: the same input, the same numbering.
    assert_eq!(new, reverse_cuthill_mckee(9, &edges(&tets)));
}

#[test]
fn the_livers_file_numbering_is_scattered_and_reverse_cuthill_mckee_gathers_it() {
    for text in [LIVER, LIVER_5K] {
        let mesh = read_gmsh(text, "liver").unwrap();
        let n = mesh.vertex_count();
        let new = reverse_cuthill_mckee(n, &mesh.edges);
        assert_permutation(&new);
        let before = bandwidth(&mesh.tets, |v| v);
        let after = bandwidth(&mesh.tets, |v| new[v as usize]);
        assert!(
            4 * after < before,
            "{n} vertices: bandwidth {before} in file order, {after} renumbered"
        );
    }
}

/// `mesh` renumbered by reverse Cuthill–McKee, checked to be `mesh` itself: every
/// vertex, element, tag, edge and surface triangle carried over by the numbering.
fn renumbered_and_checked(mesh: &TetMesh) -> (TetMesh, Vec<u32>) {
    let new = reverse_cuthill_mckee(mesh.vertex_count(), &mesh.edges);
    let r = mesh.renumbered(&new);
    let map = |v: u32| new[v as usize];
    for (v, &k) in new.iter().enumerate() {
        let k = k as usize;
        assert_eq!(r.positions[k], mesh.positions[v]);
        assert_eq!(r.node_ids[k], mesh.node_ids[v]);
        assert_eq!(r.file_index[k], mesh.file_index[v]);
    }
    let tets = |m: &TetMesh, f: &dyn Fn(u32) -> u32| -> BTreeSet<([u32; 4], i32)> {
        m.tets
            .iter()
            .zip(&m.tet_tags)
            .map(|(t, &tag)| (t.map(f), tag))
            .collect()
    };
    // Each element keeps its vertices in order, hence its orientation.
    assert_eq!(tets(&r, &|v| v), tets(mesh, &map));
    let sorted = |t: &[u32; 4]| {
        let mut k = *t;
        k.sort_unstable();
        k
    };
    assert!(r.tets.windows(2).all(|w| sorted(&w[0]) <= sorted(&w[1])));
    let edges: BTreeSet<[u32; 2]> = mesh
        .edges
        .iter()
        .map(|&[a, b]| {
            let (a, b) = (map(a), map(b));
            [a.min(b), a.max(b)]
        })
        .collect();
    assert_eq!(r.edges.iter().copied().collect::<BTreeSet<_>>(), edges);
    let surface = |m: &TetMesh, f: &dyn Fn(u32) -> u32| -> BTreeSet<([u32; 3], i32)> {
        m.surface
            .triangles
            .iter()
            .zip(&m.surface.triangle_tags)
            .map(|(t, &tag)| {
                // A triangle up to rotation, keeping its orientation.
                let t = t.map(f);
                let k = (0..3).min_by_key(|&i| t[i]).unwrap();
                ([t[k], t[(k + 1) % 3], t[(k + 2) % 3]], tag)
            })
            .collect()
    };
    assert_eq!(surface(&r, &|v| v), surface(mesh, &map));
    let (v0, v1) = (mesh.volume(&mesh.positions), r.volume(&r.positions));
    assert!((v0 - v1).abs() <= 1e-12 * v0);
    (r, new)
}

#[test]
fn a_renumbered_mesh_is_the_same_mesh() {
    for text in [LIVER, LIVER_5K] {
        let mesh = read_gmsh(text, "liver").unwrap();
        let (r, new) = renumbered_and_checked(&mesh);
        // Renumbering again composes: the file indices still find the file's vertices.
        let (again, _) = renumbered_and_checked(&r);
        for (v, &k) in new.iter().enumerate() {
            assert_eq!(r.file_index[k as usize] as usize, v);
        }
        for (k, &i) in again.file_index.iter().enumerate() {
            assert_eq!(again.positions[k], mesh.positions[i as usize]);
        }
    }
}

#[test]
fn a_renumbered_mesh_keeps_its_region_and_surface_tags() {
    // A block whose tetrahedra carry the tag of their half and whose top carries a
    // declared surface tag: both must follow their elements and triangles.
    let (positions, tets) = kuhn_box([3, 3, 2], [0.3, 0.3, 0.2], [0.0; 3]);
    let mut mesh = TetMesh::from_tets(positions, tets).unwrap();
    for t in 0..mesh.tets.len() {
        let cx: f64 = mesh.tets[t]
            .iter()
            .map(|&v| mesh.positions[v as usize].x)
            .sum();
        mesh.tet_tags[t] = if cx < 0.6 { 1 } else { 2 };
    }
    for (k, tri) in mesh.surface.triangles.iter().enumerate() {
        if tri.iter().all(|&v| mesh.positions[v as usize].z > 0.19) {
            mesh.surface.triangle_tags[k] = 7;
        }
    }
    let (r, _) = renumbered_and_checked(&mesh);
    assert!(r.surface.triangle_tags.contains(&7));
    assert!(r.tet_tags.contains(&1) && r.tet_tags.contains(&2));
}

#[test]
#[should_panic(expected = "its own new index")]
fn a_renumbering_that_is_not_a_permutation_is_refused() {
    let mesh = read_gmsh(LIVER, "liver").unwrap();
    let mut new: Vec<u32> = (0..mesh.vertex_count() as u32).collect();
    new[1] = 0;
    mesh.renumbered(&new);
}
