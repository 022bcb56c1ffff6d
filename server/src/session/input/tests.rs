//! Tests of the pose checks and the pose rate limit.

use super::*;

fn workspace() -> Workspace {
    Workspace {
        min: Point3::new(-1.0, -1.0, -1.0),
        max: Point3::new(1.0, 1.0, 1.0),
    }
}

fn pose(tip: [f64; 3], axis: [f64; 3], sequence: u64) -> v1::DevicePose {
    v1::DevicePose {
        instrument: "left".into(),
        pose: Some(v1::Pose {
            tip: Some(v1::Vec3 {
                x: tip[0],
                y: tip[1],
                z: tip[2],
            }),
            axis: Some(v1::Vec3 {
                x: axis[0],
                y: axis[1],
                z: axis[2],
            }),
        }),
        device_time_s: 0.0,
        sequence,
    }
}

#[test]
fn bad_poses_are_rejected_with_their_code() {
    let w = workspace();
    let ok = check_pose(&pose([0.1, 0.0, 0.0], [0.0, 0.0, 1.0], 5), &w, Some(4));
    assert!(ok.is_ok());
    let code = |p: &v1::DevicePose, last| check_pose(p, &w, last).unwrap_err().code;
    assert_eq!(
        code(&pose([f64::NAN, 0.0, 0.0], [0.0, 0.0, 1.0], 1), None),
        ErrorCode::InvalidPose
    );
    assert_eq!(
        code(&pose([0.0, 0.0, 0.0], [f64::INFINITY, 0.0, 1.0], 1), None),
        ErrorCode::InvalidPose
    );
    assert_eq!(
        code(&pose([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1), None),
        ErrorCode::InvalidPose
    );
    assert_eq!(
        code(&pose([0.0, 0.0, 0.0], [0.0, 0.0, 2.0], 1), None),
        ErrorCode::InvalidPose
    );
    assert_eq!(
        code(&pose([5.0, 0.0, 0.0], [0.0, 0.0, 1.0], 1), None),
        ErrorCode::OutOfWorkspace
    );
    assert_eq!(
        code(&pose([1e300, 0.0, 0.0], [0.0, 0.0, 1.0], 1), None),
        ErrorCode::OutOfWorkspace
    );
    // The echo stays short whatever the numbers (plain `{}` wrote 1e300 in 301
    // digits and -1e-300 with 300 zeros).
    let far = check_pose(&pose([1e300, -1e-300, 0.09], [0.0, 0.0, 1.0], 1), &w, None);
    assert_eq!(
        far.unwrap_err().message,
        "tip (1e300, -1e-300, 0.09) m is outside the workspace (-1, -1, -1) .. (1, 1, 1) m"
    );
    assert_eq!(
        code(&pose([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 4), Some(4)),
        ErrorCode::OutOfOrder
    );
    let mut missing = pose([0.0; 3], [0.0, 0.0, 1.0], 1);
    missing.pose = None;
    assert_eq!(code(&missing, None), ErrorCode::InvalidPose);
}

#[test]
fn the_rate_limit_admits_its_rate_and_its_burst() {
    let mut limit = RateLimit::new(100.0, 10.0);
    // A burst of 10 at once, then nothing until tokens come back.
    assert_eq!((0..20).filter(|_| limit.admit(0.0)).count(), 10);
    // 1 s at 1 kHz: 100 admitted (the rate), the rest refused.
    let admitted = (1..=1000)
        .filter(|&k| limit.admit(k as f64 / 1000.0))
        .count();
    assert!((99..=101).contains(&admitted), "{admitted}");
}

#[test]
fn a_burst_after_a_stall_is_admitted_whole() {
    // 1 kHz under a 2 kHz limit for 2 s, a 3 s stall, then the 3000 queued
    // poses at once: none refused.
    let rate = 2000.0;
    let mut limit = RateLimit::new(rate, stall_burst(rate));
    assert!((0..2000).all(|k| limit.admit(k as f64 / 1000.0)));
    assert!((0..3000).all(|_| limit.admit(5.0)));
    // And the station goes on at 1 kHz.
    assert!((1..=1000).all(|k| limit.admit(5.0 + k as f64 / 1000.0)));
}

#[test]
fn sustained_abuse_is_refused_after_the_window() {
    // 20 kHz under a 2 kHz limit: the bucket empties within
    // STALL_WINDOW_S·R/(a − R) ≈ 0.56 s, then 18 000 poses a second are refused.
    let rate = 2000.0;
    let mut limit = RateLimit::new(rate, stall_burst(rate));
    let refused = (0..60_000)
        .filter(|&k| !limit.admit(k as f64 / 20_000.0))
        .count();
    // 3 s at 20 kHz: 60 000 sent, 10 000 + 3·2000 admitted.
    assert!((43_000..=45_000).contains(&refused), "{refused}");
}
