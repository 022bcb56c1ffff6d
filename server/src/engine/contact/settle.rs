//! Settling the tissue around the stage's corrections, so that a first contact does not
//! spike.
//!
//! The contact steps run after the elastic step and move surface vertices out of the
//! instrument: a jump `δ` of position, not a motion. Left alone, a vertex jumped by `δ`
//! while its neighbours stay where the elastic step put them carries the reaction of
//! that one vertex displaced against fixed neighbours, `K_ii δ`, far stiffer than the
//! tissue. A tip arriving 1 mm into SOFA's liver in one tick reported 2.7× the steady
//! force at that depth at ν = 0.3 and 49× at ν = 0.499, at any rate and stiffness
//! (linear elasticity: the ratio is the same for any jump and any E); the next tick
//! the elastic step relaxed the neighbours and the force fell back. With the explicit
//! step the neighbours, hit by the jump, rang and pulled the held vertex away: at
//! 30 Hz, 10 MPa, ν = 0.499 it was let go and retaken, the force between 0 and 42 kN
//! around a steady 0.7 kN (`tests/contact_first_touch.rs`).
//!
//! So the free tissue near the jumped vertices is corrected with them, statically: the
//! displacement `Δu` of the free nodes that minimises the elastic energy with the
//! jumps imposed, `K_FF Δu_F = −K_FJ δ_J` (`J` the jumped vertices, `F` the free
//! nodes), solved on the free nodes within [`RINGS`] rings of the jumped ones (more
//! for a jump past the instrument's radius, see the contact stage's `SETTLE_RINGS`;
//! the rest kept), by conjugate gradients preconditioned with the inverse diagonal
//! blocks `K_ii⁻¹`. That is what the elastic step would do with the jumps imposed at
//! a low rate; as a correction of position it adds no velocity. Its region cuts the
//! decay of the displacement (as `a/ρ` from a patch of size `a`) at `ρ = L`, which
//! stiffens the response by about `1/(1 − a/L)`: with three rings around a held
//! vertex whose patch is one ring, 1.5×, within the 2× of the steady force;
//! measured on SOFA's liver, 1.07–1.08× at ν = 0.3 and 1.28× (corotational) to
//! 1.40× (linear) at ν = 0.499 (nearly incompressible tissue needs room to bulge,
//! and the region's edge takes some of it), against 2.7× and 49× without.
//!
//! **Large jumps on the corotational model.** A jump past the instrument's radius
//! deforms the tissue far out of the tangent's reach: the tissue turns, and the
//! linear correction, which cannot see the turn, leaves the corotational model's own
//! forces out of balance around it. An instrument whose first pose is 2 cm inside
//! SOFA's liver reported 1.55 N on its first tick against 0.55 N steady, where the
//! linear model, settled exactly the same way, gave 0.52 N against 0.61 N; at
//! E = 100 kPa, ν = 0.49, 264 N against 16.6 N. So for the corotational model, when
//! the largest jump passes a radius, up to [`NEWTON_PASSES`] Newton passes follow
//! the linear one (unless the contact stage scaled a jump down, see there):
//! `K̂(x) Δu_F = f_F⁰ − f_F(x)` on the region, `f(x)` the model's
//! force with every rotation extracted afresh, `f_F⁰` its value before the jumps,
//! and `K̂(x)` the corotational tangent with the rotations of the elements around
//! the region extracted afresh at `x` and held fixed, applied element by element
//! ([`Element::add_tangent_product`]). So what the jumps change in the force on the
//! free nodes is brought back to zero, and the force the tissue already carried, of
//! its weight and motion, is left as it was. The tick's assembled tangent, from the
//! rotations before the jumps, does not do: at ν = 0.49 its first Newton pass raised
//! the residual 16-fold. A pass that raises `‖f_F⁰ − f_F(x)‖` all the same is undone
//! and ends them.
//!
//! The fresh tangent `K̂(x)` holds nothing of the energy's twist modes, whose
//! stiffness grows without bound in an element the jumps press through its flat
//! state (see [`twist_tangent`]); each pass therefore adds the positive twists of
//! the elements around the region whose twist may pass a tenth of `λ + 2μ`, as the
//! implicit step does.
//!
//! Figures (the default scene's tip posed 2 cm into the free front, E = 100 kPa, or
//! 4.5 kPa at ν = 0.499, 60 Hz, implicit; residual after the linear settling and
//! after each pass, in N, without → with the twists, and the first tick's force):
//! ν = 0.3, 14.1 → 1.00 → 0.11 and 14.1 → 1.08 → 0.14, 4.49 → 4.51 N; ν = 0.45,
//! 56.5 → 6.5 → 0.95 and 56.5 → 6.2 → 1.3, 5.53 → 5.85 N; ν = 0.49,
//! 415 → 177 → 33 and 415 → 74 → 36, 41.9 → 34.0 N (22 N at 1 s); ν = 0.499,
//! 571 → 350 → 264 and 571 → 61 → 39, 106 → 23.6 N (2.8 N at 1 s): nearly
//! incompressible tissue, with the few vertices the tip's coarse triangle puts under
//! it held, has little room to give. Five passes bring that first tick to 12.3 N,
//! but the ticks after it then rose (at 100 kPa, ν = 0.49, the largest tick from
//! 69 to 156 N), so two are kept.
//!
//! [`Element::add_tangent_product`]: crate::engine::elastic::Element::add_tangent_product
//! [`twist_tangent`]: crate::engine::elastic::twist_tangent
//!
//! `K` is the stiffness the elastic step just moved the liver with: the linear one, or
//! for the corotational model the tangent `K̂ = Σ_e R_e K_e R_eᵀ` of the tick (the
//! rotations the step used), so that the correction is the increment the step itself
//! would have made; the linear `K` on turned tissue would count the turn as strain.
//!
//! On unless the scene turns it off (`contact.settle = false`). With it, a hand
//! pressing on the coarse liver keeps hold of the tissue it touches, where without it
//! the first-contact spike (83 N where the tissue gives 16 N, and 28° off) threw the
//! tip back to rest on the approach plane holding nothing; with either force model
//! the hand then comes to rest on the tissue, pulled 2, 5 or 8 mm past the surface of
//! 1 or 10 MPa tissue (`tests/haptics.rs`). Held tissue brings the calibrated force
//! model's drag with it, which is rendered at haptic rate for that reason (see
//! `engine/local_model`): sampled at the mechanics rate, as a plane tilted along the
//! reaction, it put energy into the hand.
//!
//! **A held set that pulls.** The contact steps choose what an instrument holds by
//! geometry: every vertex they moved. Around a first pose well inside the tissue,
//! some of those the settled tissue pulls away from the instrument (a vertex laid
//! on the tip's plane beside the shaft, drawn back into the tissue), and the held
//! vertices pull against each other: at E = 100 kPa, ν = 0.49, a tip posed 1 cm
//! into the free front held six vertices with 8.5–29.7 N each and 3.7 N in all.
//! The next tick's release let three go and the other three reported their 52 N,
//! against 11 N steady (162 N against 26 N at 3 cm; 17.8 N against 1.2 N at
//! ν = 0.499). So after the settling, the stage lets go of what the tissue pulls
//! away, by the hold's own law, and this module relaxes the tissue around it
//! ([`Settle::relax`]): a Newton iteration on the region around the released
//! vertices that takes away the force their instrument gave them and keeps the
//! force on the other free nodes, as the settling keeps it. Then the released
//! vertices' neighbours carry what they would carry without them, and the stage
//! looks again, a few rounds (`stage::settling::RELEASE_ROUNDS`). That tick then reported
//! 9.2 N and the next ones 11.0–11.3 N; the first ticks of a pose 3 cm in, at
//! ν = 0.49, at most 72.9 N against 31.7 N (a later retake), where the second had
//! given 162 N. Only ticks whose largest settled jump passes the instrument's
//! radius are looked at again, the jumps of a pose or a jab, where the held set is
//! furthest from what the tissue would hold: looked at after every settling, the
//! held sets of two instruments pushed 22 cm through the liver over a second
//! (`tests/contact_crossing.rs`) came out otherwise, and the second instrument's
//! held vertices were still sliding by friction 3 s in (0.92 N, changing by 0.11%
//! a tick, where they otherwise come to rest at 0.64 N). Where the tissue left by
//! the settling is itself far from the elastic step's (ν = 0.49, 2 cm: the held set
//! does not change, and the force falls from 53 N to 9 N over four ticks, 22 N at
//! 1 s), this does not help.
//!
//! **A vertex taken back is not settled.** While a held shaft's friction slides close
//! in on the cone, a vertex at the edge of the held patch can be let go (pulled away)
//! and pushed out again on alternate ticks, each time jumping by 1 µm–0.54 mm. Settled
//! on every retake, the tissue around it moved by a different approximate correction
//! each time, and the alternation lasted: the held force still varied by 2.8% after
//! 200 static ticks where without settling it is steady to the last digit from tick
//! 76 (`tests/contact_friction.rs`, μ = 0.5). Such a jump is the contact's hesitation
//! at the edge of what it holds, not a first touch: a vertex let go this tick or the
//! one before is left out of the jumps ([`Settle::taken_back`]), and the held shaft
//! then reaches the same equilibrium, to the last digit, with or without settling.
//! A retake after a lost hold is left out too. A tip posed 3 cm into the free front
//! once lost its hold on its second tick: the relaxation after its first let go the
//! vertices beside the shaft turned the tip's triangle to 6.6 mm from the tip, past
//! the tip's reach, then 1.25 r (`hold::TIP_REACH`). The third tick took the tissue
//! back 8–26 mm along the axis, unsettled: 3.69 N against 0.93 N steady (linear
//! model), 72.8 N against 25.3 N (corotational, 100 kPa, ν = 0.45). Settling such a
//! spring-back as a first touch mended the retake but not the tick with no force
//! before it; a reach of 1.5 r keeps the hold, and both go.

