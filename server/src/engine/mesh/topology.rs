//! Orientation and topology of a tetrahedral mesh, in vertex and tetrahedron *indices*:
//! normalising orientation, the unique edges, the boundary faces, and the boundary
//! surface with its adjacency. Faults are reported as [`Fault`]s, in indices too; the
//! caller (`assemble`) turns them into [`super::MeshError`]s naming file ids and lines.

use nalgebra::{Point3, Vector3};

use super::surface::Surface;

/// Relative tolerance of the flatness test `|6V| ≤ FLAT_TOLERANCE · L³` (`L` the
/// longest edge).
///
/// `6V / L³` is scale-free: it measures shape, not size, so a 1 µm tetrahedron and a
/// 1 km one are judged alike, whatever unit the file uses. A regular tetrahedron has
/// `6V / L³ = 1/√2 ≈ 0.71`; the worst tetrahedra of the liver data sets are above 0.017
/// (SOFA's liver.msh) and 0.07 (liver-5k.msh). At the other end, the triple product of
/// coordinates of size `L` carries a rounding error of a few `1e-16 · L³`, so below
/// `1e-12 · L³` the sign of the volume — the orientation — is within a few thousand ulps
/// of noise and means nothing; such an element has no usable stiffness either. The
/// tolerance sits four orders above the noise and ten below any element worth
/// simulating, so it only catches tetrahedra that really are flat.
pub(super) const FLAT_TOLERANCE: f64 = 1e-12;

/// Smallest longest edge the flatness test can judge, in mesh units: below about
/// `2.8e-99` the tolerance `FLAT_TOLERANCE · L³` is under the smallest normal f64
/// (`2.2e-308`), and the volume underflows with it, so a well-shaped element
/// would be called flat. An element smaller than this is said to be too small
/// (and one whose four nodes coincide, to be a point) rather than flat.
pub(super) const MIN_EDGE: f64 = 1e-98;

/// The faces of a positively oriented tetrahedron `[v0, v1, v2, v3]`, as local vertex
/// indices ordered so that each face's normal `(b − a) × (c − a)` points out of the
/// tetrahedron. Face `k` is the face opposite local vertex `k`.
pub(super) const OUTWARD_FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// A topological or geometric fault, in indices (vertex indices into the positions,
/// tetrahedron indices into the tetrahedra, triangle indices into the surface).
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Fault {
    NoTets,
    /// Vertex used by no tetrahedron.
    Stray {
        vertex: u32,
    },
    Degenerate {
        tet: u32,
        six_volume: f64,
        longest_edge: f64,
    },
    /// A tetrahedron whose size overflows f64 arithmetic; `largest` is its largest
    /// coordinate magnitude.
    Overflow {
        tet: u32,
        largest: f64,
    },
    /// A tetrahedron, not a point, too small for the flatness test's arithmetic
    /// (see [`MIN_EDGE`]); `extent` is its largest coordinate difference.
    Underflow {
        tet: u32,
        extent: f64,
    },
    /// More than two tetrahedra share `face` (tets in ascending order).
    FaceShared {
        face: [u32; 3],
        tets: Vec<u32>,
    },
    /// Two tetrahedra on the same side of their shared face (`tets[0] < tets[1]`).
    Folded {
        tets: [u32; 2],
        face: [u32; 3],
    },
    /// A surface edge with one triangle; `tet` owns that triangle.
    OpenEdge {
        edge: [u32; 2],
        tet: u32,
    },
    /// A surface edge with more than two triangles; `tet` is the last (highest) owner.
    NonManifoldEdge {
        edge: [u32; 2],
        triangles: usize,
        tet: u32,
    },
    /// A surface vertex whose triangles form `fans` separate fans.
    NonManifoldVertex {
        vertex: u32,
        fans: usize,
    },
    /// A boundary face (owned by `tet`) that no declared triangle covers.
    Undeclared {
        tet: u32,
        face: [u32; 3],
    },
    /// Declared triangle `declared` is not a boundary face.
    NotBoundary {
        declared: usize,
    },
    /// Declared triangle `declared` repeats declared triangle `first`.
    Repeated {
        declared: usize,
        first: usize,
    },
}

