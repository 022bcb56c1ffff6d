//! The explicit step stays bounded when a press inverts elements: the default liver
//! made nearly incompressible (ν = 0.499), without friction, and stepped explicitly,
//! pressed 6 cm deep by the left tip at 1 m/s (1.7 cm a tick), held and withdrawn.
//! The press turns elements inside out, whose twist stiffness passes the linear
//! bound the substep count was set by (`engine/elastic/twist.rs`). With the scene's
//! substep count alone, the run leaves the ±100 m of any physical place at tick 53.
//! The run must stay finite and within 10 cm of rest, and must have needed the extra
//! substeps.
//!
//! (Until the contact's settling took a jump along the instrument's axis whole, a
//! 3.5 cm jab at 2 m/s did this, and the README's press before the tip's hold was
//! widened; neither inverts elements now: `tests/explicit_chatter.rs`.)
//!
//! Not asserted: the liver's return to rest. After the withdrawal it came to rest
//! 44 mm from its sag, holding nothing, with elements still inside out: the
//! corotational energy has a spurious minimum there, which the twist substeps keep
//! stable but do not leave (issue 15's stated limit). Since the settling's Newton
//! passes (`contact/settle.rs`) it is 10.1 mm off 2 s in, still moving (3.5e-3 J).

mod common;

use common::contact::pose;
use laparo_server::engine::integrate::kinetic_energy;

/// Seconds: the press and the hold (1 s), the withdrawal (0.5 s) and 0.5 s after.
const SECONDS: f64 = 2.0;

/// Farthest any vertex may go from rest, m: the press's depth and the ringing of
/// the inverted elements (82.8 mm seen; 90.7 mm with the settling's Newton passes).
const FARTHEST: f64 = 0.1;

/// The left tip's height above the liver's middle at `t` (s), m: down from 9 cm at
/// 1 m/s to 3 cm (reached at 60 ms), held there until 1 s, then back up over half a
/// second.
fn tip_z(t: f64) -> f64 {
    if t < 1.0 {
        (0.09 - PRESS_SPEED * t).max(0.09 - DEPTH)
    } else {
        0.09 - DEPTH + DEPTH * ((t - 1.0) / 0.5).min(1.0)
    }
}

/// The press's speed, m/s.
const PRESS_SPEED: f64 = 1.0;
/// The press's depth below the tip's start, m.
const DEPTH: f64 = 0.06;

#[test]
fn a_press_that_inverts_elements_stays_bounded_when_stepped_explicitly() {
    let friction = Some(0.0);
    let mut sim = common::nearly_incompressible("explicit", friction);
    let dt = sim.dt;
    let ticks = (SECONDS / dt).round() as usize;
    let (mut base, mut most) = (u32::MAX, 0);
    let (mut farthest, mut kinetic): (f64, f64) = (0.0, 0.0);
    for k in 1..=ticks {
        let t = k as f64 * dt;
        sim.set_pose(0, Some(pose([0.0, 0.0, tip_z(t)], [0.0, 0.0, 1.0])));
        let report = sim.tick();
        base = base.min(report.substeps);
        most = most.max(report.substeps);
        let fault = laparo_server::headless::fault(&sim);
        assert!(
            fault.is_none(),
            "friction {friction:?}, tick {k}: {fault:?}"
        );
        farthest = farthest.max(sim.max_displacement());
        kinetic = kinetic.max(kinetic_energy(&sim.model, &sim.state));
    }
    let end = sim.max_displacement();
    let end_kinetic = kinetic_energy(&sim.model, &sim.state);
    println!(
        "friction {friction:?}: substeps {base}–{most}, farthest {:.1} mm, kinetic ≤ {kinetic:.3} J; \
         at {SECONDS} s {:.1} mm, {end_kinetic:.2e} J",
        farthest * 1e3,
        end * 1e3
    );
    assert!(
        most > base,
        "friction {friction:?}: no tick needed more substeps"
    );
    assert!(farthest <= FARTHEST, "friction {friction:?}: {farthest} m");
    assert!(end <= FARTHEST, "friction {friction:?}: {end} m at the end");
}
