//! Tests of the mesh module: every fault class with its line, the SOFA liver and the
//! 5k liver, orientation repair, v1/v2.2 equivalence and the surface normals.

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

// ---------------------------------------------------------------------------------------
// The data sets.

#[test]
fn sofa_liver_loads_with_closed_outward_surface() {
    let mesh = load(LIVER);
    assert_eq!(mesh.vertex_count(), 181);
    assert_eq!(mesh.node_ids, (1..=181).collect::<Vec<u64>>());
    assert_eq!(mesh.tets.len(), 596);
    assert!(mesh.tet_tags.iter().all(|&t| t == 1));
    assert_eq!(mesh.surface.vertices.len(), 140);
    assert_eq!(mesh.surface.triangles.len(), 276);
    assert_eq!(mesh.surface.edges.len(), 414);
    assert_eq!(check_surface(&mesh), 2, "Euler characteristic of a sphere");
    assert!(mesh.surface.triangle_tags.iter().all(|&t| t == 0));

    for &t in &mesh.tets {
        assert!(TetMesh::six_volume(&mesh.positions, t) > 0.0);
    }
    let volume = total_volume(&mesh);
    assert!((volume - 36.561).abs() < 1e-3, "volume {volume}");
    assert!((mesh.volume(&mesh.positions) - volume).abs() < 1e-12);
    let enclosed = divergence_volume(&mesh);
    assert!(
        ((enclosed - volume) / volume).abs() < 1e-9,
        "surface encloses {enclosed}, tets sum to {volume}"
    );

    // SOFA's coarse liver has two vertices on creases sharper than 90° (nodes 60 and
    // 94), where one adjacent triangle faces away from the averaged normal.
    assert_eq!(check_normals(&mesh), 2);

    let (lo, hi) = mesh.bounding_box();
    assert!((lo - Point3::new(-4.679, 0.218, -1.693)).norm() < 1e-3);
    assert!((hi - Point3::new(1.803, 5.157, 2.729)).norm() < 1e-3);

    // Edges: unique, sorted, i < j, and the count Euler's relation gives for a
    // tetrahedral ball: V − E + F − T = 1 (F counting every face once).
    assert!(mesh.edges.windows(2).all(|w| w[0] < w[1]));
    assert!(mesh.edges.iter().all(|e| e[0] < e[1]));
    let faces = (4 * mesh.tets.len() + mesh.surface.triangles.len()) / 2;
    let chi = mesh.vertex_count() as i64 - mesh.edges.len() as i64 + faces as i64
        - mesh.tets.len() as i64;
    assert_eq!(chi, 1);
}

#[test]
fn liver_5k_declared_triangles_are_its_boundary() {
    let mesh = load(LIVER_5K);
    assert_eq!(mesh.vertex_count(), 1408);
    assert_eq!(mesh.tets.len(), 5174);
    assert_eq!(mesh.surface.triangles.len(), 1956);
    assert_eq!(check_surface(&mesh), 2);
    // Every boundary triangle matched a declared triangle (tag 2, "boundary"), and
    // the count is the same, so the declared set is exactly the boundary.
    let elements = &LIVER_5K[LIVER_5K.find("$Elements").unwrap()..];
    let declared = elements
        .lines()
        .filter(|l| l.split_ascii_whitespace().nth(1) == Some("2"))
        .count();
    assert_eq!(declared, 1956);
    assert!(mesh.surface.triangle_tags.iter().all(|&t| t == 2));
    assert!(mesh.tet_tags.iter().all(|&t| t == 1));
    let volume = total_volume(&mesh);
    assert!((volume - 38.771).abs() < 1e-3, "volume {volume}");
    assert!(((divergence_volume(&mesh) - volume) / volume).abs() < 1e-9);
    assert_eq!(check_normals(&mesh), 0);
}

/// The liver rewritten as v2.2 text (same nodes and elements, tags "1 1").
fn liver_as_v2() -> String {
    let mut out = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n");
    let mut in_elements = false;
    let mut count_line = false;
    for line in LIVER.lines() {
        match line.trim() {
            "$NOD" => out += "$Nodes",
            "$ENDNOD" => out += "$EndNodes",
            "$ELM" => {
                out += "$Elements";
                in_elements = true;
                count_line = true;
            }
            "$ENDELM" => {
                out += "$EndElements";
                in_elements = false;
            }
            _ if in_elements && !count_line => {
                let f: Vec<&str> = line.split_ascii_whitespace().collect();
                assert_eq!(&f[1..5], ["4", "1", "1", "4"]);
                out += &format!("{} 4 2 1 1 {}", f[0], f[5..].join(" "));
            }
            _ => {
                count_line = false;
                out += line;
            }
        }
        out += "\n";
    }
    out
}

