//! Corotational elasticity: the linear tensors of each tetrahedron, applied in the
//! element's rotated frame.
//!
//! Symbols: `X_k` rest and `x_k` current positions of the element's vertices, `g_k`
//! its rest shape-function gradients, `V` its rest volume, `K_e` its 12×12 linear
//! stiffness (blocks `K_ab` of [`tet_stiffness`](super::tet_stiffness)). The
//! deformation gradient is `F = Σ_k x_k g_kᵀ` (`= I` at rest) and `R` the rotation of
//! its polar decomposition `F = R S` ([`rotation`](super::rotation)).
//!
//! The element's elastic force on its vertices is (Müller and Gross 2004; Nesme et al.
//! 2005, as SOFA's `TetrahedronFEMForceField` "polar" method)
//!
//! `f_e = −R K_e (Rᵀ x_e − X_e)`:
//!
//! the current shape is turned back by `Rᵀ`, its displacement from rest measured
//! there, the linear restoring force computed in that frame and turned forward by
//! `R`. Written with the stress, vertex `a` receives `f_a = −V R σ g_a`, where
//! `σ = λ tr(ε) I + 2μ ε` and `ε = sym(Rᵀ F) − I = S − I` (sign: a stretched element,
//! `ε > 0`, pulls its vertices back). Since `S` is symmetric, `R σ` is exactly
//! `∂Ψ/∂F` of the energy `Ψ = μ ‖S − I‖² + ½ λ (tr(S − I))²` per unit rest volume
//! (the "corotated linear" energy), so these forces derive from the energy
//! `W = Σ_e V_e Ψ_e`: equilibria are its stationary points, and damped motion loses
//! it. A rigid motion of the whole body (`x = Q X + c`, `Q` a rotation) gives
//! `R = Q`, `S = I` and no force at all, where the linear model's `−K (x − X)` is
//! large.
//!
//! With the rotations frozen over a tick the force is affine in `x`:
//!
//! `Σ_e R K_e (Rᵀ x_e − X_e) = K̂ u + o`,  `K̂ = Σ_e R K_e Rᵀ`,  `o = Σ_e R K_e (Rᵀ X_e − X_e)`,
//!
//! with `u = x − X`. `K̂` has the sparsity of `K` and blocks
//! `K̂_ab = V (λ ĝ_a ĝ_bᵀ + μ ĝ_b ĝ_aᵀ + μ (g_a · g_b) I)` with the rotated gradients
//! `ĝ_k = R g_k` (as `R K_ab Rᵀ`); `o_a = V R σ₀ g_a` with `ε₀ = sym(R) − I` (the
//! stress of the rest shape turned by `R`). [`Corotated::update`] reassembles `K̂`
//! into a preallocated [`BlockMatrix`] of the mesh's pattern, so the implicit and
//! static solvers keep multiplying a block matrix, and every other consumer of `K u`
//! reads `K̂ u + o` instead. `o` is not assembled: the update keeps the force
//! `f₀ = K̂ u₀ + o` at its positions `x₀`, so `K̂ u + o = f₀ + K̂ (x − x₀)`, a row
//! of which is an imposed vertex's reaction, and the static solve, which needs all
//! of `o`, takes it as `f₀ − K̂ u₀`. At small displacements `R → I` and
//! `K̂ u + o → K u`: the linear model is the corotational one linearised at rest.
//!
//! The implicit and explicit steps keep an element's share of `K̂` until the element
//! has turned by [`TANGENT_TURN`] from the rotation it was assembled with
//! ([`Corotated::update_tangent_within`]); the force `f₀` always uses the rotations
//! of the tick. Static solves reassemble all of `K̂` on every update.

use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

use nalgebra::{Matrix3, Point3, UnitQuaternion, Vector3};

use super::parts::Parts;
use super::rotation::{WARM_ITERATIONS, cold_rotation, extract_rotation, polar};
use super::twist;
use super::twist_tangent::{self, TwistTangent};
use super::{BlockMatrix, ElasticModel};
use crate::engine::material::Material;
use crate::engine::workers::{Disjoint, Workers, share};

/// The vertex pairs `(a, b)` of a tetrahedron whose blocks are stored: the four
/// diagonal ones, then the six edges, each with `a ≤ b`. An element's vertices are
/// kept in ascending order, so the block of `(tet[a], tet[b])` is an upper stored
/// block of [`BlockMatrix`] and receives `K̂_ab` itself, never its transpose.
const PAIRS: [(usize, usize); 10] = [
    (0, 0),
    (1, 1),
    (2, 2),
    (3, 3),
    (0, 1),
    (0, 2),
    (0, 3),
    (1, 2),
    (1, 3),
    (2, 3),
];

