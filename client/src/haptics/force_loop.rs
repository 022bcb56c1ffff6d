//! The haptic-rate force loop: device pose → blended local models → clamped force →
//! device, about a thousand times a second.
//!
//! [`ForceLoop::tick`] is one tick, synchronous and deterministic in the haptic time it
//! is given: tests and benchmarks drive it in simulated time. [`ForceLoop::spawn`]
//! runs it on its own OS thread at the configured rate against absolute deadlines.
//! Nothing in a tick allocates, locks or blocks: models come in and poses go out
//! through wait-free latest-value slots ([`super::slot`]).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use nalgebra::{Point3, Vector3};
use triple_buffer::{Output, triple_buffer};

use super::blend::Blender;
use super::device::{DevicePose, HapticDevice};
use super::passivity::Passivity;
use super::slot::{ModelInbox, ModelSlot, PoseOutbox, PoseSlot, slot};
use super::stats::{Limit, LoopStats, StatsRecorder};
use crate::proto::force::{DeviceForce, split};

/// The default haptic rate, Hz.
pub const DEFAULT_RATE_HZ: f64 = 1000.0;
/// The accepted haptic rates, Hz: the paper asks for 300 Hz or more; above 4 kHz a
/// general-purpose OS cannot keep the deadlines.
pub const RATE_RANGE_HZ: std::ops::RangeInclusive<f64> = 300.0..=4000.0;
/// The default transition time between two local models, s: one mechanics tick at
/// 60 Hz.
pub const DEFAULT_TRANSITION_S: f64 = 1.0 / 60.0;
/// How often (in ticks) the loop thread publishes its statistics.
pub const STATS_EVERY_TICKS: u64 = 100;

/// The force loop's configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceLoopConfig {
    /// Haptic rate, Hz, in [`RATE_RANGE_HZ`].
    pub rate_hz: f64,
    /// Transition time `τ` between two successive local models, s, finite and > 0
    /// (see [`super::blend`]).
    pub transition_s: f64,
    /// The trocar point the instrument pivots about, m, world frame; torques are
    /// taken about it.
    pub trocar: Point3<f64>,
}

impl ForceLoopConfig {
    /// The default rate and transition time, with the instrument's trocar.
    pub fn new(trocar: Point3<f64>) -> Self {
        ForceLoopConfig {
            rate_hz: DEFAULT_RATE_HZ,
            transition_s: DEFAULT_TRANSITION_S,
            trocar,
        }
    }

    /// Checks every field, naming the first one out of range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !RATE_RANGE_HZ.contains(&self.rate_hz) {
            return Err(ConfigError {
                field: "rate_hz",
                value: self.rate_hz,
                expected: "between 300 and 4000 Hz",
            });
        }
        if !(self.transition_s.is_finite() && self.transition_s > 0.0) {
            return Err(ConfigError {
                field: "transition_s",
                value: self.transition_s,
                expected: "finite and > 0 s",
            });
        }
        if let Some(&c) = self.trocar.coords.iter().find(|c| !c.is_finite()) {
            return Err(ConfigError {
                field: "trocar",
                value: c,
                expected: "finite coordinates, m",
            });
        }
        Ok(())
    }

    /// The nominal period, s.
    pub fn period_s(&self) -> f64 {
        1.0 / self.rate_hz
    }
}

/// A configuration field out of range.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error(
    "force loop configuration: {field} = {} is out of range (expected {expected})",
    laparo_proto::text::Number(*value)
)]
pub struct ConfigError {
    /// The field, as named in [`ForceLoopConfig`].
    pub field: &'static str,
    /// The value given.
    pub value: f64,
    /// The accepted range.
    pub expected: &'static str,
}

