//! Mesh loading errors: what is wrong, in which file, and on which line.
//!
//! Nodes and elements are always named by the ids the file gives them (Gmsh node and
//! element numbers), never by internal indices, so that a message can be checked against
//! the file by eye.

use std::fmt;

use laparo_proto::text::Number;

/// A mesh that could not be loaded: the file (`source`), the 1-based line where the
/// fault is (when one line is to blame), and what is wrong.
///
/// Displays as `liver.msh:212: node id 17 is defined twice (first at line 19)`.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshError {
    /// The file name (or other description of the input) given to the reader.
    pub source: String,
    /// The 1-based line of the offending entry, when there is one.
    pub line: Option<usize>,
    /// What is wrong.
    pub kind: MeshErrorKind,
}

impl MeshError {
    pub(super) fn new(source: &str, line: Option<usize>, kind: MeshErrorKind) -> Self {
        Self {
            source: source.to_owned(),
            line,
            kind,
        }
    }
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}: {}", self.source, line, self.kind),
            None => write!(f, "{}: {}", self.source, self.kind),
        }
    }
}

// `Display` already includes the kind's message, so `source()` stays `None`: error
// reporters that walk the chain would otherwise print the fault twice. (The field named
// `source` is the file name, which is why this impl is written by hand and not derived
// with thiserror.)
impl std::error::Error for MeshError {}

/// The fault classes of a mesh file, each carrying its details.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MeshErrorKind {
    /// The file could not be read.
    #[error("cannot read the file: {message}")]
    Io {
        kind: std::io::ErrorKind,
        message: String,
    },
    /// Not a Gmsh ASCII file of version 1 or 2.x (e.g. binary, or version 4.1).
    #[error("unsupported mesh format: {reason}")]
    UnsupportedFormat { reason: String },
    /// A volume element other than the linear tetrahedron (hexahedra, prisms,
    /// second-order tetrahedra, ...), or an element type Gmsh does not define. Dropping
    /// it silently would leave a hole in the body, so it is an error.
    #[error(
        "element {element} has type {element_type}, which is not supported \
         (the volume must be made of 4-node tetrahedra, type 4)"
    )]
    UnsupportedElement { element: u64, element_type: u32 },
    /// The text does not follow the format: see [`Syntax`].
    #[error("{0}")]
    Malformed(Syntax),
    /// An element references a node id that no node line defines.
    #[error("element {element} refers to node id {node}, which is not defined")]
    MissingNode { element: u64, node: u64 },
    /// Two node lines give the same id.
    #[error("node id {id} is defined twice (first at line {first_line})")]
    DuplicateNode { id: u64, first_line: usize },
    /// More entries than the header declares, or an element whose node count does not
    /// match its type: see [`OutOfRange`].
    #[error("{0}")]
    IndexOutOfRange(OutOfRange),
    /// A coordinate is NaN or infinite (including numbers too large for f64).
    #[error("node {node} has a non-finite {axis} coordinate \"{text}\"")]
    NonFiniteCoordinate { node: u64, axis: char, text: String },
    /// A tetrahedron with (numerically) zero volume: its orientation, and so its
    /// stiffness, is undefined.
    #[error("{}", flat_text(*element, *six_volume, *longest_edge))]
    DegenerateTet {
        element: u64,
        six_volume: f64,
        longest_edge: f64,
    },
    /// A tetrahedron so large that its edge lengths overflow f64: its corners'
    /// coordinates reach `largest` (mesh units). Its volume, orientation and
    /// stiffness cannot be computed.
    #[error(
        "element {element} is too large to compute with: its corners reach a \
         coordinate of {}, and its edge lengths overflow", Number(*largest)
    )]
    OversizedTet { element: u64, largest: f64 },
    /// A tetrahedron whose longest edge is under `1e-98` (mesh units), where the
    /// flatness test underflows: `extent` is its largest coordinate difference.
    #[error(
        "element {element} is too small to compute with: its corners differ by at \
         most {} in any coordinate, and its volume underflows (edges of at least \
         1e-98 are needed; scale the mesh's units)", Number(*extent)
    )]
    UndersizedTet { element: u64, extent: f64 },
    /// After orientation was normalised, two tetrahedra that share a face lie on the same
    /// side of it: the mesh folds over itself, which no vertex swap can repair.
    #[error(
        "elements {other} and {element} lie on the same side of their shared face \
         {}: the mesh folds over itself",
        nodes(face)
    )]
    InvertedBeyondRepair {
        /// The later of the two elements in the file (the error's line is its line).
        element: u64,
        other: u64,
        face: [u64; 3],
    },
    /// A face belongs to more than two tetrahedra.
    #[error(
        "face {} is shared by {} tetrahedra (elements {}); at most two may share a face",
        nodes(face), elements.len(), list(elements)
    )]
    FaceSharedByMany { face: [u64; 3], elements: Vec<u64> },
    /// The boundary is not closed, or the declared surface triangles are not the
    /// boundary of the tetrahedra: see [`BoundaryGap`].
    #[error("open boundary: {0}")]
    OpenBoundary(BoundaryGap),
    /// The boundary is not a 2-manifold: see [`NonManifold`].
    #[error("non-manifold boundary: {0}")]
    NonManifoldBoundary(NonManifold),
    /// The file holds no tetrahedron (type 4 element).
    #[error("the mesh has no tetrahedra (element type 4)")]
    NoTetrahedra,
    /// A node that no tetrahedron uses: it would have no mass and no stiffness.
    #[error("node {node} is used by no tetrahedron (every node needs mass)")]
    StrayNode { node: u64 },
}

