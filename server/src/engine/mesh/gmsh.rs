//! Reading Gmsh ASCII meshes, format version 1 (`$NOD`/`$ELM`, as SOFA's liver) and
//! 2.x (`$MeshFormat 2.2 0 8`, `$Nodes`, `$Elements`).
//!
//! Only the sections a volume mesh needs are read; `$PhysicalNames` and any other
//! section are skipped. Linear tetrahedra (type 4) make the volume; triangles (type 2)
//! are kept to check that they are exactly the boundary (and for their tags); points,
//! lines and other surface elements are checked for valid node references and otherwise
//! ignored; other volume elements are rejected. Blank lines, extra spaces and tabs, and
//! CRLF line ends are accepted anywhere.

use std::collections::HashMap;
use std::path::Path;

use nalgebra::Point3;

use super::TetMesh;
use super::assemble::{DeclaredTriangle, RawMesh};
use super::error::{MeshError, MeshErrorKind, OutOfRange, Syntax, excerpt};

/// Reads a Gmsh ASCII mesh (version 1 or 2.x) from `text`; `source` names the input
/// (usually the file name) in error messages.
///
/// Tetrahedra are made positively oriented, and the edges and the outward boundary
/// surface are built (see [`TetMesh`]).
///
/// # Errors
///
/// A [`MeshError`] naming the line and the fault: an unsupported format, malformed
/// text, undefined or repeated node ids, too many entries, non-finite coordinates, flat
/// or overlapping tetrahedra, an open or non-manifold boundary, declared surface
/// triangles that are not the boundary, no tetrahedra, or a node no tetrahedron uses.
pub fn read_gmsh(text: &str, source: &str) -> Result<TetMesh, MeshError> {
    let raw = Parser::new(text, source).parse()?;
    raw.into_mesh(source)
}

/// Reads a Gmsh ASCII mesh file; see [`read_gmsh`]. Errors name the path as given.
///
/// # Errors
///
/// [`MeshErrorKind::Io`] when the file cannot be read, otherwise as [`read_gmsh`].
pub fn read_gmsh_file(path: &Path) -> Result<TetMesh, MeshError> {
    let source = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| {
        let kind = MeshErrorKind::Io {
            kind: e.kind(),
            message: e.to_string(),
        };
        MeshError::new(&source, None, kind)
    })?;
    // A binary Gmsh file is not UTF-8 past its header. A lossy conversion keeps the
    // ASCII header readable, so the reader can say "binary" rather than "not text".
    let text = String::from_utf8_lossy(&bytes);
    read_gmsh(&text, &source)
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Version {
    /// `$NOD` / `$ELM`: element lines `id type reg-phys reg-elem n-nodes nodes…`.
    V1,
    /// `$MeshFormat 2.x 0 8`: element lines `id type ntags tags… nodes…`.
    V2,
}

/// How the reader treats an element type.
enum ElementKind {
    Tetrahedron,
    Triangle,
    /// Points, lines and other surface elements: nodes checked, element ignored.
    Ignored,
    /// Any other volume element.
    Unsupported,
}

/// Node count and treatment of each Gmsh element type (the types of the MSH 2.2
/// reference), `None` for an unknown type.
fn element_type(element_type: u32) -> Option<(usize, ElementKind)> {
    use ElementKind::{Ignored, Tetrahedron, Triangle, Unsupported};
    Some(match element_type {
        4 => (4, Tetrahedron),
        2 => (3, Triangle),
        // Point; lines of 2, 3, 4, 5, 6 nodes.
        15 => (1, Ignored),
        1 => (2, Ignored),
        8 => (3, Ignored),
        26 => (4, Ignored),
        27 => (5, Ignored),
        28 => (6, Ignored),
        // Quadrangles of 4, 9, 8 nodes; higher-order triangles.
        3 => (4, Ignored),
        10 => (9, Ignored),
        16 => (8, Ignored),
        9 => (6, Ignored),
        20 => (9, Ignored),
        21 => (10, Ignored),
        22 => (12, Ignored),
        23 => (15, Ignored),
        24 => (15, Ignored),
        25 => (21, Ignored),
        // Hexahedra, prisms, pyramids, higher-order tetrahedra.
        5 => (8, Unsupported),
        12 => (27, Unsupported),
        17 => (20, Unsupported),
        92 => (64, Unsupported),
        93 => (125, Unsupported),
        6 => (6, Unsupported),
        13 => (18, Unsupported),
        18 => (15, Unsupported),
        7 => (5, Unsupported),
        14 => (14, Unsupported),
        19 => (13, Unsupported),
        11 => (10, Unsupported),
        29 => (20, Unsupported),
        30 => (35, Unsupported),
        31 => (56, Unsupported),
        _ => return None,
    })
}