#[test]
fn v1_and_v2_texts_of_the_same_mesh_load_alike() {
    assert_eq!(
        load(&v1(&TWO_NODES, &TWO_TETS_V1)),
        load(&v2(&TWO_NODES, &TWO_TETS_V2))
    );
    let liver_v2 = liver_as_v2();
    assert!(liver_v2.starts_with("$MeshFormat\n2.2 0 8\n"));
    assert_eq!(load(LIVER), load(&liver_v2));
}

#[test]
fn whitespace_blank_lines_and_crlf_are_accepted() {
    let messy: String = LIVER
        .lines()
        .map(|l| format!("  {}\t \r\n\r\n", l.replace(' ', " \t  ")))
        .collect();
    assert_eq!(load(LIVER), load(&messy));
}

#[test]
fn negatively_listed_tets_are_repaired_with_the_same_boundary() {
    let raw = cube_tets();
    let negative = raw
        .iter()
        .filter(|&&t| TetMesh::six_volume(&cube_positions(), t) < 0.0)
        .count();
    assert_eq!(
        negative, 3,
        "the construction lists half the tets negatively"
    );
    let repaired = load(&cube_v1(&raw));
    for &t in &repaired.tets {
        assert!(TetMesh::six_volume(&repaired.positions, t) > 0.0);
    }

    // The same cube written correctly oriented, fixed another way (swapping the first
    // two vertices instead of the last two).
    let fixed: Vec<[u32; 4]> = raw
        .iter()
        .map(|&t| {
            if TetMesh::six_volume(&cube_positions(), t) < 0.0 {
                [t[1], t[0], t[2], t[3]]
            } else {
                t
            }
        })
        .collect();
    let correct = load(&cube_v1(&fixed));
    assert_eq!(
        canonical_boundary(&repaired.surface),
        canonical_boundary(&correct.surface)
    );
    assert_eq!(repaired.edges, correct.edges);
    assert_eq!(repaired.surface.triangles.len(), 12);
    assert_eq!(check_surface(&repaired), 2);
    assert!((total_volume(&repaired) - 1.0).abs() < 1e-12);
    assert!((divergence_volume(&repaired) - 1.0).abs() < 1e-12);
}

#[test]
fn cube_corner_normals_are_angle_weighted() {
    let mesh = load(&cube_v1(&cube_tets()));
    assert_eq!(mesh.surface.vertices.len(), 8);
    let centre = Vector3::new(0.5, 0.5, 0.5);
    for (slot, &v) in mesh.surface.vertices.iter().enumerate() {
        // Each corner sees three faces at right angles whatever the diagonal that splits
        // each face; only angle weighting gives the diagonal direction for every corner.
        let expected = (mesh.positions[v as usize].coords - centre).normalize();
        let got = mesh.surface.vertex_normals[slot];
        assert!(
            (got - expected).norm() < 1e-12,
            "corner {v}: {got:?} vs {expected:?}"
        );
    }
}

#[test]
fn scaling_keeps_normals_and_scales_volume() {
    let mut mesh = load(LIVER);
    let before = mesh.clone();
    mesh.scale(0.2 / 6.5);
    let f: f64 = 0.2 / 6.5;
    assert!((total_volume(&mesh) - total_volume(&before) * f.powi(3)).abs() < 1e-15);
    for (a, b) in mesh
        .surface
        .vertex_normals
        .iter()
        .zip(&before.surface.vertex_normals)
    {
        assert!((a - b).norm() < 1e-12);
    }
    assert_eq!(mesh.surface.triangles, before.surface.triangles);
}