/// Ways the text can break the format.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Syntax {
    /// A line with the wrong number of fields.
    #[error("{what} has {found} fields, expected {expected}")]
    FieldCount {
        what: &'static str,
        expected: usize,
        found: usize,
    },
    /// A line with too few fields.
    #[error("{what} has {found} fields, expected at least {minimum}")]
    TooFewFields {
        what: &'static str,
        minimum: usize,
        found: usize,
    },
    /// A count on the line (of tags, of nodes) larger than the fields after it:
    /// said as such, not as a field count of `count` plus the fields before it.
    #[error("{what} states {count} {items}, and only {room} fields follow the count")]
    CountPastLine {
        what: &'static str,
        count: usize,
        items: &'static str,
        room: usize,
    },
    /// A field that is not a number of the expected kind.
    #[error("cannot read {what} from \"{text}\"")]
    BadNumber { what: &'static str, text: String },
    /// The block ends (end marker, another section, or end of file) before the number
    /// of entries its header declares.
    #[error("the {section} header declares {declared} entries, but the block has {found}")]
    CountMismatch {
        section: &'static str,
        declared: usize,
        found: usize,
    },
    /// A section that is not closed by its end marker `end` (e.g. `$EndNodes`); the
    /// error's line is where the marker was expected, or the section's header when the
    /// file ends first.
    #[error("missing {end}{}", found_instead(found.as_deref()))]
    MissingEnd { end: String, found: Option<String> },
    /// The file ends right after a section header.
    #[error("the file ends inside {section}: expected {expected}")]
    Truncated {
        section: &'static str,
        expected: &'static str,
    },
    /// A required section is absent.
    #[error("the file has no {section} section")]
    MissingSection { section: &'static str },
    /// A section that may appear once appears again.
    #[error("a second {section} section")]
    DuplicateSection { section: String },
    /// Sections in an order the reader cannot follow.
    #[error("{0}")]
    SectionOrder(&'static str),
    /// Text outside any section.
    #[error("expected a section header such as $Nodes, found \"{text}\"")]
    UnexpectedLine { text: String },
}

/// An entry beyond what the header or the element type allows.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OutOfRange {
    /// More node lines than the node header declares.
    #[error("node entry {index} is beyond the {declared} nodes declared in the header")]
    NodeEntry { index: usize, declared: usize },
    /// More element lines than the element header declares.
    #[error("element entry {index} is beyond the {declared} elements declared in the header")]
    ElementEntry { index: usize, declared: usize },
    /// An element lists a number of nodes that its type does not have.
    #[error(
        "element {element} of type {element_type} lists {found} nodes; that type has {expected}"
    )]
    ElementNodes {
        element: u64,
        element_type: u32,
        found: usize,
        expected: usize,
    },
    /// A tetrahedron given in memory refers to a vertex index past the positions.
    #[error("element {element} refers to vertex index {index}, but there are {count} vertices")]
    VertexIndex {
        element: u64,
        index: u32,
        count: usize,
    },
}