/// Checks that there is at least one tetrahedron and that every vertex belongs to one.
/// Indices must be in range.
pub(super) fn check_vertices_used(vertex_count: usize, tets: &[[u32; 4]]) -> Result<(), Fault> {
    if tets.is_empty() {
        return Err(Fault::NoTets);
    }
    let mut used = vec![false; vertex_count];
    for t in tets {
        for &v in t {
            used[v as usize] = true;
        }
    }
    match used.iter().position(|&u| !u) {
        Some(v) => Err(Fault::Stray { vertex: v as u32 }),
        None => Ok(()),
    }
}

/// Rejects flat tetrahedra (see [`FLAT_TOLERANCE`]) and makes every other one positively
/// oriented by swapping its last two vertices when its signed volume is negative.
pub(super) fn orient(positions: &[Point3<f64>], tets: &mut [[u32; 4]]) -> Result<(), Fault> {
    for (i, t) in tets.iter_mut().enumerate() {
        let p = t.map(|v| positions[v as usize]);
        let six_volume = (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0])));
        let mut longest_squared: f64 = 0.0;
        for a in 0..4 {
            for b in a + 1..4 {
                longest_squared = longest_squared.max((p[b] - p[a]).norm_squared());
            }
        }
        if !(longest_squared.is_finite() && six_volume.is_finite()) {
            // Coordinates so large that the edges' squares overflow: no measure of
            // the element is meaningful, and calling it flat would mislead.
            let largest = p
                .iter()
                .flat_map(|q| q.iter().map(|c| c.abs()))
                .fold(0.0, f64::max);
            return Err(Fault::Overflow {
                tet: i as u32,
                largest,
            });
        }
        let longest_edge = longest_squared.sqrt();
        if longest_edge < MIN_EDGE {
            let extent = (0..4)
                .flat_map(|a| (a + 1..4).map(move |b| (a, b)))
                .map(|(a, b)| (p[b] - p[a]).amax())
                .fold(0.0, f64::max);
            if extent > 0.0 {
                return Err(Fault::Underflow {
                    tet: i as u32,
                    extent,
                });
            }
        }
        let tolerance = FLAT_TOLERANCE * longest_squared * longest_edge;
        if six_volume.abs() <= tolerance {
            return Err(Fault::Degenerate {
                tet: i as u32,
                six_volume,
                longest_edge,
            });
        }
        if six_volume < 0.0 {
            t.swap(2, 3);
        }
    }
    Ok(())
}

/// Unique undirected edges `[i, j]`, `i < j`, sorted.
pub(super) fn edges(tets: &[[u32; 4]]) -> Vec<[u32; 2]> {
    let mut keys: Vec<u64> = Vec::with_capacity(tets.len() * 6);
    for t in tets {
        for a in 0..4 {
            for b in a + 1..4 {
                keys.push(edge_key(t[a], t[b]));
            }
        }
    }
    keys.sort_unstable();
    keys.dedup();
    keys.into_iter().map(edge_of_key).collect()
}

