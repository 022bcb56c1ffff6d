//! Error against run time for forces (issue: reaction forces and the force loop).
//!
//! The reference is the elastic model's reaction on the instrument computed at haptic
//! rate: the same probe run by the server's engine at 1 kHz, the reaction `−Σ (K u)_i`
//! over the held vertices at each millisecond. Against it, the force the client's loop
//! renders at each 1 kHz tick when the mechanics runs at 15, 30, 60 and 120 Hz and the
//! loop extrapolates from the local models, for both force models: RMS and max error,
//! the largest change of rendered force between two haptic ticks, the largest jump a
//! model switch would make without blending, and the server's CPU time per simulated
//! second. Beside them, how far the engine's own reaction at each rate (as its last
//! tick left it) lies from the reference: the part of the error that comes from the
//! mechanics rate, not from the local model. Then the engine alone at 500, 2000 and
//! 4000 Hz against the reference: how far the reference itself has converged in the
//! tick. Then where the calibrated model's error lies: each phase of the probe's part
//! of it, and the 0.1 s that holds the most. Then the steps of the reference itself:
//! the ticks at which it lets go of tissue that still pushes on the tip, and why.
//! Then the loop on its own thread: achieved rate and period jitter.
//!
//! `cargo bench -p laparo-tests --bench force_error` (`-- --mesh FILE` runs the probe
//! on another liver with the default scene's settings, e.g.
//! `server/meshes/liver-5k.msh`; `-- --refine K` refines the liver K times when
//! loaded, `mesh.refine`; `-- --trace RATE` prints the 1 kHz trace at one rate)

use std::time::{Duration, Instant};

use laparo_client::gestures::{PROBE_PHASES, PROBE_SECONDS, Probe};
use laparo_client::haptics::{ForceLoop, ForceLoopConfig, ScriptedDevice};
use laparo_proto::force::{LocalModel, Plane};
use laparo_server::engine::contact::closest::closest_point_triangle;
use laparo_server::engine::contact::contact_normal;
use laparo_server::engine::local_model::ForceModelKind;
use laparo_server::engine::scene::Scene;
use laparo_server::engine::simulation::Simulation;
use laparo_tests::coupled::{self, front_probe, probed, reaction_history};
use nalgebra::{Point3, Unit, Vector3};

const HAPTIC_HZ: f64 = 1000.0;
const DEPTH: f64 = 0.008;
const SLIDE: f64 = 0.02;
const REPEATS: usize = 5;

/// The value given after `flag` on the command line, `None` without the flag. A flag
/// without a value, or with one that does not read as a `T`, ends the run saying
/// what it `takes`.
fn argument<T: std::str::FromStr>(flag: &str, takes: &str) -> Option<T> {
    let args: Vec<String> = std::env::args().collect();
    let k = args.iter().position(|a| a == flag)?;
    let value = args.get(k + 1).and_then(|v| v.parse().ok());
    if value.is_none() {
        eprintln!("{flag} takes {takes}");
        std::process::exit(2);
    }
    value
}

/// The liver the probe runs on: `--mesh FILE` (a relative path from the workspace's
/// root, where the README's commands run), else the default scene's. A missing
/// argument or file ends the run with a message.
fn mesh_file() -> Option<&'static str> {
    static MESH: std::sync::OnceLock<Option<String>> = std::sync::OnceLock::new();
    MESH.get_or_init(|| {
        let file: String = argument("--mesh", "a Gmsh file")?;
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let path = root.join(&file);
        if !path.is_file() {
            eprintln!("--mesh {file}: no such file ({})", path.display());
            std::process::exit(2);
        }
        Some(path.display().to_string())
    })
    .as_deref()
}

/// `--refine K`: how many times the liver is refined when loaded (`mesh.refine`),
/// 0 unless given. A missing or unreadable count ends the run with a message.
fn refine() -> u32 {
    static REFINE: std::sync::OnceLock<u32> = std::sync::OnceLock::new();
    *REFINE.get_or_init(|| argument("--refine", "a count, 0 to 3").unwrap_or(0))
}