#[test]
fn in_memory_mesh_matches_the_file() {
    let from_memory = TetMesh::from_tets(cube_positions(), cube_tets()).unwrap();
    assert_eq!(from_memory, load(&cube_v1(&cube_tets())));

    let err = TetMesh::from_tets(cube_positions(), vec![[0, 1, 2, 8]]).unwrap_err();
    assert_eq!(
        err.kind,
        MeshErrorKind::IndexOutOfRange(OutOfRange::VertexIndex {
            element: 1,
            index: 8,
            count: 8
        })
    );
    let mut positions = cube_positions();
    positions[3].y = f64::NAN;
    let err = TetMesh::from_tets(positions, cube_tets()).unwrap_err();
    assert!(matches!(
        err.kind,
        MeshErrorKind::NonFiniteCoordinate {
            node: 4,
            axis: 'y',
            ..
        }
    ));
}

#[test]
fn declared_triangle_tags_are_kept() {
    let mut elements: Vec<&str> = TWO_BOUNDARY_V2.to_vec();
    elements.extend(TWO_TETS_V2);
    let mesh = load(&v2(&TWO_NODES, &elements));
    assert_eq!(mesh.surface.triangles.len(), 6);
    assert!(mesh.surface.triangle_tags.iter().all(|&t| t == 7));
    assert_eq!(mesh.tet_tags, [1, 1]);
    assert_eq!(check_surface(&mesh), 2);
}

// ---------------------------------------------------------------------------------------
// Fault classes: kind and line.

#[test]
fn io_error() {
    let path = std::path::Path::new("/nonexistent/laparo/liver.msh");
    let err = read_gmsh_file(path).unwrap_err();
    assert!(matches!(
        err.kind,
        MeshErrorKind::Io {
            kind: std::io::ErrorKind::NotFound,
            ..
        }
    ));
    assert_eq!(err.line, None);
    assert!(
        err.to_string()
            .starts_with("/nonexistent/laparo/liver.msh: cannot read")
    );
}

#[test]
fn file_reading_matches_text_reading() {
    let dir = std::env::temp_dir().join(format!("laparo-mesh-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("two.msh");
    std::fs::write(&path, v1(&TWO_NODES, &TWO_TETS_V1)).unwrap();
    let from_file = read_gmsh_file(&path).unwrap();
    assert_eq!(from_file, load(&v1(&TWO_NODES, &TWO_TETS_V1)));

    // A binary file: an ASCII header followed by bytes that are not UTF-8.
    let binary = dir.join("binary.msh");
    let mut bytes = b"$MeshFormat\n2.2 1 8\n".to_vec();
    bytes.extend([1, 0, 0, 0, 0xff, 0xfe, b'\n']);
    bytes.extend(b"$EndMeshFormat\n$Nodes\n");
    bytes.extend([0x80, 0xff, 0x00, 0x13]);
    std::fs::write(&binary, bytes).unwrap();
    let err = read_gmsh_file(&binary).unwrap_err();
    assert!(
        matches!(err.kind, MeshErrorKind::UnsupportedFormat { .. }),
        "{err}"
    );
    assert_eq!(err.line, Some(2));
    assert!(err.to_string().contains("binary"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn unsupported_version_or_binary() {
    let v4 = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 0 1\n$EndEntities\n";
    let err = fail(v4);
    assert!(matches!(err.kind, MeshErrorKind::UnsupportedFormat { .. }));
    assert_eq!(err.line, Some(2));
    assert!(
        err.to_string()
            .starts_with("test.msh:2: unsupported mesh format: Gmsh MSH version 4.1")
    );

    let binary = v2(&TWO_NODES, &TWO_TETS_V2).replace("2.2 0 8", "2.2 1 8");
    let err = fail(&binary);
    assert!(matches!(err.kind, MeshErrorKind::UnsupportedFormat { .. }));
    assert_eq!(err.line, Some(2));

    // $Nodes without the $MeshFormat header that version 2 requires.
    let headless =
        v2(&TWO_NODES, &TWO_TETS_V2).replace("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n", "");
    let err = fail(&headless);
    assert!(matches!(err.kind, MeshErrorKind::UnsupportedFormat { .. }));
    assert_eq!(err.line, Some(5));
}

#[test]
fn unsupported_volume_element() {
    let nodes = [
        "1 0 0 0", "2 1 0 0", "3 1 1 0", "4 0 1 0", "5 0 0 1", "6 1 0 1", "7 1 1 1", "8 0 1 1",
    ];
    let err = fail(&v2(&nodes, &["1 15 2 0 1 1", "2 5 2 1 1 1 2 3 4 5 6 7 8"]));
    assert_eq!(
        err.kind,
        MeshErrorKind::UnsupportedElement {
            element: 2,
            element_type: 5
        }
    );
    assert_eq!(err.line, Some(v2_element_line(8, 1)));
}

#[test]
fn malformed_wrong_field_count() {
    let mut nodes = TWO_NODES;
    nodes[2] = "3 0 1";
    let err = fail(&v1(&nodes, &TWO_TETS_V1));
    assert_eq!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::FieldCount {
            what: "the node line (id x y z)",
            expected: 4,
            found: 3
        })
    );
    assert_eq!(err.line, Some(v1_node_line(2)));

    // v1 element line whose node count field promises more nodes than it lists.
    let err = fail(&v1(&TWO_NODES, &["1 4 1 1 4 1 2 3 4", "2 4 1 1 4 2 3 4"]));
    assert!(matches!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::FieldCount {
            expected: 9,
            found: 8,
            ..
        })
    ));
    assert_eq!(err.line, Some(v1_element_line(5, 1)));

    // v2 element line shorter than its tag count.
    let err = fail(&v2(&TWO_NODES, &["1 4 2 1 1 1 2 3 4", "2 4 9 1 1 2 3"]));
    assert!(matches!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::TooFewFields { minimum: 12, .. })
    ));
    assert_eq!(err.line, Some(v2_element_line(5, 1)));
}

