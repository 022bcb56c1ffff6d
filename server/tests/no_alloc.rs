//! A mechanics step allocates nothing: every integrator's buffers are allocated when
//! it is built. A counting global allocator sees every allocation of this test binary.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};

use laparo_server::engine::integrate::IntegratorKind;
use laparo_server::engine::scene::Scene;
use nalgebra::Vector3;

struct Counting;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn ticks_allocate_nothing() {
    for kind in [
        IntegratorKind::Explicit,
        IntegratorKind::Implicit,
        IntegratorKind::Static,
    ] {
        let mut scene = Scene::default_scene();
        scene.mechanics.integrator = kind;
        let mut sim = scene.build().unwrap();
        // Move some vertices as an instrument would, so imposed targets change too.
        let held: Vec<u32> = (0..sim.mesh.vertex_count() as u32)
            .filter(|i| !sim.fixed.contains(i))
            .take(5)
            .collect();
        sim.tick();
        let before = ALLOCATIONS.load(Ordering::SeqCst);
        for k in 0..20 {
            for &i in &held {
                let push = Vector3::new(0.0, 0.0, -0.0002 * k as f64);
                sim.imposed.set(i, sim.model.rest[i as usize] + push);
            }
            sim.tick();
            if k == 10 {
                for &i in &held {
                    sim.imposed.release(i);
                }
            }
        }
        let after = ALLOCATIONS.load(Ordering::SeqCst);
        assert_eq!(
            after - before,
            0,
            "{kind:?}: {} allocations in 20 ticks",
            after - before
        );
    }
}