/// The default scene on the chosen liver, settled ([`coupled::settled`]).
fn settled(rate_hz: f64, kind: ForceModelKind) -> Simulation {
    let mut scene = Scene::default_scene();
    if let Some(file) = mesh_file() {
        scene.mesh.file = file.to_string();
    }
    scene.mesh.refine = refine();
    coupled::settled(scene, rate_hz, kind)
}

fn haptic_ticks() -> usize {
    (PROBE_SECONDS * HAPTIC_HZ).round() as usize
}

/// The index in [`PROBE_PHASES`] of the probe's withdrawal.
fn withdraw_phase() -> usize {
    PROBE_PHASES
        .iter()
        .position(|(name, _)| *name == "withdraw")
        .expect("the probe withdraws")
}

/// The haptic tick at which the probe starts to withdraw.
fn withdrawal() -> usize {
    (PROBE_PHASES[withdraw_phase()].1 * HAPTIC_HZ).round() as usize
}

/// Length of the window [`Row::worst`] looks for, haptic ticks (0.1 s).
const WINDOW: usize = 100;

/// The reaction at each haptic tick from a run of the engine at haptic rate, and the
/// ticks of that run at which it let go of held vertices that carried a force.
fn reference(probe: &Probe) -> (Vec<Vector3<f64>>, Vec<LetGo>) {
    let mut sim = settled(HAPTIC_HZ, ForceModelKind::Geometric);
    let mut watch = LetGoWatch::default();
    let truth = reaction_history(&mut sim, probe, haptic_ticks(), HAPTIC_HZ, |sim, t| {
        watch.after_tick(sim, t)
    });
    (truth, watch.steps)
}

/// The engine alone at `rate_hz`, driven along the probe: at each haptic tick, the
/// reaction its last tick left (the pose of tick `k` is the probe's at `k / rate`).
fn engine_alone(probe: &Probe, rate_hz: f64) -> Vec<Vector3<f64>> {
    let mut sim = settled(rate_hz, ForceModelKind::Geometric);
    reaction_history(&mut sim, probe, haptic_ticks(), HAPTIC_HZ, |_, _| {})
}

/// The sum of `squares`, one a haptic tick from `t = 0`, within each phase of
/// [`PROBE_PHASES`].
fn by_phase(squares: impl IntoIterator<Item = f64>) -> [f64; PROBE_PHASES.len()] {
    let mut phases = [0.0; PROBE_PHASES.len()];
    for (j, e) in squares.into_iter().enumerate() {
        let t = j as f64 / HAPTIC_HZ;
        let k = PROBE_PHASES.iter().rposition(|&(_, start)| start <= t);
        phases[k.expect("the first phase starts at 0")] += e;
    }
    phases
}

/// The part of [`by_phase`]'s sums before the withdrawal.
fn before_withdrawal(phases: &[f64; PROBE_PHASES.len()]) -> f64 {
    phases[..withdraw_phase()].iter().sum()
}

/// How far the engine's own reaction at faster mechanics rates lies from the
/// reference: whether the reference has converged in the tick, the floor under any
/// rendering's error against it.
fn reference_convergence(probe: &Probe, truth: &[Vector3<f64>], rms_truth: f64) {
    println!(
        "\nThe engine alone at other rates against the 1 kHz reference (RMS / RMS force): how far the reference itself has converged in the tick"
    );
    println!("| mechanics (Hz) | whole probe | before withdrawal |");
    println!("|---|---|---|");
    for rate in [500.0, 2000.0, 4000.0] {
        let run = engine_alone(probe, rate);
        let phases = by_phase(run.iter().zip(truth).map(|(a, b)| (a - b).norm_squared()));
        println!(
            "| {rate} | {:.3} | {:.3} |",
            (phases.iter().sum::<f64>() / truth.len() as f64).sqrt() / rms_truth,
            (before_withdrawal(&phases) / withdrawal() as f64).sqrt() / rms_truth
        );
    }
}