/// Limits `force` to magnitude `max`, keeping its direction; a non-finite force (or
/// limit) gives zero.
pub fn clamp_force(force: &Vector3<f64>, max: f64) -> (Vector3<f64>, Limit) {
    let magnitude = force.norm();
    if !magnitude.is_finite() || max.is_nan() {
        return (Vector3::zeros(), Limit::NonFinite);
    }
    if magnitude > max {
        if max <= 0.0 {
            return (Vector3::zeros(), Limit::Clamped);
        }
        return (force * (max / magnitude), Limit::Clamped);
    }
    (*force, Limit::None)
}

/// The force loop of one instrument; see the [module documentation](self).
pub struct ForceLoop<D: HapticDevice> {
    config: ForceLoopConfig,
    device: D,
    models: ModelSlot,
    poses: PoseSlot,
    blender: Blender,
    passivity: Passivity,
    stats: StatsRecorder,
    rendered: DeviceForce,
}

impl<D: HapticDevice> ForceLoop<D> {
    /// A force loop for `device`, with the network side's ends of its slots: the
    /// inbox to write local models into, and the outbox to read the newest device
    /// pose from.
    pub fn new(
        config: ForceLoopConfig,
        device: D,
    ) -> Result<(ForceLoop<D>, ModelInbox, PoseOutbox), ConfigError> {
        config.validate()?;
        let (inbox, models) = slot();
        let (poses, outbox) = slot();
        let max_stiffness = device.max_stiffness();
        let force_loop = ForceLoop {
            config,
            device,
            models,
            poses,
            blender: Blender::new(config.transition_s),
            passivity: Passivity::new(max_stiffness),
            stats: StatsRecorder::new(config.period_s()),
            rendered: DeviceForce {
                force: Vector3::zeros(),
                axial: 0.0,
                torque: Vector3::zeros(),
            },
        };
        Ok((force_loop, inbox, outbox))
    }

    /// One haptic tick at haptic time `t` (s): read the device pose and publish it,
    /// take the newest model if one arrived, blend, damp what the models gave the
    /// hand beyond what it put in ([`super::passivity`]), clamp to the device's
    /// limit, split into the device's force and torque about the trocar, render,
    /// record. No allocation, no lock, no blocking.
    pub fn tick(&mut self, t: f64) {
        let (tip, axis) = self.device.pose(t);
        self.poses.write(DevicePose { time: t, tip, axis });
        self.passivity.observe(t, &tip, &axis);
        if let Some(mut model) = self.models.take_new() {
            let limit = self.device.max_stiffness();
            for plane in model
                .tip_plane
                .iter_mut()
                .chain(model.shaft_plane.iter_mut())
            {
                plane.limit_stiffness(limit);
            }
            self.blender.arrive(t, model, &tip, &axis);
            self.stats.record_model();
        }
        let applied = self.blender.force(t, &tip, &axis);
        let passive = self.passivity.control(&applied.force);
        let (force, limit) = clamp_force(&passive, self.device.max_force());
        let rendered = split(&force, &applied.point, &axis, &self.config.trocar);
        self.device.render(t, &rendered);
        self.passivity
            .rendered(t, force, applied.point, (applied.point - tip).dot(&axis));
        self.rendered = rendered;
        let model = self
            .blender
            .current()
            .zip(self.blender.arrival_time())
            .map(|(m, arrival)| (arrival, m.tick));
        self.stats.record_tick(t, &force, limit, model);
    }

    /// What the last tick rendered (after the clamp).
    pub fn rendered(&self) -> &DeviceForce {
        &self.rendered
    }

    /// The configuration.
    pub fn config(&self) -> &ForceLoopConfig {
        &self.config
    }

    /// The figures so far.
    pub fn stats(&self) -> LoopStats {
        LoopStats {
            damped_ticks: self.passivity.damped_ticks(),
            ..self.stats.snapshot()
        }
    }

    /// The blender, with the models in use.
    pub fn blender(&self) -> &Blender {
        &self.blender
    }

    /// The device.
    pub fn device(&self) -> &D {
        &self.device
    }

