//! A block of tissue indented by the instrument's tip, against Hertz: shared by the
//! Hertz test and the convergence bench.
//!
//! The instrument's hemispherical tip (radius `R` = its radius, 5 mm) indents a block
//! of tissue (80 × 80 mm, 60 mm deep, its bottom face fixed, no gravity, no friction,
//! the linear model: the setting of Hertz's theory) by `d`, on a grid graded to
//! `h₀` = 0.25 mm within 2.5 mm of the contact (the contact radius `a ≈ √(R d)` is
//! 1.6–3.2 mm for `d` = 0.5–2 mm) and growing by 1.4 per step outward
//! ([`kuhn_grid`]). Each depth is a static solve, repeated at the same pose until
//! the reaction changes by less than [`PASS_TOLERANCE`]: held vertices slide without
//! friction a step a pass, so the contact set settles over a dozen passes. The
//! references:
//! - Hertz: `F = 4/3 · E/(1−ν²) · √R · d^{3/2}` (half-space, `d ≪ R`);
//! - Sneddon's exact rigid sphere on a half-space (no `d ≪ R`):
//!   `d = (a/2) ln((R+a)/(R−a))`, `F = E/(2(1−ν²)) · ((a²+R²) ln((R+a)/(R−a)) − 2aR)`;
//! - Hertz with Dimitriadis et al.'s (2002) correction for a layer of thickness `h`
//!   bonded to a rigid base, `χ = √(R d)/h`:
//!   `F · (1 + 1.133χ + 1.283χ² + 0.769χ³ + 0.0975χ⁴)` (their ν = 0.5 fit). It is
//!   the closest of the three to this block, which is not a half-space: 60 mm deep
//!   and held at its base, it is 1–5% stiffer than one at these depths.

use laparo_server::engine::contact::InstrumentPose;
use laparo_server::engine::elastic::Formulation;
use laparo_server::engine::integrate::IntegratorKind;
use laparo_server::engine::mesh::TetMesh;
use laparo_server::engine::mesh::generate::{
    graded_lines, graded_lines_symmetric, kuhn_box, kuhn_grid,
};
use laparo_server::engine::scene::limits::max_cg_iterations;
use laparo_server::engine::scene::{BoxSpec, Scene};
use laparo_server::engine::simulation::Simulation;
use nalgebra::{Point3, Unit, Vector3};

pub const BLOCK_HALF_WIDTH: f64 = 0.04;
pub const BLOCK_DEPTH: f64 = 0.06;

/// Static passes at one depth stop when the reaction changes by less than this,
/// relative: a hundredth of the 10% the check allows.
pub const PASS_TOLERANCE: f64 = 1e-3;
/// Passes allowed at one depth; 12 to 19 are taken.
pub const MAX_PASSES: usize = 40;

/// The graded block: top face at `z = 0`, bottom at `−BLOCK_DEPTH`.
pub fn block() -> TetMesh {
    graded_block(0.25e-3, 2.5e-3, 1.4)
}

/// A block of the same size graded to cells of `h0` within `core` of the middle of
/// its top face, growing by `growth` a cell outward (m).
pub fn graded_block(h0: f64, core: f64, growth: f64) -> TetMesh {
    let x = graded_lines_symmetric(h0, core, growth, BLOCK_HALF_WIDTH);
    let (positions, tets) = kuhn_grid(&[x.clone(), x, depth_lines(h0, core, growth)]);
    TetMesh::from_tets(positions, tets).expect("the graded block is valid")
}

/// The block in uniform cubes of `h` (m; `h` divides its sides).
pub fn uniform_block(h: f64) -> TetMesh {
    let across = (2.0 * BLOCK_HALF_WIDTH / h).round() as usize;
    let down = (BLOCK_DEPTH / h).round() as usize;
    let (positions, tets) = kuhn_box(
        [across, across, down],
        [2.0 * BLOCK_HALF_WIDTH, 2.0 * BLOCK_HALF_WIDTH, BLOCK_DEPTH],
        [-BLOCK_HALF_WIDTH, -BLOCK_HALF_WIDTH, -BLOCK_DEPTH],
    );
    TetMesh::from_tets(positions, tets).expect("the uniform block is valid")
}