/// The boundary of positively oriented tetrahedra: the faces that belong to exactly one
/// tetrahedron, oriented outward, with the owning tetrahedron of each. Checks that no
/// face has more than two tetrahedra and that the two tetrahedra of an interior face
/// lie on opposite sides of it.
///
/// Both are decided combinatorially. For a positive tetrahedron the faces of
/// [`OUTWARD_FACES`] have the fourth vertex on their negative side, so two positive
/// tetrahedra sharing a face lie on opposite sides of it exactly when they list the face
/// in opposite cyclic orders. (This is the geometric test "the owning tetrahedron's
/// fourth vertex is behind the face", made exact.) Triangles come sorted by their vertex
/// set, which makes the result independent of hashing and of the file's element order
/// only through the tetrahedra themselves.
pub(super) fn boundary(tets: &[[u32; 4]]) -> Result<(Vec<[u32; 3]>, Vec<u32>), Fault> {
    struct Face {
        key: [u32; 3],
        tet: u32,
        /// Local face index (0..4) in `OUTWARD_FACES`.
        local: u8,
        /// Whether the outward order is an even permutation of `key`.
        even: bool,
    }
    let mut faces: Vec<Face> = Vec::with_capacity(tets.len() * 4);
    for (i, t) in tets.iter().enumerate() {
        for (local, f) in OUTWARD_FACES.iter().enumerate() {
            let tri = [t[f[0]], t[f[1]], t[f[2]]];
            let (key, even) = sorted_with_parity(tri);
            faces.push(Face {
                key,
                tet: i as u32,
                local: local as u8,
                even,
            });
        }
    }
    faces.sort_unstable_by_key(|f| (f.key, f.tet));

    let mut triangles = Vec::new();
    let mut owners = Vec::new();
    let mut start = 0;
    while start < faces.len() {
        let key = faces[start].key;
        let mut end = start + 1;
        while end < faces.len() && faces[end].key == key {
            end += 1;
        }
        match &faces[start..end] {
            [one] => {
                let t = tets[one.tet as usize];
                let f = OUTWARD_FACES[one.local as usize];
                triangles.push([t[f[0]], t[f[1]], t[f[2]]]);
                owners.push(one.tet);
            }
            [a, b] => {
                if a.even == b.even {
                    return Err(Fault::Folded {
                        tets: [a.tet, b.tet],
                        face: key,
                    });
                }
            }
            many => {
                return Err(Fault::FaceShared {
                    face: key,
                    tets: many.iter().map(|f| f.tet).collect(),
                });
            }
        }
        start = end;
    }
    Ok((triangles, owners))
}

