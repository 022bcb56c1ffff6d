//! Tests of the mesh module, by concern: the data sets and normals (`data_sets`),
//! faults of the file (`file_faults`) and of the geometry (`geometry_faults`). Here:
//! the meshes written by hand and the structural checks they share.

use nalgebra::{Point3, Vector3};

use super::topology::{self, Fault};
use super::*;

const LIVER: &str = include_str!("../../../meshes/liver.msh");
const LIVER_5K: &str = include_str!("../../../meshes/liver-5k.msh");

// ---------------------------------------------------------------------------------------
// Small meshes written by hand.

/// A v1 text. Node `i` (0-based) is on line `3 + i`, element `j` on `nodes + 6 + j`.
fn v1(nodes: &[&str], elements: &[&str]) -> String {
    let mut text = format!("$NOD\n{}\n", nodes.len());
    for n in nodes {
        text += n;
        text += "\n";
    }
    text += &format!("$ENDNOD\n$ELM\n{}\n", elements.len());
    for e in elements {
        text += e;
        text += "\n";
    }
    text + "$ENDELM\n"
}

fn v1_node_line(i: usize) -> usize {
    3 + i
}

fn v1_element_line(nodes: usize, j: usize) -> usize {
    nodes + 6 + j
}

/// A v2.2 text with a `$PhysicalNames` section (to be skipped). Node `i` is on line
/// `10 + i`, element `j` on `nodes + 13 + j`.
fn v2(nodes: &[&str], elements: &[&str]) -> String {
    let mut text = String::from(
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 1 \"volume\"\n\
         $EndPhysicalNames\n",
    );
    text += &format!("$Nodes\n{}\n", nodes.len());
    for n in nodes {
        text += n;
        text += "\n";
    }
    text += &format!("$EndNodes\n$Elements\n{}\n", elements.len());
    for e in elements {
        text += e;
        text += "\n";
    }
    text + "$EndElements\n"
}

fn v2_node_line(i: usize) -> usize {
    10 + i
}

fn v2_element_line(nodes: usize, j: usize) -> usize {
    nodes + 13 + j
}

/// Unit corner tetrahedron 1-2-3-4 and its mirror 2-3-4-5 across the face x+y+z = 1.
const TWO_NODES: [&str; 5] = ["1 0 0 0", "2 1 0 0", "3 0 1 0", "4 0 0 1", "5 1 1 1"];
const TWO_TETS_V1: [&str; 2] = ["1 4 1 1 4 1 2 3 4", "2 4 1 1 4 2 3 4 5"];
const TWO_TETS_V2: [&str; 2] = ["1 4 2 1 1 1 2 3 4", "2 4 2 1 1 2 3 4 5"];
/// The six boundary faces of the two-tet mesh, as v2.2 triangles (tag 7), elements 11..
const TWO_BOUNDARY_V2: [&str; 6] = [
    "11 2 2 7 7 1 3 2",
    "12 2 2 7 7 1 2 4",
    "13 2 2 7 7 1 4 3",
    "14 2 2 7 7 2 3 5",
    "15 2 2 7 7 2 5 4",
    "16 2 2 7 7 3 4 5",
];

fn load(text: &str) -> TetMesh {
    match read_gmsh(text, "test.msh") {
        Ok(mesh) => mesh,
        Err(e) => panic!("unexpected error: {e}"),
    }
}

fn fail(text: &str) -> MeshError {
    match read_gmsh(text, "test.msh") {
        Ok(_) => panic!("the mesh loaded but should not have"),
        Err(e) => e,
    }
}

/// The unit cube (node id = 1 + x + 2y + 4z) split into six tetrahedra around the
/// diagonal 1→8 (Kuhn), in the raw vertex order of the construction: three of them are
/// negatively oriented.
fn cube_tets() -> Vec<[u32; 4]> {
    let axes = [1u32, 2, 4];
    let perms = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    perms
        .iter()
        .map(|p| {
            let a = axes[p[0]];
            let b = a | axes[p[1]];
            [0, a, b, 7]
        })
        .collect()
}

