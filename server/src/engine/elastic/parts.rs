//! The vertices split into parts that threads work on side by side.
//!
//! A part is a range of vertex indices, each holding an equal share. Two loops of a
//! tick are shared by part:
//! - the product `K u` ([`BlockMatrix::mul_shared`](super::BlockMatrix::mul_shared)):
//!   part `t` writes the rows of its range only. A stored block `K_ij` (`i < j`) with
//!   both vertices in `t` adds `K_ij u_j` to row `i` and `K_ijᵀ u_i` to row `j` in one
//!   read, as the sequential product does; one whose `j` lies in a later part is read
//!   by both, each taking its own row's half;
//! - the corotational update ([`Corotated`](super::Corotated)): part `t` handles the
//!   elements whose four vertices lie in `t`; they write forces on those vertices
//!   and blocks in those rows only, so parts never write the same datum. The elements
//!   across a boundary (the last group) are handled afterwards, by one thread.
//!
//! Ranges only make small boundaries when the numbering has locality, so a mesh
//! split among threads is renumbered by reverse Cuthill–McKee when loaded
//! (`simulation/mesh.rs`): each range is then a band of breadth-first levels across
//! the liver. On liver-20k in two parts, 3.2% of the off-diagonal blocks and 6.1% of
//! the elements cross (the file's own numbering: 28% of the blocks). Contiguous
//! ranges also keep two threads' writes in different cache lines.
//!
//! One part is the whole mesh: the loops then add in exactly the order of the
//! sequential code. With more parts some sums run in another order, so results
//! differ from one part's in the last bits; a scene's thread count is part of the
//! scene, and re-simulation uses it.

use std::ops::Range;
use std::sync::Arc;

/// The fewest vertices a part holds: a mesh is split into at most
/// `vertices / MIN_PART_VERTICES` parts ([`part_count`]). Below it, handing a part to
/// another thread costs more than it saves. Measured (corotational bench, contact,
/// kept tangent, block Jacobi, 2 threads against 1): SOFA's liver (181 vertices)
/// 0.191 → 0.216 ms a tick, slower; liver-5k (1,408) 1.56 → 1.11 ms; liver-20k (4,765)
/// 6.81 → 4.14 ms.
pub const MIN_PART_VERTICES: usize = 512;

/// The parts a mesh of `vertices` vertices is split into for `threads` threads:
/// `threads`, or fewer so that each holds at least [`MIN_PART_VERTICES`], at least 1.
pub fn part_count(vertices: usize, threads: usize) -> usize {
    threads.min(vertices / MIN_PART_VERTICES).max(1)
}

/// The parts of a mesh's vertices and of its corotational elements.
///
/// A clone shares the element lists with the original: the integrator, its CG
/// workspace and the corotational update each keep one, and on liver-300k the lists
/// hold 1.2 MB.
#[derive(Clone, Debug)]
pub struct Parts {
    /// Part `t` is the vertices `bounds[t]..bounds[t + 1]`.
    bounds: Vec<usize>,
    /// The elements of part `t` (all four vertices in `t`), ascending, for
    /// `t < count`; group `count` holds the elements that cross a boundary.
    elements: Arc<[u32]>,
    element_start: Vec<usize>,
}

impl Parts {
    /// `count` ranges (at least 1, at most one per vertex) of `vertices` vertices,
    /// with the elements `tets` sorted into them.
    pub fn new(vertices: usize, count: usize, tets: impl Iterator<Item = [u32; 4]>) -> Self {
        let count = count.clamp(1, vertices.max(1));
        let bounds: Vec<usize> = (0..=count).map(|t| t * vertices / count).collect();
        let part = |v: u32| bounds.partition_point(|&b| b <= v as usize) - 1;
        let (elements, element_start) = group(
            count + 1,
            tets.enumerate().map(|(e, tet)| {
                let (lo, hi) = (tet.iter().min(), tet.iter().max());
                let (lo, hi) = (part(*lo.expect("four")), part(*hi.expect("four")));
                (if lo == hi { lo } else { count }, e as u32)
            }),
        );
        Parts {
            bounds,
            elements: elements.into(),
            element_start,
        }
    }

    /// Number of parts.
    pub fn count(&self) -> usize {
        self.bounds.len() - 1
    }

    /// The vertices of part `t`.
    #[inline]
    pub fn range(&self, t: usize) -> Range<usize> {
        self.bounds[t]..self.bounds[t + 1]
    }

    /// The part of vertex `v`.
    pub fn of(&self, v: usize) -> usize {
        self.bounds.partition_point(|&b| b <= v) - 1
    }

    /// The elements all of whose vertices lie in part `t`, ascending.
    pub fn elements(&self, t: usize) -> &[u32] {
        &self.elements[self.element_start[t]..self.element_start[t + 1]]
    }

    /// The elements with vertices in two parts or more, ascending.
    pub fn crossing(&self) -> &[u32] {
        self.elements(self.count())
    }

    /// Bytes held (for memory reports), the shared element lists included.
    pub fn heap_bytes(&self) -> usize {
        self.elements.len() * 4 + (self.bounds.capacity() + self.element_start.capacity()) * 8
    }
}

/// Items sorted into `groups` groups, each keeping the order it came in, with the
/// start of each group (and the end of the last).
fn group(groups: usize, items: impl Iterator<Item = (usize, u32)>) -> (Vec<u32>, Vec<usize>) {
    let items: Vec<(usize, u32)> = items.collect();
    let mut start = vec![0usize; groups + 1];
    for &(g, _) in &items {
        start[g + 1] += 1;
    }
    for g in 0..groups {
        start[g + 1] += start[g];
    }
    let mut next = start.clone();
    let mut out = vec![0u32; items.len()];
    for (g, item) in items {
        out[next[g]] = item;
        next[g] += 1;
    }
    (out, start)
}

#[cfg(test)]
mod tests;