/// What the corotational model keeps of one tetrahedron (152 bytes).
#[derive(Clone, Debug)]
pub struct Element {
    /// The vertices, in ascending order (not necessarily the mesh's order: the
    /// gradients follow them, and nothing here depends on orientation).
    pub tet: [u32; 4],
    /// Rest gradients `g₁, g₂, g₃` (1/m) of the shape functions of `tet[1..]`;
    /// `g₀ = −(g₁ + g₂ + g₃)`.
    pub g: [Vector3<f64>; 3],
    /// Rest volume `V`, m³.
    pub volume: f64,
    /// Lamé coefficients `λ`, `μ`, Pa.
    pub lambda: f64,
    pub mu: f64,
    /// Index in [`BlockMatrix::block`] of the block `(tet[a], tet[b])` of each pair
    /// `(a, b)` of [`PAIRS`].
    pub slot: [u32; 10],
}

impl Element {
    /// The four rest gradients.
    #[inline]
    pub fn gradients(&self) -> [Vector3<f64>; 4] {
        let [g1, g2, g3] = self.g;
        [-(g1 + g2 + g3), g1, g2, g3]
    }

    /// Deformation gradient `F = Σ_k x_k g_kᵀ = Σ_{k≥1} (x_k − x₀) g_kᵀ` (the second
    /// form because `Σ_k g_k = 0`; it reads edge vectors, not absolute positions).
    #[inline]
    pub fn deformation_gradient(&self, x: &[Point3<f64>]) -> Matrix3<f64> {
        let x0 = x[self.tet[0] as usize];
        self.edge_gradient(|v| x[v] - x0)
    }

    /// `Σ_{k≥1} d(v_k) g_kᵀ` for the element's vertices `v_k`: the gradient of a field
    /// given by its differences from vertex 0, `d(v) = x_v − x₀` (the deformation
    /// gradient) or `p_v − p₀` (its variation `δF` in the tangent).
    #[inline]
    fn edge_gradient(&self, d: impl Fn(usize) -> Vector3<f64>) -> Matrix3<f64> {
        let mut f = Matrix3::zeros();
        for k in 0..3 {
            f += d(self.tet[k + 1] as usize) * self.g[k].transpose();
        }
        f
    }

    /// Small-strain stress `σ = λ tr(ε) I + 2μ ε` of `ε = sym(a) − I`, Pa.
    #[inline]
    pub(super) fn stress(&self, a: &Matrix3<f64>) -> Matrix3<f64> {
        let eps = twist::symmetric(a) - Matrix3::identity();
        Matrix3::identity() * (self.lambda * eps.trace()) + 2.0 * self.mu * eps
    }

    /// Adds `m g_k` to `out` at each vertex `k` (`m = V R σ` gives the negated elastic
    /// force), with `g₀ = −(g₁ + g₂ + g₃)` applied as `−(m g₁ + m g₂ + m g₃)`.
    /// `add(v, f)` adds `f` to vertex `v`'s entry.
    #[inline]
    fn scatter(&self, m: &Matrix3<f64>, mut add: impl FnMut(usize, Vector3<f64>)) {
        let [g1, g2, g3] = self.g;
        let (f1, f2, f3) = (m * g1, m * g2, m * g3);
        add(self.tet[0] as usize, -(f1 + f2 + f3));
        add(self.tet[1] as usize, f1);
        add(self.tet[2] as usize, f2);
        add(self.tet[3] as usize, f3);
    }

    /// The element's rotation at `x`: the polar factor of `F`, extracted cold (as
    /// [`negated_force_on`] does).
    pub fn rotation_at(&self, x: &[Point3<f64>]) -> Matrix3<f64> {
        cold_rotation(&self.deformation_gradient(x))
    }

    /// `V R σ(Rᵀ F)` for the rotation `r` and the deformation gradient `f`: the
    /// matrix whose product with the rest gradient `g_k` is the element's share of
    /// the negated elastic force on its vertex `k`, N.
    #[inline]
    pub fn force_matrix(&self, r: &Matrix3<f64>, f: &Matrix3<f64>) -> Matrix3<f64> {
        self.volume * r * self.stress(&r.tr_mul(f))
    }