fn cube_positions() -> Vec<Point3<f64>> {
    (0..8u32)
        .map(|i| Point3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
        .collect()
}

fn cube_v1(tets: &[[u32; 4]]) -> String {
    let nodes: Vec<String> = cube_positions()
        .iter()
        .enumerate()
        .map(|(i, p)| format!("{} {} {} {}", i + 1, p.x, p.y, p.z))
        .collect();
    let elements: Vec<String> = tets
        .iter()
        .enumerate()
        .map(|(j, t)| {
            format!(
                "{} 4 0 0 4 {} {} {} {}",
                j + 1,
                t[0] + 1,
                t[1] + 1,
                t[2] + 1,
                t[3] + 1
            )
        })
        .collect();
    let nodes: Vec<&str> = nodes.iter().map(String::as_str).collect();
    let elements: Vec<&str> = elements.iter().map(String::as_str).collect();
    v1(&nodes, &elements)
}

/// The boundary as a sorted list of triangles, each rotated to start at its smallest
/// vertex (orientation kept).
fn canonical_boundary(surface: &Surface) -> Vec<[u32; 3]> {
    let mut tris: Vec<[u32; 3]> = surface
        .triangles
        .iter()
        .map(|&[a, b, c]| {
            if a < b && a < c {
                [a, b, c]
            } else if b < c {
                [b, c, a]
            } else {
                [c, a, b]
            }
        })
        .collect();
    tris.sort_unstable();
    tris
}

// ---------------------------------------------------------------------------------------
// Structural checks shared by the data-set tests.

/// Checks every adjacency structure of the surface against the triangles, and returns
/// the Euler characteristic V − E + F.
fn check_surface(mesh: &TetMesh) -> i64 {
    let s = &mesh.surface;
    let n = mesh.vertex_count();

    // Vertices: exactly those of the triangles, sorted; index map inverse.
    let mut expected: Vec<u32> = s.triangles.iter().flatten().copied().collect();
    expected.sort_unstable();
    expected.dedup();
    assert_eq!(s.vertices, expected);
    assert_eq!(s.surface_index.len(), n);
    for v in 0..n as u32 {
        match s.vertices.binary_search(&v) {
            Ok(slot) => assert_eq!(s.surface_index[v as usize] as usize, slot),
            Err(_) => assert_eq!(s.surface_index[v as usize], u32::MAX),
        }
    }

    // Edges: exactly those of the triangles, each used twice, in opposite directions.
    let mut from_triangles: Vec<[u32; 2]> = s
        .triangles
        .iter()
        .flat_map(|t| (0..3).map(move |k| [t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3])]))
        .collect();
    from_triangles.sort_unstable();
    let unique = {
        let mut u = from_triangles.clone();
        u.dedup();
        u
    };
    assert_eq!(s.edges, unique);
    assert_eq!(
        from_triangles.len(),
        2 * unique.len(),
        "every edge has two triangles"
    );
    for e in &s.edges {
        assert!(e[0] < e[1]);
        assert!(
            mesh.edges.binary_search(e).is_ok(),
            "surface edge {e:?} is a mesh edge"
        );
    }

    // Neighbours: across edge k lies a triangle holding the same edge reversed, whose
    // neighbour across it is this triangle.
    assert_eq!(s.triangle_neighbours.len(), s.triangles.len());
    for (t, tri) in s.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let m = s.triangle_neighbours[t][k] as usize;
            assert_ne!(m, t);
            let other = s.triangles[m];
            let j = (0..3)
                .find(|&j| other[j] == b && other[(j + 1) % 3] == a)
                .expect("the neighbour holds the edge reversed");
            assert_eq!(s.triangle_neighbours[m][j] as usize, t);
        }
    }

    // Vertex fans: each vertex lists exactly its triangles, consecutive ones sharing an
    // edge at the vertex, going counter-clockwise (the next one is across the edge that
    // ends at the vertex).
    assert_eq!(s.vertex_triangle_offsets.len(), s.vertices.len() + 1);
    assert_eq!(s.vertex_triangles.len(), 3 * s.triangles.len());
    for (slot, &v) in s.vertices.iter().enumerate() {
        let fan = s.triangles_around(slot);
        let mut listed: Vec<u32> = fan.to_vec();
        listed.sort_unstable();
        let mut holding: Vec<u32> = (0..s.triangles.len() as u32)
            .filter(|&t| s.triangles[t as usize].contains(&v))
            .collect();
        holding.sort_unstable();
        assert_eq!(listed, holding);
        for i in 0..fan.len() {
            let t = fan[i] as usize;
            let k = s.triangles[t].iter().position(|&x| x == v).unwrap();
            assert_eq!(
                s.triangle_neighbours[t][(k + 2) % 3],
                fan[(i + 1) % fan.len()]
            );
        }
    }

    // Owners: each triangle is an outward face of its tetrahedron.
    for (tri, &owner) in s.triangles.iter().zip(&s.triangle_tets) {
        let tet = mesh.tets[owner as usize];
        let opposite = tet.iter().find(|v| !tri.contains(v)).unwrap();
        let p = tri.map(|v| mesh.positions[v as usize]);
        let normal = (p[1] - p[0]).cross(&(p[2] - p[0]));
        assert!(normal.dot(&(mesh.positions[*opposite as usize] - p[0])) < 0.0);
    }
    assert_eq!(s.triangle_tags.len(), s.triangles.len());

    s.vertices.len() as i64 - s.edges.len() as i64 + s.triangles.len() as i64
}