struct Row {
    rms: f64,
    /// RMS error up to the withdrawal.
    rms_pressed: f64,
    /// Each phase of [`PROBE_PHASES`]'s part of the error: the RMS over the whole probe
    /// of the error within the phase (their squares add up to `rms²`), N.
    phases: [f64; PROBE_PHASES.len()],
    /// The [`WINDOW`] of haptic ticks holding the most of the error: its start, s,
    /// and its part, as for a phase, N.
    worst: (f64, f64),
    max: f64,
    max_step: f64,
    max_switch_jump: f64,
    server_cpu: f64,
    /// RMS difference between the engine's own reaction at this rate, as the last
    /// mechanics tick left it at each haptic tick, and the reference: what any force
    /// model would be off by if it rendered the reaction of the latest tick exactly.
    rms_engine: f64,
}

fn coupled(probe: &Probe, rate_hz: f64, kind: ForceModelKind, truth: &[Vector3<f64>]) -> Row {
    let mut cpu = Vec::new();
    let mut row = None;
    for _ in 0..REPEATS {
        let mut engine = 0.0;
        let c = probed(
            settled(rate_hz, kind),
            probe,
            HAPTIC_HZ,
            haptic_ticks(),
            |c, j| {
                engine += (c.sim.instruments[0].report.reaction - truth[j]).norm_squared();
            },
        );
        cpu.push(c.server_seconds / PROBE_SECONDS);
        let squares: Vec<f64> = c
            .haptics
            .device()
            .recorded()
            .zip(truth)
            .map(|(r, f)| (r.force.force - f).norm_squared())
            .collect();
        let max = squares.iter().fold(0.0f64, |m, &e| m.max(e)).sqrt();
        let phases = by_phase(squares.iter().copied());
        let n = truth.len() as f64;
        let (from, most) = squares
            .windows(WINDOW)
            .map(|w| w.iter().sum::<f64>())
            .enumerate()
            .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        row = Some(Row {
            rms: (phases.iter().sum::<f64>() / n).sqrt(),
            rms_pressed: (before_withdrawal(&phases) / withdrawal() as f64).sqrt(),
            phases: phases.map(|p| (p / n).sqrt()),
            worst: (from as f64 / HAPTIC_HZ, (most / n).sqrt()),
            max,
            max_step: c.haptics.stats().max_force_step,
            max_switch_jump: c.max_switch_jump,
            server_cpu: 0.0,
            rms_engine: (engine / truth.len() as f64).sqrt(),
        });
    }
    cpu.sort_by(f64::total_cmp);
    let mut row = row.expect("at least one repeat");
    row.server_cpu = cpu[cpu.len() / 2];
    row
}

/// A tick of the reference at which it let go of held vertices that carried a force.
struct LetGo {
    /// The tick's time, s.
    t: f64,
    vertices: usize,
    /// The sum of their reactions at the tick before, N.
    carried: f64,
    /// The instrument's reaction at the tick before and at this one, N.
    before: f64,
    after: f64,
    /// How near the tip `P` the nearest of their surface triangles came after the
    /// tick, in radii.
    nearest: f64,
    /// How long before the tick the tip had stopped touching all of their triangles
    /// (each triangle's nearest approach to `P` beyond [`APART`]·r), s; `None` when
    /// one of them still touched it at the tick before.
    apart_for: Option<f64>,
    /// `|T| / N` of the reaction of the one that carried the most, at the tick
    /// before: its part `T` across the instrument's surface against its push `N`
    /// onto it, with the contact stage's own normal there (`contact_normal`). At the
    /// scene's friction coefficient μ it was sliding on the friction cone. `None`
    /// when it did not push (`N ≤ 0`).
    tangential_over_normal: Option<f64>,
}

/// A triangle's nearest approach to the tip `P` beyond which the tip touches it no
/// more, in radii: the push-out leaves the surface at `r (1 + 10⁻⁴)`, so a
/// thousandth of a radius is clear of it.
const APART: f64 = 1.001;

/// A vertex instrument 0 held at the last tick.
#[derive(Clone, Copy)]
struct WatchedVertex {
    v: u32,
    /// Its reaction, N.
    reaction: Vector3<f64>,
    /// Since when, s, none of its triangles has touched the tip (see [`APART`]).
    apart_since: Option<f64>,
    /// `|T| / N` of its reaction (see [`LetGo::tangential_over_normal`]).
    tangential_over_normal: Option<f64>,
}

