//! The data sets (SOFA's liver and the 5k liver), v1/v2.2 equivalence, orientation
//! repair, scaling and the surface normals.

use super::*;

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
fn bare_cr_line_endings_are_accepted_with_their_line_numbers() {
    let cr = LIVER.replace('\n', "\r");
    assert!(!cr.contains('\n'));
    assert_eq!(load(LIVER), load(&cr));
    // A fault is reported on the line an editor shows.
    let mut nodes = TWO_NODES;
    nodes[2] = "3 0 one 0";
    let err = fail(&v1(&nodes, &TWO_TETS_V1).replace('\n', "\r"));
    assert_eq!(err.line, Some(v1_node_line(2)), "{err}");
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
