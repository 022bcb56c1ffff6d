//! Convergence of the instrument's force with mesh refinement: does a press feel the
//! same on every liver?
//!
//! `cargo bench -p laparo-server --bench convergence [-- --with-300k]`
//!
//! The default scene (liver at 0.19 m held at its upper face and underside, gravity,
//! 60 Hz implicit ticks, its material and elastic model) on SOFA's liver and the
//! liver-5k/20k/80k series (and liver-300k with `--with-300k`: about a minute a case),
//! settled under gravity for 1 s, then pressed on its free front (+z) face by
//! instrument 0 alone. Three gestures, each ramped in over 0.5 s (30 ticks) from 1 cm
//! outside and held still for 1 s (60 ticks):
//! - **tip 8 mm**, **tip 15 mm**: axis +z (the tip points into −z) through the front
//!   point ([`front_point`]: the front-face vertex nearest the middle); the
//!   instrument's foremost point `P − r Z` ends `d` past that vertex, so the tissue is
//!   indented by `d`;
//! - **shaft 10 mm**: the axis along −x, lying across the front face level with the
//!   front point, the tip 6 cm beyond it in +x; the shaft's underside ends `d` past
//!   the front point.
//!
//! For each mesh and force model (the paper's `geometric` and the `calibrated` one),
//! at the end of the hold:
//! - `reaction`: |Σ −(K u)_i| over the vertices the instrument holds, the elastic
//!   model's own answer (the force model does not feed back into the tissue, so it is
//!   the same for both force models);
//! - `rendered`: |F| of the local model at the pose, what the device is sent;
//! - `angle`: between the rendered force and the reaction, degrees;
//! - `held`: vertices held;
//! - `spread`: (max − min)/max of |rendered| over the last 0.5 s of the hold.
//!
//! Then, per gesture and force model, the spread across meshes the issue bounds: the
//! refined livers (5k, 20k, 80k) should lie within ±10% of their mean, SOFA's coarse
//! liver within ±25% of it. Numbers only: the bench asserts nothing, it reports.
//!
//! # Hertz
//!
//! Then the instrument's hemispherical tip (radius `R` = its radius, 5 mm) indents a
//! block of tissue (80 × 80 mm, 60 mm deep, its bottom face fixed, no gravity, no
//! friction, the linear model: the setting of Hertz's theory) by `d` = 0.5, 1, 1.5 and
//! 2 mm, on a grid graded to `h₀` = 0.35 mm within 3.5 mm of the contact (the contact
//! radius `a ≈ √(R d)` is 1.6–3.2 mm) and growing by 1.4 per step outward
//! ([`kuhn_grid`]). Each depth is a static solve, repeated at the same pose until the
//! contact set stops changing. The reaction is compared with:
//! - Hertz: `F = 4/3 · E/(1−ν²) · √R · d^{3/2}` (half-space, `d ≪ R`);
//! - Sneddon's exact rigid sphere on a half-space (no `d ≪ R`):
//!   `d = (a/2) ln((R+a)/(R−a))`, `F = E/(2(1−ν²)) · ((a²+R²) ln((R+a)/(R−a)) − 2aR)`;
//! - Hertz with Dimitriadis et al.'s (2002) correction for a layer of thickness `h`
//!   bonded to a rigid base, `χ = √(R d)/h`:
//!   `F · (1 + 1.133χ + 1.283χ² + 0.769χ³ + 0.0975χ⁴)` (their ν = 0.5 fit); the block's
//!   free sides make it softer than their infinite layer, so the truth for this block
//!   lies between the half-space and this.
//!
//! Flags: `--gestures-only`, `--hertz-only`, `--with-300k`.

mod common;

/// The contact tests' gestures; the bench uses `front_point`.
#[path = "../tests/common/contact.rs"]
#[allow(dead_code)]
mod gestures;