/// Node id → vertex index. Dense when the ids are compact (the usual 1..N), hashed
/// otherwise.
enum IdMap {
    Dense(Vec<u32>),
    Sparse(HashMap<u64, u32>),
}

impl IdMap {
    /// Builds the map, or returns the indices `(second, first)` of a repeated id.
    fn new(ids: &[u64]) -> Result<IdMap, (usize, usize)> {
        let max = ids.iter().copied().max().unwrap_or(0);
        if max <= 2 * ids.len() as u64 + 1024 {
            let mut map = vec![u32::MAX; max as usize + 1];
            for (i, &id) in ids.iter().enumerate() {
                let slot = &mut map[id as usize];
                if *slot != u32::MAX {
                    return Err((i, *slot as usize));
                }
                *slot = i as u32;
            }
            Ok(IdMap::Dense(map))
        } else {
            let mut map = HashMap::with_capacity(ids.len());
            for (i, &id) in ids.iter().enumerate() {
                if let Some(&first) = map.get(&id) {
                    return Err((i, first as usize));
                }
                map.insert(id, i as u32);
            }
            Ok(IdMap::Sparse(map))
        }
    }

    fn get(&self, id: u64) -> Option<u32> {
        match self {
            IdMap::Dense(map) => map
                .get(usize::try_from(id).ok()?)
                .copied()
                .filter(|&v| v != u32::MAX),
            IdMap::Sparse(map) => map.get(&id).copied(),
        }
    }
}

/// The non-blank lines of the text, trimmed, with their 1-based numbers.
struct Lines<'a> {
    inner: std::iter::Enumerate<std::str::Split<'a, char>>,
}

impl<'a> Lines<'a> {
    fn next(&mut self) -> Option<(usize, &'a str)> {
        for (i, line) in self.inner.by_ref() {
            let line = line.trim_ascii();
            if !line.is_empty() {
                return Some((i + 1, line));
            }
        }
        None
    }
}

/// A counted block being read (`$Nodes` or `$Elements` and their v1 names).
struct Block {
    /// Line of the section header.
    header: usize,
    /// Line of the count.
    count_line: usize,
    section: &'static str,
    end: &'static str,
    declared: usize,
    /// The fault for an entry beyond the declared count.
    beyond: fn(usize, usize) -> OutOfRange,
}

struct Parser<'a> {
    source: &'a str,
    /// Length of the text in bytes, to bound what an (untrusted) header count reserves.
    text_len: usize,
    lines: Lines<'a>,
    version: Option<Version>,
    raw: RawMesh,
    ids: Option<IdMap>,
    seen_elements: bool,
    /// Reused per element line.
    fields: Vec<&'a str>,
}

impl<'a> Parser<'a> {
    fn new(text: &'a str, source: &'a str) -> Self {
        Parser {
            source,
            text_len: text.len(),
            lines: Lines {
                // LF or CRLF (the CR is trimmed), or a bare CR in a file that has no
                // LF at all (old Mac editors): one line a terminator either way, so
                // the numbers in messages are the editor's.
                inner: text
                    .split(if text.contains('\n') { '\n' } else { '\r' })
                    .enumerate(),
            },
            version: None,
            raw: RawMesh::default(),
            ids: None,
            seen_elements: false,
            fields: Vec::new(),
        }
    }

    fn error(&self, line: usize, kind: MeshErrorKind) -> MeshError {
        MeshError::new(self.source, Some(line), kind)
    }

