//! A vertex numbering with locality: reverse Cuthill–McKee over the tetrahedra's
//! edge graph.
//!
//! Every per-tick sweep of the elastic model reads and writes per-vertex data through
//! the elements (`x[a]` for the four vertices of each tetrahedron, the blocks
//! `K̂[a][b]` of each of its edges), and every product `K̂ p` reads `p` at each
//! neighbour of each row. Mesh generators number vertices in whatever order their
//! refinement produced (liver-300k's tetrahedra span a median of half its vertices),
//! so those accesses land anywhere in arrays of tens of megabytes. Cuthill–McKee
//! numbers the vertices breadth-first from a peripheral vertex, neighbours in order of
//! increasing degree, which keeps every edge's two indices close (the bandwidth of
//! the vertex graph is small) and therefore each element's vertices, and each row's
//! neighbours, within a few cache lines of one another. Reversing the order (George,
//! 1971) keeps the bandwidth and gives less fill in factorisations; it is the
//! customary form.

/// The new index of each vertex (`new[old]`), a permutation of `0..vertex_count`,
/// from reverse Cuthill–McKee over the graph of `edges` (a mesh's [`edges`], each
/// `[i, j]` with `i < j`, sorted and unique). Each connected component is
/// numbered from a pseudo-peripheral vertex (the George–Liu search: from a vertex of
/// least degree, move to a least-degree vertex of the last breadth-first level while
/// that level's depth grows); a vertex that no tetrahedron uses is a component of its
/// own. Deterministic: ties go to the lower old index.
///
/// Every index in `edges` must be below `vertex_count`.
///
/// [`edges`]: super::TetMesh::edges
pub fn reverse_cuthill_mckee(vertex_count: usize, edges: &[[u32; 2]]) -> Vec<u32> {
    let graph = Graph::of_edges(vertex_count, edges);
    let mut order: Vec<u32> = Vec::with_capacity(vertex_count);
    let mut placed = vec![false; vertex_count];
    let mut levels = Levels::default();
    // Components in order of their least-degree vertex, lowest old index first.
    let mut by_degree: Vec<u32> = (0..vertex_count as u32).collect();
    by_degree.sort_by_key(|&v| (graph.degree(v), v));
    for &seed in &by_degree {
        if placed[seed as usize] {
            continue;
        }
        let start = graph.peripheral(seed, &mut levels);
        let first = order.len();
        order.push(start);
        placed[start as usize] = true;
        let mut head = first;
        while head < order.len() {
            let v = order[head];
            head += 1;
            let from = order.len();
            for &w in graph.neighbours(v) {
                if !placed[w as usize] {
                    placed[w as usize] = true;
                    order.push(w);
                }
            }
            order[from..].sort_by_key(|&w| (graph.degree(w), w));
        }
    }
    let mut new = vec![0u32; vertex_count];
    for (k, &v) in order.iter().rev().enumerate() {
        new[v as usize] = k as u32;
    }
    new
}

/// The vertex graph in compressed rows, each row sorted.
struct Graph {
    offsets: Vec<usize>,
    targets: Vec<u32>,
}

impl Graph {
    /// Both directions of each edge; a row lists its neighbours in ascending order
    /// because `edges` is sorted: row `v` receives the `w < v` of edges `[w, v]` in
    /// order of `w`, all before the edges `[v, w]` that bring the `w > v`.
    fn of_edges(vertex_count: usize, edges: &[[u32; 2]]) -> Self {
        let mut offsets = vec![0usize; vertex_count + 1];
        for &[a, b] in edges {
            offsets[a as usize + 1] += 1;
            offsets[b as usize + 1] += 1;
        }
        for k in 0..vertex_count {
            offsets[k + 1] += offsets[k];
        }
        let mut fill = offsets.clone();
        let mut targets = vec![0u32; 2 * edges.len()];
        for &[a, b] in edges {
            targets[fill[a as usize]] = b;
            fill[a as usize] += 1;
            targets[fill[b as usize]] = a;
            fill[b as usize] += 1;
        }
        Self { offsets, targets }
    }

    fn neighbours(&self, v: u32) -> &[u32] {
        &self.targets[self.offsets[v as usize]..self.offsets[v as usize + 1]]
    }

    fn degree(&self, v: u32) -> usize {
        self.offsets[v as usize + 1] - self.offsets[v as usize]
    }

