//! Faults of the file: reading, version, syntax, counts, sections and node ids, each
//! with its kind and line; damaged files give errors, not panics.

use super::*;

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
    assert_eq!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::CountPastLine {
            what: "the element line",
            count: 4,
            items: "nodes",
            room: 3
        })
    );
    assert_eq!(err.line, Some(v1_element_line(5, 1)));
    // And one that lists more nodes than it says: the count is wrong.
    let err = fail(&v1(&TWO_NODES, &["1 4 1 1 4 1 2 3 4", "2 4 1 1 3 2 3 4 5"]));
    assert!(matches!(
        err.kind,
        MeshErrorKind::Malformed(Syntax::FieldCount {
            expected: 8,
            found: 9,
            ..
        })
    ));

    // v2 element line shorter than its tag count, however large: said as a count
    // the line does not hold.
    for (count, text) in [(9, "9"), (4294967295, "4294967295")] {
        let line = format!("2 4 {text} 1 1 2 3");
        let err = fail(&v2(&TWO_NODES, &["1 4 2 1 1 1 2 3 4", line.as_str()]));
        assert_eq!(
            err.kind,
            MeshErrorKind::Malformed(Syntax::CountPastLine {
                what: "the element line",
                count,
                items: "tags",
                room: 4
            })
        );
        assert_eq!(err.line, Some(v2_element_line(5, 1)));
    }
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

/// A message quotes at most `MAX_QUOTED_CHARS` characters of the file, control
/// characters escaped: a first line of a megabyte gives a message of a line, not
/// of a megabyte, and says how long the line was.
#[test]
fn messages_quote_an_excerpt_of_a_long_line() {
    use crate::engine::mesh::error::MAX_QUOTED_CHARS;
    let long = format!("x{}\n", "y".repeat(1 << 20));
    for text in [
        long.clone(),
        format!("$NOD\n{long}$ENDNOD\n"),
        format!("$NOD\n1\n1 0 0 {long}$ENDNOD\n"),
    ] {
        let said = fail(&text).to_string();
        assert!(said.len() < 200 + MAX_QUOTED_CHARS, "{} bytes", said.len());
        assert!(
            said.contains(&format!("… ({} bytes)", long.len() - 1)),
            "{said}"
        );
    }
    let said = fail("\u{1b}[2J\n").to_string();
    assert!(
        !said.contains('\u{1b}') && said.contains("\\u{1b}[2J"),
        "{said}"
    );
}
