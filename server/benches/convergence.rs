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
//! outside the surface and held still for 1 s (60 ticks):
//! - **tip 8 mm**, **tip 15 mm**: axis +z (the tip points into −z) through the front
//!   point ([`front_point`]: the front-face vertex nearest the middle); the
//!   instrument's foremost point `P − r Z` ends `d` past that vertex, so the tissue is
//!   indented by `d`;
//! - **shaft 10 mm**: the axis along −x, lying across the front face level with the
//!   front point, the tip 6 cm beyond it in +x; the shaft's underside ends `d` past
//!   the front point.
//!
//! For each mesh and force model (the paper's `geometric` and the `calibrated` one,
//! and the calibrated one with `contact.footprint`), at the end of the hold:
//! - `reaction`: the tissue's force on the instrument as the contact stage reports
//!   it, |Σ −(K u)_i| over the vertices the instrument holds (the force model does
//!   not feed back into the tissue, so it is the same for both force models); in the
//!   rows `+ footprint`, those of the tip's end scaled to the tip's footprint and those
//!   of the shaft's side to the strip the shaft presses (scene `contact.footprint`);
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
//! Then the instrument's tip indents a graded block of tissue by 0.5–2 mm, against
//! Hertz, Sneddon's exact sphere and the bonded-layer correction (the set-up and the
//! formulas: `server/tests/common/hertz.rs`, shared with the Hertz test).
//!
//! # The shaft on uniform blocks
//!
//! Then the shaft pressed 10 mm across the block meshed at 20, 10, 5 and 2.5 mm cells
//! across it and in depth, unscaled and scaled to its strip (`contact.footprint`),
//! against the block graded to 1 mm (`press_shaft` in `server/tests/common/hertz.rs`).
//!
//! Then the tip pressed 8 mm into blocks of uniform 20, 10 and 5 mm cubes, unscaled and
//! scaled to its footprint, against the block graded to 1 mm under it.
//!
//! # Without friction
//!
//! `--frictionless` runs the gestures with the instrument's friction at 0 (the
//! scene's is 1), for the calibrated model with the footprint scale only: how much of
//! the refined livers' spread and of their distance to liver-300k comes from
//! vertices that stick where the instrument first caught them.
//!
//! Flags: `--gestures-only`, `--hertz-only`, `--stiffening-only`, `--with-300k`,
//! `--frictionless`.

mod common;

/// The contact tests' gestures; the bench uses `front_press`.
#[path = "../tests/common/contact.rs"]
#[allow(dead_code)]
mod gestures;

/// The Hertz test's block and references.
#[path = "../tests/common/hertz.rs"]
#[allow(dead_code)]
mod indentation;

use common::*;
use gestures::front_press;
use indentation::*;
use laparo_server::engine::contact::InstrumentPose;
use laparo_server::engine::integrate::IntegratorKind;
use laparo_server::engine::local_model::ForceModelKind;
use laparo_server::engine::mesh::TetMesh;
use laparo_server::engine::simulation::Simulation;
use nalgebra::Vector3;

const RATE_HZ: f64 = 60.0;
const SETTLE_TICKS: usize = 60;
const RAMP_TICKS: usize = 30;
const HOLD_TICKS: usize = 60;
/// The last ticks of the hold over which the spread is taken (0.5 s).
const SPREAD_TICKS: usize = 30;
/// Where a gesture starts: this far outside the surface (the gesture's depth plus
/// this outside its final place), m. Starting only this far from the final place put
/// the 15 mm tip 5 mm inside the liver on its first tick.
const APPROACH: f64 = 0.01;

#[derive(Clone, Copy)]
enum Gesture {
    Tip(f64),
    Shaft(f64),
}

impl Gesture {
    /// How deep the gesture presses, m.
    fn depth(self) -> f64 {
        match self {
            Gesture::Tip(d) | Gesture::Shaft(d) => d,
        }
    }

    fn label(self) -> String {
        match self {
            Gesture::Tip(d) => format!("tip {} mm", d * 1e3),
            Gesture::Shaft(d) => format!("shaft {} mm", d * 1e3),
        }
    }

    /// The final pose on `sim` (settled), for an instrument of radius `r`.
    fn pose(self, sim: &Simulation, r: f64) -> InstrumentPose {
        front_press(sim, matches!(self, Gesture::Shaft(_)), self.depth(), r)
    }
}

/// What one press gave at the end of its hold.
struct Outcome {
    reaction: Vector3<f64>,
    rendered: Vector3<f64>,
    held: usize,
    spread: f64,
}

/// Whether `--frictionless` was given: the instrument's friction set to 0.
fn frictionless() -> bool {
    std::env::args().any(|a| a == "--frictionless")
}

