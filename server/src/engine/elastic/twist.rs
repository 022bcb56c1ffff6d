//! The twist stiffness of a strongly deformed corotational element, for the explicit
//! step's substep count.
//!
//! The explicit step is stable for `h ω_max < 2`, and its substep count comes from a
//! bound `ω̂` of the linear stiffness `K` (Gershgorin, see
//! [`max_eigenvalue_bound`](super::ElasticModel::max_eigenvalue_bound)). The rotated
//! stiffness `R K Rᵀ` has the same spectrum as `K` at every rotation, but the exact
//! corotational force `R K (Rᵀ x − X)` also turns with `x`, and its Jacobian has a
//! term from the turning of `R` that `K` does not bound.
//!
//! Per element the corotated energy is `ψ(F) = ½ ε : C : ε` with `ε = S − I`,
//! `S = Rᵀ F` the (signed) stretch of the polar decomposition. In the principal frame
//! of `S` (stretches `σ_k`, principal stresses `s_k = λ tr ε + 2μ (σ_k − 1)`, the
//! derivatives `∂ψ/∂σ_k`) the Hessian `∂²ψ/∂F²` of such an isotropic energy splits
//! into (Smith, de Goes and Kim, "Analytic eigensystems for isotropic distortion
//! energies", ACM TOG 2019):
//! - three scaling modes, the eigenvalues of `λ 1 1ᵀ + 2μ I`: at most `3λ + 2μ`;
//! - three flip modes, `(s_i − s_j)/(σ_i − σ_j) = 2μ`;
//! - three twist modes, `(s_i + s_j)/(σ_i + σ_j)`: zero at rest (a twist is a
//!   rotation), and without bound as `σ_i + σ_j → 0` under stress, in an element
//!   pressed through its flat state (inverted: the extraction then returns the
//!   rotation with one stretch negative, see [`rotation`](super::rotation)).
//!
//! So a twist eigenvalue above the stiffest wave's modulus `λ + 2μ` raises `ω_max²`
//! above what the linear bound allows, by up to the ratio of the two, and the
//! explicit step grows without bound: the default liver at ν = 0.499, pressed 3.5 cm by
//! the tip and held, had a twist ratio of 5.7 on the tick a retake jumped the tip's
//! vertices, 15 elements inverted three ticks later, and the liver left the ±100 m
//! of any physical place within a second. Three times the substeps kept it bounded.
//! (That press no longer lets its tissue go and jumps it back, nor does a jab of
//! the same depth within a tick since the contact settles a jump along the axis
//! whole; a 6.5 cm press at 1 m/s without friction still inverts elements, and
//! without the twist leaves the liver at tick 40: `server/tests/explicit_inversion.rs`.)
//!
//! The ratio is taken against `λ + 2μ` (the P-wave modulus, which sets the fastest
//! wave the linear bound resolves) rather than against the largest scaling
//! eigenvalue `3λ + 2μ`, the conservative choice: the assembled `K` is not the
//! element's `C` times one geometric factor, and at ν = 0.499 the two differ by 3×.
//! At moderate strain a twist eigenvalue is `≈ 2λ|tr ε|/(σ_i + σ_j)`, which passes
//! `λ + 2μ` only at a volume change of about 100%: outside inversion the ratio stays
//! under 1 and the substep count is unchanged.

use nalgebra::{Matrix3, Vector3};

use super::corotational::Element;

/// The largest twist eigenvalue of element `e` with stretch `s` ([`stretch`]), over
/// the modulus `λ + 2μ` of its stiffest wave (see the module notes). 0 at rest and
/// under any rotation; `∞` for a stressed element with two stretches summing to
/// zero.
pub fn twist_ratio(e: &Element, s: &Matrix3<f64>) -> f64 {
    // NaN (0/0: an unstressed pair summing to zero) does not raise the ratio.
    let worst = twists(e, &s.symmetric_eigenvalues())
        .iter()
        .fold(
            0.0,
            |worst: f64, t| if t.abs() > worst { t.abs() } else { worst },
        );
    worst / (e.lambda + 2.0 * e.mu)
}

/// The pairs `(i, j)` of principal directions whose twists [`twists`] gives, in
/// its order.
pub const PAIRS: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

/// The three twist eigenvalues `τ_ij = (s_i + s_j)/(σ_i + σ_j)` (Pa) of element `e`
/// with principal stretches `σ` (in any order), `s_k = λ (Σσ − 3) + 2μ (σ_k − 1)`,
/// for the pairs of [`PAIRS`]: 0 at rest, NaN for an unstressed pair summing to
/// zero, `±∞` for a stressed one.
pub fn twists(e: &Element, sigma: &Vector3<f64>) -> [f64; 3] {
    let trace = sigma.sum() - 3.0;
    let s = sigma.map(|x| e.lambda * trace + 2.0 * e.mu * (x - 1.0));
    PAIRS.map(|(i, j)| (s[i] + s[j]) / (sigma[i] + sigma[j]))
}

/// An upper bound of [`twist_ratio`] from the entries of the stretch alone, without
/// its eigenvalues (the symmetric eigensolver costs more than the rest of the pass):
/// by Gershgorin every stretch lies within `ρ_k = Σ_{l≠k} |S_kl|` of some `S_kk`, so
/// `σ_i + σ_j ≥ 2 min_k (S_kk − ρ_k)` and `|σ_k − 1| ≤ max_k (|S_kk − 1| + ρ_k)`, while
/// `tr ε = tr S − 3` is exact; then `|s_i + s_j| ≤ 2 (λ |tr ε| + 2μ max |σ_k − 1|)`.
/// `∞` when the lower end is not positive (the bound says nothing there).
pub fn twist_ratio_bound(e: &Element, s: &Matrix3<f64>) -> f64 {
    let (mut low, mut far) = (f64::INFINITY, 0.0f64);
    for k in 0..3 {
        let radius: f64 = (0..3).filter(|&l| l != k).map(|l| s[(k, l)].abs()).sum();
        low = low.min(s[(k, k)] - radius);
        far = far.max((s[(k, k)] - 1.0).abs() + radius);
    }
    if low <= 0.0 {
        return f64::INFINITY;
    }
    let stress = e.lambda * (s.trace() - 3.0).abs() + 2.0 * e.mu * far;
    stress / (low * (e.lambda + 2.0 * e.mu))
}

/// The symmetric stretch `S = sym(Rᵀ F)` of deformation gradient `f` with its polar
/// rotation `r` (exactly `Rᵀ F` for the polar rotation).
pub fn stretch(r: &Matrix3<f64>, f: &Matrix3<f64>) -> Matrix3<f64> {
    symmetric(&r.tr_mul(f))
}

/// The symmetric part `½ (A + Aᵀ)` of `a`.
#[inline]
pub fn symmetric(a: &Matrix3<f64>) -> Matrix3<f64> {
    0.5 * (a + a.transpose())
}