#[test]
fn malformed_unparsable_number() {
    let mut nodes = TWO_NODES;
    nodes[3] = "4 0 0.0.1 1";
    let err = fail(&v1(&nodes, &TWO_TETS_V1));
    assert_eq!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::BadNumber {
            what: "a coordinate",
            text: "0.0.1".to_owned()
        })
    );
    assert_eq!(err.line, Some(v1_node_line(3)));

    let err = fail(&v2(&TWO_NODES, &["1 4 2 1 1 1 2 3 4", "2 4 2 1 1 2 3 x 5"]));
    assert!(matches!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::BadNumber {
            what: "a node id",
            ..
        })
    ));
    assert_eq!(err.line, Some(v2_element_line(5, 1)));

    let err = fail("$NOD\nfive\n$ENDNOD\n");
    assert!(matches!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::BadNumber { .. })
    ));
    assert_eq!(err.line, Some(2));
}

#[test]
fn malformed_count_mismatch() {
    // Five nodes declared, four given: the block closes early.
    let text = v1(&TWO_NODES[..4], &TWO_TETS_V1).replacen("$NOD\n4\n", "$NOD\n5\n", 1);
    let err = fail(&text);
    assert_eq!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::CountMismatch {
            section: "$NOD",
            declared: 5,
            found: 4
        })
    );
    assert_eq!(err.line, Some(v1_node_line(4)), "the $ENDNOD line");

    // Three elements declared, two given.
    let text = v2(&TWO_NODES, &TWO_TETS_V2).replace("$Elements\n2\n", "$Elements\n3\n");
    let err = fail(&text);
    assert!(matches!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::CountMismatch {
            declared: 3,
            found: 2,
            ..
        })
    ));
    assert_eq!(
        err.line,
        Some(v2_element_line(5, 2)),
        "the $EndElements line"
    );
}

#[test]
fn malformed_missing_section_end() {
    let text = v1(&TWO_NODES, &TWO_TETS_V1).replace("$ENDELM\n", "");
    let err = fail(&text);
    assert!(matches!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::MissingEnd { .. })
    ));
    assert_eq!(
        err.line,
        Some(v1_element_line(5, 0) - 2),
        "the $ELM line left open"
    );
    assert!(err.to_string().contains("$ENDELM"));

    // Another section starts where the end marker should be.
    let text = v2(&TWO_NODES, &TWO_TETS_V2).replace("$EndNodes\n", "");
    let err = fail(&text);
    assert!(matches!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::MissingEnd { found: Some(_), .. })
    ));
    assert_eq!(err.line, Some(v2_node_line(5)));

    // An unknown section that never closes.
    let err = fail(&(v2(&TWO_NODES, &TWO_TETS_V2) + "$Comments\nhello\n"));
    assert!(matches!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::MissingEnd { .. })
    ));
    assert_eq!(err.line, Some(v2_element_line(5, 3)));

    // Text outside any section.
    let err = fail(&format!("hello\n{}", v1(&TWO_NODES, &TWO_TETS_V1)));
    assert!(matches!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::UnexpectedLine { .. })
    ));
    assert_eq!(err.line, Some(1));
}