/// Follows a run tick by tick for [`LetGo`] steps.
#[derive(Default)]
struct LetGoWatch {
    held: Vec<WatchedVertex>,
    before: Vector3<f64>,
    steps: Vec<LetGo>,
}

/// The nearest approach to the tip `P` of the surface triangles around vertex `v`,
/// m (infinite for a vertex off the surface).
fn nearest_approach(sim: &Simulation, v: u32, tip: &Point3<f64>) -> f64 {
    let surface = &sim.mesh.surface;
    surface
        .slot(v)
        .map(|slot| surface.triangles_around(slot))
        .unwrap_or_default()
        .iter()
        .map(|&k| {
            let corners = surface.triangles[k as usize].map(|w| sim.state.x[w as usize]);
            (closest_point_triangle(tip, &corners).point - tip).norm()
        })
        .fold(f64::INFINITY, f64::min)
}

impl LetGoWatch {
    fn after_tick(&mut self, sim: &Simulation, t: f64) {
        let ins = &sim.instruments[0];
        let gone: Vec<WatchedVertex> = self
            .held
            .iter()
            .filter(|w| !ins.held.contains(&w.v))
            .copied()
            .collect();
        let carried: Vector3<f64> = gone.iter().map(|w| w.reaction).sum();
        if let Some(pose) = ins.current.filter(|_| carried.norm() > 0.0) {
            let nearest = gone
                .iter()
                .map(|w| nearest_approach(sim, w.v, &pose.tip))
                .fold(f64::INFINITY, f64::min);
            let apart_for = gone
                .iter()
                .map(|w| w.apart_since)
                .try_fold(f64::INFINITY, |a, s| s.map(|s| a.min(s)))
                .map(|since| t - since);
            let heaviest = gone
                .iter()
                .max_by(|a, b| a.reaction.norm().total_cmp(&b.reaction.norm()))
                .expect("a let-go that carried a force let go of a vertex");
            self.steps.push(LetGo {
                t,
                vertices: gone.len(),
                carried: carried.norm(),
                before: self.before.norm(),
                after: ins.report.reaction.norm(),
                nearest: nearest / ins.radius,
                apart_for,
                tangential_over_normal: heaviest.tangential_over_normal,
            });
        }
        let Some(pose) = ins.current else {
            self.held.clear();
            self.before = ins.report.reaction;
            return;
        };
        let last = std::mem::take(&mut self.held);
        let (length, radius) = (ins.active_length(), ins.radius);
        for (&v, &reaction) in ins.held.iter().zip(&ins.report.held_reactions) {
            let apart = nearest_approach(sim, v, &pose.tip) > APART * radius;
            let before = last.iter().find(|w| w.v == v).and_then(|w| w.apart_since);
            // The instrument's outward normal `m` at the vertex, as the stage takes it
            // for Coulomb's law: the tissue pushes with `N = −reaction·m`.
            let x = sim.state.x[v as usize];
            let ratio = contact_normal(&x, &pose, length, radius, ins.tip_contact)
                .map(|(m, _)| (m, -reaction.dot(&m)))
                .filter(|&(_, normal)| normal > 0.0)
                .map(|(m, normal)| (reaction + m * normal).norm() / normal);
            self.held.push(WatchedVertex {
                v,
                reaction,
                apart_since: apart.then(|| before.unwrap_or(t)),
                tangential_over_normal: ratio,
            });
        }
        self.before = ins.report.reaction;
    }
}