/// Builds the surface of the outward `triangles` (volume vertex indices below
/// `vertex_count`; `owners[k]` is the tetrahedron of triangle `k`, used to place faults):
/// vertices, index map, edges, triangle neighbours, vertex fans and normals. Checks that
/// every edge has exactly two triangles and every vertex exactly one fan.
///
/// A boundary built by [`boundary`] cannot have an edge with a single triangle (the
/// boundary of a sum of tetrahedra whose shared faces cancel is a closed cycle), so
/// `OpenEdge` only guards surfaces built otherwise.
pub(super) fn build_surface(
    vertex_count: usize,
    positions: &[Point3<f64>],
    triangles: Vec<[u32; 3]>,
    owners: Vec<u32>,
) -> Result<Surface, Fault> {
    debug_assert_eq!(triangles.len(), owners.len());

    // Surface vertices (ascending) and the volume → surface slot map.
    let mut surface_index = vec![u32::MAX; vertex_count];
    for tri in &triangles {
        for &v in tri {
            surface_index[v as usize] = 0;
        }
    }
    let mut vertices = Vec::new();
    for (v, slot) in surface_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = vertices.len() as u32;
            vertices.push(v as u32);
        }
    }

    // Half-edges grouped by undirected edge: neighbours and edge list.
    let mut half_edges: Vec<(u64, u32)> = Vec::with_capacity(triangles.len() * 3);
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            half_edges.push((edge_key(tri[k], tri[(k + 1) % 3]), (t * 3 + k) as u32));
        }
    }
    half_edges.sort_unstable();
    let mut neighbours = vec![[u32::MAX; 3]; triangles.len()];
    let mut edges = Vec::with_capacity(half_edges.len() / 2);
    let mut start = 0;
    while start < half_edges.len() {
        let key = half_edges[start].0;
        let mut end = start + 1;
        while end < half_edges.len() && half_edges[end].0 == key {
            end += 1;
        }
        let group = &half_edges[start..end];
        let edge = edge_of_key(key);
        match group {
            [(_, a), (_, b)] => {
                let (ta, ka) = (*a as usize / 3, *a as usize % 3);
                let (tb, kb) = (*b as usize / 3, *b as usize % 3);
                debug_assert_ne!(
                    triangles[ta][ka], triangles[tb][kb],
                    "boundary triangles must be consistently oriented"
                );
                neighbours[ta][ka] = tb as u32;
                neighbours[tb][kb] = ta as u32;
            }
            [(_, a)] => {
                return Err(Fault::OpenEdge {
                    edge,
                    tet: owners[*a as usize / 3],
                });
            }
            many => {
                let tet = many.iter().map(|(_, h)| owners[*h as usize / 3]).max();
                return Err(Fault::NonManifoldEdge {
                    edge,
                    triangles: many.len(),
                    tet: tet.unwrap_or(0),
                });
            }
        }
        edges.push(edge);
        start = end;
    }

    // Vertex → triangles, first in ascending order, then rewritten in fan order.
    let mut offsets = vec![0u32; vertices.len() + 1];
    for tri in &triangles {
        for &v in tri {
            offsets[surface_index[v as usize] as usize + 1] += 1;
        }
    }
    for s in 0..vertices.len() {
        offsets[s + 1] += offsets[s];
    }
    let mut fill = offsets.clone();
    let mut vertex_triangles = vec![0u32; offsets[vertices.len()] as usize];
    for (t, tri) in triangles.iter().enumerate() {
        for &v in tri {
            let s = surface_index[v as usize] as usize;
            vertex_triangles[fill[s] as usize] = t as u32;
            fill[s] += 1;
        }
    }
    let mut fan = Vec::new();
    for (s, &v) in vertices.iter().enumerate() {
        let range = offsets[s] as usize..offsets[s + 1] as usize;
        let around = &vertex_triangles[range.clone()];
        walk_fan(
            &triangles,
            &neighbours,
            v,
            around[0],
            around.len(),
            &mut fan,
        );
        if fan.len() != around.len() {
            return Err(Fault::NonManifoldVertex {
                vertex: v,
                fans: count_fans(&triangles, &neighbours, v, around),
            });
        }
        vertex_triangles[range].copy_from_slice(&fan);
    }

    let mut surface = Surface {
        vertex_normals: vec![Vector3::zeros(); vertices.len()],
        triangles,
        vertices,
        edges,
        triangle_neighbours: neighbours,
        vertex_triangle_offsets: offsets,
        vertex_triangles,
        surface_index,
        triangle_tets: owners,
        triangle_tags: Vec::new(),
    };
    surface.triangle_tags = vec![0; surface.triangles.len()];
    surface.update_normals(positions);
    Ok(surface)
}