use common::*;
use gestures::front_point;
use laparo_server::engine::contact::InstrumentPose;
use laparo_server::engine::elastic::Formulation;
use laparo_server::engine::integrate::IntegratorKind;
use laparo_server::engine::local_model::ForceModelKind;
use laparo_server::engine::mesh::TetMesh;
use laparo_server::engine::mesh::generate::{graded_lines, graded_lines_symmetric, kuhn_grid};
use laparo_server::engine::scene::limits::max_cg_iterations;
use laparo_server::engine::scene::{BoxSpec, Scene};
use laparo_server::engine::simulation::Simulation;
use nalgebra::{Point3, Unit, Vector3};

const RATE_HZ: f64 = 60.0;
const SETTLE_TICKS: usize = 60;
const RAMP_TICKS: usize = 30;
const HOLD_TICKS: usize = 60;
/// The last ticks of the hold over which the spread is taken (0.5 s).
const SPREAD_TICKS: usize = 30;
/// Where a gesture starts: this far outside its final place, m.
const APPROACH: f64 = 0.01;

#[derive(Clone, Copy)]
enum Gesture {
    Tip(f64),
    Shaft(f64),
}

impl Gesture {
    fn label(self) -> String {
        match self {
            Gesture::Tip(d) => format!("tip {} mm", d * 1e3),
            Gesture::Shaft(d) => format!("shaft {} mm", d * 1e3),
        }
    }

    /// The final pose on `sim` (settled), for an instrument of radius `r`.
    fn pose(self, sim: &Simulation, r: f64) -> InstrumentPose {
        let f = front_point(sim);
        match self {
            Gesture::Tip(d) => InstrumentPose::new(
                Point3::new(f.x, f.y, f.z - d + r),
                Unit::new_normalize(Vector3::z()),
            ),
            Gesture::Shaft(d) => InstrumentPose::new(
                Point3::new(f.x + 0.06, f.y, f.z - d + r),
                Unit::new_normalize(-Vector3::x()),
            ),
        }
    }
}

/// What one press gave at the end of its hold.
struct Outcome {
    reaction: Vector3<f64>,
    rendered: Vector3<f64>,
    held: usize,
    spread: f64,
}

fn run(file: &str, kind: ForceModelKind, gesture: Gesture) -> Outcome {
    let mut scene = scene(file, IntegratorKind::Implicit, 1e-6);
    scene.mechanics.rate_hz = RATE_HZ;
    scene.force_model.kind = kind;
    let mut sim = build(&scene);
    for _ in 0..SETTLE_TICKS {
        sim.tick();
    }
    for k in 1..sim.instruments.len() {
        sim.set_pose(k, None);
    }
    let end = gesture.pose(&sim, sim.instruments[0].radius);
    let start = InstrumentPose::new(end.tip + Vector3::z() * APPROACH, end.axis);
    let mut magnitudes = Vec::new();
    for k in 1..=RAMP_TICKS + HOLD_TICKS {
        let pose = start.lerp(&end, k as f64 / RAMP_TICKS as f64);
        sim.set_pose(0, Some(pose));
        sim.tick();
        if k > RAMP_TICKS + HOLD_TICKS - SPREAD_TICKS {
            magnitudes.push(sim.forces.as_ref().unwrap().forces[0].force.norm());
        }
        assert!(
            sim.state
                .x
                .iter()
                .all(|p| p.coords.iter().all(|c| c.is_finite())),
            "{file} {}: non-finite state at tick {k}",
            gesture.label()
        );
    }
    let (lo, hi) = magnitudes
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &m| {
            (lo.min(m), hi.max(m))
        });
    Outcome {
        reaction: sim.instruments[0].report.reaction,
        rendered: sim.forces.as_ref().unwrap().forces[0].force,
        held: sim.instruments[0].held.len(),
        spread: if hi > 0.0 { (hi - lo) / hi } else { 0.0 },
    }
}

