//! Colliding edges (paper §2.3, eq. 2–5) and the "closer to the axis" test of the
//! confidence intervals (§2.4, eq. 6), derived again.
//!
//! # Setting
//!
//! In the instrument's frame (§2.2, [`super::pose`]) the instrument is still: its axis
//! segment is `{P + βZ : β ∈ [0, l]}` (`P` the tip, `Z` the unit axis toward the handle,
//! `l` the shaft length). A mesh edge moves linearly during the step:
//! `A(t) = A + tΔA`, `B(t) = B + tΔB`, `t ∈ [0, 1]`, where `A = R(A_old)` and
//! `ΔA = A_new − A` ([`MovingEdge`]). The edge crossed the axis if eq. 2 holds:
//!
//! ```text
//! A(t) + α (B(t) − A(t)) = P + β Z,   (t, α, β) ∈ [0, 1] × [0, 1] × [0, l]     (2)
//! ```
//!
//! (The paper prints β's range once as `]−∞, 0]` and once as `[0, l]`; with `Z` pointing
//! from the tip to the handle the shaft is `β ∈ [0, l]`, and `β < 0` is beyond the tip.)
//!
//! # Derivation
//!
//! Take an orthonormal frame `(e₁, e₂, Z)` with `e₁ × e₂ = Z` and split every vector
//! into its projection on the plane ⊥ `Z` and its height along `Z`:
//! `a(t), b(t) ∈ ℝ²` are the projections of `A(t) − P`, `B(t) − P`, and
//! `z_a(t) = (A(t) − P)·Z`, `z_b(t)` likewise; `d = b − a`. Eq. 2 splits into
//!
//! ```text
//! a(t) + α d(t) = 0           (the edge's shadow passes through the axis' shadow)
//! β = z_a(t) + α (z_b(t) − z_a(t))   (the height of that point)
//! ```
//!
//! The 2D part needs `a`, `b` and the origin collinear: with the 2D cross product
//! `u × v = u₁v₂ − u₂v₁`,
//!
//! ```text
//! s(t) = a(t) × b(t) = Z · ((A(t) − P) × (B(t) − P)) = 0                          (3)
//! s(t) = c₂t² + c₁t + c₀,  c₀ = a₀ × b₀,  c₁ = a₀ × Δb + Δa × b₀,  c₂ = Δa × Δb
//! ```
//!
//! `s` is also `(A(t) − P)·((B(t) − A(t)) × Z)`, the dot product the paper takes, and up
//! to the factor `|Z × (B − A)|` it is the signed distance between the edge's line and
//! the axis line: its sign says on which side of the axis the edge passes, and a
//! crossing is a change of that sign. At a root the origin's position on the shadow is
//! the *signed* least-squares parameter and the height follows without division:
//!
//! ```text
//! α = −a·d / |d|²,   β = (A(t) + α (B(t) − A(t)) − P)·Z = z_a + α (z_b − z_a)   (4, 5)
//! ```
//!
//! # What is wrong in the printed equations
//!
//! - Eq. 3 is right up to a misplaced parenthesis: the linear coefficient is
//!   `ΔA·((B − A) × Z) − (P − A)·((ΔB − ΔA) × Z)` — the second term is multiplied by
//!   `t` too (as printed it reads as a constant, with an unmatched `)`).
//! - Eq. 4 and 5 are ratios of norms, `|α|` and `|β|`: they drop the signs, so an edge
//!   meeting the axis line beyond its end A (α < 0) or beyond the tip (β < 0) would pass
//!   the `[0, 1] × [0, l]` test. The signed forms are
//!   `α = ((P − A(t)) × Z)·(e × Z) / |e × Z|²` and `β = ((A(t) − P) × e)·(Z × e) / |Z × e|²`
//!   with `e = B(t) − A(t)`; we use the 2D forms above.
//! - Eq. 5's denominator has `B + ΔB` where it needs `B + tΔB`, and the sentence before
//!   eq. 4 names the vector `B + tΔB − A − ΔB` for `B + tΔB − A − tΔA`.
//! - Eq. 6 is wrong as printed; see [`closer_to_axis`].
//!
//! # Decisions
//!
//! The rule of the paper: the edge is *colliding* if exactly one root of (3) gives a
//! valid triple. Two valid roots mean it crossed and came back within the step (a
//! double root — tangency, touching without changing side — counts twice, so it is not
//! a crossing either). A root at `t = 0` is not counted: a contact present at the start
//! of the step was the previous step's `t = 1` (the contact stage resolves it there),
//! and counting both ends would count it twice; the crossing instant is in `(0, 1]`
//! (up to the time tolerance below).
//! Degenerate cases, each decided explicitly ([`edge_crossing`]):
//!
//! - the edge does not move (every point moves less than the touching tolerance):
//!   nothing can cross, whether or not it touches the axis already — `None`;
//! - the edge stays parallel to `Z` (its shadow is a point; `s ≡ 0`):
//!   [`CrossingKind::AlongAxis`];
//! - the edge stays in a plane containing the axis line (`s ≡ 0`, no side to change):
//!   [`CrossingKind::InPlane`], decided from the endpoints' motion in that plane;
//! - `c₂ = 0` (e.g. a translating edge): the linear root; `c₂ = c₁ = 0`: no root;
//! - the shadow collapses to a point at a root (the edge is parallel to `Z` at that
//!   instant, `d = 0` makes `s = 0` wherever the origin is): valid only if that point is
//!   on the axis and the edge's height range meets `[0, l]`;
//! - an endpoint on the axis at the root: `α ∈ {0, 1}` within the tolerance, valid.
//!
//! # Tolerances
//!
//! One length sets them all, the edge's [`MovingEdge::scale`]: the largest of its length
//! at either end of the step and its endpoints' motions. A point is *on* the axis if it
//! lies within `tol = TOUCH_RELATIVE · scale` of it (`TOUCH_RELATIVE = 1e-9`): f64
//! coordinates near a liver (≤ 0.3 m) are exact to ~1e-17 m and the cancellations here
//! (differences of positions, cross products, roots) lose at most a few digits more
//! for an edge of 1 mm, so 1e-9 keeps a margin of ~10⁶ over rounding while staying far
//! below any physical length (1e-9 of a 1 cm edge is 1e-11 m against an instrument
//! radius of millimetres). Instants get the matching tolerance
//! `t_eps = tol / max(|ΔA|, |ΔB|)`, the time in which no point of the edge moves more
//! than `tol`: a root within `t_eps` of 0 is the start of the step (not counted), one
//! within `t_eps` past 1 is its end (counted, clamped to 1) — so a contact exactly at a
//! step boundary is counted once whichever way rounding puts it. A polynomial
//! coefficient is *zero* if it is below `ROUNDING = 16ε` times the magnitude of its
//! terms — below that its value and sign are rounding noise. The edge is *static* if
//! both displacements are ≤ `tol`, *parallel to the axis* if its shadow is ≤ `tol` at
//! both ends of the step.