/// Matches the declared surface triangles (any orientation) against the boundary
/// triangles. Returns, for each boundary triangle, the index of its declared triangle,
/// or `None` where none is declared.
///
/// Every declared triangle must be a boundary face. When the declared triangles form a
/// closed surface (every edge in exactly two of them) they are the file's statement of
/// the whole boundary, so a boundary face they do not cover — a hole in the volume, a
/// stray tetrahedron — is an open-boundary fault. When they are patches (a tagged
/// "fixed" face, say) the rest of the boundary is simply untagged.
pub(super) fn match_declared(
    surface: &Surface,
    declared: &[[u32; 3]],
) -> Result<Vec<Option<usize>>, Fault> {
    if declared.is_empty() {
        return Ok(vec![None; surface.triangles.len()]);
    }
    let mut keys: Vec<([u32; 3], usize)> = declared
        .iter()
        .enumerate()
        .map(|(i, &tri)| (sorted_with_parity(tri).0, i))
        .collect();
    keys.sort_unstable();
    if let Some(w) = keys.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(Fault::Repeated {
            declared: w[1].1,
            first: w[0].1,
        });
    }
    let mut matched = vec![false; declared.len()];
    let mut result = Vec::with_capacity(surface.triangles.len());
    let mut missing = None;
    for (t, &tri) in surface.triangles.iter().enumerate() {
        let key = sorted_with_parity(tri).0;
        match keys.binary_search_by(|(k, _)| k.cmp(&key)) {
            Ok(pos) => {
                let d = keys[pos].1;
                matched[d] = true;
                result.push(Some(d));
            }
            Err(_) => {
                if missing.is_none() {
                    missing = Some(Fault::Undeclared {
                        tet: surface.triangle_tets[t],
                        face: tri,
                    });
                }
                result.push(None);
            }
        }
    }
    // A declared triangle that is not on the boundary names its own line, so it is the
    // more useful report when both faults are present.
    if let Some(d) = matched.iter().position(|&m| !m) {
        return Err(Fault::NotBoundary { declared: d });
    }
    match missing {
        Some(fault) if is_closed(declared) => Err(fault),
        _ => Ok(result),
    }
}

/// Whether every edge of `triangles` belongs to exactly two of them.
fn is_closed(triangles: &[[u32; 3]]) -> bool {
    let mut edges: Vec<(u32, u32)> = triangles
        .iter()
        .flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))))
        .collect();
    edges.sort_unstable();
    edges.chunk_by(|a, b| a == b).all(|run| run.len() == 2)
}

/// Collects into `fan` the triangles around surface vertex `v`, starting at `start` and
/// turning counter-clockwise seen from outside, until back at `start` (at most `limit`
/// triangles).
fn walk_fan(
    triangles: &[[u32; 3]],
    neighbours: &[[u32; 3]],
    v: u32,
    start: u32,
    limit: usize,
    fan: &mut Vec<u32>,
) {
    fan.clear();
    let mut t = start;
    while fan.len() < limit {
        fan.push(t);
        let tri = triangles[t as usize];
        let Some(k) = tri.iter().position(|&x| x == v) else {
            return;
        };
        // Cross the edge that ends at v, (tri[k + 2], v): the next triangle
        // counter-clockwise around v.
        t = neighbours[t as usize][(k + 2) % 3];
        if t == start || t == u32::MAX {
            return;
        }
    }
}

/// Number of fans (edge-connected groups) among the triangles `around` vertex `v`.
fn count_fans(triangles: &[[u32; 3]], neighbours: &[[u32; 3]], v: u32, around: &[u32]) -> usize {
    let mut visited = vec![false; around.len()];
    let mut fan = Vec::new();
    let mut fans = 0;
    while let Some(i) = visited.iter().position(|&seen| !seen) {
        fans += 1;
        walk_fan(triangles, neighbours, v, around[i], around.len(), &mut fan);
        for t in &fan {
            if let Some(j) = around.iter().position(|x| x == t) {
                visited[j] = true;
            }
        }
        visited[i] = true;
    }
    fans
}

/// The vertices of a triangle in ascending order, and whether the given order is an even
/// permutation (a rotation) of the ascending one.
fn sorted_with_parity([a, b, c]: [u32; 3]) -> ([u32; 3], bool) {
    // Rotate the smallest to the front (a rotation keeps the parity); the rest is
    // ascending exactly when the permutation is even.
    let (x, y, z) = if a <= b && a <= c {
        (a, b, c)
    } else if b <= a && b <= c {
        (b, c, a)
    } else {
        (c, a, b)
    };
    if y < z {
        ([x, y, z], true)
    } else {
        ([x, z, y], false)
    }
}

fn edge_key(a: u32, b: u32) -> u64 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    (u64::from(lo) << 32) | u64::from(hi)
}

fn edge_of_key(key: u64) -> [u32; 2] {
    [(key >> 32) as u32, key as u32]
}