    fn syntax(&self, line: usize, syntax: Syntax) -> MeshError {
        self.error(line, MeshErrorKind::Malformed(syntax))
    }

    fn parse(mut self) -> Result<RawMesh, MeshError> {
        while let Some((n, line)) = self.lines.next() {
            if !line.starts_with('$') {
                return Err(self.syntax(
                    n,
                    Syntax::UnexpectedLine {
                        text: excerpt(line),
                    },
                ));
            }
            let name = line.split_ascii_whitespace().next().unwrap_or(line);
            match name {
                "$MeshFormat" => self.mesh_format(n)?,
                "$NOD" => self.nodes(n, "$NOD")?,
                "$Nodes" => self.nodes(n, "$Nodes")?,
                "$ELM" => self.elements(n, "$ELM")?,
                "$Elements" => self.elements(n, "$Elements")?,
                _ if name
                    .get(1..4)
                    .is_some_and(|s| s.eq_ignore_ascii_case("end")) =>
                {
                    return Err(self.syntax(
                        n,
                        Syntax::UnexpectedLine {
                            text: excerpt(line),
                        },
                    ));
                }
                _ => self.skip_section(n, name)?,
            }
        }
        if self.ids.is_none() {
            return Err(MeshError::new(
                self.source,
                None,
                MeshErrorKind::Malformed(Syntax::MissingSection {
                    section: if self.version == Some(Version::V2) {
                        "$Nodes"
                    } else {
                        "$NOD (v1) or $Nodes (v2)"
                    },
                }),
            ));
        }
        Ok(self.raw)
    }

    /// `$MeshFormat`: `version file-type data-size`; only ASCII 2.x is accepted.
    fn mesh_format(&mut self, header: usize) -> Result<(), MeshError> {
        if self.version.is_some() {
            return Err(self.syntax(
                header,
                Syntax::DuplicateSection {
                    section: "$MeshFormat".to_owned(),
                },
            ));
        }
        let Some((n, line)) = self.lines.next() else {
            return Err(self.syntax(
                header,
                Syntax::Truncated {
                    section: "$MeshFormat",
                    expected: "the line \"version file-type data-size\"",
                },
            ));
        };
        let fields: Vec<&str> = line.split_ascii_whitespace().collect();
        if fields.len() != 3 {
            return Err(self.syntax(
                n,
                Syntax::FieldCount {
                    what: "the $MeshFormat line",
                    expected: 3,
                    found: fields.len(),
                },
            ));
        }
        let version: f64 = fields[0].parse().map_err(|_| {
            self.syntax(
                n,
                Syntax::BadNumber {
                    what: "the format version",
                    text: excerpt(fields[0]),
                },
            )
        })?;
        if !(2.0..3.0).contains(&version) {
            return Err(self.error(
                n,
                MeshErrorKind::UnsupportedFormat {
                    reason: format!(
                        "Gmsh MSH version {} is not supported; save the mesh as \
                         version 2.2 ASCII (or version 1)",
                        fields[0]
                    ),
                },
            ));
        }
        match fields[1] {
            "0" => {}
            "1" => {
                return Err(self.error(
                    n,
                    MeshErrorKind::UnsupportedFormat {
                        reason: "binary Gmsh files (file-type 1) are not supported; \
                                 save the mesh as ASCII"
                            .to_owned(),
                    },
                ));
            }
            other => {
                return Err(self.error(
                    n,
                    MeshErrorKind::UnsupportedFormat {
                        reason: format!("unknown Gmsh file-type \"{other}\" (0 is ASCII)"),
                    },
                ));
            }
        }
        self.version = Some(Version::V2);
        self.expect_end(header, "$EndMeshFormat")
    }

    /// Expects the end marker of a section as the next line.
    fn expect_end(&mut self, header: usize, end: &str) -> Result<(), MeshError> {
        match self.lines.next() {
            Some((_, line)) if line.eq_ignore_ascii_case(end) => Ok(()),
            Some((n, line)) => Err(self.syntax(
                n,
                Syntax::MissingEnd {
                    end: end.to_owned(),
                    found: Some(excerpt(line)),
                },
            )),
            None => Err(self.syntax(
                header,
                Syntax::MissingEnd {
                    end: end.to_owned(),
                    found: None,
                },
            )),
        }
    }

