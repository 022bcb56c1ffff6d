//! Vertices whose positions are imposed.

use nalgebra::Point3;

/// The set of vertices whose positions are imposed, with their targets.
///
/// Fixed nodes are imposed at their rest position for the whole run; vertices held by
/// an instrument are imposed at the position the contact stage gives them and released
/// when it lets go. Insertion and removal are O(1) and never allocate: the index list
/// is preallocated for every vertex.
#[derive(Clone, Debug)]
pub struct Imposed {
    mask: Vec<bool>,
    target: Vec<Point3<f64>>,
    /// Position of each imposed vertex in `list` (undefined for free vertices).
    slot: Vec<u32>,
    list: Vec<u32>,
}

impl Imposed {
    /// No vertex imposed, for a mesh of `n` vertices.
    pub fn new(n: usize) -> Self {
        Imposed {
            mask: vec![false; n],
            target: vec![Point3::origin(); n],
            slot: vec![0; n],
            list: Vec::with_capacity(n),
        }
    }

    /// Imposes vertex `i` at `target` (m).
    pub fn set(&mut self, i: u32, target: Point3<f64>) {
        let iu = i as usize;
        if !self.mask[iu] {
            self.mask[iu] = true;
            self.slot[iu] = self.list.len() as u32;
            self.list.push(i);
        }
        self.target[iu] = target;
    }

    /// Frees vertex `i`.
    pub fn release(&mut self, i: u32) {
        let iu = i as usize;
        if self.mask[iu] {
            self.mask[iu] = false;
            let s = self.slot[iu] as usize;
            let last = *self.list.last().expect("an imposed vertex is in the list");
            self.list.swap_remove(s);
            if last != i {
                self.slot[last as usize] = s as u32;
            }
        }
    }

    /// Whether vertex `i` is imposed.
    #[inline]
    pub fn is_imposed(&self, i: usize) -> bool {
        self.mask[i]
    }

    /// The imposed flags, one per vertex.
    pub fn mask(&self) -> &[bool] {
        &self.mask
    }

    /// The target of vertex `i` (meaningful only if imposed).
    #[inline]
    pub fn target(&self, i: usize) -> Point3<f64> {
        self.target[i]
    }

    /// The imposed vertices, in no particular order.
    pub fn list(&self) -> &[u32] {
        &self.list
    }
}
