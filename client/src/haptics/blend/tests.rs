use nalgebra::{Point3, Unit, Vector3};
use proptest::prelude::*;

use super::*;
use crate::proto::force::{ForceModel, Plane};

fn model(tick: u64, tip_plane: Option<Plane>, shaft_plane: Option<Plane>) -> LocalModel {
    LocalModel {
        tick,
        sim_time: tick as f64 / 60.0,
        tip: Point3::origin(),
        axis: Vector3::z_axis(),
        tip_plane,
        shaft_plane,
        kind: ForceModel::Geometric,
        young_modulus: None,
    }
}

fn plane(normal: [f64; 3], anchor: [f64; 3], stiffness: f64) -> Plane {
    Plane {
        normal: Unit::new_normalize(Vector3::from(normal)),
        anchor: Point3::from(anchor),
        stiffness,
        drag: Vector3::zeros(),
    }
}

fn assert_close(a: &Vector3<f64>, b: &Vector3<f64>, rel: f64) {
    let scale = a.norm().max(b.norm()).max(1e-300);
    assert!(
        (a - b).norm() <= rel * scale,
        "{a:?} != {b:?} (relative {})",
        (a - b).norm() / scale
    );
}

const TAU: f64 = 1.0 / 60.0;

#[test]
fn no_model_no_force() {
    let b = Blender::new(TAU);
    let tip = Point3::new(0.0, 0.0, -0.01);
    let f = b.force(0.3, &tip, &Vector3::z_axis());
    assert_eq!(f.force, Vector3::zeros());
    assert_eq!(f.point, tip);
    assert!(b.current().is_none() && b.arrival_time().is_none());
}

#[test]
fn smoothstep_ends_and_slope() {
    assert_eq!(smoothstep(-1.0), 0.0);
    assert_eq!(smoothstep(0.0), 0.0);
    assert_eq!(smoothstep(1.0), 1.0);
    assert_eq!(smoothstep(2.0), 1.0);
    assert_eq!(smoothstep(0.5), 0.5);
    let h = 1e-6;
    let slope = (smoothstep(0.5 + h) - smoothstep(0.5 - h)) / (2.0 * h);
    assert!((slope - SMOOTHSTEP_MAX_SLOPE).abs() < 1e-6);
}

/// Switching models, finished transition or not, leaves the force and its point
/// where they were; after τ the force is the new model's alone.
#[test]
fn switches_are_continuous_and_transitions_end_on_the_new_model() {
    let a = model(
        1,
        Some(plane([0.0, 0.0, 1.0], [0.0, 0.0, 0.0], 400.0)),
        None,
    );
    let b = model(
        2,
        Some(plane([0.2, 0.1, 1.0], [0.0, 0.0, 0.002], 600.0)),
        Some(plane([1.0, 0.0, 0.1], [0.004, 0.0, 0.01], 300.0)),
    );
    let c = model(
        3,
        None,
        Some(plane([1.0, 0.3, 0.0], [0.006, 0.0, 0.02], 900.0)),
    );
    let axis = Unit::new_normalize(Vector3::new(0.1, 0.0, 1.0));
    let pose = |t: f64| Point3::new(0.001 * t, -0.002 * t, -0.008 + 0.01 * t);
    let mut blender = Blender::new(TAU);

    // First model: blends in from zero.
    blender.arrive(0.0, a, &pose(0.0), &axis);
    assert_eq!(
        blender.force(0.0, &pose(0.0), &axis).force,
        Vector3::zeros()
    );

    // After τ: model a exactly; then b arrives after a finished transition.
    let t1 = 0.02;
    let before = blender.force(t1, &pose(t1), &axis);
    assert_eq!(before.force, a.force(&pose(t1), &axis).force);
    blender.arrive(t1, b, &pose(t1), &axis);
    let after = blender.force(t1, &pose(t1), &axis);
    assert_close(&after.force, &before.force, 1e-12);
    assert!((after.point - before.point).norm() <= 1e-12);

    // c arrives in the middle of b's transition.
    let t2 = t1 + 0.4 * TAU;
    let before = blender.force(t2, &pose(t2), &axis);
    let (fa, fb) = (
        a.force(&pose(t2), &axis).force,
        b.force(&pose(t2), &axis).force,
    );
    assert!((before.force - fa).norm() > 1e-3 && (before.force - fb).norm() > 1e-3);
    blender.arrive(t2, c, &pose(t2), &axis);
    let after = blender.force(t2, &pose(t2), &axis);
    assert_close(&after.force, &before.force, 1e-12);
    assert!((after.point - before.point).norm() <= 1e-12);
    assert_eq!(blender.previous().map(|m| m.tick), Some(2));

    // Still continuous one tick later, and exactly c after τ.
    let t3 = t2 + 1e-3;
    let next = blender.force(t3, &pose(t3), &axis);
    assert!((next.force - after.force).norm() < 0.5);
    let t4 = t2 + TAU;
    assert_eq!(
        blender.force(t4, &pose(t4), &axis),
        c.force(&pose(t4), &axis)
    );
}

