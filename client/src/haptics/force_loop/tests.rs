use nalgebra::{Point3, Unit, Vector3};

use super::*;
use crate::haptics::device::{HandDevice, HandParams, ScriptedDevice};
use crate::proto::force::{ForceModel, LocalModel, Plane};

const TROCAR: Point3<f64> = Point3::new(0.02, 0.0, 0.12);

fn tissue(stiffness: f64) -> LocalModel {
    LocalModel {
        tick: 42,
        sim_time: 0.7,
        tip: Point3::origin(),
        axis: Vector3::z_axis(),
        tip_plane: Some(Plane {
            normal: Vector3::z_axis(),
            anchor: Point3::origin(),
            stiffness,
            drag: Vector3::zeros(),
        }),
        shaft_plane: None,
        kind: ForceModel::Geometric,
        young_modulus: Some(3.0e3),
    }
}

#[test]
fn config_rejects_out_of_range_fields_by_name() {
    let ok = ForceLoopConfig::new(TROCAR);
    assert_eq!(ok.validate(), Ok(()));
    for rate in [300.0, 4000.0] {
        assert!(
            ForceLoopConfig {
                rate_hz: rate,
                ..ok
            }
            .validate()
            .is_ok()
        );
    }
    let cases = [
        (
            ForceLoopConfig {
                rate_hz: 299.0,
                ..ok
            },
            "rate_hz",
        ),
        (
            ForceLoopConfig {
                rate_hz: 4001.0,
                ..ok
            },
            "rate_hz",
        ),
        (
            ForceLoopConfig {
                rate_hz: f64::NAN,
                ..ok
            },
            "rate_hz",
        ),
        (
            ForceLoopConfig {
                transition_s: 0.0,
                ..ok
            },
            "transition_s",
        ),
        (
            ForceLoopConfig {
                transition_s: -0.01,
                ..ok
            },
            "transition_s",
        ),
        (
            ForceLoopConfig {
                transition_s: f64::NAN,
                ..ok
            },
            "transition_s",
        ),
        (
            ForceLoopConfig {
                transition_s: f64::INFINITY,
                ..ok
            },
            "transition_s",
        ),
        (
            ForceLoopConfig {
                trocar: Point3::new(0.0, f64::NAN, 0.0),
                ..ok
            },
            "trocar",
        ),
    ];
    for (config, field) in cases {
        let err = config.validate().unwrap_err();
        assert_eq!(err.field, field);
        assert!(err.to_string().contains(field), "{err}");
        let device = ScriptedDevice::fixed(Point3::origin(), Vector3::z_axis(), 1.0, 1);
        assert!(ForceLoop::new(config, device).is_err());
    }
    // A value far out of range is echoed short, not in its 301 digits.
    let huge = ForceLoopConfig {
        transition_s: -1e300,
        ..ok
    };
    let e = huge.validate().unwrap_err().to_string();
    assert!(e.contains("transition_s = -1e300 is out of range"), "{e}");
}

#[test]
fn clamp_keeps_the_direction_and_stops_at_the_limit() {
    let f = Vector3::new(3.0, -4.0, 12.0); // |f| = 13
    let (c, limit) = clamp_force(&f, 6.5);
    assert_eq!(limit, Limit::Clamped);
    assert!((c.norm() - 6.5).abs() <= 1e-12 * 6.5);
    assert!(c.cross(&f).norm() <= 1e-12 * 13.0 * 6.5 && c.dot(&f) > 0.0);
    assert_eq!(clamp_force(&f, 13.5), (f, Limit::None));
    assert_eq!(clamp_force(&f, f64::INFINITY), (f, Limit::None));
    let nan = Vector3::new(f64::NAN, 0.0, 1.0);
    assert_eq!(
        clamp_force(&nan, 10.0),
        (Vector3::zeros(), Limit::NonFinite)
    );
    let inf = Vector3::new(f64::INFINITY, 0.0, 1.0);
    assert_eq!(
        clamp_force(&inf, 10.0),
        (Vector3::zeros(), Limit::NonFinite)
    );
}