/// Prints how far the refined livers' values lie from their mean, and SOFA's liver
/// from that mean, against the bounds.
fn summarise(what: &str, per_mesh: &[(&str, f64)]) {
    let refined: Vec<f64> = per_mesh
        .iter()
        .filter(|(l, _)| ["liver-5k", "liver-20k", "liver-80k"].contains(l))
        .map(|&(_, v)| v)
        .collect();
    if refined.len() < 2 {
        return;
    }
    let mean = refined.iter().sum::<f64>() / refined.len() as f64;
    let sofa = per_mesh
        .iter()
        .find(|(l, _)| *l == "sofa-liver")
        .map_or("not run".to_string(), |&(_, s)| {
            format!("{:+.1}%", 100.0 * (s - mean) / mean)
        });
    println!(
        "{what}: 5k/20k/80k within {:.1}% of their mean {mean:.3} N (goal ±10%); SOFA {sofa} (goal ±25%)",
        100.0 * deviation(&refined),
    );
}

fn angle_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    if a.norm() == 0.0 || b.norm() == 0.0 {
        return f64::NAN;
    }
    (a.dot(b) / (a.norm() * b.norm()))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// Largest deviation of `values` from their mean, relative to the mean.
fn deviation(values: &[f64]) -> f64 {
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    values
        .iter()
        .map(|v| (v - mean).abs() / mean)
        .fold(0.0, f64::max)
}

/// The graded block of the Hertz check: top face at `z = 0`, bottom at `−BLOCK_DEPTH`.
const BLOCK_HALF_WIDTH: f64 = 0.04;
const BLOCK_DEPTH: f64 = 0.06;

/// Static passes at one depth stop when the reaction changes by less than this,
/// relative: a hundredth of the 10% the check allows.
const PASS_TOLERANCE: f64 = 1e-3;
const MAX_PASSES: usize = 40;

fn block() -> TetMesh {
    let (h0, core, growth) = (0.35e-3, 3.5e-3, 1.4);
    let x = graded_lines_symmetric(h0, core, growth, BLOCK_HALF_WIDTH);
    let z: Vec<f64> = graded_lines(h0, core, growth, BLOCK_DEPTH)
        .iter()
        .rev()
        .map(|d| -d)
        .collect();
    let (positions, tets) = kuhn_grid(&[x.clone(), x, z]);
    TetMesh::from_tets(positions, tets).expect("the graded block is valid")
}

/// Sneddon's rigid sphere of radius `r` pressed `d` into a half-space of plane-strain
/// modulus `e_star = E/(1−ν²)`: the contact radius from `d = (a/2) ln((r+a)/(r−a))`
/// (increasing in `a` on `(0, r)`, found by bisection), then the force.
fn sneddon(e_star: f64, r: f64, d: f64) -> f64 {
    let depth = |a: f64| 0.5 * a * ((r + a) / (r - a)).ln();
    let (mut lo, mut hi) = (0.0, r * (1.0 - 1e-12));
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if depth(mid) < d { lo = mid } else { hi = mid }
    }
    let a = 0.5 * (lo + hi);
    0.5 * e_star * ((a * a + r * r) * ((r + a) / (r - a)).ln() - 2.0 * a * r)
}

