//! Two instruments crossing deep inside the liver, held still: while what they hold
//! does not change, neither does their force.
//!
//! Both come in through their trocars, tilted 0.15 rad apart (up and down), to 22,
//! 24 and 26 cm (past each other, through the liver's middle), over a second, and
//! hold for two. The elements between the two shafts are stretched along one axis
//! and pressed through their flat state along another (stretches like 4.6, −0.3,
//! 0.7), where the corotated energy's twist stiffness is several times the
//! stiffest wave's modulus. Stepped with the rotations frozen over the tick and
//! nothing of that stiffness, the implicit step overshot and the tissue cycled
//! with period two, the held sets unchanged: 8.2 ↔ 8.9 N on the left instrument at
//! 24 cm, its tick-to-tick change 1.8%, 9.4% and 12.2% at 22, 24 and 26 cm. With
//! the positive twists in the step's tangent (`elastic/twist_tangent.rs`) it is
//! steady to the digit printed.
//!
//! Not checked here: with the shafts 0.1 rad apart (at 20, 24 and 26 cm), the held
//! sets themselves change every tick (the tip lays one coarse triangle on its end,
//! then another), and the force with them, 4–29% a tick (3–69% before the twists).
//! At 20 cm and 0.05 rad they did not before the twists and do since (6% and 16%),
//! while at 24 and 26 cm and 0.05 rad they did (3–31%) and no longer do. That is
//! issue 15's contact on the face under the tip, not the step.

mod common;

use common::contact::pose;
use laparo_server::engine::scene::Scene;
use nalgebra::{Rotation3, Vector3};

/// The largest tick-to-tick change of either instrument's force over the last half
/// second, relative to it.
const STEADY: f64 = 1e-3;

/// The largest relative change of either instrument's force between two ticks of
/// the last half second of the hold, and whether their held sets changed then.
fn crossing(depth: f64, pitch: f64) -> (f64, bool) {
    let mut sim = Scene::default_scene().build().unwrap();
    sim.solve_static();
    let trocars: Vec<_> = sim.instruments.iter().map(|i| i.trocar).collect();
    let second = (1.0 / sim.dt).round() as usize;
    let (mut change, mut held_changed) = (0.0f64, false);
    let mut last: Option<(Vec<Vec<u32>>, [f64; 2])> = None;
    for k in 1..=3 * second {
        let reach = 0.01 + (depth - 0.01) * k.min(second) as f64 / second as f64;
        for (i, trocar) in trocars.iter().enumerate() {
            let tilt = if i == 0 { pitch } else { -pitch };
            let d =
                Rotation3::from_axis_angle(&Vector3::x_axis(), tilt) * -trocar.coords.normalize();
            sim.set_pose(i, Some(pose((trocar + d * reach).into(), (-d).into())));
        }
        sim.tick();
        let fault = laparo_server::headless::fault(&sim);
        assert!(fault.is_none(), "{depth} m, tick {k}: {fault:?}");
        if k <= 5 * second / 2 {
            continue;
        }
        let held: Vec<Vec<u32>> = sim
            .instruments
            .iter()
            .map(|i| {
                let mut h = i.held.clone();
                h.sort_unstable();
                h
            })
            .collect();
        let force = [0, 1].map(|i| sim.instruments[i].report.reaction.norm());
        if let Some((before, was)) = &last {
            held_changed |= *before != held;
            for i in 0..2 {
                change = change.max((force[i] - was[i]).abs() / was[i]);
            }
        }
        last = Some((held, force));
    }
    let (held, force) = last.expect("ticks after the first half second");
    println!(
        "{depth} m: {:.3} and {:.3} N, holding {} and {} vertices; largest change a tick {:.4}%",
        force[0],
        force[1],
        held[0].len(),
        held[1].len(),
        100.0 * change
    );
    (change, held_changed)
}

#[test]
fn two_instruments_crossing_inside_the_liver_and_held_still_hold_a_steady_force() {
    for depth in [0.22, 0.24, 0.26] {
        let (change, held_changed) = crossing(depth, 0.15);
        assert!(
            !held_changed,
            "{depth} m: the held sets changed while held still"
        );
        assert!(
            change <= STEADY,
            "{depth} m: a tick changed the force by {:.2}%",
            100.0 * change
        );
    }
}
