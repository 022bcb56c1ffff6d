//! In which precision the implicit solve reads the stiffness blocks.
//!
//! The blocks are assembled, and the corotational `K̂` reassembled, in f64. A
//! product `K p` reads every stored block once (72 bytes in f64, 36 in f32) and
//! does 36 multiply-adds with it. On a mesh whose blocks fit in the processor's
//! cache the product waits on arithmetic, and widening f32 to f64 only adds to it;
//! on one whose blocks do not, it waits on memory, and half the bytes pay.
//!
//! Measured with the bench `storage` (one core, this machine's 32 MB cache), f32
//! against f64 in one run: the time ratios of the product `K u` and of a solve of
//! the default scene's linear implicit 60 Hz system (block-Jacobi CG from rest to
//! the tolerance 1e-4); how far the f32 solution lies from the f64 one, against the
//! error the tolerance itself leaves; and the ratio of the median tick of the
//! default scene (corotational, contact: a 2 cm/s press) with block Jacobi and with
//! multigrid.
//!
//! | mesh | f64 blocks | product | solve | its f64 / f32 | solutions apart | tolerance's error | tick, block Jacobi | tick, multigrid |
//! |---|---|---|---|---|---|---|---|---|
//! | SOFA's liver | 0.08 MB | 1.19 | 1.18 | 63 / 63 | 3.1e-7 | 5.5e-5 | 1.04 | 1.01 |
//! | liver-5k | 0.65 MB | 1.30 | 1.13 | 83 / 83 | 3.1e-7 | 3.8e-5 | 1.03 | 1.14 |
//! | liver-20k | 2.3 MB | 1.10 | 1.05 | 129 / 129 | 3.5e-7 | 3.2e-5 | 1.05 | 1.11 |
//! | liver-80k | 8.5 MB | 1.04 | 1.02 | 190 / 190 | 5.1e-7 | 1.6e-5 | 1.06 | 1.05 |
//! | liver-300k | 32 MB | 0.74 | 0.58 | 272 / 271 | 8.3e-7 | 1.4e-5 | 0.68 | 0.91 |
//!
//! So f32 costs no accuracy at any size (each product is within 2.6e-8 of f64's,
//! the solutions lie 17–180 times closer to each other than to the exact one, and
//! the press's reaction agrees to the fourth digit), and pays only beyond the
//! cache: liver-300k's tick falls from 456 to 311 ms with block Jacobi and from 432
//! to 391 ms with multigrid, whose hierarchy stayed f64 then (see below). How much
//! depends on the cache the tick gets on a shared machine: over this session's
//! runs liver-300k's block-Jacobi tick took 283–456 ms in f64 and 294–311 ms in
//! f32 (the corotational bench and this one), so f32 mostly takes the f64 tick's
//! sensitivity to it away. On two threads (`LAPARO_THREADS=2`) the ratios are 0.96
//! (162 → 155 ms) and 0.93. `auto` takes f32 from [`F32_FROM_BYTES`].
//!
//! The multigrid hierarchy's sparse matrices (prolongators, restrictions and
//! coarse operators, [`Amg::round_to_f32`](super::amg::Amg::round_to_f32)) follow
//! the same rule on their own size: a V-cycle streams them as a product streams the
//! blocks, and they outgrow the cache first (f64: 7.9 MB on liver-20k, 25 MB on
//! liver-80k, 124 MB on liver-300k, against 2.3, 8.5 and 32 MB of blocks). Rounded,
//! a cycle moves by 2e-8 of itself (`amg/tests.rs`) and stays symmetric positive
//! definite, so CG converges as before (8 iterations a tick on liver-80k, 10 on
//! liver-300k, either way). Measured with this bench, blocks and hierarchy in f32
//! against both in f64, multigrid: liver-80k's tick 67.5 → 58.1 ms (0.86),
//! liver-300k's 288 → 230 ms (0.80, where the blocks alone gave 0.91); and with
//! the corotational bench under `auto` (the hierarchy alone in f32 on liver-80k),
//! two alternating runs of the binaries before and after: 62.3 → 52.0 and 60.3 →
//! 59.4 ms.
//!
//! The choice depends on the mesh only, never on the machine, so a re-simulation
//! of a recording reproduces it.

use serde::{Deserialize, Serialize};

/// A scene's `[mechanics] stiffness`: the precision of the stiffness blocks the
/// implicit solve's products read, and of the multigrid hierarchy's sparse
/// matrices (its prolongators, restrictions and coarse operators,
/// [`Amg::round_to_f32`](super::amg::Amg::round_to_f32)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StiffnessStorage {
    /// Each of the two in f32 when its f64 bytes would take [`F32_FROM_BYTES`] or
    /// more, f64 below: the blocks of liver-300k, the hierarchies of liver-80k
    /// (25 MB) and liver-300k (124 MB).
    #[default]
    Auto,
    /// Both f64, as assembled.
    F64,
    /// Copies rounded to f32: the blocks' refreshed whenever they change, the
    /// hierarchy's once, when it is built.
    F32,
}

/// The f64 blocks' size from which `auto` reads an f32 copy: 16 MB, half this
/// machine's 32 MB cache (liver-80k's 8.5 MB gains nothing, liver-300k's 32 MB a
/// third of its solve).
pub const F32_FROM_BYTES: usize = 16 << 20;

impl StiffnessStorage {
    /// Whether a stiffness of `blocks` stored 3×3 blocks is read in f32.
    pub fn uses_f32(self, blocks: usize) -> bool {
        self.rounds(blocks * std::mem::size_of::<[f64; 9]>())
    }

    /// Whether matrices that take `bytes` in f64 are held in f32: the stiffness
    /// blocks, and apart from them the multigrid hierarchy's sparse matrices
    /// ([`Amg::matrix_bytes`](super::amg::Amg::matrix_bytes)).
    pub fn rounds(self, bytes: usize) -> bool {
        match self {
            StiffnessStorage::Auto => bytes >= F32_FROM_BYTES,
            StiffnessStorage::F64 => false,
            StiffnessStorage::F32 => true,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_takes_f32_from_the_threshold_and_the_others_keep_their_word() {
        let edge = F32_FROM_BYTES / 72;
        assert!(!StiffnessStorage::Auto.uses_f32(edge - 1));
        assert!(StiffnessStorage::Auto.uses_f32(edge + 1));
        // liver-80k's and liver-300k's stored blocks.
        assert!(!StiffnessStorage::Auto.uses_f32(118_495));
        assert!(StiffnessStorage::Auto.uses_f32(446_380));
        assert!(!StiffnessStorage::F64.uses_f32(usize::MAX / 100));
        assert!(StiffnessStorage::F32.uses_f32(1));
        // The hierarchy's bytes are weighed alike.
        assert!(!StiffnessStorage::Auto.rounds(F32_FROM_BYTES - 1));
        assert!(StiffnessStorage::Auto.rounds(F32_FROM_BYTES));
        assert!(!StiffnessStorage::F64.rounds(usize::MAX));
        assert!(StiffnessStorage::F32.rounds(0));
    }
}
