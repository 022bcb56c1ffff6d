//! The force loop's tick allocates nothing: a counting global allocator counts the
//! allocations made on this thread while a flag is set, around 10 000 ticks with
//! models arriving.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use laparo_client::haptics::{
    ForceLoop, ForceLoopConfig, HandDevice, HandParams, HapticDevice, ScriptedDevice,
};
use laparo_client::proto::force::{ForceModel, LocalModel, Plane};
use nalgebra::{Point3, Unit, Vector3};

struct Counting;

// Both the flag and the count are per thread: the test harness runs tests on
// several threads at once, and one test's allocations must not count in another's.
thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn note() {
    // `try_with`: a thread's locals may already be gone while it frees its last
    // allocations at exit.
    if COUNTING.try_with(Cell::get).unwrap_or(false) {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
    }
}

// SAFETY: forwards every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note();
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note();
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        note();
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations made on this thread while running `f`.
fn allocations_in(f: impl FnOnce()) -> u64 {
    let before = ALLOCATIONS.with(Cell::get);
    COUNTING.with(|c| c.set(true));
    f();
    COUNTING.with(|c| c.set(false));
    ALLOCATIONS.with(Cell::get) - before
}

const TROCAR: Point3<f64> = Point3::new(0.01, 0.0, 0.12);

/// One model per mechanics tick, with tip and shaft planes that change each time.
fn models(n: usize) -> Vec<LocalModel> {
    (0..n)
        .map(|i| {
            let a = i as f64 * 0.37;
            LocalModel {
                tick: i as u64,
                sim_time: i as f64 / 60.0,
                tip: Point3::origin(),
                axis: Vector3::z_axis(),
                tip_plane: (i % 5 != 4).then(|| Plane {
                    normal: Unit::new_normalize(Vector3::new(0.2 * a.sin(), 0.2 * a.cos(), 1.0)),
                    anchor: Point3::new(0.0, 0.0, 0.002 * a.sin()),
                    stiffness: 300.0 + 100.0 * a.cos(),
                    drag: Vector3::zeros(),
                }),
                shaft_plane: (i % 3 == 0).then(|| Plane {
                    normal: Unit::new_normalize(Vector3::new(1.0, 0.1 * a.sin(), 0.0)),
                    anchor: Point3::new(0.004, 0.0, 0.01),
                    stiffness: 200.0,
                    drag: Vector3::zeros(),
                }),
                kind: ForceModel::Calibrated,
                young_modulus: Some(3.0e3),
            }
        })
        .collect()
}

fn run<D: HapticDevice>(device: D) -> u64 {
    let config = ForceLoopConfig::new(TROCAR);
    let (mut force_loop, mut inbox, mut outbox) = ForceLoop::new(config, device).unwrap();
    let models = models(10_000usize.div_ceil(16));
    let dt = config.period_s();
    let allocations = allocations_in(|| {
        for k in 0..10_000usize {
            if k % 16 == 0 {
                inbox.write(models[k / 16]);
            }
            force_loop.tick(k as f64 * dt);
            let _ = outbox.take_new();
            if k % 100 == 0 {
                let _ = force_loop.stats();
            }
        }
    });
    let stats = force_loop.stats();
    assert_eq!(stats.ticks, 10_000);
    assert_eq!(stats.models_received, models.len() as u64);
    assert!(stats.max_force_step > 0.0, "the test must exercise forces");
    allocations
}

#[test]
fn ticks_with_a_scripted_device_allocate_nothing() {
    let path = Box::new(|t: f64| {
        let tip = Point3::new(
            0.003 * (3.0 * t).sin(),
            0.0,
            -0.01 * (1.0 + (2.0 * t).sin()),
        );
        (tip, Unit::new_normalize(TROCAR - tip))
    });
    assert_eq!(run(ScriptedDevice::new(path, 8.0, 512)), 0);
}

#[test]
fn ticks_with_a_hand_allocate_nothing() {
    let target = Box::new(|t: f64| (Point3::new(0.0, 0.005 * t.sin(), -0.015), Vector3::z_axis()));
    let hand = HandDevice::new(
        HandParams::default(),
        TROCAR,
        Point3::new(0.0, 0.0, 0.01),
        target,
    );
    assert_eq!(run(hand), 0);
}

#[test]
fn the_counter_counts() {
    assert!(allocations_in(|| drop(std::hint::black_box(vec![1u8; 64]))) >= 1);
}
