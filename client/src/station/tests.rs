use nalgebra::{Point3, Vector3};

use super::intake::error_code_name;
use super::link::check_granted;
use super::*;
use crate::haptics::{ForceLoop, ForceLoopConfig, ScriptedDevice};
use crate::proto::force::LocalModel;
use crate::proto::v1::{ErrorCode, InstrumentState};

fn state(model: Option<v1::LocalModel>) -> InstrumentState {
    InstrumentState {
        instrument: "left".into(),
        tick: 7,
        local_model: model,
        ..Default::default()
    }
}

fn good_model() -> v1::LocalModel {
    let m = LocalModel::free(7, 7.0 / 60.0, Point3::origin(), Vector3::z_axis());
    v1::LocalModel::from(&m)
}

#[test]
fn invalid_and_missing_models_are_counted_and_skipped() {
    let device = ScriptedDevice::fixed(Point3::origin(), Vector3::z_axis(), 1.0, 1);
    let (mut force_loop, mut inbox, _outbox) =
        ForceLoop::new(ForceLoopConfig::new(Point3::new(0.0, 0.0, 0.1)), device).unwrap();
    let mut intake = ModelIntake::default();

    let mut bad = good_model();
    bad.pose.as_mut().unwrap().axis.as_mut().unwrap().z = f64::NAN;
    assert_eq!(intake.take(&state(Some(bad)), &mut inbox), None);
    assert_eq!(intake.take(&state(None), &mut inbox), None);
    assert_eq!(
        intake,
        ModelIntake {
            applied: 0,
            invalid: 2
        }
    );
    force_loop.tick(0.0);
    assert_eq!(
        force_loop.stats().models_received,
        0,
        "nothing reached the loop"
    );

    assert!(
        intake
            .take(&state(Some(good_model())), &mut inbox)
            .is_some()
    );
    assert_eq!(intake.applied, 1);
    force_loop.tick(0.001);
    assert_eq!(force_loop.stats().models_received, 1);
}

#[test]
fn error_codes_are_named_as_in_the_contract() {
    assert_eq!(
        error_code_name(ErrorCode::OutOfOrder as i32),
        "ERROR_CODE_OUT_OF_ORDER"
    );
    assert_eq!(error_code_name(999), "UNKNOWN_999");
}

#[test]
fn ticks_are_counted_once_each() {
    let mut t = TickCounter::default();
    for tick in [3, 3, 4, 4, 2, 5] {
        t.see(tick, tick as f64);
    }
    assert_eq!((t.ticks, t.last), (3, Some(5)));
}

#[test]
fn a_status_keeps_its_code_and_message() {
    let e = StationError::from(tonic::Status::not_found("no session \"x\""));
    assert!(matches!(
        &e,
        StationError::Status { code: tonic::Code::NotFound, message } if message == "no session \"x\""
    ));
}

#[test]
fn a_join_must_grant_every_instrument_claimed() {
    let claimed = vec!["left".to_string(), "right".to_string()];
    let joined = |granted: &[&str]| v1::Joined {
        instruments: granted.iter().map(|s| s.to_string()).collect(),
        ..Default::default()
    };
    assert!(check_granted(&claimed, &joined(&["left", "right"])).is_ok());
    assert!(check_granted(&[], &joined(&[])).is_ok());
    for partial in [
        &["left"][..],
        &[],
        &["right", "left"],
        &["left", "right", "x"],
    ] {
        let e = check_granted(&claimed, &joined(partial)).unwrap_err();
        assert!(
            matches!(&e, StationError::Protocol(m) if m.contains("granted")),
            "{partial:?}: {e}"
        );
    }
}

#[test]
fn the_sending_rate_is_the_lower_of_the_two_and_always_a_timer_period() {
    assert_eq!(sending_rate(250.0, 1000.0), 250.0);
    assert_eq!(sending_rate(250.0, 100.0), 100.0);
    // A server that states no limit, or one that is not a rate, leaves the configured.
    for none in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert_eq!(sending_rate(250.0, none), 250.0, "{none}");
    }
    // A server's limit far below any station's rate still gives a period a timer
    // holds (1 / 1e-300 s would panic in `Duration::from_secs_f64`).
    for limit in [1e-300, f64::MIN_POSITIVE, 1e-3] {
        let rate = sending_rate(250.0, limit);
        assert_eq!(rate, *POSE_RATE_RANGE_HZ.start(), "{limit}");
        assert!(std::time::Duration::try_from_secs_f64(1.0 / rate).is_ok());
    }
    let mut config = StationConfig::new("http://h:1", "s", vec!["left".to_string()]);
    config.pose_rate_hz = 1e-300;
    let e = config.check_rates().unwrap_err().to_string();
    assert!(e.contains("pose rate = 1e-300 Hz is out of range"), "{e}");
    assert!(e.ends_with("(expected between 0.1 and 100000)"), "{e}");
    config.pose_rate_hz = 100_000.0;
    config.haptic_rate_hz = 299.5;
    let e = config.check_rates().unwrap_err().to_string();
    assert_eq!(
        e,
        "haptic rate = 299.5 Hz is out of range (expected between 300 and 4000)"
    );
}

#[test]
fn a_status_is_named_as_the_grpc_specification_spells_it() {
    // Every code, against its Debug name turned to upper snake case.
    for i in 0..=16 {
        let code = tonic::Code::from(i);
        let mut snake = String::new();
        for (k, c) in format!("{code:?}").chars().enumerate() {
            if c.is_uppercase() && k > 0 {
                snake.push('_');
            }
            snake.push(c.to_ascii_uppercase());
        }
        assert_eq!(crate::connect::failure::code_name(code), snake, "code {i}");
    }
    let error = StationError::from(tonic::Status::not_found("no session `s9`"));
    assert_eq!(
        error.to_string(),
        "the server answered NOT_FOUND: no session `s9`"
    );
}