    /// The element's share of `K̂ p` for rotation `r` held fixed: `V R σ(Rᵀ δF) g_k` at
    /// each vertex `k`, `δF = Σ_k p_k g_kᵀ` (the tangent of the corotational force
    /// with the rotation frozen, as the implicit step uses it), added to `out`.
    pub fn add_tangent_product(
        &self,
        r: &Matrix3<f64>,
        p: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
    ) {
        let p0 = p[self.tet[0] as usize];
        let df = self.edge_gradient(|v| p[v] - p0);
        // σ(Rᵀ δF + I) is the stress of ε = sym(Rᵀ δF): linear in δF.
        let m = self.volume * r * self.stress(&(r.tr_mul(&df) + Matrix3::identity()));
        self.scatter(&m, |v, f| out[v] += f);
    }

    /// Strain `ε = sym(Rᵀ F) − I` for rotation `r`.
    #[inline]
    pub fn strain(&self, r: &Matrix3<f64>, f: &Matrix3<f64>) -> Matrix3<f64> {
        twist::stretch(r, f) - Matrix3::identity()
    }

    /// Adds this element's stored blocks of `K̂` with rotation `r` to `blocks`:
    ///
    /// `K̂_ab = V (λ ĝ_a ĝ_bᵀ + μ ĝ_b ĝ_aᵀ + μ (ĝ_a · ĝ_b) I)`,  `ĝ_k = R g_k`
    ///
    /// (`ĝ_a · ĝ_b = g_a · g_b`: a rotation keeps dot products). Written as
    /// `(Vλ ĝ_a) ĝ_bᵀ + ĝ_b (Vμ ĝ_a)ᵀ` with the scaled gradients formed once per
    /// vertex, a block costs two products and two sums per entry.
    /// `add(k, b)` adds `b` to stored block `k`.
    #[inline]
    fn add_blocks(&self, r: &Matrix3<f64>, mut add: impl FnMut(usize, Matrix3<f64>)) {
        let [g1, g2, g3] = self.g;
        let (h1, h2, h3) = (r * g1, r * g2, r * g3);
        let h = [-(h1 + h2 + h3), h1, h2, h3];
        let (vl, vm) = (self.volume * self.lambda, self.volume * self.mu);
        let lh = h.map(|h| vl * h);
        let mh = h.map(|h| vm * h);
        for (&(a, b), &slot) in PAIRS.iter().zip(&self.slot) {
            let d = mh[a].dot(&h[b]);
            let mut block = lh[a] * h[b].transpose() + h[b] * mh[a].transpose();
            block.m11 += d;
            block.m22 += d;
            block.m33 += d;
            add(slot as usize, block);
        }
    }

    /// Replaces this element's share of `K̂` assembled with rotation `old` by the
    /// one with `new`: adds `K̂_ab(new) − K̂_ab(old)` to each stored block. The term
    /// `μ V (ĝ_a · ĝ_b) I` is the same for every rotation and is left as it is, so a
    /// replacement costs about what one assembly does and reads and writes each
    /// block once.
    #[inline]
    fn replace_blocks(
        &self,
        old: &Matrix3<f64>,
        new: &Matrix3<f64>,
        mut add: impl FnMut(usize, Matrix3<f64>),
    ) {
        let [g1, g2, g3] = self.g;
        let rotated = |r: &Matrix3<f64>| {
            let (h1, h2, h3) = (r * g1, r * g2, r * g3);
            [-(h1 + h2 + h3), h1, h2, h3]
        };
        let (h, k) = (rotated(new), rotated(old));
        let (vl, vm) = (self.volume * self.lambda, self.volume * self.mu);
        let (lh, mh) = (h.map(|h| vl * h), h.map(|h| vm * h));
        let (lk, mk) = (k.map(|k| vl * k), k.map(|k| vm * k));
        for (&(a, b), &slot) in PAIRS.iter().zip(&self.slot) {
            add(
                slot as usize,
                lh[a] * h[b].transpose() + h[b] * mh[a].transpose()
                    - lk[a] * k[b].transpose()
                    - k[b] * mk[a].transpose(),
            );
        }
    }
}