#[test]
fn missing_node_id() {
    let err = fail(&v1(&TWO_NODES, &["1 4 1 1 4 1 2 3 4", "2 4 1 1 4 2 3 4 9"]));
    assert_eq!(
        err.kind,
        MeshErrorKind::MissingNode {
            element: 2,
            node: 9
        }
    );
    assert_eq!(err.line, Some(v1_element_line(5, 1)));
    assert_eq!(
        err.to_string(),
        "test.msh:12: element 2 refers to node id 9, which is not defined"
    );
}

#[test]
fn duplicate_node_id() {
    let mut nodes = TWO_NODES;
    nodes[4] = "3 1 1 1";
    let err = fail(&v1(&nodes, &TWO_TETS_V1));
    assert_eq!(
        err.kind,
        MeshErrorKind::DuplicateNode {
            id: 3,
            first_line: 5
        }
    );
    assert_eq!(err.line, Some(v1_node_line(4)));
    assert_eq!(
        err.to_string(),
        "test.msh:7: node id 3 is defined twice (first at line 5)"
    );

    // Sparse ids take the hashed path.
    let sparse = ["10 0 0 0", "2000000 1 0 0", "30 0 1 0", "10 0 0 1"];
    let err = fail(&v1(&sparse, &["1 4 1 1 4 10 2000000 30 10"]));
    assert_eq!(
        err.kind,
        MeshErrorKind::DuplicateNode {
            id: 10,
            first_line: 3
        }
    );
    assert_eq!(err.line, Some(v1_node_line(3)));
}

#[test]
fn sparse_node_ids_load() {
    let sparse = ["10 0 0 0", "2000000 1 0 0", "30 0 1 0", "7 0 0 1"];
    let mesh = load(&v1(&sparse, &["1 4 1 1 4 10 2000000 30 7"]));
    assert_eq!(mesh.node_ids, [10, 2000000, 30, 7]);
    assert_eq!(mesh.tets, [[0, 1, 2, 3]]);
    assert_eq!(check_surface(&mesh), 2);
}

#[test]
fn index_out_of_range() {
    // Six node lines under a header of five.
    let mut nodes = TWO_NODES.to_vec();
    nodes.push("6 2 2 2");
    let text = v1(&nodes, &TWO_TETS_V1).replacen("$NOD\n6\n", "$NOD\n5\n", 1);
    let err = fail(&text);
    assert_eq!(
        err.kind,
        MeshErrorKind::IndexOutOfRange(OutOfRange::NodeEntry {
            index: 6,
            declared: 5
        })
    );
    assert_eq!(err.line, Some(v1_node_line(5)));

    // Three element lines under a header of two.
    let text = v1(
        &TWO_NODES,
        &[
            "1 4 1 1 4 1 2 3 4",
            "2 4 1 1 4 2 3 4 5",
            "3 4 1 1 4 1 2 3 5",
        ],
    )
    .replace("$ELM\n3\n", "$ELM\n2\n");
    let err = fail(&text);
    assert!(matches!(
        err.kind,
        MeshErrorKind::IndexOutOfRange(OutOfRange::ElementEntry {
            index: 3,
            declared: 2
        })
    ));
    assert_eq!(err.line, Some(v1_element_line(5, 2)));

    // A v1 tetrahedron that declares (and lists) five nodes.
    let err = fail(&v1(
        &TWO_NODES,
        &["1 4 1 1 4 1 2 3 4", "2 4 1 1 5 2 3 4 5 1"],
    ));
    assert_eq!(
        err.kind,
        MeshErrorKind::IndexOutOfRange(OutOfRange::ElementNodes {
            element: 2,
            element_type: 4,
            found: 5,
            expected: 4
        })
    );
    assert_eq!(err.line, Some(v1_element_line(5, 1)));

    // A v2.2 tetrahedron with three nodes.
    let err = fail(&v2(&TWO_NODES, &["1 4 2 1 1 1 2 3", "2 4 2 1 1 2 3 4 5"]));
    assert!(matches!(
        err.kind,
        MeshErrorKind::IndexOutOfRange(OutOfRange::ElementNodes {
            found: 3,
            expected: 4,
            ..
        })
    ));
    assert_eq!(err.line, Some(v2_element_line(5, 0)));
}

