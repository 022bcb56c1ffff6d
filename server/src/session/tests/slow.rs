//! A session whose ticks run slower than their period.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use super::*;
use crate::engine::integrate::IntegratorKind;

/// The default scene made slow on purpose: explicit at 1 kHz on tissue of 100 MPa
/// takes about 300 substeps and 13 ms a tick on this machine, so one simulated
/// second is about 13 s of wall time.
fn slow_scene() -> Scene {
    let mut scene = Scene::default_scene();
    scene.material.young_modulus = 1e8;
    scene.mechanics.integrator = IntegratorKind::Explicit;
    scene.mechanics.rate_hz = 1000.0;
    scene
}

/// The idle timeout and the tick times are looked at once a second of wall time
/// when a simulated second takes longer: they used to wait for a simulated second
/// of ticks, which a scene at the work bound (30 s a tick) reaches after 30 minutes,
/// holding its session slot and a core all that time.
#[test]
fn a_session_slower_than_real_time_reports_its_ticks_and_closes_when_idle() {
    let config = SessionConfig {
        idle_timeout: Some(Duration::from_millis(500)),
        recordings: None,
    };
    let start = Instant::now();
    let session = Session::start("s1".into(), slow_scene(), &config).unwrap();
    // Nobody joins. Closed after a check finds it idle and the next finds it idle
    // for the timeout: about 2 s, where a simulated second takes about 13 s (and
    // more on a slower or busier machine).
    let bound = Duration::from_secs(8);
    while !session.is_closed() && start.elapsed() < bound {
        std::thread::sleep(Duration::from_millis(20));
    }
    let ticks = session.stats.tick.load(Ordering::Relaxed);
    assert!(
        session.is_closed(),
        "still open after {:?} and {ticks} ticks",
        start.elapsed()
    );
    let dt = 1.0 / session.scene.mechanics.rate_hz;
    assert!(
        (ticks as f64) * dt < 1.0,
        "{ticks} ticks: a simulated second passed, so this says nothing of slow ticks"
    );
    let p50 = f64::from_bits(session.stats.tick_p50_bits.load(Ordering::Relaxed));
    assert!(p50 > 0.0, "no tick time reported before the close");
}