/// The elements of `model`'s mesh, for the corotational model, each with its
/// vertices sorted (see [`PAIRS`]).
pub(super) fn elements(
    positions: &[Point3<f64>],
    tets: &[[u32; 4]],
    stiffness: &BlockMatrix,
    materials: &[Material],
    tet_material: &[u16],
) -> Vec<Element> {
    tets.iter()
        .zip(tet_material)
        .map(|(&mesh_tet, &m)| {
            let (mesh_g, volume) = super::shape_gradients(positions, mesh_tet);
            let mut order = [0, 1, 2, 3];
            order.sort_unstable_by_key(|&k| mesh_tet[k]);
            let tet = order.map(|k| mesh_tet[k]);
            let g = order.map(|k| mesh_g[k]);
            let (lambda, mu) = materials[m as usize].lame();
            let slot = PAIRS.map(|(a, b)| {
                stiffness
                    .find_upper(tet[a], tet[b])
                    .expect("every pair of a tetrahedron's vertices is an edge of the mesh")
                    as u32
            });
            Element {
                tet,
                g: [g[1], g[2], g[3]],
                volume,
                lambda,
                mu,
                slot,
            }
        })
        .collect()
}

/// Upper bound on the largest eigenvalue of `M⁻¹ K̂` for every choice of element
/// rotations (rad²/s²), for the explicit substep.
///
/// `uᵀ K̂ u = Σ_e (R_eᵀ u_e)ᵀ K_e (R_eᵀ u_e) ≤ Σ_e κ_e |u_e|²` with `κ_e ≥ λ_max(K_e)`,
/// so `uᵀ K̂ u ≤ Σ_i |u_i|² Σ_{e∋i} κ_e ≤ max_i (Σ_{e∋i} κ_e / m_i) uᵀ M u`. For
/// `κ_e`: `uᵀ K_e u = V (λ (tr G)² + 2μ |sym G|²)` with `G = Σ_k u_k g_kᵀ`;
/// `tr G = Σ_k u_k · g_k`, so `(tr G)² ≤ Σ_k |g_k|² Σ_k |u_k|²` (Cauchy–Schwarz), and
/// `|sym G|² ≤ |G|² ≤ λ_max(Σ_k g_k g_kᵀ) Σ_k |u_k|²`, hence
/// `κ_e = V (λ Σ_k |g_k|² + 2μ λ_max(Σ_k g_k g_kᵀ))`. Unlike a Gershgorin bound on
/// `K`, it does not change when the elements turn.
pub(super) fn max_eigenvalue_bound(elements: &[Element], mass: &[f64]) -> f64 {
    let mut sum = vec![0.0; mass.len()];
    for e in elements {
        let g = e.gradients();
        let gg: Matrix3<f64> = g.iter().map(|g| g * g.transpose()).sum();
        let top = gg.symmetric_eigenvalues().max();
        let kappa = e.volume * (e.lambda * gg.trace() + 2.0 * e.mu * top);
        for &v in &e.tet {
            sum[v as usize] += kappa;
        }
    }
    sum.iter().zip(mass).map(|(s, m)| s / m).fold(0.0, f64::max)
}

/// Elastic energy `W = Σ_e V_e (½ λ (tr ε)² + μ ε:ε)`, `ε = sym(Rᵀ F) − I`, of the
/// configuration `x`, J, with every rotation extracted afresh.
pub(super) fn strain_energy(elements: &[Element], x: &[Point3<f64>]) -> f64 {
    elements
        .iter()
        .map(|e| {
            let f = e.deformation_gradient(x);
            let eps = e.strain(&cold_rotation(&f), &f);
            e.volume * (0.5 * e.lambda * eps.trace().powi(2) + e.mu * eps.component_mul(&eps).sum())
        })
        .sum()
}

/// `out = Σ_e R_e K_e (R_eᵀ x_e − X_e)`, the negated elastic force at `x` (N), with
/// every rotation extracted afresh (not warm-started): what an equilibrium check
/// needs, independent of the rotations a solver carried.
pub(super) fn negated_force(elements: &[Element], x: &[Point3<f64>], out: &mut [Vector3<f64>]) {
    out.iter_mut().for_each(|o| *o = Vector3::zeros());
    for e in elements {
        let f = e.deformation_gradient(x);
        let rs = e.force_matrix(&cold_rotation(&f), &f);
        for (&v, g) in e.tet.iter().zip(&e.gradients()) {
            out[v as usize] += rs * g;
        }
    }
}

/// The elements around each vertex, in compressed rows: those of vertex `v` are
/// `element[start[v]..start[v + 1]]`. Built once with the model, for the force on one
/// vertex ([`negated_force_on`]).
#[derive(Clone, Debug, Default)]
pub struct VertexElements {
    start: Vec<u32>,
    element: Vec<u32>,
}