/// Random tip-plane models arriving about every 1/60 s while the tip moves slowly:
/// the force changes per haptic tick by at most
///
/// `1.5 (dt/τ) (2 F_max + (N + 1) λ_max v τ) + λ_max v dt`,
///
/// with `F_max` the largest force of any model on the path, `λ_max` the largest
/// stiffness (each model's force is λ-Lipschitz in the tip), `v` the tip speed and `N`
/// the number of models. Derivation: between two ticks with the same models,
/// `F₂ − F₁ = (w₂ − w₁)(F_cur(x₁) − F_prev(x₁) − Δ) + (1 − w₂)(F_prev(x₂) − F_prev(x₁))
/// + w₂ (F_cur(x₂) − F_cur(x₁))`; `|w₂ − w₁| ≤ 1.5 dt/τ`; `|F_cur| ≤ F_max`;
/// `F_prev(x₁) + Δ` is the output at the switch plus `F_prev(x₁) − F_prev(x_s)`, at most
/// `G + λ_max v τ` while the transition runs (`t − t_s < τ`), where the output's bound
/// `G` grows by at most `λ_max v τ` per model above `F_max` (it is a convex
/// combination of `F_max`-bounded terms and the previous switch's output, drifted).
/// An arrival itself changes nothing (continuity). A model that replaced the previous
/// one outright would jump by up to `2 F_max`.
#[test]
fn force_steps_per_tick_are_bounded_by_the_transition() {
    let config = ProptestConfig {
        cases: 64,
        ..ProptestConfig::default()
    };
    let plane_strategy = (
        prop::array::uniform3(-1.0f64..1.0),
        prop::array::uniform3(-0.02f64..0.02),
        0.0f64..800.0,
        prop::bool::weighted(0.85),
    );
    let strategy = (
        prop::collection::vec((plane_strategy, 0usize..4), 2..20),
        1.0f64 / 120.0..1.0 / 30.0,
        prop::array::uniform3(-0.05f64..0.05),
        prop::array::uniform3(-0.02f64..0.02),
    );
    proptest!(config, |((models, tau, velocity, start) in strategy)| {
        let dt = 1e-3;
        let velocity = Vector3::from(velocity);
        let start = Point3::from(start);
        let axis = Vector3::z_axis();
        let n = models.len();
        let ticks = ((n as f64 / 60.0 + 2.0 * tau) / dt).ceil() as usize;
        let end = start + velocity * (ticks as f64 * dt);
        let mut arrivals = Vec::new();
        let (mut f_max, mut lambda_max) = (0.0f64, 0.0f64);
        for (i, ((normal, anchor, stiffness, contact), jitter)) in models.iter().enumerate() {
            let normal = Vector3::from(*normal);
            let tip_plane = (*contact && normal.norm() > 0.1).then(|| Plane {
                normal: Unit::new_normalize(normal),
                anchor: Point3::from(*anchor),
                stiffness: *stiffness,
                drag: Vector3::zeros(),
            });
            if let Some(p) = &tip_plane {
                lambda_max = lambda_max.max(p.stiffness);
                for x in [start, end] {
                    f_max = f_max.max(p.stiffness * (p.anchor - x).dot(&p.normal).max(0.0));
                }
            }
            let at = ((i as f64 / 60.0) / dt).round() as usize + jitter;
            arrivals.push((at, model(i as u64, tip_plane, None)));
        }
        let speed = velocity.norm();
        let bound = SMOOTHSTEP_MAX_SLOPE * (dt / tau)
            * (2.0 * f_max + (n as f64 + 1.0) * lambda_max * speed * tau)
            + lambda_max * speed * dt;

        let mut blender = Blender::new(tau);
        let mut next = arrivals.iter().peekable();
        let mut last: Option<Vector3<f64>> = None;
        for k in 0..ticks {
            let t = k as f64 * dt;
            let tip = start + velocity * t;
            while let Some((_, m)) = next.next_if(|(at, _)| *at <= k) {
                let before = blender.force(t, &tip, &axis).force;
                blender.arrive(t, *m, &tip, &axis);
                let after = blender.force(t, &tip, &axis).force;
                prop_assert!((after - before).norm() <= 1e-12 * before.norm().max(1e-12));
            }
            let f = blender.force(t, &tip, &axis).force;
            if let Some(prev) = last {
                let step = (f - prev).norm();
                prop_assert!(step <= bound * (1.0 + 1e-9) + 1e-12,
                    "tick {k}: step {step} N > bound {bound} N");
            }
            last = Some(f);
        }
    });
}