/// How the boundary fails to be closed or to match the declared surface.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BoundaryGap {
    /// A boundary edge used by only one boundary triangle.
    #[error("boundary edge {} belongs to only one boundary triangle", nodes(edge))]
    Edge { edge: [u64; 2] },
    /// A face of the tetrahedra's boundary that no declared triangle covers.
    #[error(
        "boundary face {} of element {element} is not among the declared surface triangles",
        nodes(face)
    )]
    Undeclared { element: u64, face: [u64; 3] },
    /// A declared triangle that is not a boundary face of the tetrahedra.
    #[error(
        "declared triangle {element} {} is not a boundary face of the tetrahedra",
        nodes(face)
    )]
    NotBoundary { element: u64, face: [u64; 3] },
    /// The same triangle declared twice.
    #[error("declared triangle {element} repeats triangle {first}")]
    Repeated { element: u64, first: u64 },
}

/// How the boundary fails to be a 2-manifold.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum NonManifold {
    /// A boundary edge shared by more than two boundary triangles.
    #[error(
        "boundary edge {} is shared by {triangles} boundary triangles",
        nodes(edge)
    )]
    Edge { edge: [u64; 2], triangles: usize },
    /// A boundary vertex whose triangles form several fans (e.g. two tetrahedra that
    /// touch at one vertex only).
    #[error("the boundary triangles around node {node} form {fans} separate fans")]
    Vertex { node: u64, fans: usize },
}

/// `(nodes 3, 5, 9)`.
fn nodes(ids: &[u64]) -> String {
    format!("(nodes {})", list(ids))
}

/// `3, 5, 9`.
fn list(ids: &[u64]) -> String {
    let parts: Vec<String> = ids.iter().map(u64::to_string).collect();
    parts.join(", ")
}

/// Most characters of a file's text quoted in a message.
pub const MAX_QUOTED_CHARS: usize = 60;

/// The text of a file quoted in a message: its first [`MAX_QUOTED_CHARS`]
/// characters, control characters escaped, with how long it was when that is more.
/// A message quoted whole lines: a mesh whose first line was 30 MB of one
/// character made a 30 MB error, which a server put in every scene listing (and
/// which broke creating a session from it over gRPC), and a file that was not a
/// mesh had its first line quoted back.
pub(super) fn excerpt(text: &str) -> String {
    let mut out: String = text
        .chars()
        .take(MAX_QUOTED_CHARS)
        .flat_map(|c| c.escape_debug())
        .collect();
    if text.chars().nth(MAX_QUOTED_CHARS).is_some() {
        out.push_str(&format!("… ({} bytes)", text.len()));
    }
    out
}

fn found_instead(found: Option<&str>) -> String {
    match found {
        Some(text) => format!(" (found \"{text}\")"),
        None => " before the end of the file".to_owned(),
    }
}

/// The text of [`MeshErrorKind::DegenerateTet`]: a tetrahedron whose four nodes
/// coincide is said to be a point, not measured against its zero edge.
fn flat_text(element: u64, six_volume: f64, longest_edge: f64) -> String {
    if longest_edge == 0.0 {
        return format!("element {element} is a point: its four nodes are at one place");
    }
    format!(
        "element {element} is a flat tetrahedron: |6V| = {} is at most 1e-12 × (longest \
         edge {})³",
        Number(six_volume),
        Number(longest_edge)
    )
}