#[test]
fn non_finite_coordinates() {
    for (bad, axis) in [("4 0 0 nan", 'z'), ("4 inf 0 1", 'x'), ("4 0 1e999 1", 'y')] {
        let mut nodes = TWO_NODES;
        nodes[3] = bad;
        let err = fail(&v1(&nodes, &TWO_TETS_V1));
        assert!(
            matches!(err.kind, MeshErrorKind::NonFiniteCoordinate { node: 4, axis: a, .. } if a == axis),
            "{err}"
        );
        assert_eq!(err.line, Some(v1_node_line(3)));
    }
}

#[test]
fn degenerate_tet() {
    let mut nodes = TWO_NODES;
    nodes[4] = "5 0.25 0.5 0"; // in the plane z = 0 of nodes 1, 2, 3
    let err = fail(&v1(&nodes, &["1 4 1 1 4 1 2 3 4", "2 4 1 1 4 1 2 3 5"]));
    assert!(
        matches!(err.kind, MeshErrorKind::DegenerateTet { element: 2, .. }),
        "{err}"
    );
    assert_eq!(err.line, Some(v1_element_line(5, 1)));
}

#[test]
fn degeneracy_test_is_scale_free() {
    // A well-shaped tetrahedron a nanometre across is fine...
    let tiny = ["1 0 0 0", "2 1e-9 0 0", "3 0 1e-9 0", "4 0 0 1e-9"];
    let mesh = load(&v1(&tiny, &["1 4 1 1 4 1 2 3 4"]));
    assert!(TetMesh::six_volume(&mesh.positions, mesh.tets[0]) > 0.0);
    // ...and a huge one flat to 1e-14 of its size is not, although |6V| = 1e4.
    let flat = ["1 0 0 0", "2 1e6 0 0", "3 0 1e6 0", "4 3e5 3e5 1e-8"];
    let err = fail(&v1(&flat, &["1 4 1 1 4 1 2 3 4"]));
    assert!(matches!(
        err.kind,
        MeshErrorKind::DegenerateTet { element: 1, .. }
    ));
    assert_eq!(err.line, Some(v1_element_line(4, 0)));
}

#[test]
fn inverted_beyond_repair() {
    // Node 5 moved to the same side of face 2-3-4 as node 1: element 2 is listed
    // negatively, gets repaired, and then overlaps element 1.
    let mut nodes = TWO_NODES;
    nodes[4] = "5 0.2 0.2 0.2";
    let err = fail(&v1(&nodes, &TWO_TETS_V1));
    assert_eq!(
        err.kind,
        MeshErrorKind::InvertedBeyondRepair {
            element: 2,
            other: 1,
            face: [2, 3, 4]
        }
    );
    assert_eq!(err.line, Some(v1_element_line(5, 1)));
    assert_eq!(
        err.to_string(),
        "test.msh:12: elements 1 and 2 lie on the same side of their shared face \
         (nodes 2, 3, 4): the mesh folds over itself"
    );
}

#[test]
fn face_shared_by_three_tets() {
    let mut nodes = TWO_NODES.to_vec();
    nodes.push("6 2 2 2");
    let err = fail(&v1(
        &nodes,
        &[
            "1 4 1 1 4 1 2 3 4",
            "2 4 1 1 4 2 3 4 5",
            "3 4 1 1 4 2 3 4 6",
        ],
    ));
    assert_eq!(
        err.kind,
        MeshErrorKind::FaceSharedByMany {
            face: [2, 3, 4],
            elements: vec![1, 2, 3]
        }
    );
    assert_eq!(err.line, Some(v1_element_line(6, 2)));
}