/// Where the reference lets go of tissue that still pushes on the instrument: the
/// `steps` of the 1 kHz engine along the probe at which the vertices it let go had
/// carried, at the tick before, reactions summing to more than a tenth of the RMS
/// force. For each: when, how many vertices, the reaction they carried, the
/// instrument's reaction before and after, how near the tip `P` the nearest of
/// their surface triangles came after the tick, in radii (the contact stage keeps a
/// vertex laid on the tip plane beside the shaft while one of its triangles is within
/// 1.05 r of `P`), how long before it the tip had stopped touching every one of
/// those triangles, and whether the heaviest of them was sliding (`|T| / N` at the
/// friction coefficient). Such a step happens within one tick of the engine; a force
/// loop fed at a lower mechanics rate learns of it only with the next model, so that
/// a step `F` rendered `L` late costs `F √(L / T)` of RMS error over the probe's `T`,
/// whatever the force model.
fn let_go_while_pushing(steps: &[LetGo], rms_truth: f64) {
    println!(
        "\nThe reference's let-go steps: ticks of the 1 kHz engine at which the vertices let go had carried more than a tenth of the RMS force"
    );
    println!(
        "| t (s) | vertices let go | their reaction (N) | instrument's reaction before (N) | after (N) | their triangles' nearest approach to the tip (r) | the tip touched none of them for (ms) | heaviest one's tangential / normal reaction (— if it did not push) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for g in steps.iter().filter(|g| g.carried > 0.1 * rms_truth) {
        let apart = g
            .apart_for
            .map_or_else(|| "—".to_string(), |s| format!("{:.0}", s * 1e3));
        let sliding = g
            .tangential_over_normal
            .map_or_else(|| "—".to_string(), |r| format!("{r:.2}"));
        println!(
            "| {:.3} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {apart} | {sliding} |",
            g.t, g.vertices, g.carried, g.before, g.after, g.nearest
        );
    }
}

/// Where the calibrated model's error lies in the probe: each phase's part, and the
/// 0.1 s holding the most (RMS over the whole probe of the error within them / RMS
/// force: the squares of the phases' parts add up to the whole's).
fn error_by_phase(rows: &[(f64, Row)], rms_truth: f64) {
    println!(
        "\nThe calibrated model's error by phase of the probe: each phase's part, RMS over the whole probe / RMS force (their squares add up to the whole's), and the {} s holding the most",
        WINDOW as f64 / HAPTIC_HZ
    );
    let names: Vec<String> = PROBE_PHASES
        .iter()
        .map(|(name, start)| format!("{name} from {start} s"))
        .collect();
    println!(
        "| mechanics (Hz) | {} | worst {} s: from (s) | its part |",
        names.join(" | "),
        WINDOW as f64 / HAPTIC_HZ
    );
    println!("|---|{}---|---|", "---|".repeat(PROBE_PHASES.len()));
    for (rate, r) in rows {
        let parts: Vec<String> = r
            .phases
            .iter()
            .map(|p| format!("{:.3}", p / rms_truth))
            .collect();
        println!(
            "| {rate} | {} | {:.3} | {:.3} |",
            parts.join(" | "),
            r.worst.0,
            r.worst.1 / rms_truth
        );
    }
}

fn loop_on_its_thread() {
    let plane = Plane {
        normal: Vector3::z_axis(),
        anchor: Point3::new(0.0, 0.0, 0.01),
        stiffness: 100.0,
        drag: Vector3::zeros(),
    };
    let axis: Unit<Vector3<f64>> = Vector3::z_axis();
    let device = ScriptedDevice::fixed(Point3::origin(), axis, 10.0, 1);
    let config = ForceLoopConfig::new(Point3::new(0.0, 0.0, 0.2));
    let (haptics, mut inbox, _outbox) = ForceLoop::new(config, device).expect("valid");
    let handle = haptics.spawn();
    let start = Instant::now();
    let mut tick = 0;
    while start.elapsed() < Duration::from_secs(3) {
        tick += 1;
        inbox.write(LocalModel {
            tip_plane: Some(plane),
            ..LocalModel::free(tick, tick as f64 / 60.0, Point3::origin(), axis)
        });
        std::thread::sleep(Duration::from_micros(16_667));
    }
    let (_, s) = handle.stop();
    println!(
        "\nForce loop on its thread, 1 kHz nominal, 3 s, a model every 16.7 ms (std::thread::sleep to absolute deadlines, no real-time priority)"
    );
    println!(
        "| ticks | achieved rate (Hz) | jitter p50 (µs) | p99 (µs) | p99.9 (µs) | max (µs) | missed deadlines | max model age (ms) | models received |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    println!(
        "| {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {:.1} | {} |",
        s.ticks,
        s.rate_hz,
        s.jitter.p50 * 1e6,
        s.jitter.p99 * 1e6,
        s.jitter.p999 * 1e6,
        s.jitter.max * 1e6,
        s.missed_deadlines,
        s.max_model_age_s * 1e3,
        s.models_received
    );
}