fn run(mesh: &MeshCase, (kind, footprint): (ForceModelKind, bool), gesture: Gesture) -> Outcome {
    let mut scene = scene(mesh, IntegratorKind::Implicit, 1e-6);
    scene.mechanics.rate_hz = RATE_HZ;
    scene.force_model.kind = kind;
    scene.contact.footprint = footprint;
    if frictionless() {
        scene.instruments[0].friction = 0.0;
    }
    let mut sim = build(&scene);
    for _ in 0..SETTLE_TICKS {
        sim.tick();
    }
    for k in 1..sim.instruments.len() {
        sim.set_pose(k, None);
    }
    let end = gesture.pose(&sim, sim.instruments[0].radius);
    let start = InstrumentPose::new(
        end.tip + Vector3::z() * (gesture.depth() + APPROACH),
        end.axis,
    );
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
            "{} {}: non-finite state at tick {k}",
            mesh.label,
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
    let value = |label: &str| per_mesh.iter().find(|(l, _)| *l == label).map(|&(_, v)| v);
    let sofa = value("sofa-liver").map_or("not run".to_string(), |s| {
        format!("{:+.1}%", 100.0 * (s - mean) / mean)
    });
    println!(
        "{what}: 5k/20k/80k within {:.1}% of their mean {mean:.3} N (goal ±10%); SOFA {sofa} (goal ±25%)",
        100.0 * deviation(&refined),
    );
    // SOFA's liver against itself refined: the same surface, so only the mesh differs.
    if let (Some(coarse), Some(r1), Some(r2)) = (
        value("sofa-liver"),
        value("sofa-liver-r1"),
        value("sofa-liver-r2"),
    ) {
        let pct = |v: f64| 100.0 * (v - r2) / r2;
        println!(
            "{what}: SOFA's liver {:+.1}%, refined once {:+.1}%, against refined twice {r2:.3} N; refined twice against the 5k/20k/80k mean {:+.1}%",
            pct(coarse),
            pct(r1),
            100.0 * (r2 - mean) / mean,
        );
    }
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

fn hertz_block() {
    let mut sim = block_scene();
    let e_star = plane_strain_modulus(&sim);
    let m = &sim.model.materials[0];
    println!(
        "\nHertz: tip of radius R indenting a block 80 × 80 × 60 mm ({} tetrahedra, {} vertices), E = {} Pa, ν = {}, linear, static, no friction",
        sim.mesh.tets.len(),
        sim.mesh.vertex_count(),
        m.young_modulus,
        m.poisson_ratio
    );
    let r = sim.instruments[0].radius;
    println!(
        "| d mm | reaction N | Hertz N | Sneddon N | bonded-layer Hertz N | vs Hertz | vs Sneddon | vs bonded layer | held | static passes (last change) | CG its |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for d in [0.5e-3, 1.0e-3, 1.5e-3, 2.0e-3] {
        let i = indent(&mut sim, d);
        let f = i.force;
        let (hertz, sneddon, bonded) = (
            hertz(e_star, r, d),
            sneddon(e_star, r, d),
            bonded_layer(e_star, r, d),
        );
        println!(
            "| {:.1} | {f:.4} | {hertz:.4} | {sneddon:.4} | {bonded:.4} | {:+.1}% | {:+.1}% | {:+.1}% | {} | {} ({:.0e}) | {} |",
            d * 1e3,
            100.0 * (f - hertz) / hertz,
            100.0 * (f - sneddon) / sneddon,
            100.0 * (f - bonded) / bonded,
            i.held,
            i.passes,
            i.change,
            i.cg_iterations
        );
    }
}

/// The shaft pressed 10 mm across blocks of uniform cells (5 mm along the shaft), at
/// 20, 10, 5 and 2.5 mm across it and in depth, against the block graded to 1 mm:
/// how much of a coarse mesh's excess force the footprint scale takes out, and what
/// is left. Each block is pressed 2.5, 5 then 10 mm, as the footprint test does; the
/// graded block also straight to 5 then 10 mm, to show how much the held set (which
/// keeps what it took while the pull stays under the adhesion) depends on the path.
fn stiffening() {
    const PATH: [f64; 3] = [2.5e-3, 5e-3, 10e-3];
    let force = |mesh: TetMesh, footprint: bool, path: &[f64]| {
        press_along(mesh, footprint, press_shaft, path)
            .pop()
            .expect("a path of one depth at least")
    };
    let reference = force(graded_shaft_block(), true, &PATH).force;
    let shorter = force(graded_shaft_block(), true, &PATH[1..]).force;
    println!(
        "\nShaft pressed 10 mm across the block (80 × 80 × 60 mm, linear, static, no friction) by 2.5, 5 and 10 mm, against the block graded to 1 mm across it: {reference:.4} N (pressed by 5 and 10 mm: {shorter:.4} N, {:+.1}%)",
        100.0 * (shorter / reference - 1.0)
    );
    println!(
        "| cells across and in depth mm | tetrahedra | reaction N | vs graded | scaled N | vs graded | held | static passes (last change) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for h in [20e-3, 10e-3, 5e-3, 2.5e-3] {
        let mesh = || {
            shaft_block(
                uniform_lines(-BLOCK_HALF_WIDTH, BLOCK_HALF_WIDTH, h),
                uniform_lines(-BLOCK_DEPTH, 0.0, h),
            )
        };
        let tets = mesh().tets.len();
        let off = force(mesh(), false, &PATH);
        let on = force(mesh(), true, &PATH);
        block_row(h, tets, (&off, &on), reference);
    }
}

/// A row of the uniform blocks' tables: cell size `h` (m), tetrahedra, the press's
/// force unscaled and scaled, each against the graded block's `reference` (N).
fn block_row(h: f64, tets: usize, (off, on): (&Indentation, &Indentation), reference: f64) {
    println!(
        "| {} | {tets} | {:.4} | {:+.1}% | {:.4} | {:+.1}% | {} | {} ({:.0e}) |",
        h * 1e3,
        off.force,
        100.0 * (off.force / reference - 1.0),
        on.force,
        100.0 * (on.force / reference - 1.0),
        on.held,
        on.passes,
        on.change
    );
}

/// The tip pressed 8 mm (its hemispherical end wholly in) into blocks of uniform
/// cubes of 20, 10 and 5 mm, against the block graded to 1 mm under the tip, unscaled
/// and scaled to its footprint: what the tip's scale leaves of a coarse mesh's excess
/// force, as [`stiffening`] shows for the shaft. Each block is pressed 2, 4, 6 then
/// 8 mm, as the footprint test does.
fn tip_stiffening() {
    const PATH: [f64; 4] = [2e-3, 4e-3, 6e-3, 8e-3];
    let force = |mesh: TetMesh, footprint: bool| {
        press_along(mesh, footprint, indent, &PATH)
            .pop()
            .expect("a path of one depth at least")
    };
    let reference = force(graded_block(1e-3, 7e-3, 1.4), true).force;
    println!(
        "\nTip pressed 8 mm into the block (80 × 80 × 60 mm, linear, static, no friction) by 2, 4, 6 and 8 mm, against the block graded to 1 mm under the tip: {reference:.4} N"
    );
    println!(
        "| cubes mm | tetrahedra | reaction N | vs graded | scaled N | vs graded | held | static passes (last change) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for h in [20e-3, 10e-3, 5e-3] {
        let mesh = || uniform_block(h);
        let tets = mesh().tets.len();
        let off = force(mesh(), false);
        let on = force(mesh(), true);
        block_row(h, tets, (&off, &on), reference);
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let only = |what: &str| args.iter().any(|a| a == what);
    if only("--stiffening-only") {
        stiffening();
        tip_stiffening();
        return;
    }
    if !only("--gestures-only") {
        hertz_block();
    }
    if only("--hertz-only") {
        return;
    }
    if !only("--gestures-only") {
        stiffening();
        tip_stiffening();
    }
    gestures();
}

fn gestures() {
    let with_300k = std::env::args().any(|a| a == "--with-300k");
    let mut labels = vec![
        "sofa-liver",
        "sofa-liver-r1",
        "sofa-liver-r2",
        "liver-5k",
        "liver-20k",
        "liver-80k",
    ];
    if with_300k {
        labels.push("liver-300k");
    }
    let meshes = meshes(&labels);
    let gestures = [
        Gesture::Tip(0.008),
        Gesture::Tip(0.015),
        Gesture::Shaft(0.010),
    ];
    // Each force model, and the calibrated one with the tip's force scaled to its
    // footprint (scene `contact.footprint`).
    let all = [
        (ForceModelKind::Geometric, false),
        (ForceModelKind::Calibrated, false),
        (ForceModelKind::Calibrated, true),
    ];
    // Without friction, only the row the bounds apply to.
    let kinds = if frictionless() { &all[2..] } else { &all[..] };
    println!(
        "Press on the default liver's free front, 60 Hz implicit, CG tol 1e-6, ramp 0.5 s, hold 1 s; values at the end of the hold{}",
        if frictionless() {
            "; instrument friction 0 (the scene's is 1)"
        } else {
            ""
        }
    );
    for gesture in gestures {
        println!("\n{}", gesture.label());
        println!("| mesh | force model | reaction N | rendered N | angle ° | held | spread % |");
        println!("|---|---|---|---|---|---|---|");
        for &(kind, footprint) in kinds {
            let label = format!("{kind:?}{}", if footprint { " + footprint" } else { "" });
            // |reaction| and |rendered| per mesh label.
            let mut reaction = Vec::new();
            let mut rendered = Vec::new();
            for m in &meshes {
                let o = run(m, (kind, footprint), gesture);
                println!(
                    "| {} | {label} | {:.3} | {:.3} | {:.1} | {} | {:.2} |",
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
            summarise(&format!("{label} reaction"), &reaction);
            summarise(&format!("{label} rendered"), &rendered);
        }
    }
}