#[test]
fn open_boundary_declared_triangles() {
    // The declared triangles close around tetrahedron 1 only, and tetrahedron 2 sits
    // apart from it: the declared surface does not enclose the volume.
    let nodes = [
        "1 0 0 0", "2 1 0 0", "3 0 1 0", "4 0 0 1", "5 5 0 0", "6 6 0 0", "7 5 1 0", "8 5 0 1",
    ];
    let elements = [
        "11 2 2 7 7 1 3 2",
        "12 2 2 7 7 1 2 4",
        "13 2 2 7 7 1 4 3",
        "14 2 2 7 7 2 3 4",
        "1 4 2 1 1 1 2 3 4",
        "2 4 2 1 1 5 6 7 8",
    ];
    let err = fail(&v2(&nodes, &elements));
    assert!(
        matches!(
            err.kind,
            MeshErrorKind::OpenBoundary(BoundaryGap::Undeclared { element: 2, .. })
        ),
        "{err}"
    );
    assert_eq!(err.line, Some(v2_element_line(8, 5)));

    // Declared patches that do not close are tags on part of the boundary, not a
    // statement of all of it: five of the six faces load, tagged, the sixth untagged.
    let mut elements: Vec<&str> = TWO_BOUNDARY_V2[..5].to_vec();
    elements.extend(TWO_TETS_V2);
    let mesh = load(&v2(&TWO_NODES, &elements));
    let mut tags = mesh.surface.triangle_tags.clone();
    tags.sort();
    assert_eq!(tags, [0, 7, 7, 7, 7, 7]);

    // A declared triangle that is an interior face.
    let mut elements: Vec<&str> = TWO_BOUNDARY_V2.to_vec();
    elements.push("17 2 2 7 7 2 3 4");
    elements.extend(TWO_TETS_V2);
    let err = fail(&v2(&TWO_NODES, &elements));
    assert_eq!(
        err.kind,
        MeshErrorKind::OpenBoundary(BoundaryGap::NotBoundary {
            element: 17,
            face: [2, 3, 4]
        })
    );
    assert_eq!(err.line, Some(v2_element_line(5, 6)));

    // The same face declared twice (in either orientation).
    let mut elements: Vec<&str> = TWO_BOUNDARY_V2.to_vec();
    elements.push("17 2 2 7 7 1 2 3");
    elements.extend(TWO_TETS_V2);
    let err = fail(&v2(&TWO_NODES, &elements));
    assert_eq!(
        err.kind,
        MeshErrorKind::OpenBoundary(BoundaryGap::Repeated {
            element: 17,
            first: 11
        })
    );
    assert_eq!(err.line, Some(v2_element_line(5, 6)));
}

#[test]
fn open_boundary_edge_of_a_surface() {
    // The boundary of tetrahedra is always closed (shared faces cancel), so an edge with
    // one triangle can only come from a surface built otherwise; the surface builder
    // still rejects it.
    let positions = [
        Point3::origin(),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(0.0, 1.0, 0.0),
    ];
    let fault = topology::build_surface(3, &positions, vec![[0, 1, 2]], vec![0]).unwrap_err();
    assert_eq!(
        fault,
        Fault::OpenEdge {
            edge: [0, 1],
            tet: 0
        }
    );
}

#[test]
fn non_manifold_edge() {
    // Two tetrahedra that share only the edge 1-2.
    let nodes = [
        "1 0 0 0", "2 1 0 0", "3 0 1 0", "4 0 0 1", "5 0 -1 0", "6 0 0 -1",
    ];
    let err = fail(&v1(&nodes, &["1 4 1 1 4 1 2 3 4", "2 4 1 1 4 1 2 5 6"]));
    assert_eq!(
        err.kind,
        MeshErrorKind::NonManifoldBoundary(NonManifold::Edge {
            edge: [1, 2],
            triangles: 4
        })
    );
    assert_eq!(err.line, Some(v1_element_line(6, 1)));
}

#[test]
fn non_manifold_vertex() {
    // Two tetrahedra that touch at node 1 only.
    let nodes = [
        "1 0 0 0", "2 1 0 0", "3 0 1 0", "4 0 0 1", "5 -1 0 0", "6 0 -1 0", "7 0 0 -1",
    ];
    let err = fail(&v1(&nodes, &["1 4 1 1 4 1 2 3 4", "2 4 1 1 4 1 5 6 7"]));
    assert_eq!(
        err.kind,
        MeshErrorKind::NonManifoldBoundary(NonManifold::Vertex { node: 1, fans: 2 })
    );
    assert_eq!(err.line, Some(v1_node_line(0)));
}