use nalgebra::{Isometry3, Point3, Vector2, Vector3};

use super::pose::{InstrumentPose, perpendicular};

/// Points within `TOUCH_RELATIVE · scale` of the axis are on it (see the module doc for
/// why 1e-9; `scale` is [`MovingEdge::scale`]).
pub const TOUCH_RELATIVE: f64 = 1e-9;

/// A value of a polynomial coefficient below `ROUNDING` times the magnitude of its
/// terms is rounding noise: each term is a 2D cross product (two rounded products and a
/// difference) of vectors that were rounded once in `X − P` and once in the projection,
/// a few ε each; 16ε bounds their sum.
const ROUNDING: f64 = 16.0 * f64::EPSILON;

/// An edge `(A, B)` of the mesh during one step, in the instrument's frame:
/// `A(t) = a + t·delta_a`, `B(t) = b + t·delta_b`, `t ∈ [0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MovingEdge {
    /// `A = R(A_old)`: the previous position carried by the instrument's motion.
    pub a: Point3<f64>,
    /// `B = R(B_old)`.
    pub b: Point3<f64>,
    /// `ΔA = A_new − R(A_old)`.
    pub delta_a: Vector3<f64>,
    /// `ΔB = B_new − R(B_old)`.
    pub delta_b: Vector3<f64>,
}

impl MovingEdge {
    /// An edge from its start positions and displacements.
    pub fn new(
        a: Point3<f64>,
        b: Point3<f64>,
        delta_a: Vector3<f64>,
        delta_b: Vector3<f64>,
    ) -> Self {
        Self {
            a,
            b,
            delta_a,
            delta_b,
        }
    }