    /// Skips an unknown section up to its `$End…` line.
    fn skip_section(&mut self, header: usize, name: &str) -> Result<(), MeshError> {
        let end = format!("$End{}", &name[1..]);
        while let Some((_, line)) = self.lines.next() {
            if line.eq_ignore_ascii_case(&end) {
                return Ok(());
            }
        }
        Err(self.syntax(header, Syntax::MissingEnd { end, found: None }))
    }

    /// Reads the count line of a block.
    fn count(&mut self, header: usize, section: &'static str) -> Result<(usize, usize), MeshError> {
        let Some((n, line)) = self.lines.next() else {
            return Err(self.syntax(
                header,
                Syntax::Truncated {
                    section,
                    expected: "the entry count",
                },
            ));
        };
        let mut fields = line.split_ascii_whitespace();
        let first = fields.next().unwrap_or("");
        let extra = fields.count();
        if extra != 0 {
            return Err(self.syntax(
                n,
                Syntax::FieldCount {
                    what: "the count line",
                    expected: 1,
                    found: extra + 1,
                },
            ));
        }
        let count = first.parse::<usize>().map_err(|_| {
            self.syntax(
                n,
                Syntax::BadNumber {
                    what: "the entry count",
                    text: excerpt(first),
                },
            )
        })?;
        Ok((n, count))
    }

    /// Next entry line of a counted block after `read` entries, or `None` once the end
    /// marker closes a complete block. Faults: too few entries (count mismatch), too many
    /// (index out of range), a missing end marker.
    fn entry(&mut self, block: &Block, read: usize) -> Result<Option<(usize, &'a str)>, MeshError> {
        let missing_end = |found: Option<&str>| Syntax::MissingEnd {
            end: block.end.to_owned(),
            found: found.map(str::to_owned),
        };
        let too_few = Syntax::CountMismatch {
            section: block.section,
            declared: block.declared,
            found: read,
        };
        match self.lines.next() {
            None if read < block.declared => Err(self.syntax(block.count_line, too_few)),
            None => Err(self.syntax(block.header, missing_end(None))),
            Some((n, line)) if line.starts_with('$') => {
                if read < block.declared {
                    Err(self.syntax(n, too_few))
                } else if line.eq_ignore_ascii_case(block.end) {
                    Ok(None)
                } else {
                    Err(self.syntax(n, missing_end(Some(line))))
                }
            }
            Some((n, _)) if read >= block.declared => Err(self.error(
                n,
                MeshErrorKind::IndexOutOfRange((block.beyond)(read + 1, block.declared)),
            )),
            Some(entry) => Ok(Some(entry)),
        }
    }

    /// `$NOD` (v1) or `$Nodes` (v2): `count`, then `id x y z` lines.
    fn nodes(&mut self, header: usize, name: &'static str) -> Result<(), MeshError> {
        if self.ids.is_some() {
            return Err(self.syntax(
                header,
                Syntax::DuplicateSection {
                    section: name.to_owned(),
                },
            ));
        }
        let end = match (name, self.version) {
            ("$NOD", None) => {
                self.version = Some(Version::V1);
                "$ENDNOD"
            }
            ("$Nodes", Some(Version::V2)) => "$EndNodes",
            ("$Nodes", _) => {
                return Err(self.error(
                    header,
                    MeshErrorKind::UnsupportedFormat {
                        reason: "a $Nodes section without a $MeshFormat header \
                                 (version 2 files start with $MeshFormat)"
                            .to_owned(),
                    },
                ));
            }
            _ => {
                return Err(self.error(
                    header,
                    MeshErrorKind::UnsupportedFormat {
                        reason: "a version 1 $NOD section in a version 2 file".to_owned(),
                    },
                ));
            }
        };
        let (count_line, declared) = self.count(header, name)?;
        // The count is untrusted: reserve no more than the text could hold (a node line
        // takes at least 8 bytes).
        let reserve = declared.min(self.text_len / 8);
        self.raw.positions.reserve(reserve);
        self.raw.node_ids.reserve(reserve);
        self.raw.node_lines.reserve(reserve);
        let block = Block {
            header,
            count_line,
            section: name,
            end,
            declared,
            beyond: |index, declared| OutOfRange::NodeEntry { index, declared },
        };
        let mut read = 0;
        while let Some((n, line)) = self.entry(&block, read)? {
            self.node(n, line)?;
            read += 1;
        }
        if read > u32::MAX as usize - 1 {
            return Err(self.error(
                count_line,
                MeshErrorKind::UnsupportedFormat {
                    reason: format!("{read} nodes are more than this reader can index"),
                },
            ));
        }
        match IdMap::new(&self.raw.node_ids) {
            Ok(map) => {
                self.ids = Some(map);
                Ok(())
            }
            Err((second, first)) => Err(self.error(
                self.raw.node_lines[second],
                MeshErrorKind::DuplicateNode {
                    id: self.raw.node_ids[second],
                    first_line: self.raw.node_lines[first],
                },
            )),
        }
    }