use nalgebra::{Matrix3, Point3, Vector3};

use crate::engine::elastic::corotational::negated_force_on_with;
use crate::engine::elastic::twist;
use crate::engine::elastic::twist_tangent::{self, TwistTangent};
use crate::engine::elastic::{BlockMatrix, ElasticModel, Formulation};

/// Rings of neighbours of the jumped vertices whose free nodes are settled.
pub const RINGS: usize = 3;
/// Conjugate-gradient iterations at most; the region is a few hundred nodes, whose
/// condition number (about `(L/h)²/(1 − 2ν)`) CG brings down by `1e-3` in far fewer
/// for ν ≤ 0.49; at ν = 0.499 the bound stops it where it is, each iterate being an
/// improvement of the energy.
pub(super) const MAX_ITERATIONS: usize = 60;
/// Relative residual at which the settling stops: the force it leaves is a thousandth
/// of the jump's unrelaxed one.
const TOLERANCE: f64 = 1e-3;
/// Newton passes after the linear settling, for the corotational model and jumps past
/// a radius (see the module documentation), each a CG solve of at most
/// [`MAX_ITERATIONS`] iterations (an inexact Newton step: more changed none of the
/// figures) after one evaluation of the model's force and rotations on the region.
/// Two take the residual down 10–100-fold for ν ≤ 0.49 and 15-fold at ν = 0.499;
/// more lowered the first tick but raised the ticks after (see the module notes).
const NEWTON_PASSES: usize = 2;