/// A scripted press into one fixed tip plane: after the model's transition the force
/// is `λ·depth` along the normal, its torque is about the trocar, it vanishes when
/// the tip withdraws; the outbox always holds the pose of the last tick.
#[test]
fn tick_renders_the_plane_force_of_a_scripted_press() {
    let lambda = 350.0;
    // Down to 12 mm deep over 0.5 s, back out to 4 mm above by 1 s.
    let depth = |t: f64| {
        if t < 0.5 {
            0.024 * t
        } else {
            0.012 - 0.032 * (t - 0.5)
        }
    };
    let path: crate::haptics::Trajectory = Box::new(move |t| {
        let tip = Point3::new(0.003, -0.002, -depth(t));
        (tip, Unit::new_normalize(TROCAR - tip))
    });
    let device = ScriptedDevice::new(path, 50.0, 2000);
    let config = ForceLoopConfig::new(TROCAR);
    let (mut fl, mut inbox, mut outbox) = ForceLoop::new(config, device).unwrap();
    assert_eq!(outbox.latest(), None);
    inbox.write(tissue(lambda));
    let dt = config.period_s();
    let mut checked = (0, 0);
    for k in 0..1000 {
        let t = k as f64 * dt;
        fl.tick(t);
        let pose = outbox.take_new().expect("a pose every tick");
        let rendered = fl.device().last().unwrap();
        assert_eq!(rendered.time, t);
        assert_eq!(pose.time, t);
        assert_eq!(pose.tip, Point3::new(0.003, -0.002, -depth(t)));
        if t < config.transition_s {
            continue;
        }
        let f = rendered.force;
        let expected = Vector3::z() * (lambda * depth(t).max(0.0));
        assert!((f.force - expected).norm() <= 1e-12 * expected.norm().max(1e-12));
        assert!((f.axial - f.force.dot(&pose.axis)).abs() <= 1e-15);
        assert!((f.torque - (pose.tip - TROCAR).cross(&f.force)).norm() <= 1e-15);
        if depth(t) > 0.0 {
            checked.0 += 1;
        } else {
            assert_eq!(f.force, Vector3::zeros());
            checked.1 += 1;
        }
    }
    assert!(checked.0 > 500 && checked.1 > 100, "{checked:?}");
    let stats = fl.stats();
    assert_eq!(stats.ticks, 1000);
    assert_eq!(stats.models_received, 1);
    assert_eq!(stats.model_tick, Some(42));
    assert_eq!((stats.clamped_ticks, stats.non_finite_ticks), (0, 0));
    assert!((stats.model_age_s - 999.0 * dt).abs() < 1e-12);
    assert!((stats.rate_hz - 1000.0).abs() < 1e-6);
    assert!(stats.jitter.max < 1e-9);
}

#[test]
fn tick_clamps_to_the_device_limit() {
    let tip = Point3::new(0.0, 0.0, -0.05); // 5 cm deep at 400 N/m: 20 N
    let device = ScriptedDevice::fixed(tip, Unit::new_normalize(TROCAR - tip), 4.0, 16);
    let (mut fl, mut inbox, _outbox) =
        ForceLoop::new(ForceLoopConfig::new(TROCAR), device).unwrap();
    inbox.write(tissue(400.0));
    for k in 0..100 {
        fl.tick(k as f64 * 1e-3);
    }
    let f = fl.device().last().unwrap().force.force;
    assert!((f.norm() - 4.0).abs() <= 1e-12 * 4.0);
    assert!(f.normalize().dot(&Vector3::z()) > 1.0 - 1e-12);
    assert!(fl.stats().clamped_ticks > 50);
}

/// A hand pressing into the tissue through the loop settles at the equilibrium
/// `k_h (x_t − x) = λ d` without oscillating: the energy of hand and tissue together
/// ends below where it started and the hand comes to rest (passivity of the loop at
/// 1 kHz for `c_h` well above `λ dt / 2`).
#[test]
fn a_hand_pressing_through_the_loop_settles() {
    let lambda = 400.0;
    let params = HandParams::default();
    let start = Point3::new(0.0, 0.0, 0.01);
    let inside = Point3::new(0.0, 0.0, -0.02);
    // The target waits outside until the model has blended in, then steps inside.
    let target: crate::haptics::Trajectory =
        Box::new(move |t| (if t < 0.1 { start } else { inside }, Vector3::z_axis()));
    let hand = HandDevice::new(params, TROCAR, start, target);
    let (mut fl, mut inbox, _outbox) = ForceLoop::new(ForceLoopConfig::new(TROCAR), hand).unwrap();
    inbox.write(tissue(lambda));
    let dt = 1e-3;
    let total = |fl: &ForceLoop<HandDevice>| {
        let d = (-fl.device().tip().z).max(0.0);
        fl.device().discrete_energy() + 0.5 * lambda * d * d
    };
    let mut e0 = None;
    for k in 0..4000 {
        let t = k as f64 * dt;
        fl.tick(t);
        if t > 0.1 && e0.is_none() {
            e0 = Some(total(&fl));
        }
    }
    let e0 = e0.unwrap();
    let hand = fl.device();
    let k = params.stiffness;
    let depth = k * 0.02 / (k + lambda);
    assert!((hand.tip().z + depth).abs() < 1e-6, "{:?}", hand.tip());
    assert!(hand.kinetic_energy() < 1e-12);
    assert!(total(&fl) < e0);
    assert!(
        hand.force_work() < 0.0,
        "the tissue took energy from the hand"
    );
}