impl VertexElements {
    pub(super) fn new(vertices: usize, elements: &[Element]) -> Self {
        let mut start = vec![0u32; vertices + 1];
        for e in elements {
            for &v in &e.tet {
                start[v as usize + 1] += 1;
            }
        }
        for i in 0..vertices {
            start[i + 1] += start[i];
        }
        let mut next = start.clone();
        let mut element = vec![0u32; start[vertices] as usize];
        for (k, e) in elements.iter().enumerate() {
            for &v in &e.tet {
                element[next[v as usize] as usize] = k as u32;
                next[v as usize] += 1;
            }
        }
        VertexElements { start, element }
    }

    /// The elements that contain vertex `v`.
    pub fn of(&self, v: u32) -> &[u32] {
        let v = v as usize;
        match (self.start.get(v), self.start.get(v + 1)) {
            (Some(&a), Some(&b)) => &self.element[a as usize..b as usize],
            _ => &[],
        }
    }

    pub(super) fn heap_bytes(&self) -> usize {
        (self.start.capacity() + self.element.capacity()) * 4
    }
}

/// `Σ_{e∋v} R_e K_e (R_eᵀ x_e − X_e)` at vertex `v`: the negated elastic force on `v`
/// alone (N), every rotation around it extracted afresh, as
/// [`negated_force`] would give at `v`. The reaction of the tissue on a vertex an
/// instrument holds, at the cost of the few elements around it.
pub(super) fn negated_force_on(
    elements: &[Element],
    around: &VertexElements,
    v: u32,
    x: &[Point3<f64>],
) -> Vector3<f64> {
    negated_force_on_with(elements, around, v, |k| {
        let e = &elements[k as usize];
        let f = e.deformation_gradient(x);
        e.force_matrix(&cold_rotation(&f), &f)
    })
}

/// `Σ_{e∋v} m_e g_{e,v}`: the negated elastic force on vertex `v`, N, from each
/// element's [`Element::force_matrix`] as `force_matrix(e)` gives it, summed in the
/// order of `around`. [`negated_force_on`] and the contact's settling (which keeps
/// the rotations it extracted) both sum here, so that they agree to the last bit.
pub fn negated_force_on_with(
    elements: &[Element],
    around: &VertexElements,
    v: u32,
    mut force_matrix: impl FnMut(u32) -> Matrix3<f64>,
) -> Vector3<f64> {
    let mut out = Vector3::zeros();
    for &k in around.of(v) {
        let e = &elements[k as usize];
        let rs = force_matrix(k);
        for (&w, g) in e.tet.iter().zip(&e.gradients()) {
            if w == v {
                out += rs * g;
            }
        }
    }
    out
}

/// How far an element may turn from the rotation its share of `K̂` was assembled
/// with before the implicit and explicit steps reassemble that share
/// ([`Corotated::update_tangent_within`]), rad.
///
/// What it changes: `K̂` enters a tick only as the tangent of the force about the
/// tick's start, `f(x) ≈ f₀ + K̂ (x − x₀)`, where `f₀` is always computed with the
/// rotations extracted afresh. A share assembled with `R′` instead of `R` differs by
/// `R′ K_e R′ᵀ − R K_e Rᵀ`, of norm at most `2 ‖R′ − R‖ ‖K_e‖ ≤ 2θ ‖K_e‖` for a turn
/// `θ` between them. So the tick's step `x − x₀` is solved with a tangent off by at
/// most 2e-3 of each element's stiffness, and the reaction an imposed vertex reads,
/// `f₀ + K̂ (x − x₀)`, by at most 2e-3 of the force change over the tick; nothing
/// changes at rest or at equilibrium, where `f₀` alone decides. `K̂` stays a sum of
/// rotated `K_e`, so it stays symmetric positive semidefinite and under the explicit
/// step's eigenvalue bound ([`ElasticModel::max_eigenvalue_bound`]) as the exact one
/// does.
///
/// Measured with the bench `corotational` (a 2 cm/s press, liver-20k): a fifth of
/// the shares are reassembled per tick, the update takes 0.8 of the time, and the
/// final state and reaction lie within 3e-6 and 6e-6 of the exact tangent's, against
/// 9e-5 between either and the converged static answer. 2e-4 rad reassembled half
/// the shares for about the same error; 3e-3 a tenth, for twice the error.
pub const TANGENT_TURN: f64 = 1e-3;

