//! The force loop on its own thread: it runs, takes every model sent (one at a time),
//! publishes its statistics, and gives the device back when stopped or dropped. No
//! assertion depends on timing values: the machine may be slow or shared.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use laparo_client::haptics::{ForceLoop, ForceLoopConfig, HapticDevice, ScriptedDevice};
use laparo_client::proto::force::{DeviceForce, ForceModel, LocalModel, Plane};
use nalgebra::{Point3, Unit, Vector3};

const TROCAR: Point3<f64> = Point3::new(0.0, 0.0, 0.12);

fn model(tick: u64) -> LocalModel {
    LocalModel {
        tick,
        sim_time: tick as f64 / 60.0,
        tip: Point3::origin(),
        axis: Vector3::z_axis(),
        tip_plane: Some(Plane {
            normal: Vector3::z_axis(),
            anchor: Point3::origin(),
            stiffness: 300.0 + tick as f64,
            drag: Vector3::zeros(),
        }),
        shaft_plane: None,
        kind: ForceModel::Geometric,
        young_modulus: None,
    }
}

/// Polls `done` every millisecond for up to 20 s (a generous bound, not a timing
/// assertion).
fn wait_for(mut done: impl FnMut() -> bool) {
    let start = Instant::now();
    while !done() {
        assert!(start.elapsed() < Duration::from_secs(20), "gave up waiting");
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn spawned_loop_runs_takes_every_model_and_returns_the_device() {
    let tip = Point3::new(0.0, 0.0, -0.005);
    let device = ScriptedDevice::fixed(tip, Unit::new_normalize(TROCAR - tip), 10.0, 64);
    let (force_loop, mut inbox, mut outbox) =
        ForceLoop::new(ForceLoopConfig::new(TROCAR), device).unwrap();
    let mut handle = force_loop.spawn();
    for tick in 1..=3 {
        inbox.write(model(tick));
        wait_for(|| inbox.consumed());
    }
    wait_for(|| handle.stats().ticks > 0);
    let live = handle.stats();
    assert!(live.rate_hz >= 0.0 && live.jitter.p50 <= live.jitter.max);
    let pose = outbox.latest().expect("the loop publishes the device pose");
    assert_eq!(pose.tip, tip);

    let (device, stats) = handle.stop();
    assert!(stats.ticks >= live.ticks);
    assert_eq!(stats.models_received, 3);
    assert_eq!(stats.model_tick, Some(3));
    assert_eq!(device.rendered(), stats.ticks);
    let last = device.last().unwrap();
    assert!(
        last.force.force.z > 0.0,
        "pressing in gives an upward force"
    );
}

/// A device that says when it is dropped.
struct Watched(Arc<AtomicBool>);

impl HapticDevice for Watched {
    fn pose(&mut self, _t: f64) -> (Point3<f64>, Unit<Vector3<f64>>) {
        (Point3::origin(), Vector3::z_axis())
    }
    fn render(&mut self, _t: f64, _force: &DeviceForce) {}
    fn max_force(&self) -> f64 {
        1.0
    }
}

impl Drop for Watched {
    fn drop(&mut self) {
        self.0.store(true, Ordering::SeqCst);
    }
}

#[test]
fn dropping_the_handle_stops_the_thread() {
    let dropped = Arc::new(AtomicBool::new(false));
    let (force_loop, _inbox, mut outbox) =
        ForceLoop::new(ForceLoopConfig::new(TROCAR), Watched(Arc::clone(&dropped))).unwrap();
    let handle = force_loop.spawn();
    wait_for(|| outbox.latest().is_some());
    assert!(!dropped.load(Ordering::SeqCst));
    drop(handle);
    // The thread was joined: it returned and dropped the device before drop returned.
    assert!(dropped.load(Ordering::SeqCst));
}
