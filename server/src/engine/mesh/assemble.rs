//! From parsed nodes and elements to a checked [`TetMesh`]: the order of the checks,
//! and the translation of index-based topology faults into errors that name the file's
//! node and element ids and lines.

use nalgebra::Point3;

use super::TetMesh;
use super::error::{BoundaryGap, MeshError, MeshErrorKind, NonManifold, OutOfRange};
use super::topology::{self, Fault};

/// A surface triangle declared by the file (Gmsh element type 2).
#[derive(Clone, Debug)]
pub(super) struct DeclaredTriangle {
    pub nodes: [u32; 3],
    pub tag: i32,
    pub element: u64,
    pub line: Option<usize>,
}

/// Nodes and elements as read, with where they came from, before any check of the
/// geometry or topology. Node references are already resolved to vertex indices.
#[derive(Clone, Debug, Default)]
pub(super) struct RawMesh {
    pub positions: Vec<Point3<f64>>,
    pub node_ids: Vec<u64>,
    /// Line of each node (empty when the mesh does not come from a file).
    pub node_lines: Vec<usize>,
    pub tets: Vec<[u32; 4]>,
    pub tet_tags: Vec<i32>,
    /// Element id of each tetrahedron.
    pub element_ids: Vec<u64>,
    /// Line of each tetrahedron (empty when the mesh does not come from a file).
    pub element_lines: Vec<usize>,
    pub declared: Vec<DeclaredTriangle>,
}

impl RawMesh {
    /// Runs the checks in order — tetrahedra present, no stray node, no flat
    /// tetrahedron (then orientation is normalised), faces shared consistently,
    /// manifold closed boundary, declared triangles equal to the boundary — and builds
    /// the mesh.
    pub fn into_mesh(mut self, source: &str) -> Result<TetMesh, MeshError> {
        let fail = |raw: &RawMesh, fault: Fault| Err(raw.describe(source, fault));
        let n = self.positions.len();
        if let Err(fault) = topology::check_vertices_used(n, &self.tets) {
            return fail(&self, fault);
        }
        if let Err(fault) = topology::orient(&self.positions, &mut self.tets) {
            return fail(&self, fault);
        }
        let (triangles, owners) = match topology::boundary(&self.tets) {
            Ok(boundary) => boundary,
            Err(fault) => return fail(&self, fault),
        };
        let mut surface = match topology::build_surface(n, &self.positions, triangles, owners) {
            Ok(surface) => surface,
            Err(fault) => return fail(&self, fault),
        };
        let declared: Vec<[u32; 3]> = self.declared.iter().map(|d| d.nodes).collect();
        match topology::match_declared(&surface, &declared) {
            Ok(matches) => {
                for (tag, m) in surface.triangle_tags.iter_mut().zip(matches) {
                    *tag = m.map_or(0, |d| self.declared[d].tag);
                }
            }
            Err(fault) => return fail(&self, fault),
        }
        let edges = topology::edges(&self.tets);
        Ok(TetMesh {
            file_index: (0..n as u32).collect(),
            positions: self.positions,
            node_ids: self.node_ids,
            tets: self.tets,
            tet_tags: self.tet_tags,
            edges,
            surface,
        })
    }