    /// The edge seen from the instrument (§2.2): the previous positions are carried by
    /// the instrument's rigid motion `r` ([`super::pose::rigid_motion`]), the current
    /// ones are where they are.
    pub fn in_instrument_frame(
        r: &Isometry3<f64>,
        old: [Point3<f64>; 2],
        new: [Point3<f64>; 2],
    ) -> Self {
        let a = r.transform_point(&old[0]);
        let b = r.transform_point(&old[1]);
        Self::new(a, b, new[0] - a, new[1] - b)
    }

    /// `A(t)`.
    pub fn a_at(&self, t: f64) -> Point3<f64> {
        self.a + self.delta_a * t
    }

    /// `B(t)`.
    pub fn b_at(&self, t: f64) -> Point3<f64> {
        self.b + self.delta_b * t
    }

    /// The point `A(t) + α (B(t) − A(t))`.
    pub fn point_at(&self, t: f64, alpha: f64) -> Point3<f64> {
        let a = self.a_at(t);
        a + (self.b_at(t) - a) * alpha
    }

    /// The same edge with its ends swapped (a crossing's `α` becomes `1 − α`).
    pub fn reversed(&self) -> Self {
        Self::new(self.b, self.a, self.delta_b, self.delta_a)
    }

    /// The length that scales the tolerances: the largest of the edge's length at the
    /// start and at the end of the step and of its endpoints' displacements.
    pub fn scale(&self) -> f64 {
        let e0 = (self.b - self.a).norm();
        let e1 = (self.b_at(1.0) - self.a_at(1.0)).norm();
        e0.max(e1).max(self.delta_a.norm()).max(self.delta_b.norm())
    }
}

/// How a crossing was decided.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CrossingKind {
    /// The generic case: the edge passed from one side of the axis to the other
    /// (`s(t)` of eq. 3 changed sign once at a valid point).
    Transversal,
    /// The edge stayed in a plane containing the axis line (`s ≡ 0`): an endpoint
    /// passed over the axis segment within that plane.
    InPlane,
    /// The edge stayed parallel to the axis (its shadow on the plane ⊥ `Z` is a point)
    /// and that point passed over the axis, or the edge slid along the axis line onto
    /// the axis segment.
    AlongAxis,
}

/// Where and when an edge crossed the axis segment: eq. 2 holds at `(t, alpha, beta)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossing {
    /// The crossing instant `t_c ∈ (0, 1]` (fraction of the step).
    pub t: f64,
    /// Position on the edge, `α ∈ [0, 1]` (0 at `A`, 1 at `B`).
    pub alpha: f64,
    /// Position on the axis, `β ∈ [0, l]`, m from the tip toward the handle.
    pub beta: f64,
    /// Which case decided it.
    pub kind: CrossingKind,
}

/// One end of an edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EdgeEnd {
    A,
    B,
}

