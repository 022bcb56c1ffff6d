//! A simulation and a force loop coupled in simulated time.

use std::time::Instant;

use laparo_client::gestures::Probe;
use laparo_client::haptics::{
    ForceLoop, ForceLoopConfig, HapticDevice, ModelInbox, PoseOutbox, ScriptedDevice,
};
use laparo_server::engine::contact::InstrumentPose;
use laparo_server::engine::local_model::ForceModelKind;
use laparo_server::engine::scene::Scene;
use laparo_server::engine::simulation::Simulation;
use nalgebra::Vector3;

/// Instrument 0 of `sim` driven by a force loop's device.
///
/// Every haptic tick `t = j / haptic_hz`: the loop ticks (device pose out, newest
/// model in, force to the device). Every mechanics tick (`1 / rate_hz` of the scene):
/// the simulation takes the device's latest pose, ticks, and its local model goes to
/// the loop's inbox, which the loop reads at its next tick. The loop's transition
/// time is the mechanics period, the paper's choice of blending over one model.
pub struct Coupled<D: HapticDevice> {
    pub sim: Simulation,
    pub haptics: ForceLoop<D>,
    inbox: ModelInbox,
    outbox: PoseOutbox,
    haptic_period: f64,
    ticks: u64,
    next_mechanics: f64,
    /// Wall time spent in the simulation's ticks, s: the server's CPU time.
    pub server_seconds: f64,
    /// Largest jump a model switch would have made without blending: the new model's
    /// force at the device pose against the force rendered just before, N.
    pub max_switch_jump: f64,
    /// Largest spring of any plane of any model sent (`λ`, or `κ λ` for the held
    /// tissue's pull), N/m.
    pub max_stiffness: f64,
}

impl<D: HapticDevice> Coupled<D> {
    /// Couples `sim` (instrument 0) with a force loop at `haptic_hz` on `device`.
    pub fn new(sim: Simulation, device: D, haptic_hz: f64) -> Self {
        let trocar = sim.instruments[0].trocar;
        let config = ForceLoopConfig {
            rate_hz: haptic_hz,
            transition_s: sim.dt,
            trocar,
        };
        let (haptics, inbox, outbox) =
            ForceLoop::new(config, device).expect("the harness's configuration is valid");
        Coupled {
            sim,
            haptics,
            inbox,
            outbox,
            haptic_period: 1.0 / haptic_hz,
            ticks: 0,
            next_mechanics: 0.0,
            server_seconds: 0.0,
            max_switch_jump: 0.0,
            max_stiffness: 0.0,
        }
    }

    /// Haptic time of the next tick, s.
    pub fn time(&self) -> f64 {
        self.ticks as f64 * self.haptic_period
    }

    /// One haptic tick, and the mechanics tick when one is due. Returns whether the
    /// mechanics ticked.
    pub fn step(&mut self) -> bool {
        let t = self.time();
        self.haptics.tick(t);
        self.ticks += 1;
        // Half a haptic period of slack against rounding of the two clocks.
        if t + 0.5 * self.haptic_period < self.next_mechanics {
            return false;
        }
        self.next_mechanics += self.sim.dt;
        let pose = self.outbox.latest().expect("the loop ticked");
        self.sim
            .set_pose(0, Some(InstrumentPose::new(pose.tip, pose.axis)));
        let start = Instant::now();
        self.sim.tick();
        self.server_seconds += start.elapsed().as_secs_f64();
        let model = self
            .sim
            .forces
            .as_ref()
            .expect("a scene with instruments")
            .models[0];
        // What the loop rendered at its last tick (before its clamp).
        let rendered = self.haptics.blender().force(t, &pose.tip, &pose.axis).force;
        let jump = (model.force(&pose.tip, &pose.axis).force - rendered).norm();
        self.max_switch_jump = self.max_switch_jump.max(jump);
        for plane in model.tip_plane.iter().chain(&model.shaft_plane) {
            self.max_stiffness = self.max_stiffness.max(plane.stiffest_spring());
        }
        self.inbox.write(model);
        true
    }

    /// Runs until haptic time `t`, s.
    pub fn run_until(&mut self, t: f64) {
        while self.time() < t {
            self.step();
        }
    }
}

/// `scene` with its mechanics at `rate_hz` and force model `kind`, built and settled
/// under gravity for 1 s with its instruments away: where the probes start.
pub fn settled(mut scene: Scene, rate_hz: f64, kind: ForceModelKind) -> Simulation {
    scene.mechanics.rate_hz = rate_hz;
    scene.force_model.kind = kind;
    let mut sim = scene.build().expect("the probed scene builds");
    for _ in 0..rate_hz.round() as usize {
        sim.tick();
    }
    sim
}

/// Instrument 0 of `sim` driven along `probe` by a scripted device through a force
/// loop at `haptic_hz` for `ticks` haptic ticks, the device keeping every force it
/// was sent; `each(coupled, j)` sees the pair after haptic tick `j`.
pub fn probed(
    sim: Simulation,
    probe: &Probe,
    haptic_hz: f64,
    ticks: usize,
    mut each: impl FnMut(&Coupled<ScriptedDevice>, usize),
) -> Coupled<ScriptedDevice> {
    let device = ScriptedDevice::new(probe.trajectory(), 1e3, ticks);
    let mut c = Coupled::new(sim, device, haptic_hz);
    for j in 0..ticks {
        c.step();
        each(&c, j);
    }
    c
}

/// A [`Probe`] of the front face of `sim`'s liver (as it is now) near its middle, by
/// instrument 0: `depth` past the surface, `slide` sideways, m.
pub fn front_probe(sim: &Simulation, depth: f64, slide: f64) -> Probe {
    let surface = sim
        .mesh
        .surface
        .vertices
        .iter()
        .map(|&v| sim.state.x[v as usize]);
    Probe::on_front(surface, sim.instruments[0].trocar, depth, slide)
        .expect("the default liver has a front face")
}

/// The engine alone, with no force loop: `sim` driven along `probe` by instrument 0
/// at its own rate (tick `k` takes the probe's pose at `k · dt`), sampled `samples`
/// times at `sample_hz` from `t = 0`. Each sample is the reaction on the instrument
/// that the last tick at or before it left (zero before the first tick).
/// `after_tick(sim, t)` sees the simulation after each tick, `t` the tick's time.
pub fn reaction_history(
    sim: &mut Simulation,
    probe: &Probe,
    samples: usize,
    sample_hz: f64,
    mut after_tick: impl FnMut(&Simulation, f64),
) -> Vec<Vector3<f64>> {
    let mut reaction = Vector3::zeros();
    let mut k = 0u64;
    (0..samples)
        .map(|j| {
            let t = j as f64 / sample_hz;
            // The slack keeps a tick due at the sample's instant from being read as
            // one after it through round-off of `k · dt`.
            while k as f64 * sim.dt <= t + 1e-9 {
                let at = k as f64 * sim.dt;
                let (tip, axis) = probe.pose(at);
                sim.set_pose(0, Some(InstrumentPose::new(tip, axis)));
                sim.tick();
                after_tick(sim, at);
                reaction = sim.instruments[0].report.reaction;
                k += 1;
            }
            reaction
        })
        .collect()
}