/// Heights of the grid lines from the block's base to its top face, graded to `h0`
/// within `core` of the top and growing by `growth` a cell downward (m).
pub fn depth_lines(h0: f64, core: f64, growth: f64) -> Vec<f64> {
    graded_lines(h0, core, growth, BLOCK_DEPTH)
        .iter()
        .rev()
        .map(|d| -d)
        .collect()
}

/// Lines from `from` to `to` every `h` (m; `h` divides the span).
pub fn uniform_lines(from: f64, to: f64, h: f64) -> Vec<f64> {
    let n = ((to - from) / h).round() as usize;
    (0..=n)
        .map(|i| from + (to - from) * i as f64 / n as f64)
        .collect()
}

/// A block of the same size for a shaft laid along x ([`press_shaft`]): 5 mm cells
/// along the shaft (the strip's length, which every mesh resolves), lines `across` it
/// (y) and `down` (z, from the base to the top face).
pub fn shaft_block(across: Vec<f64>, down: Vec<f64>) -> TetMesh {
    let along = uniform_lines(-BLOCK_HALF_WIDTH, BLOCK_HALF_WIDTH, 5e-3);
    let (positions, tets) = kuhn_grid(&[along, across, down]);
    TetMesh::from_tets(positions, tets).expect("the shaft's block is valid")
}

/// The shaft's block graded to 1 mm across the shaft and in depth within 7 mm of its
/// line of contact, growing by 1.4 a cell outward; 5 mm along it.
pub fn graded_shaft_block() -> TetMesh {
    shaft_block(
        graded_lines_symmetric(1e-3, 7e-3, 1.4, BLOCK_HALF_WIDTH),
        depth_lines(1e-3, 7e-3, 1.4),
    )
}

/// The block as a static scene with one frictionless instrument, its tip approached
/// from above (so the stage sees the surface from outside first).
pub fn block_scene() -> Simulation {
    block_scene_on(block(), true)
}

/// The block scene's setting (static, linear, frictionless, fixed at its base, the
/// tip above the top face) on another block of the same size, the tip's force scaled
/// to its footprint or not (`contact.footprint`).
pub fn block_scene_on(mesh: TetMesh, footprint: bool) -> Simulation {
    let mut scene = Scene::default_scene();
    scene.contact.footprint = footprint;
    scene.gravity = [0.0; 3];
    scene.material.model = Formulation::Linear;
    scene.mechanics.integrator = IntegratorKind::Static;
    scene.mechanics.cg_tolerance = 1e-8;
    scene.mechanics.cg_max_iterations = max_cg_iterations(mesh.vertex_count());
    scene.fixed.surface_only = false;
    scene.fixed.boxes = vec![BoxSpec {
        min: [-1.0, -1.0, -1.0],
        max: [1.0, 1.0, -BLOCK_DEPTH + 1e-6],
    }];
    scene.instruments.truncate(1);
    scene.instruments[0].friction = 0.0;
    let mut sim = scene.build_on(mesh).expect("the block scene builds");
    let r = sim.instruments[0].radius;
    sim.set_pose(0, Some(pose(r + 0.005)));
    sim.tick();
    sim
}

/// The shaft laid across the block's top face along −x, its tip 2 cm beyond the
/// block's +x side (so only the shaft touches), its underside at height `z`.
fn shaft_pose(r: f64, z: f64) -> InstrumentPose {
    InstrumentPose::new(
        Point3::new(BLOCK_HALF_WIDTH + 0.02, 0.0, z + r),
        Unit::new_normalize(-Vector3::x()),
    )
}

/// Presses the shaft `d` into the block's top face (its underside `d` below it) and
/// solves until the contact set settles, as [`indent`] does for the tip. A fresh
/// scene's shaft starts 5 mm above the face, so that the stage sees the surface from
/// outside first.
pub fn press_shaft(sim: &mut Simulation, d: f64) -> Indentation {
    let r = sim.instruments[0].radius;
    if sim.instruments[0].held.is_empty() {
        sim.set_pose(0, Some(shaft_pose(r, 0.005)));
        sim.tick();
    }
    settle_at(sim, shaft_pose(r, -d))
}