/// With `--trace RATE`: the reference, the engine's own reaction at `RATE` and the
/// rendered force (calibrated model) every 50 ms, to see where the error comes from.
fn trace(probe: &Probe, rate_hz: f64, truth: &[Vector3<f64>]) {
    let sim = settled(rate_hz, ForceModelKind::Calibrated);
    let mut reaction = Vec::with_capacity(haptic_ticks());
    let c = probed(sim, probe, HAPTIC_HZ, haptic_ticks(), |c, _| {
        reaction.push(c.sim.instruments[0].report.reaction)
    });
    println!(
        "| t s | reference N | engine at {rate_hz} Hz N | rendered N | rendered − reference N |"
    );
    println!("|---|---|---|---|---|");
    let rendered: Vec<_> = c
        .haptics
        .device()
        .recorded()
        .map(|r| r.force.force)
        .collect();
    for j in (0..haptic_ticks()).step_by(50) {
        let f = |v: &Vector3<f64>| format!("{:.3} {:.3} {:.3}", v.x, v.y, v.z);
        println!(
            "| {:.2} | {} | {} | {} | {:.3} |",
            j as f64 / HAPTIC_HZ,
            f(&truth[j]),
            f(&reaction[j]),
            f(&rendered[j]),
            (rendered[j] - truth[j]).norm()
        );
    }
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let probe = front_probe(&settled(60.0, ForceModelKind::Geometric), DEPTH, SLIDE);
    let (truth, let_go) = reference(&probe);
    if let Some(rate) = argument("--trace", "a mechanics rate in Hz") {
        trace(&probe, rate, &truth);
        return;
    }
    let peak = truth.iter().map(|f| f.norm()).fold(0.0, f64::max);
    let rms_truth =
        (truth.iter().map(|f| f.norm_squared()).sum::<f64>() / truth.len() as f64).sqrt();
    println!(
        "Probe of {}{}: {} mm past the surface, {} mm slide, axis through the trocar, {} s; reference reaction at 1 kHz: peak {:.3} N, RMS {:.3} N",
        mesh_file().unwrap_or("the default liver"),
        match refine() {
            0 => String::new(),
            1 => " refined once".to_string(),
            2 => " refined twice".to_string(),
            k => format!(" refined {k} times"),
        },
        DEPTH * 1e3,
        SLIDE * 1e3,
        PROBE_SECONDS,
        peak,
        rms_truth
    );
    println!(
        "| mechanics (Hz) | force model | RMS error (N) | RMS error / RMS force | RMS error before withdrawal (N) | max error (N) | largest step per haptic tick (N) | largest switch jump without blending (N) | server CPU s per simulated s (median of {REPEATS}) | the engine's own reaction at this rate vs the reference, RMS / RMS force |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut calibrated = Vec::new();
    for rate in [15.0, 30.0, 60.0, 120.0] {
        for kind in [ForceModelKind::Geometric, ForceModelKind::Calibrated] {
            let r = coupled(&probe, rate, kind, &truth);
            println!(
                "| {rate} | {kind:?} | {:.4} | {:.3} | {:.4} | {:.4} | {:.4} | {:.4} | {:.5} | {:.3} |",
                r.rms,
                r.rms / rms_truth,
                r.rms_pressed,
                r.max,
                r.max_step,
                r.max_switch_jump,
                r.server_cpu,
                r.rms_engine / rms_truth
            );
            if kind == ForceModelKind::Calibrated {
                calibrated.push((rate, r));
            }
        }
    }
    error_by_phase(&calibrated, rms_truth);
    reference_convergence(&probe, &truth, rms_truth);
    let_go_while_pushing(&let_go, rms_truth);
    loop_on_its_thread();
}