/// Halvings of a Newton pass of [`Settle::relax`] that raised the residual before it
/// is undone whole. The relaxation's first pass on the fresh tangent overshoots:
/// at E = 100 kPa, ν = 0.49, a tip posed 1 cm into the free front, it raised the
/// residual from 98 to 146 N, so that the relaxation did nothing and the two held
/// vertices left carried 52 N against 11 N steady; halved once, it fell to 46 N and
/// the next pass to 36 N, and the tick reported 9.2 N. (The settling of the jumps
/// keeps its passes whole: its figures are tuned to them, see the module notes.)
const BACKTRACK: usize = 3;

/// Buffers of the settling, allocated once for the mesh.
#[derive(Debug)]
pub(super) struct Settle {
    /// The free nodes being settled.
    region: Vec<u32>,
    /// Nodes reached by the search (free or not), ring after ring.
    reached: Vec<u32>,
    mark: Vec<u32>,
    stamp: u32,
    /// The jump of each jumped vertex (zero elsewhere).
    pub jump: Vec<Vector3<f64>>,
    /// Contact ticks counted by the stage ([`Settle::next_tick`]), and the tick at which
    /// each vertex was last let go by an instrument (0: never).
    tick: u64,
    let_go: Vec<u64>,
    du: Vec<Vector3<f64>>,
    r: Vec<Vector3<f64>>,
    z: Vec<Vector3<f64>>,
    p: Vec<Vector3<f64>>,
    q: Vec<Vector3<f64>>,
    inv_diag: Vec<Matrix3<f64>>,
    /// The model's force on each region node before the jumps (Newton passes).
    force: Vec<Vector3<f64>>,
    /// Where the jumped vertices are while that force is taken.
    swap: Vec<Point3<f64>>,
    /// The elements around the region, their rotations at the last Newton pass, and
    /// which were gathered at this one (`element_stamp`).
    elements: Vec<u32>,
    rotation: Vec<Matrix3<f64>>,
    element_mark: Vec<u32>,
    element_stamp: u32,
    /// The positive twist modes of the strongly deformed elements around the region
    /// at the last Newton pass, added to its tangent.
    twist: TwistTangent,
}

