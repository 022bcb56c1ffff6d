//! The explicit step stays bounded when a press inverts elements: the default liver
//! made nearly incompressible (ν = 0.499), without friction, and stepped explicitly,
//! pressed 6.5 cm deep by the left tip at about 1 m/s (1.7 cm a tick), held and
//! withdrawn. The press turns elements inside out, whose twist stiffness passes the
//! linear bound the substep count was set by (`engine/elastic/twist.rs`). With the
//! scene's substep count alone, the middle press leaves the ±100 m of any physical
//! place at tick 40. Every run must stay finite and within [`FARTHEST`] of rest,
//! and must have needed the extra substeps.
//!
//! The press is run as a grid of nine neighbours ([`SPEEDS`] × [`OFFSETS`]), not one:
//! after the first inversions the motion is chaotic, and how far the tissue rings
//! is not a property of the step. Across the grid the farthest vertex goes 78–106
//! mm; summing each node's settling force in another order, a change of round-off
//! alone, once took the middle press (then 6 cm deep) from 90.7 to 200.9 mm
//! (634 J). What is asserted is what the twist substeps are for: every run finite
//! and bounded ([`FARTHEST`]), where the scene's substeps alone run away.
//!
//! (Until the contact's settling took a jump along the instrument's axis whole, a
//! 3.5 cm jab at 2 m/s did this, and the README's press before the tip's hold was
//! widened; neither inverts elements now: `tests/explicit_chatter.rs`. The press was
//! 6 cm deep until the tip's reach grew from 1.25 to 1.5 radii
//! (`engine/contact/hold.rs`, `TIP_REACH`): the tip then kept its hold through six
//! of the nine 6 cm presses, which inverted nothing. At 6.5 cm all nine invert.)
//!
//! Not asserted: the liver's return to rest. The tip lets go of a vertex the tissue
//! still presses on it once none of its triangles lies within reach of the tip, and
//! takes it back with a jump (issue 15's face contact, not built). 2 s in, the
//! grid's runs are 1.8–68.6 mm from rest; an earlier run of the middle press came
//! to rest 44 mm off with 17 elements inside out, on a spurious minimum of the
//! corotational energy that the twist substeps keep stable but do not leave.

mod common;

use common::contact::pose;
use laparo_server::engine::integrate::kinetic_energy;

/// Seconds: the press and the hold (1 s), the withdrawal (0.5 s) and 0.5 s after.
const SECONDS: f64 = 2.0;

/// Farthest any vertex may go from rest, m: the press's depth and the ringing of
/// the inverted elements. Measured: 77.9–106.1 mm over the grid (the middle press
/// 105.5 mm, kinetic energy up to 65 J); 200.9 mm once for the 6 cm press with the
/// settling's sums reordered (see the module documentation). The bound keeps a
/// quarter over that. A run without the twist substeps leaves ±100 m.
const FARTHEST: f64 = 0.25;

/// The press's speeds, m/s: 1 m/s and 2% either side.
const SPEEDS: [f64; 3] = [0.98, 1.0, 1.02];
/// The tip's offsets along x from the liver's middle, m.
const OFFSETS: [f64; 3] = [-0.5e-3, 0.0, 0.5e-3];
/// The press's depth below the tip's start, m.
const DEPTH: f64 = 0.065;

/// The left tip's height above the liver's middle at `t` (s), m: down from 9 cm at
/// `speed` to 2.5 cm (reached at about 65 ms), held there until 1 s, then back up
/// over half a second.
fn tip_z(speed: f64, t: f64) -> f64 {
    if t < 1.0 {
        (0.09 - speed * t).max(0.09 - DEPTH)
    } else {
        0.09 - DEPTH + DEPTH * ((t - 1.0) / 0.5).min(1.0)
    }
}

/// What one press saw.
struct Run {
    substeps: (u32, u32),
    farthest: f64,
    kinetic: f64,
    end: f64,
}

/// The press at `speed`, the tip `dx` along x, run for [`SECONDS`]; panics on a
/// fault (a non-finite or runaway state).
fn press(speed: f64, dx: f64) -> Run {
    let mut sim = common::nearly_incompressible("explicit", Some(0.0));
    let dt = sim.dt;
    let ticks = (SECONDS / dt).round() as usize;
    let (mut base, mut most) = (u32::MAX, 0);
    let (mut farthest, mut kinetic): (f64, f64) = (0.0, 0.0);
    for k in 1..=ticks {
        let t = k as f64 * dt;
        sim.set_pose(0, Some(pose([dx, 0.0, tip_z(speed, t)], [0.0, 0.0, 1.0])));
        let report = sim.tick();
        base = base.min(report.substeps);
        most = most.max(report.substeps);
        let fault = laparo_server::headless::fault(&sim);
        assert!(fault.is_none(), "{speed} m/s, {dx} m, tick {k}: {fault:?}");
        farthest = farthest.max(sim.max_displacement());
        kinetic = kinetic.max(kinetic_energy(&sim.model, &sim.state));
    }
    Run {
        substeps: (base, most),
        farthest,
        kinetic,
        end: sim.max_displacement(),
    }
}

#[test]
fn a_press_that_inverts_elements_stays_bounded_when_stepped_explicitly() {
    let cases: Vec<(f64, f64)> = SPEEDS
        .iter()
        .flat_map(|&s| OFFSETS.iter().map(move |&dx| (s, dx)))
        .collect();
    // Two threads: the presses are independent and each takes seconds.
    let runs: Vec<Run> = std::thread::scope(|scope| {
        let (front, back) = cases.split_at(cases.len() / 2);
        let other = scope.spawn(|| back.iter().map(|&(s, dx)| press(s, dx)).collect::<Vec<_>>());
        let mut runs: Vec<Run> = front.iter().map(|&(s, dx)| press(s, dx)).collect();
        runs.extend(other.join().expect("the other presses ran"));
        runs
    });
    for (&(speed, dx), run) in cases.iter().zip(&runs) {
        println!(
            "{speed} m/s, x {:+.1} mm: substeps {}–{}, farthest {:.1} mm, kinetic ≤ {:.3} J; at {SECONDS} s {:.1} mm",
            dx * 1e3,
            run.substeps.0,
            run.substeps.1,
            run.farthest * 1e3,
            run.kinetic,
            run.end * 1e3
        );
    }
    for (&(speed, dx), run) in cases.iter().zip(&runs) {
        assert!(
            run.substeps.1 > run.substeps.0,
            "{speed} m/s, {dx} m: no tick needed more substeps"
        );
        assert!(
            run.farthest <= FARTHEST,
            "{speed} m/s, {dx} m: {} m from rest",
            run.farthest
        );
        assert!(
            run.end <= FARTHEST,
            "{speed} m/s, {dx} m: {} m from rest at the end",
            run.end
        );
    }
}
