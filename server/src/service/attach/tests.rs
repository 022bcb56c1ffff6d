use super::*;
use crate::service::auth::Role;

fn trainee(name: &str) -> Caller {
    Caller {
        name: name.into(),
        role: Role::Trainee,
        instruments: None,
    }
}

fn pose(sequence: u64) -> v1::DevicePose {
    v1::DevicePose {
        instrument: "left".into(),
        sequence,
        ..Default::default()
    }
}

#[test]
fn handles_are_32_hex_digits_and_differ() {
    let a = Attachments::default();
    let (h1, _rx1) = a.attach(trainee("a")).unwrap();
    let (h2, _rx2) = a.attach(trainee("a")).unwrap();
    assert_eq!(h1.len(), 32);
    assert!(
        h1.chars()
            .all(|c| c.is_ascii_hexdigit() && !c.is_ascii_uppercase())
    );
    assert_ne!(h1, h2);
}

#[test]
fn poses_reach_the_queue_in_order_with_the_leave_last() {
    let a = Attachments::default();
    let (handle, mut rx) = a.attach(trainee("a")).unwrap();
    let queued = a
        .send(
            &trainee("a"),
            v1::SendPosesRequest {
                handle,
                poses: vec![pose(1), pose(2)],
                leave: true,
            },
        )
        .unwrap();
    assert_eq!(queued, 2);
    let kinds: Vec<_> = std::iter::from_fn(|| rx.try_recv().ok())
        .map(|m| m.kind.unwrap())
        .collect();
    assert!(matches!(&kinds[0], v1::station_message::Kind::Pose(p) if p.sequence == 1));
    assert!(matches!(&kinds[1], v1::station_message::Kind::Pose(p) if p.sequence == 2));
    assert!(matches!(&kinds[2], v1::station_message::Kind::Leave(_)));
    assert_eq!(kinds.len(), 3);
}

#[test]
fn another_callers_handle_and_a_made_up_one_are_not_found() {
    let a = Attachments::default();
    let (handle, _rx) = a.attach(trainee("a")).unwrap();
    let other = a.send(
        &trainee("b"),
        v1::SendPosesRequest {
            handle: handle.clone(),
            ..Default::default()
        },
    );
    assert_eq!(other.unwrap_err().code(), tonic::Code::NotFound);
    let made_up = a.send(
        &trainee("a"),
        v1::SendPosesRequest {
            handle: "0".repeat(32),
            ..Default::default()
        },
    );
    assert_eq!(made_up.unwrap_err().code(), tonic::Code::NotFound);
    a.detach(&handle);
    let ended = a.send(
        &trainee("a"),
        v1::SendPosesRequest {
            handle,
            ..Default::default()
        },
    );
    assert_eq!(ended.unwrap_err().code(), tonic::Code::NotFound);
}

#[test]
fn too_many_poses_in_a_call_and_a_full_queue_are_refused() {
    let a = Attachments::default();
    let (handle, _rx) = a.attach(trainee("a")).unwrap();
    let many = a.send(
        &trainee("a"),
        v1::SendPosesRequest {
            handle: handle.clone(),
            poses: (0..=MAX_POSES_PER_CALL as u64).map(pose).collect(),
            leave: false,
        },
    );
    assert_eq!(many.unwrap_err().code(), tonic::Code::InvalidArgument);
    let mut sent = 0;
    let full = loop {
        let r = a.send(
            &trainee("a"),
            v1::SendPosesRequest {
                handle: handle.clone(),
                poses: (0..MAX_POSES_PER_CALL as u64).map(pose).collect(),
                leave: false,
            },
        );
        match r {
            Ok(n) => sent += n as usize,
            Err(e) => break e,
        }
        assert!(sent <= QUEUE, "the queue took more than it holds");
    };
    assert_eq!(full.code(), tonic::Code::ResourceExhausted);
    assert_eq!(sent, QUEUE);
}
