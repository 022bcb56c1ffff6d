//! The contact stage's buffers, allocated once for the mesh, and its work counters:
//! what the stage and its steps (`edges`, `tip`, `push`) share within a tick.

use nalgebra::Point3;

use super::crossing::Crossing;
use crate::engine::mesh::Surface;

/// Counters of the work the stage did, cumulative since it was built: they show which
/// parts of the algorithm a scene exercises (a scene without shaft contact tests no
/// edge; a scene without instruments builds no stage at all).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ContactStats {
    /// Instrument-ticks processed.
    pub instrument_ticks: u64,
    /// Candidate triangles returned by the broad phase.
    pub candidate_triangles: u64,
    /// Edge–axis crossing tests (eq. 2–5).
    pub edge_tests: u64,
    /// Colliding edges found.
    pub colliding_edges: u64,
    /// Vertex moves made by the stage.
    pub vertex_moves: u64,
}

/// Buffers of the stage, allocated once for the mesh.
#[derive(Debug)]
pub(super) struct Scratch {
    /// Start positions of the tick in the current instrument's frame, `R(x_start)`.
    pub rel_start: Vec<Point3<f64>>,
    pub fixed: Vec<bool>,
    /// The longest rest length of the surface edges at each vertex, m (0 off the
    /// surface): how far a corner of a triangle touching the instrument can be from
    /// it (`tip::MAX_STRETCH`).
    pub span: Vec<f64>,
    /// Candidate triangles, edges and vertices for the current instrument.
    pub triangles: Vec<u32>,
    pub edges: Vec<u32>,
    pub vertices: Vec<u32>,
    pub colliding: Vec<(u32, Crossing)>,
    pub interval: Vec<[f64; 2]>,
    pub interval_vertices: Vec<u32>,
    pub interval_mark: Vec<u32>,
    pub edge_mark: Vec<u32>,
    pub vertex_mark: Vec<u32>,
    pub moved_mark: Vec<u32>,
    /// Vertices moved for the current instrument.
    pub moved: Vec<u32>,
    /// Bumped for every instrument and pass, so marks never need clearing.
    pub mark: u32,
    /// Bumped for every gathering of candidates (and every set of intervals).
    pub gather_mark: u32,
    pub stats: ContactStats,
}

impl Scratch {
    /// Buffers for the surface of a mesh whose vertices are at `rest` and whose
    /// vertices `fixed` are supports.
    pub fn new(surface: &Surface, rest: &[Point3<f64>], fixed: &[u32]) -> Self {
        let n = rest.len();
        let mut fixed_mask = vec![false; n];
        for &v in fixed {
            fixed_mask[v as usize] = true;
        }
        let mut span = vec![0.0f64; n];
        for &[a, b] in &surface.edges {
            let l = (rest[a as usize] - rest[b as usize]).norm();
            for v in [a, b] {
                span[v as usize] = span[v as usize].max(l);
            }
        }
        Scratch {
            rel_start: rest.to_vec(),
            fixed: fixed_mask,
            span,
            triangles: Vec::with_capacity(surface.triangles.len()),
            edges: Vec::with_capacity(surface.edges.len()),
            vertices: Vec::with_capacity(surface.vertices.len()),
            colliding: Vec::with_capacity(surface.edges.len()),
            interval: vec![[0.0, 1.0]; n],
            interval_vertices: Vec::with_capacity(n),
            interval_mark: vec![0; n],
            edge_mark: vec![0; surface.edges.len()],
            vertex_mark: vec![0; n],
            moved_mark: vec![0; n],
            moved: Vec::with_capacity(n),
            mark: 0,
            gather_mark: 0,
            stats: ContactStats::default(),
        }
    }

    /// Records that the stage moved vertex `v` for the current instrument.
    pub fn touch(&mut self, v: u32) {
        self.stats.vertex_moves += 1;
        if self.moved_mark[v as usize] != self.mark {
            self.moved_mark[v as usize] = self.mark;
            self.moved.push(v);
        }
    }
}