/// Whether the region's force at the current positions is already in `Settle::q`
/// (and, corotational, its elements' rotations in `Settle::rotation`).
#[derive(Clone, Copy, PartialEq)]
enum Evaluated {
    Here,
    Not,
}

/// The stiffness a CG solve of the settling applies.
#[derive(Clone, Copy)]
enum Tangent<'a> {
    /// The tick's `K̂` (or `K`), assembled.
    Assembled(&'a BlockMatrix),
    /// The corotational tangent with the rotations of [`Settle::rotation`], element
    /// by element.
    Fresh(&'a ElasticModel),
}

impl Settle {
    /// Buffers for a mesh of `n` vertices and `elements` corotational elements.
    pub fn new(n: usize, elements: usize) -> Self {
        Settle {
            region: Vec::with_capacity(n),
            reached: Vec::with_capacity(n),
            mark: vec![0; n],
            stamp: 0,
            jump: vec![Vector3::zeros(); n],
            tick: 1,
            let_go: vec![0; n],
            du: vec![Vector3::zeros(); n],
            r: vec![Vector3::zeros(); n],
            z: vec![Vector3::zeros(); n],
            p: vec![Vector3::zeros(); n],
            q: vec![Vector3::zeros(); n],
            inv_diag: vec![Matrix3::zeros(); n],
            force: vec![Vector3::zeros(); n],
            swap: vec![Point3::origin(); n],
            elements: Vec::with_capacity(elements),
            rotation: vec![Matrix3::identity(); elements],
            element_mark: vec![0; elements],
            element_stamp: 0,
            twist: TwistTangent::new(elements),
        }
    }

    /// Counts a contact tick.
    pub fn next_tick(&mut self) {
        self.tick += 1;
    }

    /// Notes that vertex `v` was let go this tick.
    pub fn let_go(&mut self, v: u32) {
        self.let_go[v as usize] = self.tick;
    }

    /// Whether vertex `v` was let go this tick or the one before: taken back now, its
    /// jump is the contact's own hesitation at the edge of a held patch, not a first
    /// touch (see the module documentation).
    pub fn taken_back(&self, v: u32) -> bool {
        self.tick - self.let_go[v as usize] <= 1
    }

    /// Settles the free nodes (not `imposed`) within `rings` rings of the vertices
    /// `jumped` (at least [`RINGS`]), whose jumps are in `self.jump`, with the
    /// stiffness `k`, and moves them in `x`: at most [`MAX_ITERATIONS`] CG iterations
    /// for every [`RINGS`] rings. With `nonlinear`, the model and where each jumped
    /// vertex was before its jump, the Newton passes follow (see the module
    /// documentation); the jumped vertices are put back where `x` had them. Clears the
    /// jumps. Returns the largest move of a free node, m.
    pub fn settle(
        &mut self,
        k: &BlockMatrix,
        imposed: &[bool],
        jumped: &[u32],
        rings: usize,
        nonlinear: Option<(&ElasticModel, &[Point3<f64>])>,
        x: &mut [Point3<f64>],
    ) -> f64 {
        let rings = rings.max(RINGS);
        self.gather_region(k, imposed, jumped, rings);
        // The model's own force on the region before the jumps, which the Newton
        // passes below restore, from the elements around the region.
        if let Some((model, before)) = nonlinear {
            self.gather_elements(model);
            for &v in jumped {
                self.swap[v as usize] = x[v as usize];
                x[v as usize] = before[v as usize];
            }
            self.negated_force(model, x);
            for &i in &self.region {
                self.force[i as usize] = self.q[i as usize];
            }
            // The jumps as settled.
            for &v in jumped {
                x[v as usize] += self.jump[v as usize];
            }
        }
        // b = −K_FJ δ_J on the region; the jumps are zero elsewhere.
        for idx in 0..self.region.len() {
            let i = self.region[idx] as usize;
            self.r[i] = -k.row_times(i, &self.jump);
        }
        self.diagonal(k);
        let iterations = MAX_ITERATIONS * rings.div_ceil(RINGS);
        let mut largest = self.solve(Tangent::Assembled(k), iterations, x);
        if let Some((model, _)) = nonlinear {
            let passes = (NEWTON_PASSES, MAX_ITERATIONS, 0);
            largest = largest.max(self.newton(model, k, passes, Evaluated::Not, x));
            for &v in jumped {
                x[v as usize] = self.swap[v as usize];
            }
        }
        for &v in jumped {
            self.jump[v as usize] = Vector3::zeros();
        }
        largest
    }

    /// Relaxes the free nodes within `rings` rings (at least [`RINGS`]) of the
    /// vertices `released`, let go after the settling because the tissue pulls them
    /// away from the instrument (see the module documentation's "A held set that
    /// pulls"), and moves them in `x`. Each released vertex loses the force its
    /// instrument gave it: the model's force on it, `f_v(x)`, is to vanish (its share
    /// of the tissue's weight and inertia, a hundredth of a newton on the default
    /// liver, is neglected), and the force on the region's other free nodes to stay
    /// what it is. That is the Newton iteration `K Δu_F = f⁰_F − f_F(x)` of the
    /// settling with `f⁰_v = 0` on the released vertices: one exact solve for the
    /// linear model (`k` is its `K`), [`NEWTON_PASSES`] passes on the fresh tangent
    /// for the corotational one.
    pub fn relax(
        &mut self,
        k: &BlockMatrix,
        imposed: &[bool],
        released: &[u32],
        rings: usize,
        model: &ElasticModel,
        x: &mut [Point3<f64>],
    ) {
        let rings = rings.max(RINGS);
        self.gather_region(k, imposed, released, rings);
        if model.formulation == Formulation::Corotational {
            self.gather_elements(model);
        }
        self.region_force(model, x);
        for &i in &self.region {
            self.force[i as usize] = self.q[i as usize];
        }
        for &v in released {
            self.force[v as usize] = Vector3::zeros();
        }
        self.diagonal(k);
        let passes = match model.formulation {
            Formulation::Linear => 1,
            Formulation::Corotational => NEWTON_PASSES,
        };
        let iterations = MAX_ITERATIONS * rings.div_ceil(RINGS);
        // `q` (and, corotational, `rotation`) still hold the force at `x`.
        let from = Evaluated::Here;
        self.newton(model, k, (passes, iterations, BACKTRACK), from, x);
    }

    /// The region: the free nodes (not `imposed`) among `seeds` and within `rings`
    /// rings of them, through the rows of `k`.
    fn gather_region(&mut self, k: &BlockMatrix, imposed: &[bool], seeds: &[u32], rings: usize) {
        self.stamp = self.stamp.wrapping_add(1);
        self.region.clear();
        self.reached.clear();
        for &v in seeds {
            if self.mark[v as usize] != self.stamp {
                self.mark[v as usize] = self.stamp;
                self.reached.push(v);
                if !imposed[v as usize] {
                    self.region.push(v);
                }
            }
        }
        let mut ring = 0..self.reached.len();
        for _ in 0..rings {
            let end = self.reached.len();
            for idx in ring.clone() {
                let i = self.reached[idx] as usize;
                k.for_each_in_row(i, |j, _| {
                    if self.mark[j] != self.stamp {
                        self.mark[j] = self.stamp;
                        self.reached.push(j as u32);
                        if !imposed[j] {
                            self.region.push(j as u32);
                        }
                    }
                });
            }
            ring = end..self.reached.len();
        }
    }

    /// The corotational elements around the region, for its force and fresh tangent.
    fn gather_elements(&mut self, model: &ElasticModel) {
        self.elements.clear();
        self.element_stamp = self.element_stamp.wrapping_add(1);
        for &i in &self.region {
            for &e in model.vertex_elements.of(i) {
                if self.element_mark[e as usize] != self.element_stamp {
                    self.element_mark[e as usize] = self.element_stamp;
                    self.elements.push(e);
                }
            }
        }
    }

    /// The preconditioner: the inverse diagonal blocks `K_ii⁻¹` of `k` on the region.
    fn diagonal(&mut self, k: &BlockMatrix) {
        for idx in 0..self.region.len() {
            let i = self.region[idx] as usize;
            let mut d = Matrix3::zeros();
            k.for_each_in_row(i, |j, kij| {
                if j == i {
                    d = *kij;
                }
            });
            self.inv_diag[i] = d.try_inverse().unwrap_or_else(Matrix3::zeros);
        }
    }

    /// Up to `passes` Newton passes `K Δu_F = f⁰_F − f_F(x)` on the region, `f⁰` in
    /// `force`, each a CG solve of at most `iterations` iterations: for the
    /// corotational model on its fresh tangent with the twists (see the module
    /// documentation), for the linear one on `k`. A pass that raises the residual is
    /// halved, up to `backtrack` times, then undone, and ends them. `from` says
    /// whether the region's force at `x` is already in `q`. Returns the largest move
    /// of a free node, m.
    fn newton(
        &mut self,
        model: &ElasticModel,
        k: &BlockMatrix,
        (passes, iterations, backtrack): (usize, usize, usize),
        from: Evaluated,
        x: &mut [Point3<f64>],
    ) -> f64 {
        let mut largest: f64 = 0.0;
        let mut last = f64::INFINITY;
        let mut pass = 0;
        let mut halvings = 0;
        let mut evaluated = from == Evaluated::Here;
        loop {
            // The force here (and, corotational, the rotations for the tangent here).
            if !evaluated {
                self.region_force(model, x);
            }
            evaluated = false;
            let mut residual = 0.0;
            for &i in &self.region {
                let i = i as usize;
                self.r[i] = self.force[i] - self.q[i];
                residual += self.r[i].norm_squared();
            }
            if residual > last {
                // The pass made things worse (the tangent, its rotations held
                // fixed, is too far from the tissue's): half of it is taken back,
                // up to `backtrack` times, then the rest, and no more.
                let undo = if halvings < backtrack { 0.5 } else { 1.0 };
                for &i in &self.region {
                    let i = i as usize;
                    self.du[i] *= undo;
                    x[i] -= self.du[i];
                }
                if halvings < backtrack {
                    halvings += 1;
                    continue;
                }
                break;
            }
            if pass == passes {
                break;
            }
            pass += 1;
            halvings = 0;
            last = residual;
            let tangent = match model.formulation {
                Formulation::Corotational => {
                    self.twist_modes(model, x);
                    Tangent::Fresh(model)
                }
                Formulation::Linear => Tangent::Assembled(k),
            };
            largest = largest.max(self.solve(tangent, iterations, x));
        }
        largest
    }

    /// The model's negated elastic force at `x` on the region's nodes, in `q`: for the
    /// corotational model by [`negated_force`](Self::negated_force), for the linear
    /// one `(K (x − x₀))_i`.
    fn region_force(&mut self, model: &ElasticModel, x: &[Point3<f64>]) {
        match model.formulation {
            Formulation::Corotational => self.negated_force(model, x),
            Formulation::Linear => {
                for &i in &self.region {
                    self.q[i as usize] = model.negated_elastic_force_on(i, x);
                }
            }
        }
    }

    /// The model's negated elastic force at `x` on the region's nodes, in `q` (whose
    /// other entries it leaves as they were): each element around the region rotated
    /// once, afresh, its rotation kept in `rotation` for the tangent; each node's sum
    /// taken as [`ElasticModel::negated_elastic_force_on`] takes it, to the last bit.
    fn negated_force(&mut self, model: &ElasticModel, x: &[Point3<f64>]) {
        for &e in &self.elements {
            self.rotation[e as usize] = model.elements[e as usize].rotation_at(x);
        }
        for &i in &self.region {
            self.q[i as usize] =
                negated_force_on_with(&model.elements, &model.vertex_elements, i, |e| {
                    let element = &model.elements[e as usize];
                    element
                        .force_matrix(&self.rotation[e as usize], &element.deformation_gradient(x))
                });
        }
    }

    /// The positive twist modes at `x` of the elements around the region whose
    /// twist may pass [`twist_tangent::FROM`], with the rotations of the last
    /// [`negated_force`](Self::negated_force), for the Newton passes' tangent.
    fn twist_modes(&mut self, model: &ElasticModel, x: &[Point3<f64>]) {
        self.twist.clear();
        for &e in &self.elements {
            let (element, r) = (&model.elements[e as usize], &self.rotation[e as usize]);
            let f = element.deformation_gradient(x);
            if twist_tangent::strongly_deformed(element, &twist::stretch(r, &f)) {
                self.twist.add(element, r, &f);
            }
        }
    }

    /// Solves `K_FF Δu_F = b` on the region, `b` in `r`, by at most `iterations` CG
    /// iterations preconditioned with `inv_diag`, and adds `Δu` to `x`. Returns the
    /// largest move, m.
    fn solve(&mut self, k: Tangent, iterations: usize, x: &mut [Point3<f64>]) -> f64 {
        let mut rr = 0.0;
        for &i in &self.region {
            let i = i as usize;
            self.du[i] = Vector3::zeros();
            self.z[i] = self.inv_diag[i] * self.r[i];
            self.p[i] = self.z[i];
            rr += self.r[i].norm_squared();
        }
        let stop = TOLERANCE * TOLERANCE * rr;
        let mut rz: f64 = self
            .region
            .iter()
            .map(|&i| self.r[i as usize].dot(&self.z[i as usize]))
            .sum();
        for _ in 0..iterations {
            if rr <= stop || rz <= 0.0 {
                break;
            }
            // q = K_FF p: p is zero outside the region (cleared after every use).
            match k {
                Tangent::Assembled(k) => {
                    for idx in 0..self.region.len() {
                        let i = self.region[idx] as usize;
                        self.q[i] = k.row_times(i, &self.p);
                    }
                }
                Tangent::Fresh(model) => {
                    for &e in &self.elements {
                        for v in model.elements[e as usize].tet {
                            self.q[v as usize] = Vector3::zeros();
                        }
                    }
                    for &e in &self.elements {
                        model.elements[e as usize].add_tangent_product(
                            &self.rotation[e as usize],
                            &self.p,
                            &mut self.q,
                        );
                    }
                    self.twist.mul_add(1.0, &self.p, &mut self.q);
                }
            }
            let mut pq = 0.0;
            for &i in &self.region {
                pq += self.p[i as usize].dot(&self.q[i as usize]);
            }
            if pq <= 0.0 {
                break;
            }
            let alpha = rz / pq;
            rr = 0.0;
            let mut rz_new = 0.0;
            for &i in &self.region {
                let i = i as usize;
                self.du[i] += self.p[i] * alpha;
                self.r[i] -= self.q[i] * alpha;
                self.z[i] = self.inv_diag[i] * self.r[i];
                rr += self.r[i].norm_squared();
                rz_new += self.r[i].dot(&self.z[i]);
            }
            let beta = rz_new / rz;
            rz = rz_new;
            for &i in &self.region {
                let i = i as usize;
                self.p[i] = self.z[i] + self.p[i] * beta;
            }
        }
        let mut largest: f64 = 0.0;
        for &i in &self.region {
            let i = i as usize;
            x[i] += self.du[i];
            largest = largest.max(self.du[i].norm());
            self.p[i] = Vector3::zeros();
        }
        largest
    }
}

#[cfg(test)]
mod tests;