/// Whether `edge` crossed the axis segment `{P + βZ : β ∈ [0, length]}` of `pose`
/// during the step (eq. 2–5, the module doc derives them), and where.
///
/// Returns the crossing if it is the only one of the step (the paper's "exactly one"
/// rule), `None` if there is none, if there are two (crossed and came back, or
/// tangency), if the edge does not move, or if an input is not finite or `length < 0`.
///
/// Degenerate cases, in the order they are tested (`tol` as in the module doc):
/// 1. *Static*: both displacements ≤ `tol` — `None`, even if the edge touches the axis
///    (nothing crossed during this step).
/// 2. *Parallel to Z*: the shadow `d` is ≤ `tol` at both ends of the step (so all
///    along, `d` being linear in `t`) — the edge's shadow is the point `m(t)`, the
///    midpoint of `a(t)` and `b(t)`. If the edge touches the axis segment at `t = 0`:
///    `None`. If `m` moves by more than `tol`: the crossing is at `m`'s closest
///    approach to the axis, if that is within `tol` at some `t > 0`, with β the middle
///    of the overlap of the edge's height range with `[0, l]` (the whole overlap
///    touches; the middle is the deterministic representative). If `m` does not move
///    and is on the axis line: the edge slides along the axis line and the crossing is
///    the first instant its height range meets `[0, l]`.
/// 3. *In a plane containing the axis line*: `|c₀| + |c₁| + |c₂|` (a bound on `|s|`
///    over the step) is ≤ `tol · min_t |d(t)|` (the axis line is within `tol` of the
///    edge's line all along) or ≤ rounding noise. There is no side to change; the edge
///    meets the axis line when an endpoint passes over it. If the edge touches the
///    axis segment at `t = 0`: `None`. Otherwise the crossing is the first instant in
///    `(0, 1]` at which an endpoint passes over the axis segment (its shadow passes
///    within `tol` of the origin — or, for an endpoint on the axis line all along, its
///    height enters `[0, l]`): the origin "crossed into" the shadow there. An endpoint
///    moves on a straight line and meets the axis line at most once, so the edge cannot
///    come back out through the same end: the first event is the crossing whether the
///    edge stays on the axis ("into") or slides across it ("through"). Not reported:
///    an edge straddling the axis line whose meeting point slides past the tip or past
///    `l` without an endpoint passing over the shaft: shifting the axis off the
///    edge's plane by any small amount, to either side, leaves the edge on one side
///    of it all along (for a plane that does not turn), so it is contact, not
///    crossing (the tip and push-out stages, §2.5–2.6, handle it).
/// 4. *Generic*: the roots of eq. 3 from the stable quadratic formula
///    (`q = −(c₁ + sign(c₁)√D)/2`, roots `q/c₂` and `c₀/q`, no cancellation); `c₂` at
///    rounding level → linear; `c₁` too → constant, no root. Each root in `(0, 1]`
///    (up to `t_eps`, module doc) is valid if the point of the edge nearest the axis
///    line on its shadow, with
///    `α = clamp(−a·d/|d|², 0, 1)`, is within `tol` of the axis line and its height
///    within `[−tol, l + tol]` (β is then clamped to `[0, l]`); a shadow shorter than
///    `tol` at the root is judged as in case 2.
pub fn edge_crossing(edge: &MovingEdge, pose: &InstrumentPose, length: f64) -> Option<Crossing> {
    let finite = |v: &Vector3<f64>| v.iter().all(|x| x.is_finite());
    let inputs = [
        &edge.a.coords,
        &edge.b.coords,
        &edge.delta_a,
        &edge.delta_b,
        &pose.tip.coords,
        pose.axis.as_ref(),
    ];
    if !(inputs.into_iter().all(finite) && length.is_finite() && length >= 0.0) {
        return None;
    }
    let scale = edge.scale();
    let tol = TOUCH_RELATIVE * scale;
    if edge.delta_a.norm() <= tol && edge.delta_b.norm() <= tol {
        return None;
    }
    let motion = edge.delta_a.norm().max(edge.delta_b.norm());
    let local = Local::new(edge, pose, length, tol, tol / motion);
    if local.d(0.0).norm() <= tol && local.d(1.0).norm() <= tol {
        return local.along_axis();
    }
    let (a0, da, b0, db) = (local.a0, local.da, local.b0, local.db);
    let c0 = cross(&a0, &b0);
    let c1 = cross(&a0, &db) + cross(&da, &b0);
    let c2 = cross(&da, &db);
    // Magnitudes of the terms of each coefficient, from the 3D vectors (which bound
    // their shadows and carry the rounding of X − P).
    let (na0, nda, nb0, ndb) = (
        (edge.a - pose.tip).norm(),
        edge.delta_a.norm(),
        (edge.b - pose.tip).norm(),
        edge.delta_b.norm(),
    );
    let noise0 = na0 * nb0;
    let noise1 = na0 * ndb + nda * nb0;
    let noise2 = nda * ndb;
    let bound = c0.abs() + c1.abs() + c2.abs();
    if bound <= tol * local.min_shadow_length() || bound <= ROUNDING * (noise0 + noise1 + noise2) {
        return local.in_plane();
    }
    let (roots, n) = quadratic_roots(c2, c1, c0, ROUNDING * noise2, ROUNDING * noise1);
    let mut found = None;
    let mut count = 0;
    for &t in &roots[..n] {
        if let Some(t) = local.in_step(t)
            && let Some(c) = local.probe(t, CrossingKind::Transversal)
        {
            count += 1;
            found = Some(c);
        }
    }
    if count == 1 { found } else { None }
}