    /// The device, mutably.
    pub fn device_mut(&mut self) -> &mut D {
        &mut self.device
    }

    /// The device back, with the final figures.
    pub fn into_parts(self) -> (D, LoopStats) {
        let stats = self.stats();
        (self.device, stats)
    }
}

impl<D: HapticDevice + 'static> ForceLoop<D> {
    /// Runs the loop on its own OS thread, named `laparo-force-loop`, at the
    /// configured rate.
    ///
    /// Tick `k` is due at `start + k·period` (absolute deadlines: no drift), and runs
    /// at haptic time = wall time since `start`. The thread sleeps until each
    /// deadline; when it wakes more than a period late it counts the deadlines it
    /// missed and moves on to the next one due, rather than running a burst of ticks
    /// to catch up. Statistics are published every [`STATS_EVERY_TICKS`] ticks.
    ///
    /// Panics if the OS cannot create a thread, as [`std::thread::spawn`] does.
    pub fn spawn(self) -> ForceLoopHandle<D> {
        let stop = Arc::new(AtomicBool::new(false));
        let (mut stats_in, stats_out) = triple_buffer(&LoopStats::default());
        let thread_stop = Arc::clone(&stop);
        let mut force_loop = self;
        let thread = std::thread::Builder::new()
            .name("laparo-force-loop".into())
            .spawn(move || {
                let period = Duration::from_secs_f64(force_loop.config.period_s());
                let start = Instant::now();
                let mut k: u64 = 0;
                let mut ticks: u64 = 0;
                while !thread_stop.load(Ordering::Relaxed) {
                    force_loop.tick(start.elapsed().as_secs_f64());
                    ticks += 1;
                    if ticks.is_multiple_of(STATS_EVERY_TICKS) {
                        stats_in.write(force_loop.stats());
                    }
                    k += 1;
                    let mut deadline = start + period.mul_f64(k as f64);
                    let now = Instant::now();
                    if now > deadline + period {
                        let late = (now - deadline).as_secs_f64() / period.as_secs_f64();
                        let missed = late.floor() as u64;
                        force_loop.stats.record_missed(missed);
                        k += missed;
                        deadline = start + period.mul_f64(k as f64);
                    }
                    if let Some(wait) = deadline.checked_duration_since(now) {
                        std::thread::sleep(wait);
                    }
                }
                force_loop.into_parts()
            })
            .expect("failed to spawn the force-loop thread");
        ForceLoopHandle {
            stop,
            stats: stats_out,
            thread: Some(thread),
        }
    }
}

impl<D: HapticDevice> std::fmt::Debug for ForceLoop<D> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ForceLoop")
            .field("config", &self.config)
            .field("blender", &self.blender)
            .finish_non_exhaustive()
    }
}

/// A force loop running on its own thread. Dropping it stops the thread.
pub struct ForceLoopHandle<D: HapticDevice> {
    stop: Arc<AtomicBool>,
    stats: Output<LoopStats>,
    thread: Option<JoinHandle<(D, LoopStats)>>,
}

impl<D: HapticDevice> ForceLoopHandle<D> {
    /// The newest statistics the loop published (every [`STATS_EVERY_TICKS`] ticks).
    pub fn stats(&mut self) -> LoopStats {
        *self.stats.read()
    }

    /// Stops the loop after its current tick, joins its thread, and returns the
    /// device and the final statistics. A panic on the loop thread is resumed here.
    pub fn stop(mut self) -> (D, LoopStats) {
        self.stop.store(true, Ordering::Relaxed);
        let thread = self.thread.take().expect("the thread is joined only here");
        match thread.join() {
            Ok(parts) => parts,
            Err(panic) => std::panic::resume_unwind(panic),
        }
    }
}

impl<D: HapticDevice> Drop for ForceLoopHandle<D> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl<D: HapticDevice> std::fmt::Debug for ForceLoopHandle<D> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ForceLoopHandle")
            .field("running", &self.thread.is_some())
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests;