    /// A pseudo-peripheral vertex of `seed`'s component (George and Liu, 1979): the
    /// start of a breadth-first search whose level structure is as deep as a few
    /// restarts find.
    fn peripheral(&self, seed: u32, levels: &mut Levels) -> u32 {
        let mut start = seed;
        let mut depth = levels.search(self, start);
        loop {
            let candidate = levels
                .last()
                .iter()
                .copied()
                .min_by_key(|&w| (self.degree(w), w))
                .unwrap_or(start);
            let deeper = levels.search(self, candidate);
            if deeper <= depth {
                return start;
            }
            start = candidate;
            depth = deeper;
        }
    }
}

/// Scratch of a breadth-first level search.
#[derive(Default)]
struct Levels {
    /// The vertices reached, level by level.
    queue: Vec<u32>,
    /// Where the last level begins in `queue`.
    last_level: usize,
    /// The search that last reached each vertex (0: none), so the marks need no reset.
    mark: Vec<u32>,
    search: u32,
}

impl Levels {
    /// Searches breadth-first from `start`; returns the number of levels.
    fn search(&mut self, graph: &Graph, start: u32) -> usize {
        let n = graph.offsets.len() - 1;
        if self.mark.len() != n {
            self.mark = vec![0; n];
        }
        self.search += 1;
        let id = self.search;
        self.queue.clear();
        self.queue.push(start);
        self.mark[start as usize] = id;
        let (mut begin, mut depth) = (0, 0);
        while begin < self.queue.len() {
            let end = self.queue.len();
            self.last_level = begin;
            depth += 1;
            for k in begin..end {
                for &w in graph.neighbours(self.queue[k]) {
                    if self.mark[w as usize] != id {
                        self.mark[w as usize] = id;
                        self.queue.push(w);
                    }
                }
            }
            begin = end;
        }
        depth
    }

    fn last(&self) -> &[u32] {
        &self.queue[self.last_level..]
    }
}

impl super::TetMesh {
    /// The same mesh with vertex `v` renumbered `new[v]` (a permutation of
    /// `0..vertex_count`, e.g. from [`reverse_cuthill_mckee`]), and its tetrahedra
    /// listed in order of their sorted new vertex indices, so that a sweep over the
    /// elements walks the vertex arrays forwards. Node ids, file indices, tags and
    /// surface tags follow their vertices and elements; each tetrahedron keeps its
    /// vertices' order, so its orientation; edges and the surface are rebuilt, so
    /// they keep their sorted conventions.
    ///
    /// # Panics
    ///
    /// If `new` is not a permutation of `0..vertex_count` (a caller's error; the
    /// mesh's own checks cannot fail on a renumbering of a checked mesh).
    pub fn renumbered(&self, new: &[u32]) -> super::TetMesh {
        let n = self.vertex_count();
        let mut seen = vec![false; n];
        assert!(
            new.len() == n
                && new
                    .iter()
                    .all(|&k| (k as usize) < n && !std::mem::replace(&mut seen[k as usize], true)),
            "a renumbering gives every vertex its own new index"
        );
        let mut positions = self.positions.clone();
        let mut node_ids = self.node_ids.clone();
        let mut file_index = self.file_index.clone();
        for (v, &k) in new.iter().enumerate() {
            let k = k as usize;
            positions[k] = self.positions[v];
            node_ids[k] = self.node_ids[v];
            file_index[k] = self.file_index[v];
        }
        let mut elements: Vec<([u32; 4], i32)> = self
            .tets
            .iter()
            .zip(&self.tet_tags)
            .map(|(t, &tag)| (t.map(|v| new[v as usize]), tag))
            .collect();
        elements.sort_by_key(|(t, _)| {
            let mut key = *t;
            key.sort_unstable();
            key
        });
        let declared = self
            .surface
            .triangles
            .iter()
            .zip(&self.surface.triangle_tags)
            .filter(|&(_, &tag)| tag != 0)
            .map(|(t, &tag)| super::assemble::DeclaredTriangle {
                nodes: t.map(|v| new[v as usize]),
                tag,
                element: 0,
                line: None,
            })
            .collect();
        let raw = super::assemble::RawMesh {
            positions,
            node_ids,
            node_lines: Vec::new(),
            tets: elements.iter().map(|(t, _)| *t).collect(),
            tet_tags: elements.iter().map(|(_, tag)| *tag).collect(),
            element_ids: (1..=elements.len() as u64).collect(),
            element_lines: Vec::new(),
            declared,
        };
        let mut mesh = raw
            .into_mesh("(renumbered mesh)")
            .unwrap_or_else(|e| unreachable!("a renumbering keeps a checked mesh valid: {e}"));
        mesh.file_index = file_index;
        mesh
    }
}