/// Whether the motion of one end of a crossing edge moves the edge *closer* to the axis
/// (eq. 6, §2.4): the confidence interval of that vertex is then cut to `[0, t_c]`,
/// otherwise to `[t_c, 1]`.
///
/// # Derivation (transversal crossings)
///
/// `s = Z·((A − P) × (B − P))` (eq. 3) is, up to a positive factor, the signed distance
/// between the edge's line and the axis line, and the edge crosses when `s` changes
/// sign. Let each end move on its own clock, `s(t_A, t_B) = a(t_A) × b(t_B)`. At the
/// crossing its rate is `s' = κ_A + κ_B` with the contributions of each end
///
/// ```text
/// κ_A = ∂s/∂t_A = Δa × b(t_c) = Z·(ΔA × (B(t_c) − P)),   κ_B = a(t_c) × Δb = Z·((A(t_c) − P) × ΔB).
/// ```
///
/// End A drives the edge toward the axis — from the side it was on before `t_c` to
/// zero — iff `κ_A` has the sign of `s'`: `κ_A (κ_A + κ_B) > 0`. Then holding A at
/// `t_A ≤ t_c` and the other end per its own answer (`t_B ≥ t_c` if it does not
/// drive) keeps `s` on the pre-crossing side to first order, which is what the
/// confidence intervals need: `s(t_c + δ_A, t_c + δ_B) ≈ κ_A δ_A + κ_B δ_B` with each
/// term of the pre-crossing sign. A still vertex (`ΔA = 0`) does not drive.
///
/// # The printed eq. 6
///
/// With `n = Z ∧ AB` the paper prints `(ΔA ∧ n)·(AP ∧ n)`, which expands to
/// `|n|² (ΔA·AP) − (ΔA·n)(AP·n)`: `|n|²` times the dot product of the parts of `ΔA`
/// and `AP` *in* the plane spanned by `Z` and the edge. The motion that matters is the
/// one *along* `n`, the common normal of the edge and the axis: a vertex moving
/// straight at the axis along `n` gets 0, and one sliding along its own edge gets a
/// sign. The intended test is with dot products, `(ΔA·n)(AP·n) > 0` — the motion along
/// the common normal points from the edge toward `P`. Since `b(t_c) = (1 − α) d(t_c)`,
/// `κ_A = −(1 − α) ΔA·n(t_c)` and the sign before the crossing is that of
/// `AP·n`, so the test above is the corrected eq. 6 with `n` taken at the crossing
/// instead of at the start; the two agree for an edge that translates.
///
/// # In-plane and along-axis crossings
///
/// There `s ≡ 0` and carries no side; the end is closer if its motion brings it nearer
/// the contact point `C = P + βZ`: `(X − C)·ΔX < 0` with `X` its start position.
pub fn closer_to_axis(
    edge: &MovingEdge,
    end: EdgeEnd,
    crossing: &Crossing,
    pose: &InstrumentPose,
) -> bool {
    let z = pose.axis.into_inner();
    match crossing.kind {
        CrossingKind::Transversal => {
            let a = edge.a_at(crossing.t) - pose.tip;
            let b = edge.b_at(crossing.t) - pose.tip;
            let kappa_a = z.dot(&edge.delta_a.cross(&b));
            let kappa_b = z.dot(&a.cross(&edge.delta_b));
            let rate = kappa_a + kappa_b;
            let kappa = match end {
                EdgeEnd::A => kappa_a,
                EdgeEnd::B => kappa_b,
            };
            kappa * rate > 0.0
        }
        CrossingKind::InPlane | CrossingKind::AlongAxis => {
            let contact = pose.point_at(crossing.beta);
            let (x, dx) = match end {
                EdgeEnd::A => (edge.a, edge.delta_a),
                EdgeEnd::B => (edge.b, edge.delta_b),
            };
            (x - contact).dot(&dx) < 0.0
        }
    }
}

/// 2D cross product `u₁v₂ − u₂v₁`.
fn cross(u: &Vector2<f64>, v: &Vector2<f64>) -> f64 {
    u.x * v.y - u.y * v.x
}

/// Real roots of `c₂t² + c₁t + c₀`, ascending, and how many. `c₂` is taken as zero if
/// `|c₂| ≤ zero2`, and then `c₁` if `|c₁| ≤ zero1` (no root). A double root is returned
/// twice. The stable form `q = −(c₁ + sign(c₁)√D)/2`, roots `q/c₂` and `c₀/q`, never
/// subtracts nearly equal numbers (the textbook `(−c₁ ± √D)/2c₂` does for one root when
/// `c₁² ≫ |4c₂c₀|`).
fn quadratic_roots(c2: f64, c1: f64, c0: f64, zero2: f64, zero1: f64) -> ([f64; 2], usize) {
    if c2.abs() <= zero2 {
        if c1.abs() <= zero1 {
            return ([0.0; 2], 0);
        }
        return ([-c0 / c1, 0.0], 1);
    }
    let disc = c1 * c1 - 4.0 * c2 * c0;
    if disc < 0.0 {
        return ([0.0; 2], 0);
    }
    let q = -0.5 * (c1 + disc.sqrt().copysign(c1));
    if q == 0.0 {
        // c₁ = 0 and D = 0, so c₀ = 0: s = c₂t², a double root at 0.
        return ([0.0; 2], 2);
    }
    let (r1, r2) = (q / c2, c0 / q);
    if r1 <= r2 {
        ([r1, r2], 2)
    } else {
        ([r2, r1], 2)
    }
}