    /// One node line: `id x y z`.
    fn node(&mut self, n: usize, line: &str) -> Result<(), MeshError> {
        let mut fields = [""; 4];
        let mut found = 0;
        for field in line.split_ascii_whitespace() {
            if found < 4 {
                fields[found] = field;
            }
            found += 1;
        }
        if found != 4 {
            return Err(self.syntax(
                n,
                Syntax::FieldCount {
                    what: "the node line (id x y z)",
                    expected: 4,
                    found,
                },
            ));
        }
        let id = self.number::<u64>(n, fields[0], "a node id")?;
        let mut xyz = [0.0; 3];
        for (k, axis) in ['x', 'y', 'z'].into_iter().enumerate() {
            let text = fields[k + 1];
            let value = self.number::<f64>(n, text, "a coordinate")?;
            if !value.is_finite() {
                return Err(self.error(
                    n,
                    MeshErrorKind::NonFiniteCoordinate {
                        node: id,
                        axis,
                        text: excerpt(text),
                    },
                ));
            }
            xyz[k] = value;
        }
        self.raw.positions.push(Point3::from(xyz));
        self.raw.node_ids.push(id);
        self.raw.node_lines.push(n);
        Ok(())
    }

    /// `$ELM` (v1) or `$Elements` (v2): `count`, then element lines.
    fn elements(&mut self, header: usize, name: &'static str) -> Result<(), MeshError> {
        let end = if name == "$ELM" {
            "$ENDELM"
        } else {
            "$EndElements"
        };
        let (expected, nodes) = match self.version {
            Some(Version::V1) => ("$ELM", "$NOD"),
            _ => ("$Elements", "$Nodes"),
        };
        if self.ids.is_none() {
            return Err(self.syntax(
                header,
                Syntax::SectionOrder("the element section comes before the node section"),
            ));
        }
        if name != expected {
            return Err(self.error(
                header,
                MeshErrorKind::UnsupportedFormat {
                    reason: format!("a {name} section in a file whose nodes are in {nodes}"),
                },
            ));
        }
        if self.seen_elements {
            return Err(self.syntax(
                header,
                Syntax::DuplicateSection {
                    section: name.to_owned(),
                },
            ));
        }
        self.seen_elements = true;
        let (count_line, declared) = self.count(header, name)?;
        let reserve = declared.min(self.text_len / 8);
        self.raw.tets.reserve(reserve);
        self.raw.tet_tags.reserve(reserve);
        self.raw.element_ids.reserve(reserve);
        self.raw.element_lines.reserve(reserve);
        let block = Block {
            header,
            count_line,
            section: name,
            end,
            declared,
            beyond: |index, declared| OutOfRange::ElementEntry { index, declared },
        };
        let mut read = 0;
        while let Some((n, line)) = self.entry(&block, read)? {
            self.element(n, line)?;
            read += 1;
        }
        Ok(())
    }

    /// One element line, v1 `id type reg-phys reg-elem n-nodes nodes…` or v2
    /// `id type ntags tags… nodes…`.
    fn element(&mut self, n: usize, line: &'a str) -> Result<(), MeshError> {
        let mut fields = std::mem::take(&mut self.fields);
        fields.clear();
        fields.extend(line.split_ascii_whitespace());
        let result = self.element_fields(n, &fields);
        self.fields = fields;
        result
    }