/// Σ over the outward surface of (centroid · area normal) / 3: the enclosed volume.
fn divergence_volume(mesh: &TetMesh) -> f64 {
    mesh.surface
        .triangles
        .iter()
        .map(|tri| {
            let p = tri.map(|v| mesh.positions[v as usize]);
            let area_normal = (p[1] - p[0]).cross(&(p[2] - p[0])) / 2.0;
            let centroid = (p[0].coords + p[1].coords + p[2].coords) / 3.0;
            centroid.dot(&area_normal) / 3.0
        })
        .sum()
}

fn total_volume(mesh: &TetMesh) -> f64 {
    mesh.tets
        .iter()
        .map(|&t| TetMesh::six_volume(&mesh.positions, t) / 6.0)
        .sum()
}

/// Unit vertex normals, and the number of (triangle, corner) pairs whose face normal
/// and vertex normal point to opposite sides. Such a pair can only occur at a crease
/// sharper than a right angle: if all the normals around a vertex are pairwise less than
/// 90° apart, their weighted average has a positive dot product with each of them.
/// This checks that every disagreement is at such a crease.
fn check_normals(mesh: &TetMesh) -> usize {
    let s = &mesh.surface;
    assert_eq!(s.vertex_normals.len(), s.vertices.len());
    for n in &s.vertex_normals {
        assert!(
            (n.norm() - 1.0).abs() < 1e-12,
            "vertex normal {n:?} is not unit"
        );
    }
    let mut disagreeing = 0;
    for tri in &s.triangles {
        let p = tri.map(|v| mesh.positions[v as usize]);
        let face = (p[1] - p[0]).cross(&(p[2] - p[0]));
        for &v in tri {
            let slot = s.slot(v).unwrap();
            if face.dot(&s.vertex_normals[slot]) <= 0.0 {
                disagreeing += 1;
                let normals: Vec<Vector3<f64>> = s
                    .triangles_around(slot)
                    .iter()
                    .map(|&t| {
                        let q = s.triangles[t as usize].map(|v| mesh.positions[v as usize]);
                        (q[1] - q[0]).cross(&(q[2] - q[0]))
                    })
                    .collect();
                let crease = normals
                    .iter()
                    .any(|a| normals.iter().any(|b| a.dot(b) < 0.0));
                assert!(
                    crease,
                    "node {} disagrees with a face but has no sharp crease",
                    mesh.node_ids[v as usize]
                );
            }
        }
    }
    disagreeing
}

mod data_sets;
mod file_faults;
mod generated;
mod geometry_faults;
mod order;
mod refine;
