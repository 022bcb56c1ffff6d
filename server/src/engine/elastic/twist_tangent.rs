//! The twist stiffness of strongly deformed elements, for the tangents of the
//! implicit step, the static solve and the contact settling's Newton passes.
//!
//! The implicit step freezes each element's rotation over the tick and solves with
//! `K̂ = Σ_e R K_e Rᵀ` ([`corotational`](super::corotational)). In the principal
//! frame of the stretch `S = Rᵀ F = Q diag(σ) Qᵀ` the Hessian of the corotated
//! energy splits into scaling, flip and twist modes (Smith, de Goes and Kim 2019; see
//! [`twist`]). `K̂` holds the scaling and flip modes exactly, and
//! nothing of the three twists `T_ij = R (q_i q_jᵀ − q_j q_iᵀ)/√2`: `Rᵀ T_ij` is
//! skew, so the frozen strain `sym(Rᵀ δF)` does not see them. Their eigenvalues are
//!
//! `τ_ij = (s_i + s_j)/(σ_i + σ_j)`,  `s_k = λ (Σσ − 3) + 2μ (σ_k − 1)`,
//!
//! zero at rest and small under moderate strain, but several times the stiffest
//! wave's modulus `λ + 2μ` in an element stretched along one axis and squeezed
//! through its flat state along another. There the force turns with `x` much faster
//! than `K̂` says, the step overshoots, and the tissue cycles with period two:
//! two instruments crossing 24 cm deep in the default liver and held still gave the
//! left one 8.2 ↔ 8.9 N on alternate ticks, the held sets unchanged, free vertices
//! swinging 9–10 mm and back, with six elements at `τ/(λ + 2μ)` 2.4–9.6 (stretches
//! like 4.6, −0.3, 0.7). The linear model and the explicit step do not cycle.
//!
//! So the step adds, for each element whose twist may pass [`FROM`]`·(λ + 2μ)`, its
//! positive twists: `K_ab += V τ_ij (T_ij g_a)(T_ij g_b)ᵀ` for `τ_ij > 0`. `K̂` plus
//! them is the element's Hessian with its negative twists set to zero (the
//! projection of Teran et al. 2005), so the system stays symmetric positive
//! definite and the step stays unconditionally stable; a negative twist (an element
//! squeezed, about to buckle) is left out as before. The other elements' twists,
//! each under a tenth of `λ + 2μ`, are left out for what they would cost.
//!
//! Elements are taken in the order of their index up to [`MAX_ELEMENTS`] a tick
//! (modes preallocated: nothing is allocated in a tick); beyond it the rest keep
//! `K̂` alone, as every element did before.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

use super::corotational::Element;
use super::twist;

/// The twist over `λ + 2μ` from which an element's positive twists join the
/// tangent, read from [`twist_ratio_bound`](super::twist::twist_ratio_bound) (from
/// the stretch's entries, never below the ratio), so that the eigenvalues are taken
/// only for strongly deformed elements: 55 of the default liver's 596 in a 2 cm
/// press, whose twists all stay under a tenth. Below it a twist adds under a tenth
/// of the stiffest wave's modulus, which `K̂` holds for every element. Taking only
/// the twists above a tenth was not enough: the crossing above still changed its
/// force by 2% a tick.
pub const FROM: f64 = 0.1;

/// Whether an element of stretch `s` ([`stretch`](twist::stretch)) may have a twist
/// above [`FROM`]`·(λ + 2μ)`, by the cheap bound: whether its twists join a tangent.
#[inline]
pub fn strongly_deformed(e: &Element, s: &Matrix3<f64>) -> bool {
    twist::twist_ratio_bound(e, s) > FROM
}

/// Elements whose twists a tick adds at most (three modes each, 120 bytes a mode:
/// 369 kB).
pub const MAX_ELEMENTS: usize = 1024;

/// One positive twist mode of one element: the stiffness `c = V τ` (J) along the
/// direction whose vertex vectors are `w_a = T g_a` (1/m).
#[derive(Clone, Copy, Debug)]
struct Mode {
    tet: [u32; 4],
    w: [Vector3<f64>; 4],
    c: f64,
}

/// The positive twist modes of the elements flagged this tick.
#[derive(Clone, Debug)]
pub struct TwistTangent {
    modes: Vec<Mode>,
}

impl TwistTangent {
    /// An empty set with room for the modes of [`MAX_ELEMENTS`] elements, or of all
    /// `elements` of a smaller mesh.
    pub fn new(elements: usize) -> Self {
        TwistTangent {
            modes: Vec::with_capacity(3 * elements.min(MAX_ELEMENTS)),
        }
    }

    /// Forgets the last tick's modes.
    pub fn clear(&mut self) {
        self.modes.clear();
    }

    /// Adds the positive twist modes of element `e` (rotation `r`, deformation
    /// gradient `f`), while there is room (nothing is allocated).
    pub fn add(&mut self, e: &Element, r: &Matrix3<f64>, f: &Matrix3<f64>) {
        let eigen = SymmetricEigen::new(twist::stretch(r, f));
        let (sigma, q) = (eigen.eigenvalues, eigen.eigenvectors);
        let g = e.gradients();
        for ((i, j), tau) in twist::PAIRS.into_iter().zip(twist::twists(e, &sigma)) {
            // Negative (squeezed) or not finite (an unstressed pair summing to zero):
            // nothing to add.
            if !(tau > 0.0 && tau.is_finite()) || self.modes.len() == self.modes.capacity() {
                continue;
            }
            let (qi, qj) = (q.column(i), q.column(j));
            let t =
                r * (qi * qj.transpose() - qj * qi.transpose()) * std::f64::consts::FRAC_1_SQRT_2;
            self.modes.push(Mode {
                tet: e.tet,
                w: g.map(|g| t * g),
                c: e.volume * tau,
            });
        }
    }

    /// Bytes held (for memory reports).
    pub fn heap_bytes(&self) -> usize {
        self.modes.capacity() * std::mem::size_of::<Mode>()
    }

    /// `out += scale · K_tw p`, `K_tw = Σ c w wᵀ` over the modes.
    pub fn mul_add(&self, scale: f64, p: &[Vector3<f64>], out: &mut [Vector3<f64>]) {
        for m in &self.modes {
            let along: f64 = (0..4).map(|a| m.w[a].dot(&p[m.tet[a] as usize])).sum();
            let k = scale * m.c * along;
            for a in 0..4 {
                out[m.tet[a] as usize] += k * m.w[a];
            }
        }
    }
}