/// The per-tick state of the corotational model: each element's rotation (the warm
/// start of the next extraction), the rotated stiffness `K̂`, and the positions `x₀`
/// of the last update with the negated force `f₀ = K̂ u₀ + o` there, which together
/// hold the affine force of the frozen rotations (the offset `o` itself is not
/// assembled: `K̂ u + o = f₀ + K̂ (x − x₀)`, and a tick needs it only on the rows of
/// the imposed vertices). Allocated once; [`update`](Self::update) and
/// [`force`](Self::force) allocate nothing.
#[derive(Clone, Debug)]
pub struct Corotated {
    rotation: Vec<UnitQuaternion<f64>>,
    /// The rotation each element's share of `K̂` was last assembled with.
    assembled: Vec<UnitQuaternion<f64>>,
    /// `K̂ = Σ_e R_e K_e R_eᵀ`, on the pattern of the model's stiffness, N/m.
    pub tangent: BlockMatrix,
    /// `x₀`, m.
    at: Vec<Point3<f64>>,
    /// `f₀ = Σ_e R_e K_e (R_eᵀ x₀_e − X_e)`, N.
    force_at: Vec<Vector3<f64>>,
    /// How many elements' shares of `K̂` the last update assembled.
    reassembled: usize,
    /// The elements split for threads (one part unless [`set_parts`](Self::set_parts)).
    parts: Parts,
    /// Whether each element's twist may pass [`twist_tangent::FROM`] at `x₀`.
    twisted: Vec<bool>,
    /// The positive twist modes of those elements at `x₀`, as
    /// [`update_twist`](Self::update_twist) last built them.
    twist: TwistTangent,
}

impl Corotated {
    /// The workspace of a corotational model at rest (`R = I`, `K̂ = K`, `o = 0`).
    pub fn new(model: &ElasticModel) -> Self {
        Corotated {
            rotation: vec![UnitQuaternion::identity(); model.elements.len()],
            assembled: vec![UnitQuaternion::identity(); model.elements.len()],
            tangent: model.stiffness.clone(),
            at: model.rest.clone(),
            force_at: vec![Vector3::zeros(); model.vertex_count()],
            reassembled: 0,
            parts: Parts::new(
                model.vertex_count(),
                1,
                model.elements.iter().map(|e| e.tet),
            ),
            twisted: vec![false; model.elements.len()],
            twist: TwistTangent::new(model.elements.len()),
        }
    }

    /// Number of elements.
    pub fn rotation_count(&self) -> usize {
        self.rotation.len()
    }

    /// The rotation of element `e` as last extracted.
    pub fn rotation(&self, e: usize) -> Matrix3<f64> {
        *self.rotation[e].to_rotation_matrix().matrix()
    }

    /// The largest [`twist_ratio`](super::twist::twist_ratio) over the elements at
    /// `x` if above 1, else at most 1, each rotation extracted there (warm-started,
    /// and kept for the next extraction): how far the turning of the rotations
    /// raises the stiffness above the linear bound, for the explicit step. One pass
    /// over the elements, nothing allocated.
    pub fn twist_ratio(&mut self, model: &ElasticModel, x: &[Point3<f64>]) -> f64 {
        let mut worst: f64 = 0.0;
        for (e, q) in model.elements.iter().zip(&mut self.rotation) {
            let f = e.deformation_gradient(x);
            extract_rotation(&f, q, WARM_ITERATIONS);
            let s = twist::stretch(q.to_rotation_matrix().matrix(), &f);
            // Only a ratio above 1 changes the step: the cheap bound rules most
            // elements out before the eigenvalues are taken.
            if twist::twist_ratio_bound(e, &s) <= worst.max(1.0) {
                continue;
            }
            let ratio = twist::twist_ratio(e, &s);
            if ratio > worst {
                worst = ratio;
            }
        }
        worst
    }

    /// The rotation element `e`'s share of `K̂` was last assembled with.
    pub fn assembled_rotation(&self, e: usize) -> Matrix3<f64> {
        *self.assembled[e].to_rotation_matrix().matrix()
    }

    /// How many elements' shares of `K̂` the last update assembled (all of them
    /// after [`update`](Self::update)).
    pub fn reassembled(&self) -> usize {
        self.reassembled
    }