    /// Checks meshes given in memory (no file lines): indices in range and coordinates
    /// finite, which a file reader checks while parsing.
    pub fn check_indices_and_coordinates(&self, source: &str) -> Result<(), MeshError> {
        for (i, p) in self.positions.iter().enumerate() {
            if let Some(axis) = (0..3).find(|&k| !p[k].is_finite()) {
                let kind = MeshErrorKind::NonFiniteCoordinate {
                    node: self.node_ids[i],
                    axis: ['x', 'y', 'z'][axis],
                    text: p[axis].to_string(),
                };
                return Err(MeshError::new(source, None, kind));
            }
        }
        let count = self.positions.len();
        for (i, t) in self.tets.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&v| v as usize >= count) {
                let kind = MeshErrorKind::IndexOutOfRange(OutOfRange::VertexIndex {
                    element: self.element_ids[i],
                    index,
                    count,
                });
                return Err(MeshError::new(source, None, kind));
            }
        }
        Ok(())
    }

    fn node_line(&self, v: u32) -> Option<usize> {
        self.node_lines.get(v as usize).copied()
    }

    fn tet_line(&self, t: u32) -> Option<usize> {
        self.element_lines.get(t as usize).copied()
    }

    fn ids<const N: usize>(&self, vertices: [u32; N]) -> [u64; N] {
        vertices.map(|v| self.node_ids[v as usize])
    }

    /// Names the fault with file ids and places it on the most useful line.
    fn describe(&self, source: &str, fault: Fault) -> MeshError {
        let (line, kind) = match fault {
            Fault::NoTets => (None, MeshErrorKind::NoTetrahedra),
            Fault::Stray { vertex } => (
                self.node_line(vertex),
                MeshErrorKind::StrayNode {
                    node: self.node_ids[vertex as usize],
                },
            ),
            Fault::Degenerate {
                tet,
                six_volume,
                longest_edge,
            } => (
                self.tet_line(tet),
                MeshErrorKind::DegenerateTet {
                    element: self.element_ids[tet as usize],
                    six_volume,
                    longest_edge,
                },
            ),
            Fault::Underflow { tet, extent } => (
                self.tet_line(tet),
                MeshErrorKind::UndersizedTet {
                    element: self.element_ids[tet as usize],
                    extent,
                },
            ),
            Fault::Overflow { tet, largest } => (
                self.tet_line(tet),
                MeshErrorKind::OversizedTet {
                    element: self.element_ids[tet as usize],
                    largest,
                },
            ),
            Fault::FaceShared { face, tets } => (
                tets.iter().max().and_then(|&t| self.tet_line(t)),
                MeshErrorKind::FaceSharedByMany {
                    face: self.ids(face),
                    elements: tets.iter().map(|&t| self.element_ids[t as usize]).collect(),
                },
            ),
            Fault::Folded { tets: [a, b], face } => (
                self.tet_line(b),
                MeshErrorKind::InvertedBeyondRepair {
                    element: self.element_ids[b as usize],
                    other: self.element_ids[a as usize],
                    face: self.ids(face),
                },
            ),
            Fault::OpenEdge { edge, tet } => (
                self.tet_line(tet),
                MeshErrorKind::OpenBoundary(BoundaryGap::Edge {
                    edge: self.ids(edge),
                }),
            ),
            Fault::NonManifoldEdge {
                edge,
                triangles,
                tet,
            } => (
                self.tet_line(tet),
                MeshErrorKind::NonManifoldBoundary(NonManifold::Edge {
                    edge: self.ids(edge),
                    triangles,
                }),
            ),
            Fault::NonManifoldVertex { vertex, fans } => (
                self.node_line(vertex),
                MeshErrorKind::NonManifoldBoundary(NonManifold::Vertex {
                    node: self.node_ids[vertex as usize],
                    fans,
                }),
            ),
            Fault::Undeclared { tet, face } => (
                self.tet_line(tet),
                MeshErrorKind::OpenBoundary(BoundaryGap::Undeclared {
                    element: self.element_ids[tet as usize],
                    face: self.ids(face),
                }),
            ),
            Fault::NotBoundary { declared } => {
                let d = &self.declared[declared];
                (
                    d.line,
                    MeshErrorKind::OpenBoundary(BoundaryGap::NotBoundary {
                        element: d.element,
                        face: self.ids(d.nodes),
                    }),
                )
            }
            Fault::Repeated { declared, first } => {
                let d = &self.declared[declared];
                (
                    d.line,
                    MeshErrorKind::OpenBoundary(BoundaryGap::Repeated {
                        element: d.element,
                        first: self.declared[first].element,
                    }),
                )
            }
        };
        MeshError::new(source, line, kind)
    }
}