#[test]
fn no_tetrahedra() {
    let err = fail(&v2(&TWO_NODES[..3], &["1 2 2 1 1 1 2 3"]));
    assert_eq!(err.kind, MeshErrorKind::NoTetrahedra);
    assert_eq!(err.line, None);
    let err = fail("$NOD\n1\n1 0 0 0\n$ENDNOD\n");
    assert_eq!(err.kind, MeshErrorKind::NoTetrahedra);
    let err = fail("");
    assert!(matches!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::MissingSection { .. })
    ));
}

#[test]
fn stray_node() {
    let mut nodes = TWO_NODES.to_vec();
    nodes.insert(2, "42 5 5 5");
    let err = fail(&v1(&nodes, &TWO_TETS_V1));
    assert_eq!(err.kind, MeshErrorKind::StrayNode { node: 42 });
    assert_eq!(err.line, Some(v1_node_line(2)));
}

#[test]
fn damaged_files_give_errors_not_panics() {
    let texts = [
        v1(&TWO_NODES, &TWO_TETS_V1),
        v2(
            &TWO_NODES,
            &[&TWO_BOUNDARY_V2[..], &TWO_TETS_V2[..]].concat(),
        ),
    ];
    let replacements = [
        "",
        "x",
        "-1",
        "0",
        "99",
        "1e999",
        "nan",
        "18446744073709551616",
        "$End",
    ];
    for text in &texts {
        let lines: Vec<&str> = text.lines().collect();
        let mut variants = Vec::new();
        for i in 0..lines.len() {
            let mut dropped = lines.clone();
            dropped.remove(i);
            variants.push(dropped.join("\n"));
            let mut doubled = lines.clone();
            doubled.insert(i, lines[i]);
            variants.push(doubled.join("\n"));
            let tokens: Vec<&str> = lines[i].split(' ').collect();
            for k in 0..tokens.len() {
                for r in replacements {
                    let mut changed = tokens.clone();
                    changed[k] = r;
                    let mut edited = lines.clone();
                    let line = changed.join(" ");
                    edited[i] = &line;
                    variants.push(edited.join("\n"));
                }
            }
        }
        for cut in 0..text.len() {
            variants.push(text[..cut].to_owned());
        }
        for variant in &variants {
            // Either outcome is fine; a panic is not. An error always names the source.
            if let Err(e) = read_gmsh(variant, "test.msh") {
                assert!(e.to_string().starts_with("test.msh:"));
            }
        }
    }
}

/// Load time of the 300k-tet liver; run with
/// `LAPARO_BIG_MESH=/path/liver-300k.msh cargo test --release -- --ignored big_mesh`.
#[test]
#[ignore = "needs LAPARO_BIG_MESH pointing at a large .msh file"]
fn big_mesh_load_time() {
    let Ok(path) = std::env::var("LAPARO_BIG_MESH") else {
        return;
    };
    let text = std::fs::read_to_string(&path).unwrap();
    let start = std::time::Instant::now();
    let mesh = read_gmsh(&text, &path).unwrap();
    let elapsed = start.elapsed();
    eprintln!(
        "{path}: {} nodes, {} tets, {} surface triangles in {elapsed:?}",
        mesh.vertex_count(),
        mesh.tets.len(),
        mesh.surface.triangles.len()
    );
    let start = std::time::Instant::now();
    let mut surface = mesh.surface.clone();
    surface.update_normals(&mesh.positions);
    eprintln!("update_normals: {:?}", start.elapsed());
    assert_eq!(check_surface(&mesh), 2);
}

#[test]
fn local_vertex_normal_agrees_with_the_global_update() {
    let mut mesh = load(LIVER);
    // Deform it so the check is not on the load-time normals only.
    let deformed: Vec<_> = mesh
        .positions
        .iter()
        .map(|p| Point3::new(p.x * 1.1, p.y + 0.2 * p.x.sin(), p.z))
        .collect();
    mesh.surface.update_normals(&deformed);
    for (slot, &v) in mesh.surface.vertices.iter().enumerate() {
        let local = mesh.surface.vertex_normal(v, &deformed);
        assert!(
            (local - mesh.surface.vertex_normals[slot]).norm() < 1e-12,
            "vertex {v}"
        );
    }
    assert_eq!(
        mesh.surface.vertex_normal(u32::MAX - 1, &deformed),
        Vector3::zeros()
    );
}