    /// Extracts every element's rotation at `x`, reassembles `K̂` with them, and
    /// writes `out = K̂ u + o = Σ_e R_e K_e (R_eᵀ x_e − X_e)`, the negated elastic
    /// force at `x` (N), which is kept with `x` for [`row`](Self::row).
    pub fn update(&mut self, model: &ElasticModel, x: &[Point3<f64>], out: &mut [Vector3<f64>]) {
        self.update_shared(model, x, out, 0.0, None);
    }

    /// As [`update`](Self::update), but the share of `K̂` of an element that has
    /// turned by at most `turn` (rad) since it was last assembled is kept: the force
    /// `out` is exact, the tangent `K̂` within `2 · turn` of each element's stiffness
    /// (see [`TANGENT_TURN`]). A share is replaced by adding the difference of the
    /// new and the old; each replacement leaves a rounding of about one ulp of the
    /// block's sum, which after a million replacements of one block (hours at 60 Hz
    /// with that element always turning) is about 1e-13 of it. `turn = 0` (or less)
    /// is [`update`](Self::update): all of `K̂` assembled afresh.
    pub fn update_tangent_within(
        &mut self,
        model: &ElasticModel,
        x: &[Point3<f64>],
        out: &mut [Vector3<f64>],
        turn: f64,
    ) {
        self.update_shared(model, x, out, turn, None);
    }

    /// [`update_tangent_within`](Self::update_tangent_within), each part of
    /// [`set_parts`](Self::set_parts) handled by one of `workers` (see [`Parts`]).
    pub fn update_shared(
        &mut self,
        model: &ElasticModel,
        x: &[Point3<f64>],
        out: &mut [Vector3<f64>],
        turn: f64,
        workers: Option<&Workers>,
    ) {
        if turn <= 0.0 {
            self.tangent
                .block
                .iter_mut()
                .for_each(|b| *b = Matrix3::zeros());
            self.update_with(model, x, out, workers, |e, q, qa, add| {
                *qa = *q;
                e.add_blocks(q.to_rotation_matrix().matrix(), add);
                true
            });
            return;
        }
        // |q · q′| = cos(θ/2) for the turn θ between the rotations q and q′.
        let cos_half = (0.5 * turn).cos();
        self.update_with(model, x, out, workers, |e, q, qa, add| {
            if q.coords.dot(&qa.coords).abs() >= cos_half {
                return false;
            }
            let (old, new) = (qa.to_rotation_matrix(), q.to_rotation_matrix());
            e.replace_blocks(old.matrix(), new.matrix(), add);
            *qa = *q;
            true
        });
    }

    /// Splits the update's elements into `parts` (built on this model's elements),
    /// for [`update_shared`](Self::update_shared). The default is one part.
    pub fn set_parts(&mut self, parts: Parts) {
        self.parts = parts;
    }

    /// The pass both updates make: each element's rotation extracted (warm-started)
    /// and its force added to `out`, then `tangent(element, rotation, assembled
    /// rotation, add to K̂'s block)`, which says whether it assembled the element's
    /// share, and flags the elements whose twist may pass [`twist_tangent::FROM`]
    /// (for [`update_twist`](Self::update_twist)); `x` and `out` kept for
    /// [`row`](Self::row).
    #[inline]
    fn update_with(
        &mut self,
        model: &ElasticModel,
        x: &[Point3<f64>],
        out: &mut [Vector3<f64>],
        workers: Option<&Workers>,
        tangent: impl Fn(
            &Element,
            &UnitQuaternion<f64>,
            &mut UnitQuaternion<f64>,
            &mut dyn FnMut(usize, Matrix3<f64>),
        ) -> bool
        + Sync,
    ) {
        let blocks = Disjoint::new(&mut self.tangent.block);
        let assembled = Disjoint::new(&mut self.assembled);
        let twisted = Disjoint::new(&mut self.twisted);
        self.reassembled = each_element(
            model,
            &self.parts,
            &mut self.rotation,
            x,
            out,
            workers,
            |e, k, q, a| {
                // SAFETY: element `k`'s entries are its own.
                unsafe {
                    *twisted.at(k) = twist_tangent::strongly_deformed(e, &twist::symmetric(a));
                }
                // SAFETY: element `k`'s blocks lie in the rows of its part's vertices
                // (or it is a crossing element, handled alone), and `k` is its own.
                let qa = unsafe { assembled.at(k) };
                tangent(e, q, qa, &mut |slot, b| unsafe { *blocks.at(slot) += b })
            },
        );
        self.at.copy_from_slice(x);
        self.force_at.copy_from_slice(out);
    }

