//! A deep press on nearly incompressible tissue holds without chatter, stepped
//! explicitly as implicitly: the default liver at ν = 0.499, pressed 3.5 cm by the
//! left tip and held until 2 s, either over a second (the README's press) or as a
//! jab at 2 m/s (in about one tick).
//!
//! *The press.* The tip press lays the triangle under the tip on the tip and keeps
//! the vertices the tissue presses on it; the one it pulls away is let go, and the
//! triangle turns about its held edge as that vertex follows the tissue. While the
//! bound on that turn was 1.05 r (`hold::TIP_REACH`), the press let both held
//! vertices go at 0.75–0.77 s, 5 mm past the first touch, and caught the tissue
//! again the next tick with a jump. From then on the held set cycled between 3 and 0
//! vertices every few ticks to the end of the hold, with 30–65 N on each retake
//! stepped implicitly and 44–76 N stepped explicitly (the chatter issue 15 names),
//! where the hold is 2.76 N.
//!
//! *The jab.* While the settling around the contact's jumps scaled every jump down to
//! one radius (`SETTLE_REACH` in the contact stage), the jab's 3.5 cm jump left
//! 1.04 J of strain energy around it, 25 times the hold's, and its tick gave 78 N.
//! The implicit step dissipated it within five ticks; the explicit step rang with
//! 0.2–0.9 J of kinetic energy, let the tissue go and caught it again with 54–104 N
//! for the rest of the hold.
//!
//! Checked here, for both integrators and both gestures, with the scene's friction
//! and without:
//! - from the first touch to the end the tip always holds something;
//! - over the last half second the held set does not change;
//! - the first touch's force is at most twice the end's (issue 15's bound on a
//!   first contact), and no tick's force exceeds the end's by more than half for the
//!   press, or twice it for the jab (2.5 times without friction, see the test): a
//!   retake's jump gave 11–44 times it;
//! - at the end the explicit and implicit forces agree within 1% for the press: both
//!   hold the same vertices in equilibrium, where the two integrators must reach the
//!   same static answer (3% for the jab, whose held vertices stick where its first
//!   ticks left them).

mod common;

use common::contact::pose;

/// The left tip's height above the liver's middle at `t` (s), m: 9 cm down to 5.5 cm
/// at `speed` (m/s), then held.
fn tip_z(t: f64, speed: f64) -> f64 {
    (0.09 - speed * t).max(0.055)
}

/// The README's press: 3.5 cm over a second, m/s.
const PRESS: f64 = 0.035;
/// The jab, m/s: 3.3 cm on the first tick at 60 Hz, the rest on the second.
const JAB: f64 = 2.0;

/// The press and the hold, s.
const SECONDS: f64 = 2.0;

/// What one run shows.
struct Hold {
    /// The force on the tick of the first touch, N.
    first: f64,
    /// The force at the end of the hold, N.
    end: f64,
    /// The largest force of any tick, N.
    largest: f64,
}

fn press(integrator: &str, friction: Option<f64>, speed: f64) -> Hold {
    let mut sim = common::nearly_incompressible(integrator, friction);
    let dt = sim.dt;
    let ticks = (SECONDS / dt).round() as usize;
    let settled_from = ((SECONDS - 0.5) / dt).round() as usize;
    let (mut touched, mut first, mut largest, mut settled) = (None, 0.0, 0.0f64, None);
    for k in 1..=ticks {
        let t = k as f64 * dt;
        sim.set_pose(0, Some(pose([0.0, 0.0, tip_z(t, speed)], [0.0, 0.0, 1.0])));
        sim.tick();
        let fault = laparo_server::headless::fault(&sim);
        assert!(
            fault.is_none(),
            "{integrator}, {friction:?}, tick {k}: {fault:?}"
        );
        let ins = &sim.instruments[0];
        let mut held = ins.held.clone();
        held.sort_unstable();
        if touched.is_none() && !held.is_empty() {
            touched = Some(t);
            first = ins.report.reaction.norm();
        }
        assert!(
            touched.is_none() || !held.is_empty(),
            "{integrator}, friction {friction:?}, {speed} m/s: the tip let everything go \
             at {t:.3} s, {:.1} mm past its first touch",
            (tip_z(touched.unwrap_or(t), speed) - tip_z(t, speed)) * 1e3
        );
        if k == settled_from {
            settled = Some(held.clone());
        }
        if k > settled_from {
            assert_eq!(
                Some(&held),
                settled.as_ref(),
                "{integrator}, friction {friction:?}, {speed} m/s: the held set changed at \
                 {t:.3} s"
            );
        }
        largest = largest.max(ins.report.reaction.norm());
    }
    let end = sim.instruments[0].report.reaction.norm();
    println!(
        "{integrator}, friction {friction:?}, {speed} m/s: first touch {:.3} s, {} held \
         at the end, {end:.3} N, first {first:.3} N, largest {largest:.3} N",
        touched.unwrap_or(f64::NAN),
        sim.instruments[0].held.len()
    );
    assert!(touched.is_some(), "{integrator}: the press touched nothing");
    Hold {
        first,
        end,
        largest,
    }
}

#[test]
fn a_deep_press_on_nearly_incompressible_tissue_holds_steadily_stepped_either_way() {
    both_ways(PRESS, &[None, Some(0.0)], 1.5, 0.01);
}

#[test]
fn a_deep_jab_on_nearly_incompressible_tissue_holds_steadily_stepped_either_way() {
    // With the scene's friction the held vertices stick where the jab's first ticks
    // left them, which the two integrators' transients set apart by a little: 2.3%
    // in force.
    both_ways(JAB, &[None], 2.0, 0.03);
    // Without friction the same two vertices are held from the second tick to the
    // end by both integrators (this once let go on the explicit step's third tick
    // and caught the tissue again with 12 N, 5× the hold). The ticks after the
    // first touch, while the tip arrives, give what they give with friction
    // (3.8–4.0 N), but the held vertices then slide until the drag is gone, and the
    // hold ends lower, 1.87–1.88 N: 2.0–2.1× below those ticks, so the bound on any
    // tick is 2.5× here. A retake would still pass it several times over.
    both_ways(JAB, &[Some(0.0)], 2.5, 0.03);
}

/// The first-contact tick's force against the hold's, at most: issue 15's bound.
const FIRST_TOUCH: f64 = 2.0;

/// The gesture at `speed` stepped both ways with each friction (`None`: the
/// scene's): the first touch within [`FIRST_TOUCH`] and no tick above `bound` times
/// the end's force, and the two ends within `agree` of each other.
fn both_ways(speed: f64, frictions: &[Option<f64>], bound: f64, agree: f64) {
    for &friction in frictions {
        let implicit = press("implicit", friction, speed);
        let explicit = press("explicit", friction, speed);
        for (name, run) in [("implicit", &implicit), ("explicit", &explicit)] {
            assert!(
                run.first <= FIRST_TOUCH * run.end,
                "{name}, friction {friction:?}, {speed} m/s: the first touch gave {} N, \
                 the hold ends at {} N",
                run.first,
                run.end
            );
            assert!(
                run.largest <= bound * run.end,
                "{name}, friction {friction:?}, {speed} m/s: a tick gave {} N, the hold \
                 ends at {} N",
                run.largest,
                run.end
            );
        }
        let apart = (explicit.end - implicit.end).abs() / implicit.end;
        println!(
            "friction {friction:?}, {speed} m/s: explicit and implicit {:.2}% apart",
            apart * 100.0
        );
        assert!(
            apart <= agree,
            "friction {friction:?}, {speed} m/s: explicit {} N, implicit {} N",
            explicit.end,
            implicit.end
        );
    }
}