fn hertz() {
    let mesh = block();
    let mut scene = Scene::default_scene();
    scene.gravity = [0.0; 3];
    scene.material.model = Formulation::Linear;
    scene.mechanics.integrator = IntegratorKind::Static;
    scene.mechanics.cg_tolerance = 1e-8;
    scene.fixed.surface_only = false;
    scene.fixed.boxes = vec![BoxSpec {
        min: [-1.0, -1.0, -1.0],
        max: [1.0, 1.0, -BLOCK_DEPTH + 1e-6],
    }];
    scene.instruments.truncate(1);
    scene.instruments[0].friction = 0.0;
    scene.mechanics.cg_max_iterations = max_cg_iterations(mesh.vertex_count());
    let (e, nu) = (scene.material.young_modulus, scene.material.poisson_ratio);
    let e_star = e / (1.0 - nu * nu);
    println!(
        "\nHertz: tip of radius R indenting a block 80 × 80 × 60 mm ({} tetrahedra, {} vertices), E = {e} Pa, ν = {nu}, linear, static, no friction",
        mesh.tets.len(),
        mesh.vertex_count()
    );
    let mut sim = scene.build_on(mesh).expect("the block scene builds");
    let r = sim.instruments[0].radius;
    println!(
        "| d mm | reaction N | Hertz N | Sneddon N | bonded-layer Hertz N | vs Hertz | vs Sneddon | vs bonded layer | held | static passes | CG its |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let axis = Unit::new_normalize(Vector3::z());
    // Approach from above, so the stage sees the surface from outside first.
    sim.set_pose(
        0,
        Some(InstrumentPose::new(Point3::new(0.0, 0.0, r + 0.005), axis)),
    );
    sim.tick();
    for d in [0.5e-3, 1.0e-3, 1.5e-3, 2.0e-3] {
        let pose = InstrumentPose::new(Point3::new(0.0, 0.0, r - d), axis);
        let mut passes = 0;
        let mut its = 0u64;
        let mut last = f64::NAN;
        let mut change = f64::NAN;
        // The same pose until the reaction stops changing (the contact set settled).
        for _ in 0..MAX_PASSES {
            sim.set_pose(0, Some(pose));
            let report = sim.tick();
            its += report.cg_iterations as u64;
            passes += 1;
            let f = sim.instruments[0].report.reaction.z;
            change = (f - last).abs() / f.abs();
            if change <= PASS_TOLERANCE {
                break;
            }
            last = f;
        }
        let f = sim.instruments[0].report.reaction.z;
        let hertz = 4.0 / 3.0 * e_star * r.sqrt() * d.powf(1.5);
        let chi = (r * d).sqrt() / BLOCK_DEPTH;
        let bonded = hertz
            * (1.0
                + 1.133 * chi
                + 1.283 * chi.powi(2)
                + 0.769 * chi.powi(3)
                + 0.0975 * chi.powi(4));
        let sneddon = sneddon(e_star, r, d);
        println!(
            "| {:.1} | {f:.4} | {hertz:.4} | {sneddon:.4} | {bonded:.4} | {:+.1}% | {:+.1}% | {:+.1}% | {} | {passes} ({change:.0e}) | {its} |",
            d * 1e3,
            100.0 * (f - hertz) / hertz,
            100.0 * (f - sneddon) / sneddon,
            100.0 * (f - bonded) / bonded,
            sim.instruments[0].held.len(),
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if !args.iter().any(|a| a == "--gestures-only") {
        hertz();
    }
    if args.iter().any(|a| a == "--hertz-only") {
        return;
    }
    gestures();
}

fn gestures() {
    let with_300k = std::env::args().any(|a| a == "--with-300k");
    let mut labels = vec!["sofa-liver", "liver-5k", "liver-20k", "liver-80k"];
    if with_300k {
        labels.push("liver-300k");
    }
    let meshes = meshes(&labels);
    let gestures = [
        Gesture::Tip(0.008),
        Gesture::Tip(0.015),
        Gesture::Shaft(0.010),
    ];
    let kinds = [ForceModelKind::Geometric, ForceModelKind::Calibrated];
    println!(
        "Press on the default liver's free front, 60 Hz implicit, CG tol 1e-6, ramp 0.5 s, hold 1 s; values at the end of the hold"
    );
    for gesture in gestures {
        println!("\n{}", gesture.label());
        println!("| mesh | force model | reaction N | rendered N | angle ° | held | spread % |");
        println!("|---|---|---|---|---|---|---|");
        for kind in kinds {
            // |reaction| and |rendered| per mesh label.
            let mut reaction = Vec::new();
            let mut rendered = Vec::new();
            for m in &meshes {
                let o = run(&m.file, kind, gesture);
                println!(
                    "| {} | {kind:?} | {:.3} | {:.3} | {:.1} | {} | {:.2} |",
                    m.label,
                    o.reaction.norm(),
                    o.rendered.norm(),
                    angle_deg(&o.reaction, &o.rendered),
                    o.held,
                    100.0 * o.spread
                );
                reaction.push((m.label, o.reaction.norm()));
                rendered.push((m.label, o.rendered.norm()));
            }
            summarise(&format!("{kind:?} reaction"), &reaction);
            summarise(&format!("{kind:?} rendered"), &rendered);
        }
    }
}