    /// Builds the positive twist modes ([`twist_tangent`]) of the elements the last
    /// update flagged, at its positions `x₀` and rotations, for the implicit step and
    /// the static solve ([`twist`](Self::twist)). The flags come from the update's
    /// element pass (a Gershgorin bound, cheap); the eigenvalues taken here are not,
    /// so only the solves that use the tangent ask for them: the explicit step's
    /// substeps do without.
    pub fn update_twist(&mut self, model: &ElasticModel) {
        self.twist.clear();
        for (k, flagged) in self.twisted.iter().enumerate() {
            if *flagged {
                let e = &model.elements[k];
                let r = self.rotation[k].to_rotation_matrix();
                self.twist
                    .add(e, r.matrix(), &e.deformation_gradient(&self.at));
            }
        }
    }

    /// The twist modes [`update_twist`](Self::update_twist) last built (none before).
    pub fn twist(&self) -> &TwistTangent {
        &self.twist
    }
    /// Row `i` of `K̂ u + o` at `x` with the rotations of the last
    /// [`update`](Self::update): `f₀_i + Σ_j K̂_ij (x_j − x₀_j)`, N (exact: with
    /// the rotations frozen the force is affine in `x`). The reaction on an imposed
    /// vertex, at the cost of its row.
    pub fn row(&self, i: usize, x: &[Point3<f64>]) -> Vector3<f64> {
        let mut acc = self.force_at[i];
        self.tangent
            .for_each_in_row(i, |j, k| acc += k * (x[j] - self.at[j]));
        acc
    }

    /// Bytes held (for memory reports).
    pub fn heap_bytes(&self) -> usize {
        self.tangent.heap_bytes()
            + (self.at.capacity() + self.force_at.capacity()) * 24
            + self.rotation.capacity() * std::mem::size_of::<UnitQuaternion<f64>>()
            + self.twisted.capacity()
            + self.twist.heap_bytes()
    }

    /// Extracts every element's rotation at `x` and writes
    /// `out = Σ_e R_e K_e (R_eᵀ x_e − X_e)` (the negated elastic force, N), leaving
    /// `K̂`, `x₀` and `f₀` as they were: what an explicit substep needs.
    pub fn force(&mut self, model: &ElasticModel, x: &[Point3<f64>], out: &mut [Vector3<f64>]) {
        self.force_shared(model, x, out, None);
    }

    /// [`force`](Self::force), shared among `workers` as
    /// [`update_shared`](Self::update_shared) is.
    pub fn force_shared(
        &mut self,
        model: &ElasticModel,
        x: &[Point3<f64>],
        out: &mut [Vector3<f64>],
        workers: Option<&Workers>,
    ) {
        each_element(
            model,
            &self.parts,
            &mut self.rotation,
            x,
            out,
            workers,
            |_, _, _, _| false,
        );
    }
}

/// Extracts each element's rotation at `x` (warm-started from `rotation`) and adds
/// its force to `out` (zeroed first), then calls `then(element, index, rotation,
/// Rᵀ F)`;
/// returns how many calls said true. The elements of each of `parts` run on one of
/// `workers`, then the crossing ones on this thread.
fn each_element(
    model: &ElasticModel,
    parts: &Parts,
    rotation: &mut [UnitQuaternion<f64>],
    x: &[Point3<f64>],
    out: &mut [Vector3<f64>],
    workers: Option<&Workers>,
    then: impl Fn(&Element, usize, &UnitQuaternion<f64>, &Matrix3<f64>) -> bool + Sync,
) -> usize {
    out.iter_mut().for_each(|o| *o = Vector3::zeros());
    let forces = Disjoint::new(out);
    let rotations = Disjoint::new(rotation);
    let counted = AtomicUsize::new(0);
    let run = |group: &[u32]| {
        let mut count = 0;
        for &k in group {
            let k = k as usize;
            let e = &model.elements[k];
            // SAFETY: every element of a part has its four vertices in it, and
            // element `k` is its own: no other part touches these entries.
            let q = unsafe { rotations.at(k) };
            let p = polar(&e.deformation_gradient(x), q, WARM_ITERATIONS);
            e.scatter(&(e.volume * p.r * e.stress(&p.a)), |v, f| unsafe {
                *forces.at(v) += f
            });
            if then(e, k, q, &p.a) {
                count += 1;
            }
        }
        counted.fetch_add(count, Relaxed);
    };
    share(workers, parts.count(), &|t| run(parts.elements(t)));
    run(parts.crossing());
    counted.into_inner()
}
