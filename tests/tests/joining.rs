//! What `Station.Join` grants, as the contract states it: the role a station must
//! state, watching without instruments (the rule of `Observe`), a claim granted
//! whole or refused with a status, instrument states every tick at any surface
//! frame rate.

use laparo_client::station::{StationConfig, StationError, run_station};
use laparo_proto::v1;
use laparo_proto::v1::server_message::Kind;
use laparo_server::service::{Role, ServeConfig};
use laparo_tests::server::*;
use tonic::Code;
use tonic::transport::Channel;

const TEACHER: Option<&str> = Some("instructor-token");
const TRAINEE: Option<&str> = Some("trainee-token");

/// A server with an instructor token and a trainee token that may claim anything.
async fn server_with_tokens() -> TestServer {
    let tokens = tokens(&[
        (TEACHER.unwrap(), "instructor", Role::Instructor, None),
        (TRAINEE.unwrap(), "trainee", Role::Trainee, None),
    ]);
    TestServer::start(ServeConfig {
        tokens: Some(tokens),
        ..ServeConfig::default()
    })
    .await
}

fn code<T>(r: Result<T, tonic::Status>) -> Option<Code> {
    r.err().map(|s| s.code())
}

async fn info(ch: &Channel, token: Option<&str>, session: &str) -> v1::SessionInfo {
    v1::sessions_client::SessionsClient::new(ch.clone())
        .get_session(with_token(
            v1::GetSessionRequest {
                session_id: session.to_string(),
            },
            token,
        ))
        .await
        .unwrap()
        .into_inner()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_station_without_instruments_watches_only_with_an_instructor_token() {
    let server = server_with_tokens().await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), TEACHER)
        .await
        .unwrap()
        .session_id;
    // The trainee may neither observe nor watch through a station…
    let refused = join(ch.clone(), TRAINEE, &session, &[]).await;
    let status = refused.err().expect("a trainee may not watch");
    assert_eq!(status.code(), Code::PermissionDenied, "{status:?}");
    assert!(status.message().contains("instructor"), "{status:?}");
    // …and was not counted as a station.
    assert!(info(&ch, TEACHER, &session).await.stations.is_empty());
    // It may drive an instrument, and then sees the session as a station does.
    let (_trainee, joined) = join(ch.clone(), TRAINEE, &session, &["left"])
        .await
        .unwrap();
    assert_eq!(joined.instruments, vec!["left".to_string()]);
    // The instructor may watch through a station with no instrument: frames come.
    let (mut watcher, _) = join(ch.clone(), TEACHER, &session, &[]).await.unwrap();
    assert!(
        wait_for(&mut watcher.rx, WAIT, |m| matches!(
            m.kind,
            Some(Kind::SurfaceFrame(_))
        ))
        .await
        .is_some()
    );
    assert_eq!(info(&ch, TEACHER, &session).await.stations.len(), 2);
    drop(watcher);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_join_must_state_its_role() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    for role in [v1::Role::Unspecified as i32, 99, -1] {
        let mut message = open(&session, &["left"]);
        if let Some(v1::station_message::Kind::Open(o)) = &mut message.kind {
            o.role = role;
        }
        let status = join_raw(ch.clone(), None, Some(message))
            .await
            .err()
            .expect("the join is refused");
        assert_eq!(
            status.code(),
            Code::InvalidArgument,
            "role {role}: {status:?}"
        );
        assert!(
            status.message().contains("JoinRequest.role"),
            "the message names the field: {status:?}"
        );
    }
    // Nothing was granted: the instrument is free.
    let holders = info(&ch, None, &session).await.instruments;
    assert!(
        holders.iter().all(|h| h.station_id.is_none()),
        "{holders:?}"
    );
    server.shutdown().await.unwrap();
}