/// The edge in the frame `(e₁, e₂, Z)` of the axis, with its origin at the tip:
/// shadows `a(t) = a0 + t·da`, `b(t) = b0 + t·db` and heights `z_a(t)`, `z_b(t)`.
struct Local {
    a0: Vector2<f64>,
    da: Vector2<f64>,
    b0: Vector2<f64>,
    db: Vector2<f64>,
    za0: f64,
    dza: f64,
    zb0: f64,
    dzb: f64,
    length: f64,
    tol: f64,
    /// `tol / max(|ΔA|, |ΔB|)`: within this fraction of the step no point of the edge
    /// moves by more than `tol`, so an instant closer than this to 0 is the start.
    t_eps: f64,
}

impl Local {
    fn new(edge: &MovingEdge, pose: &InstrumentPose, length: f64, tol: f64, t_eps: f64) -> Self {
        let z = pose.axis.into_inner();
        let e1 = perpendicular(&z).into_inner();
        let e2 = z.cross(&e1);
        let shadow = |v: Vector3<f64>| Vector2::new(v.dot(&e1), v.dot(&e2));
        let ra = edge.a - pose.tip;
        let rb = edge.b - pose.tip;
        Self {
            a0: shadow(ra),
            da: shadow(edge.delta_a),
            b0: shadow(rb),
            db: shadow(edge.delta_b),
            za0: ra.dot(&z),
            dza: edge.delta_a.dot(&z),
            zb0: rb.dot(&z),
            dzb: edge.delta_b.dot(&z),
            length,
            tol,
            t_eps,
        }
    }

    /// The instant `t` if it belongs to this step, `(0, 1]` up to `t_eps`: an instant
    /// within `t_eps` of 0 is the start (the previous step's end), one within `t_eps`
    /// past 1 is the end (clamped to 1).
    fn in_step(&self, t: f64) -> Option<f64> {
        (t > self.t_eps && t <= 1.0 + self.t_eps).then(|| t.min(1.0))
    }

    fn a(&self, t: f64) -> Vector2<f64> {
        self.a0 + self.da * t
    }

    fn b(&self, t: f64) -> Vector2<f64> {
        self.b0 + self.db * t
    }

    fn d(&self, t: f64) -> Vector2<f64> {
        self.b(t) - self.a(t)
    }

