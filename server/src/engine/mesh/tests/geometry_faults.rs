//! Faults of the geometry: indices out of range, non-finite or degenerate tetrahedra,
//! inverted ones, and boundaries that are not a closed manifold, each with its kind and
//! line.

use super::*;

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
fn a_tet_too_large_to_compute_with_is_named_so_not_flat() {
    // Edges of 1e308 overflow their squares; before, this read "flat tetrahedron:
    // |6V| = 1e308 is at most 1e-12 × (longest edge inf)³".
    let mut nodes = TWO_NODES;
    nodes[1] = "2 1e308 0 0";
    let err = fail(&v1(&nodes, &TWO_TETS_V1));
    assert_eq!(
        err.kind,
        MeshErrorKind::OversizedTet {
            element: 1,
            largest: 1e308
        },
        "{err}"
    );
    assert_eq!(err.line, Some(v1_element_line(5, 0)));
    assert!(
        err.to_string().contains("too large to compute with"),
        "{err}"
    );
    // Edges of 1e110 have finite squares but a volume of 1e330, which overflows.
    nodes = [
        "1 0 0 0",
        "2 1e110 0 0",
        "3 0 1e110 0",
        "4 0 0 1e110",
        "5 1 1 1",
    ];
    let err = fail(&v1(&nodes[..4], &TWO_TETS_V1[..1]));
    assert!(
        matches!(err.kind, MeshErrorKind::OversizedTet { element: 1, .. }),
        "{err}"
    );
}

#[test]
fn a_tet_too_small_to_compute_with_is_named_so_and_a_point_is_a_point() {
    // A regular-cornered tetrahedron 1e-150 across: its edges' squares underflow to
    // zero, and it read "flat ... (longest edge 0)³".
    let tiny = ["1 0 0 0", "2 1e-150 0 0", "3 0 1e-150 0", "4 0 0 1e-150"];
    let err = fail(&v1(&tiny, &TWO_TETS_V1[..1]));
    assert_eq!(
        err.kind,
        MeshErrorKind::UndersizedTet {
            element: 1,
            extent: 1e-150
        },
        "{err}"
    );
    assert!(
        err.to_string().contains("too small to compute with"),
        "{err}"
    );
    // Just above the bound, the same shape is judged by its shape and passes.
    let small = ["1 0 0 0", "2 1e-90 0 0", "3 0 1e-90 0", "4 0 0 1e-90"];
    let mesh = load(&v1(&small, &TWO_TETS_V1[..1]));
    assert!(TetMesh::six_volume(&mesh.positions, mesh.tets[0]) > 0.0);
    // Four nodes at one place: a point, said so.
    let point = ["1 2 3 4", "2 2 3 4", "3 2 3 4", "4 2 3 4"];
    let err = fail(&v1(&point, &TWO_TETS_V1[..1]));
    assert!(
        matches!(err.kind, MeshErrorKind::DegenerateTet { element: 1, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("is a point"), "{err}");
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