    fn element_fields(&mut self, n: usize, fields: &[&str]) -> Result<(), MeshError> {
        let v1 = self.version == Some(Version::V1);
        let minimum = if v1 { 5 } else { 3 };
        if fields.len() < minimum {
            return Err(self.syntax(
                n,
                Syntax::TooFewFields {
                    what: "the element line",
                    minimum,
                    found: fields.len(),
                },
            ));
        }
        let id = self.number::<u64>(n, fields[0], "an element id")?;
        let ty = self.number::<u32>(n, fields[1], "an element type")?;
        let (tag, node_fields) = if v1 {
            let reg_phys = self.number::<i32>(n, fields[2], "a physical region")?;
            self.number::<i32>(n, fields[3], "an elementary region")?;
            let count = self.number::<usize>(n, fields[4], "a node count")?;
            if count > fields.len() - 5 {
                return Err(self.syntax(
                    n,
                    Syntax::CountPastLine {
                        what: "the element line",
                        count,
                        items: "nodes",
                        room: fields.len() - 5,
                    },
                ));
            }
            let expected = count + 5;
            if fields.len() != expected {
                return Err(self.syntax(
                    n,
                    Syntax::FieldCount {
                        what: "the element line",
                        expected,
                        found: fields.len(),
                    },
                ));
            }
            (reg_phys, &fields[5..])
        } else {
            let tags = self.number::<usize>(n, fields[2], "a tag count")?;
            if tags > fields.len() - 3 {
                return Err(self.syntax(
                    n,
                    Syntax::CountPastLine {
                        what: "the element line",
                        count: tags,
                        items: "tags",
                        room: fields.len() - 3,
                    },
                ));
            }
            let minimum = tags + 3;
            let mut first = 0;
            for (k, text) in fields[3..minimum].iter().enumerate() {
                let tag = self.number::<i32>(n, text, "a tag")?;
                if k == 0 {
                    first = tag;
                }
            }
            (first, &fields[minimum..])
        };
        let supported =
            element_type(ty).filter(|(_, kind)| !matches!(kind, ElementKind::Unsupported));
        let Some((node_count, kind)) = supported else {
            return Err(self.error(
                n,
                MeshErrorKind::UnsupportedElement {
                    element: id,
                    element_type: ty,
                },
            ));
        };
        if node_fields.len() != node_count {
            return Err(self.error(
                n,
                MeshErrorKind::IndexOutOfRange(OutOfRange::ElementNodes {
                    element: id,
                    element_type: ty,
                    found: node_fields.len(),
                    expected: node_count,
                }),
            ));
        }
        let mut vertices = [0u32; 4];
        for (k, text) in node_fields.iter().enumerate() {
            let node = self.number::<u64>(n, text, "a node id")?;
            let ids = self.ids.as_ref().expect("nodes are read before elements");
            let Some(v) = ids.get(node) else {
                return Err(self.error(n, MeshErrorKind::MissingNode { element: id, node }));
            };
            if k < 4 {
                vertices[k] = v;
            }
        }
        match kind {
            ElementKind::Tetrahedron => {
                self.raw.tets.push(vertices);
                self.raw.tet_tags.push(tag);
                self.raw.element_ids.push(id);
                self.raw.element_lines.push(n);
            }
            ElementKind::Triangle => self.raw.declared.push(DeclaredTriangle {
                nodes: [vertices[0], vertices[1], vertices[2]],
                tag,
                element: id,
                line: Some(n),
            }),
            ElementKind::Ignored | ElementKind::Unsupported => {}
        }
        Ok(())
    }

    fn number<T: std::str::FromStr>(
        &self,
        n: usize,
        text: &str,
        what: &'static str,
    ) -> Result<T, MeshError> {
        text.parse::<T>().map_err(|_| {
            self.syntax(
                n,
                Syntax::BadNumber {
                    what,
                    text: excerpt(text),
                },
            )
        })
    }
}