    /// `min over t ∈ [0, 1] of |d(t)|` (closest approach of a linear 2D path to 0).
    fn min_shadow_length(&self) -> f64 {
        let d0 = self.d(0.0);
        let dd = self.db - self.da;
        let dd2 = dd.norm_squared();
        let t = if dd2 > 0.0 {
            (-d0.dot(&dd) / dd2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (d0 + dd * t).norm()
    }

    /// The crossing at instant `t`, if the edge meets the axis segment then (within
    /// `tol`): the point of the edge nearest the axis line on the shadow, on the axis
    /// line within `tol`, at a height within `[−tol, l + tol]`.
    fn probe(&self, t: f64, kind: CrossingKind) -> Option<Crossing> {
        let (l, tol) = (self.length, self.tol);
        let a = self.a(t);
        let d = self.b(t) - a;
        let za = self.za0 + self.dza * t;
        let zb = self.zb0 + self.dzb * t;
        let alpha = if d.norm() > tol {
            (-a.dot(&d) / d.norm_squared()).clamp(0.0, 1.0)
        } else {
            // The shadow is a point: the edge is parallel to the axis at this instant.
            // Every point of the overlap of its height range with [0, l] touches; take
            // the middle of the overlap.
            let (lo, hi) = if za <= zb { (za, zb) } else { (zb, za) };
            let beta = 0.5 * (lo.clamp(0.0, l) + hi.clamp(0.0, l));
            if (zb - za).abs() > tol {
                ((beta - za) / (zb - za)).clamp(0.0, 1.0)
            } else {
                0.5
            }
        };
        if (a + d * alpha).norm() > tol {
            return None;
        }
        let beta = za + alpha * (zb - za);
        if beta < -tol || beta > l + tol {
            return None;
        }
        Some(Crossing {
            t,
            alpha,
            beta: beta.clamp(0.0, l),
            kind,
        })
    }

    /// Case 2 of [`edge_crossing`]: the edge stays parallel to the axis.
    fn along_axis(&self) -> Option<Crossing> {
        if self.probe(0.0, CrossingKind::AlongAxis).is_some() {
            return None;
        }
        let m0 = (self.a0 + self.b0) * 0.5;
        let dm = (self.da + self.db) * 0.5;
        let t = if dm.norm() <= self.tol {
            if m0.norm() > self.tol {
                return None;
            }
            // On the axis line all along: the first instant the height range
            // [min(z_a, z_b), max(z_a, z_b)] meets [0, l], i.e.
            // (z_a ≥ 0 or z_b ≥ 0) and (z_a ≤ l or z_b ≤ l).
            let mut first = f64::INFINITY;
            for (zi0, dzi) in [(self.za0, self.dza), (self.zb0, self.dzb)] {
                for (zj0, dzj) in [(self.za0, self.dza), (self.zb0, self.dzb)] {
                    let above_tip = times_at_least(zi0, dzi, 0.0);
                    let below_end = times_at_least(-zj0, -dzj, -self.length);
                    if let (Some(p), Some(q)) = (above_tip, below_end) {
                        let (lo, hi) = (p.0.max(q.0), p.1.min(q.1));
                        if lo <= hi {
                            first = first.min(lo);
                        }
                    }
                }
            }
            first
        } else {
            (-m0.dot(&dm) / dm.norm_squared()).clamp(0.0, 1.0)
        };
        self.probe(self.in_step(t)?, CrossingKind::AlongAxis)
    }

    /// Case 3 of [`edge_crossing`]: the edge stays in a plane containing the axis line.
    fn in_plane(&self) -> Option<Crossing> {
        if self.probe(0.0, CrossingKind::InPlane).is_some() {
            return None;
        }
        let mut first: Option<Crossing> = None;
        let ends = [
            (self.a0, self.da, self.za0, self.dza),
            (self.b0, self.db, self.zb0, self.dzb),
        ];
        for (x0, dx, z0, dz) in ends {
            let Some(t) = self.endpoint_event(x0, dx, z0, dz) else {
                continue;
            };
            if let Some(c) = self.probe(t, CrossingKind::InPlane)
                && first.is_none_or(|f| c.t < f.t)
            {
                first = Some(c);
            }
        }
        first
    }

    /// The instant in `(0, 1]` at which an endpoint (shadow `x0 + t·dx`, height
    /// `z0 + t·dz`) passes over the axis: its shadow's closest approach to the origin,
    /// if within `tol`; for an endpoint on the axis line all along, the instant its
    /// height enters `[0, l]`.
    fn endpoint_event(&self, x0: Vector2<f64>, dx: Vector2<f64>, z0: f64, dz: f64) -> Option<f64> {
        let tol = self.tol;
        if x0.norm() <= tol && (x0 + dx).norm() <= tol {
            let inside_at_start = (0.0..=self.length).contains(&z0);
            let t = if inside_at_start {
                return None;
            } else if z0 < 0.0 {
                -z0 / dz
            } else {
                (self.length - z0) / dz
            };
            return self.in_step(t);
        }
        let dd = dx.norm_squared();
        if dd == 0.0 {
            return None;
        }
        let t = (-x0.dot(&dx) / dd).clamp(0.0, 1.0);
        let t = self.in_step(t)?;
        ((x0 + dx * t).norm() <= tol).then_some(t)
    }
}

/// The instants `t ∈ [0, 1]` with `z0 + t·dz ≥ bound`, as an interval, if any.
fn times_at_least(z0: f64, dz: f64, bound: f64) -> Option<(f64, f64)> {
    if dz == 0.0 {
        return (z0 >= bound).then_some((0.0, 1.0));
    }
    let t = (bound - z0) / dz;
    let (lo, hi) = if dz > 0.0 {
        (t.max(0.0), 1.0)
    } else {
        (0.0, t.min(1.0))
    };
    (lo <= hi).then_some((lo, hi))
}

#[cfg(test)]
mod tests;