/// The leading comment of field `field` of message `message` in `file` of the
/// contract, as its descriptors carry it (and reflection serves it).
fn contract_comment(file: &str, message: &str, field: &str) -> String {
    use prost::Message;
    let set = prost_types::FileDescriptorSet::decode(laparo_proto::FILE_DESCRIPTOR_SET).unwrap();
    let f = set.file.iter().find(|f| f.name() == file).unwrap();
    let m = f
        .message_type
        .iter()
        .position(|m| m.name() == message)
        .unwrap();
    let k = f.message_type[m]
        .field
        .iter()
        .position(|x| x.name() == field)
        .unwrap();
    // Path: message_type (4), its index, field (2), its index.
    let path = [4, m as i32, 2, k as i32];
    let info = f.source_code_info.as_ref().unwrap();
    let location = info.location.iter().find(|l| l.path == path).unwrap();
    location.leading_comments().to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_claim_is_granted_whole_or_refused_with_a_status() {
    // The contract says what the server answers below.
    let said = contract_comment("laparo/v1/station.proto", "JoinRequest", "instruments");
    for code in ["ALREADY_EXISTS", "NOT_FOUND", "granted whole"] {
        assert!(said.contains(code), "JoinRequest.instruments: {said}");
    }
    assert!(!said.contains("INSTRUMENT_TAKEN"), "{said}");
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let (_a, joined_a) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    // A taken instrument among free ones refuses the whole join: the free one is
    // not granted, no station is added.
    let taken = join(ch.clone(), None, &session, &["right", "left"]).await;
    let status = taken.err().expect("refused");
    assert_eq!(status.code(), Code::AlreadyExists, "{status:?}");
    assert!(status.message().contains("left"), "{status:?}");
    let unknown = join(ch.clone(), None, &session, &["right", "middle"]).await;
    assert_eq!(code(unknown), Some(Code::NotFound));
    let now = info(&ch, None, &session).await;
    assert_eq!(now.stations.len(), 1, "{now:?}");
    let holder = |name: &str| {
        now.instruments
            .iter()
            .find(|h| h.instrument == name)
            .and_then(|h| h.station_id)
    };
    assert_eq!(holder("left"), Some(joined_a.station_id));
    assert_eq!(holder("right"), None);
    // Granted whole: both claims in Joined, in the order claimed.
    let (_b, joined_b) = join(ch.clone(), None, &session, &["right"]).await.unwrap();
    assert_eq!(joined_b.instruments, vec!["right".to_string()]);
    drop(_b);

    // The client's station: a refused join is the server's status, and it runs
    // nothing.
    let url = format!("http://{}", server.addr);
    let config = |instruments: &[&str]| {
        let mut c = StationConfig::new(
            url.clone(),
            session.clone(),
            instruments.iter().map(|s| s.to_string()).collect(),
        );
        c.duration = Some(std::time::Duration::from_millis(300));
        c
    };
    let refused = run_station(config(&["left"])).await;
    assert!(
        matches!(
            &refused,
            Err(StationError::Status {
                code: Code::AlreadyExists,
                ..
            })
        ),
        "{refused:?}"
    );
    let unknown = run_station(config(&["middle"])).await;
    assert!(
        matches!(
            &unknown,
            Err(StationError::Status {
                code: Code::NotFound,
                ..
            })
        ),
        "{unknown:?}"
    );
    // `right` is free again once station B's stream is gone; wait for it.
    let free = tokio::time::timeout(WAIT, async {
        loop {
            let i = info(&ch, None, &session).await;
            if i.instruments
                .iter()
                .any(|h| h.instrument == "right" && h.station_id.is_none())
            {
                return;
            }
            tokio::time::sleep(std::time::Duration::from_millis(20)).await;
        }
    })
    .await;
    assert!(free.is_ok(), "station B's instrument was never released");
    let ran = run_station(config(&["right"])).await.unwrap();
    assert_eq!(ran.instruments, vec!["right".to_string()]);
    server.shutdown().await.unwrap();
}

/// A station that asks for few surface frames still gets its instruments' states
/// (and the local models they carry, which its force loop renders from) every
/// tick: at `--frame-rate 1` it used to get one model a second.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_station_at_a_low_surface_rate_gets_every_ticks_state() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let mut opening = open(&session, &["left"]);
    if let Some(v1::station_message::Kind::Open(j)) = &mut opening.kind {
        j.surface_frame_rate_hz = Some(2.0);
    }
    let mut station = join_raw(ch, None, Some(opening)).await.unwrap();
    let joined = match station.rx.message().await.unwrap() {
        Some(v1::ServerMessage {
            kind: Some(Kind::Joined(j)),
        }) => j,
        other => panic!("expected Joined, got {other:?}"),
    };
    assert_eq!(joined.surface_frame_rate_hz, 2.0);
    // Half a second of the default scene's 60 Hz ticks after the first state.
    let (mut surfaces, mut state_ticks) = (0, std::collections::BTreeSet::new());
    let mut first = None;
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
    loop {
        assert!(std::time::Instant::now() < deadline, "the stream stalled");
        let m = station
            .rx
            .message()
            .await
            .unwrap()
            .expect("the stream goes on");
        match m.kind {
            Some(Kind::SurfaceFrame(_)) => surfaces += 1,
            Some(Kind::InstrumentState(s)) if s.instrument == "left" => {
                let first = *first.get_or_insert(s.tick);
                if s.tick >= first + 30 {
                    break;
                }
                state_ticks.insert(s.tick);
            }
            _ => {}
        }
    }
    // A watch channel keeps only the newest frame, so a busy machine may skip a few
    // ticks; at 2 Hz, one surface comes at once and the next after 30 ticks.
    assert!(
        state_ticks.len() >= 15,
        "states of {} of 30 ticks",
        state_ticks.len()
    );
    assert!(
        surfaces <= 3,
        "{surfaces} surfaces in half a second at 2 Hz"
    );
}