/// The tip straight down (axis +z), its segment end `P` at height `z`.
fn pose(z: f64) -> InstrumentPose {
    InstrumentPose::new(Point3::new(0.0, 0.0, z), Unit::new_normalize(Vector3::z()))
}

/// `E/(1−ν²)` of the block scene's material.
pub fn plane_strain_modulus(sim: &Simulation) -> f64 {
    let m = &sim.model.materials[0];
    m.young_modulus / (1.0 - m.poisson_ratio * m.poisson_ratio)
}

/// Hertz's force for a sphere of radius `r` pressed `d` into a half-space.
pub fn hertz(e_star: f64, r: f64, d: f64) -> f64 {
    4.0 / 3.0 * e_star * r.sqrt() * d.powf(1.5)
}

/// Sneddon's rigid sphere of radius `r` pressed `d` into a half-space: the contact
/// radius from `d = (a/2) ln((r+a)/(r−a))` (increasing in `a` on `(0, r)`, found by
/// bisection), then the force.
pub fn sneddon(e_star: f64, r: f64, d: f64) -> f64 {
    let depth = |a: f64| 0.5 * a * ((r + a) / (r - a)).ln();
    let (mut lo, mut hi) = (0.0, r * (1.0 - 1e-12));
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if depth(mid) < d { lo = mid } else { hi = mid }
    }
    let a = 0.5 * (lo + hi);
    0.5 * e_star * ((a * a + r * r) * ((r + a) / (r - a)).ln() - 2.0 * a * r)
}

/// Hertz corrected for a layer `BLOCK_DEPTH` thick bonded to a rigid base.
pub fn bonded_layer(e_star: f64, r: f64, d: f64) -> f64 {
    let chi = (r * d).sqrt() / BLOCK_DEPTH;
    hertz(e_star, r, d)
        * (1.0 + 1.133 * chi + 1.283 * chi.powi(2) + 0.769 * chi.powi(3) + 0.0975 * chi.powi(4))
}

/// One indentation's outcome.
pub struct Indentation {
    /// The tissue's force on the instrument along +z, N.
    pub force: f64,
    pub held: usize,
    pub passes: usize,
    /// The last pass's relative change of the force.
    pub change: f64,
    pub cg_iterations: u64,
}

/// A press of the block scene's instrument `d` deep (m), settled: [`indent`] for the
/// tip, [`press_shaft`] for the shaft.
pub type Press = fn(&mut Simulation, f64) -> Indentation;

/// A fresh block scene on `mesh` (its force scaled to the footprint or not) pressed
/// by `press` to each of `depths` in turn: the outcomes, in order.
pub fn press_along(
    mesh: TetMesh,
    footprint: bool,
    press: Press,
    depths: &[f64],
) -> Vec<Indentation> {
    let mut sim = block_scene_on(mesh, footprint);
    depths.iter().map(|&d| press(&mut sim, d)).collect()
}

/// Indents the block `d` deep and solves until the contact set settles.
pub fn indent(sim: &mut Simulation, d: f64) -> Indentation {
    let r = sim.instruments[0].radius;
    settle_at(sim, pose(r - d))
}

/// Static passes at `pose` until the reaction along +z changes by less than
/// [`PASS_TOLERANCE`] (or [`MAX_PASSES`] are spent).
fn settle_at(sim: &mut Simulation, pose: InstrumentPose) -> Indentation {
    let (mut passes, mut cg_iterations) = (0, 0u64);
    let (mut last, mut change) = (f64::NAN, f64::NAN);
    for _ in 0..MAX_PASSES {
        sim.set_pose(0, Some(pose));
        cg_iterations += u64::from(sim.tick().cg_iterations);
        passes += 1;
        let f = sim.instruments[0].report.reaction.z;
        change = (f - last).abs() / f.abs();
        if change <= PASS_TOLERANCE {
            break;
        }
        last = f;
    }
    Indentation {
        force: sim.instruments[0].report.reaction.z,
        held: sim.instruments[0].held.len(),
        passes,
        change,
        cg_iterations,
    }
}
