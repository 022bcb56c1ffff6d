//! `Station.Join`: a trainee station's bidirectional stream; and `Station.Attach`
//! with `Station.SendPoses`, the same station split into a server stream and unary
//! calls for browsers ([`super::attach`]).
//!
//! The first message must be `open` (a `JoinRequest`), within [`OPEN_TIMEOUT`]; the
//! server checks the role (`ROLE_UNSPECIFIED` is `INVALID_ARGUMENT`), the session and
//! every instrument claimed, answers `Joined` with the scene, then streams frames,
//! instrument states and events, while the station streams device poses.
//!
//! A join is granted whole or refused whole, before `Joined`, with a status: an
//! unknown instrument is `NOT_FOUND`, one held by another station `ALREADY_EXISTS`,
//! one the caller's token may not claim `PERMISSION_DENIED`, one claimed twice
//! `INVALID_ARGUMENT`. A station with no instrument only watches, which is the
//! right of an instructor token, as `Observe` is: a trainee token is
//! `PERMISSION_DENIED`.
//!
//! A bad pose is dropped and answered with a
//! `StationError` on this stream (and an `INPUT_REJECTED` event for the others); the
//! session, the other stations and the recording go on. More than
//! [`ABUSE_LIMIT`] rejected messages within a second close the stream:
//! `RESOURCE_EXHAUSTED` when most were over the pose rate, `INVALID_ARGUMENT`
//! otherwise. Leaving, dropping the connection or the server ending the stream all
//! release the station's instruments, which are withdrawn from the body (the
//! tissue they held is let go) and have no holder until a station claims them
//! again.
//!
//! The server also ends the stream of a station that is gone ([`liveness`]: silent
//! or frozen for the station timeout; `DEADLINE_EXCEEDED`, after a
//! `STATION_TIMED_OUT` event) or that an instructor evicts
//! ([`Session::evict`]; `ABORTED` naming who and why, after a `STATION_EVICTED`
//! event). Either way the status goes out ahead of anything still queued for the
//! station, and the instruments are released as above.
//!
//! [`liveness`]: super::liveness

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use laparo_proto::text::printable;
use laparo_proto::v1;
use laparo_proto::v1::ErrorCode;
use laparo_proto::v1::station_message::Kind;
use tokio::sync::{mpsc, oneshot, watch};
use tonic::{Request, Response, Status, Streaming};

use super::attach::{AttachStream, Attachments};
use super::auth::{Role, caller};
use super::decode_status::contract_status;
use super::limits::MAX_STATIONS_PER_SESSION;
use super::liveness::{Gone, Liveness, Outbound, StationTimeout, Taken};
use super::recorder_room::RecorderRoom;
use super::registry::Registry;
use super::stream::{Item, OUTBOUND, States, Wrap, frame_rate, pump};
use crate::session::{Eviction, PoseIn, RateLimit, Rejection, Session, check_pose};

/// How long a station has to send its opening message.
pub const OPEN_TIMEOUT: Duration = Duration::from_secs(10);
/// Rejected messages within one second that close the stream.
pub const ABUSE_LIMIT: u32 = 100;
/// `INPUT_REJECTED` events a station causes per second at most (the rest are
/// counted in the next one's detail), so that one bad station cannot flood the
/// others' streams.
const REJECTION_EVENTS_PER_SECOND: u32 = 5;

/// Limits on what stations send.
#[derive(Clone, Copy, Debug)]
pub struct PoseLimits {
    /// Poses per second per instrument.
    pub rate_hz: f64,
    /// Poses that may arrive at once (a network burst): a stall window's worth.
    pub burst: f64,
}

impl Default for PoseLimits {
    /// 2 kHz: twice a 1 kHz haptic device's rate; a burst of
    /// [`STALL_WINDOW_S`](crate::session::input::STALL_WINDOW_S) at that rate, so
    /// that poses queued by a network stall are not counted as abuse.
    fn default() -> Self {
        PoseLimits {
            rate_hz: 2000.0,
            burst: crate::session::input::stall_burst(2000.0),
        }
    }
}

pub struct StationService {
    pub registry: Arc<Registry>,
    pub limits: PoseLimits,
    /// How long a station may be silent or frozen ([`super::liveness`]).
    pub timeout: StationTimeout,
    /// Stations opened by Attach, by handle.
    pub attachments: Arc<Attachments>,
}

type Out = mpsc::Sender<Result<v1::ServerMessage, Status>>;

#[tonic::async_trait]
impl v1::station_server::Station for StationService {
    type JoinStream = Outbound<v1::ServerMessage>;
    type AttachStream = AttachStream;

    async fn join(
        &self,
        request: Request<Streaming<v1::StationMessage>>,
    ) -> Result<Response<Self::JoinStream>, Status> {
        let caller = caller(&request)?;
        self.admit(&caller, &request)?;
        let mut inbound = request.into_inner();
        let first = tokio::time::timeout(OPEN_TIMEOUT, inbound.message())
            .await
            .map_err(|_| Status::deadline_exceeded("no opening message within 10 s"))?
            .map_err(contract_status)?
            .ok_or_else(|| {
                Status::invalid_argument("the stream ended before its opening message")
            })?;
        let Some(Kind::Open(open)) = first.kind else {
            return Err(Status::invalid_argument(
                "the first message of Join must be `open` (a JoinRequest)",
            ));
        };
        let opened = self.open(&caller, &open)?;
        let outbound = opened.run(Inbound::Join(Box::new(inbound)), self.reading(), || {});
        Ok(Response::new(outbound))
    }

    async fn attach(
        &self,
        request: Request<v1::JoinRequest>,
    ) -> Result<Response<Self::AttachStream>, Status> {
        let caller = caller(&request)?;
        self.admit(&caller, &request)?;
        // The handle is taken before the station opens: a station opened (its
        // instruments claimed, its joining announced) and then refused a handle
        // stayed in the roster holding them, with nobody to leave.
        let (handle, poses) = self.attachments.attach(caller.clone())?;
        let opened = match self.open(&caller, request.get_ref()) {
            Ok(opened) => opened,
            Err(refused) => {
                self.attachments.detach(&handle);
                return Err(refused);
            }
        };
        let attachments = self.attachments.clone();
        let ended = handle.clone();
        let outbound = opened.run(Inbound::Attach(poses), self.reading(), move || {
            attachments.detach(&ended)
        });
        Ok(Response::new(super::attach::stream(handle, outbound)))
    }

    async fn send_poses(
        &self,
        request: Request<v1::SendPosesRequest>,
    ) -> Result<Response<v1::SendPosesResponse>, Status> {
        let caller = caller(&request)?;
        let queued = self.attachments.send(&caller, request.into_inner())?;
        Ok(Response::new(v1::SendPosesResponse { queued }))
    }
}

/// A station granted and announced, before its stream runs.
struct Opened {
    session: Arc<Session>,
    station: u64,
    claimed: Vec<usize>,
    rate: f64,
    tx: Out,
    rx: mpsc::Receiver<Result<v1::ServerMessage, Status>>,
    /// Where an instructor's eviction of the station arrives.
    evicted: oneshot::Receiver<Eviction>,
}

impl StationService {
    /// What the reader of a station's messages enforces: pose limits and the
    /// station timeout.
    fn reading(&self) -> (PoseLimits, StationTimeout) {
        (self.limits, self.timeout)
    }

    /// The per-caller join rate (token name and peer address), shared by Join and
    /// Attach.
    fn admit<T>(&self, caller: &super::auth::Caller, request: &Request<T>) -> Result<(), Status> {
        let peer = request.remote_addr().map(|a| a.ip().to_string());
        let key = format!("{} {}", caller.name, peer.unwrap_or_default());
        self.registry.joins.admit(&key, std::time::Instant::now())
    }

    /// Checks a `JoinRequest` (lengths, role, session, claims), adds the station
    /// to the session and queues `Joined` and the recording's events: what Join
    /// and Attach share.
    fn open(&self, caller: &super::auth::Caller, open: &v1::JoinRequest) -> Result<Opened, Status> {
        super::limits::check_name("session_id", &open.session_id)?;
        super::limits::check_name("client_name", &open.client_name)?;
        super::limits::check_names("instruments", &open.instruments)?;
        let role = join_role(open.role)?;
        if role == v1::Role::Instructor {
            caller.require_instructor("joining as an instructor station")?;
        }
        if open.instruments.is_empty() {
            // A station with no instrument only watches: the rule of Observe.
            caller.require_instructor("joining with no instrument (watching the session)")?;
        }
        let session = self.registry.get(&open.session_id)?;
        let mut claimed = Vec::with_capacity(open.instruments.len());
        for name in &open.instruments {
            let k = session.instrument_index(name).ok_or_else(|| {
                Status::not_found(format!(
                    "session `{}` has no instrument `{}`",
                    session.id,
                    printable(name)
                ))
            })?;
            if caller.role == Role::Trainee && !caller.may_claim(name) {
                return Err(Status::permission_denied(format!(
                    "`{}` may not claim instrument `{}`",
                    caller.name,
                    printable(name)
                )));
            }
            if claimed.contains(&k) {
                return Err(Status::invalid_argument(format!(
                    "instrument `{}` claimed twice",
                    printable(name)
                )));
            }
            claimed.push(k);
        }
        let rate = frame_rate(open.surface_frame_rate_hz, session.scene.mechanics.rate_hz)?;
        let (station, evicted) = {
            let mut roster = session.roster();
            if roster.stations.len() >= MAX_STATIONS_PER_SESSION {
                return Err(Status::resource_exhausted(format!(
                    "session `{}` has {MAX_STATIONS_PER_SESSION} stations already \
                     (MAX_STATIONS_PER_SESSION)",
                    session.id
                )));
            }
            for &k in &claimed {
                if let Some(holder) = roster.holders[k] {
                    return Err(Status::already_exists(format!(
                        "instrument `{}` is already claimed by station {holder}",
                        session.scene.instruments[k].name
                    )));
                }
            }
            let station = Session::add_station(
                &mut roster,
                role,
                // Escaped once here: the name goes into events and session infos.
                &printable(&open.client_name),
                &claimed,
                open.instruments.clone(),
            );
            (station, Session::eviction_handle(&mut roster, station))
        };
        session.publish(
            v1::EventKind::StationJoined,
            Some(station),
            None,
            printable(&format!(
                "{} ({})",
                open.client_name,
                open.instruments.join(", ")
            ))
            .into_owned(),
        );
        let (tx, rx) = mpsc::channel(OUTBOUND);
        let joined = v1::ServerMessage {
            kind: Some(v1::server_message::Kind::Joined(v1::Joined {
                station_id: station,
                session_id: session.id.clone(),
                scene: Some(session.description.clone()),
                instruments: open.instruments.clone(),
                surface_frame_rate_hz: rate,
                tick: session.stats.tick.load(Ordering::Relaxed),
                max_pose_rate_hz: self.limits.rate_hz,
            })),
        };
        let _ = tx.try_send(Ok(joined));
        for event in session.recording_events() {
            let _ = tx.try_send(Ok(v1::ServerMessage {
                kind: Some(v1::server_message::Kind::Event(event)),
            }));
        }
        Ok(Opened {
            session,
            station,
            claimed,
            rate,
            tx,
            rx,
            evicted,
        })
    }
}

impl Opened {
    /// Runs the station: frames and events out ([`pump`]), its messages in
    /// ([`receive`]) until it leaves, is found gone or is evicted; then its
    /// instruments are released, the departure told, and `ended` called. Returns
    /// the outgoing stream.
    fn run(
        self,
        inbound: Inbound,
        (limits, timeout): (PoseLimits, StationTimeout),
        ended: impl FnOnce() + Send + 'static,
    ) -> Outbound<v1::ServerMessage> {
        let Opened {
            session,
            station,
            claimed,
            rate,
            tx,
            rx,
            evicted,
        } = self;
        let (done_tx, done) = watch::channel(false);
        let connected = session.connect();
        tokio::spawn(pump(
            session.clone(),
            tx.clone(),
            rate,
            States::EveryTick,
            done,
        ));
        let taken = Taken::new(Instant::now());
        let (outbound, cut) = Outbound::new(rx, taken.clone());
        let reader = Reader {
            limits,
            liveness: Liveness::new(timeout, Instant::now(), taken),
            check_period: timeout.check_period(),
            evicted,
        };
        tokio::spawn(async move {
            let _connected = connected;
            let ending = receive(&session, station, &claimed, inbound, &tx, reader).await;
            let evicted = end(&session, station, ending, cut);
            ended();
            session.remove_station(station);
            session.publish(
                v1::EventKind::StationLeft,
                Some(station),
                None,
                String::new(),
            );
            let _ = done_tx.send(true);
            if let Some(done) = evicted {
                let _ = done.send(());
            }
        });
        outbound
    }
}

/// How a station's reading ended.
enum Ending {
    /// It left, half-closed, broke, was closed for abuse, or its session closed:
    /// its stream says so by itself.
    Ended,
    /// It was silent or frozen for the station timeout.
    Gone(Gone),
    /// An instructor evicted it.
    Evicted(Eviction),
}

/// Announces a station ended by the server (timed out or evicted) and cuts its
/// stream with the status that says why; the eviction's acknowledgement, to send
/// once its instruments are free.
fn end(
    session: &Session,
    station: u64,
    ending: Ending,
    cut: oneshot::Sender<Status>,
) -> Option<oneshot::Sender<()>> {
    match ending {
        Ending::Ended => None,
        Ending::Gone(gone) => {
            let detail = format!("station {station} {gone}: its instruments are released");
            let _ = cut.send(Status::deadline_exceeded(detail.clone()));
            session.publish(v1::EventKind::StationTimedOut, Some(station), None, detail);
            None
        }
        Ending::Evicted(e) => {
            let detail = format!("evicted by `{}`: {}", e.by, e.reason);
            let _ = cut.send(Status::aborted(format!("station {station} {detail}")));
            session.publish(v1::EventKind::StationEvicted, Some(station), None, detail);
            Some(e.done)
        }
    }
}

/// Where a station's messages come from: Join's stream, or the queue SendPoses
/// fills for a station opened by Attach.
enum Inbound {
    Join(Box<Streaming<v1::StationMessage>>),
    Attach(mpsc::Receiver<v1::StationMessage>),
}

impl Inbound {
    async fn message(&mut self) -> Result<Option<v1::StationMessage>, Status> {
        match self {
            Inbound::Join(stream) => stream.message().await,
            Inbound::Attach(queue) => Ok(queue.recv().await),
        }
    }
}

/// The role a `JoinRequest` states: trainee or instructor. `ROLE_UNSPECIFIED` and
/// numbers the contract does not define are `INVALID_ARGUMENT` naming the field (a
/// station must say what it is; it is never taken for a trainee).
fn join_role(role: i32) -> Result<v1::Role, Status> {
    match v1::Role::try_from(role) {
        Ok(r @ (v1::Role::Trainee | v1::Role::Instructor)) => Ok(r),
        _ => Err(Status::invalid_argument(format!(
            "JoinRequest.role must be ROLE_TRAINEE (1) or ROLE_INSTRUCTOR (2), got {role}"
        ))),
    }
}

/// Per claimed instrument: its index, rate limit and last accepted sequence.
struct Claim {
    index: usize,
    limit: RateLimit,
    last: Option<u64>,
}

/// A station's claims while it reads; when it ends, each instrument's pose-rate
/// bucket goes back to the session for the next station that claims it
/// ([`Session::keep_pose_budget`]), before the instruments are freed.
struct Claims<'a> {
    session: &'a Session,
    /// The instant the buckets' times count from.
    since: Instant,
    list: Vec<Claim>,
}

impl Drop for Claims<'_> {
    fn drop(&mut self) {
        for c in &self.list {
            self.session.keep_pose_budget(c.index, c.limit, self.since);
        }
    }
}

/// What the reader of a station's messages watches besides them.
struct Reader {
    limits: PoseLimits,
    liveness: Liveness,
    check_period: Duration,
    evicted: oneshot::Receiver<Eviction>,
}

/// Reads the station's messages until it leaves, drops, is closed for abuse, is
/// found gone or is evicted.
async fn receive(
    session: &Arc<Session>,
    station: u64,
    claimed: &[usize],
    mut inbound: Inbound,
    tx: &Out,
    reader: Reader,
) -> Ending {
    let Reader {
        limits,
        mut liveness,
        check_period,
        mut evicted,
    } = reader;
    let mut check = tokio::time::interval(check_period);
    check.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);

    let start = Instant::now();
    let mut claims = Claims {
        session,
        since: start,
        list: claimed
            .iter()
            .map(|&index| Claim {
                index,
                limit: session
                    .take_pose_budget(index, start)
                    .unwrap_or_else(|| RateLimit::new(limits.rate_hz, limits.burst)),
                last: None,
            })
            .collect(),
    };
    let (mut window_start, mut rejected, mut rate_limited) = (0.0, 0u32, 0u32);
    let (mut events_this_second, mut unreported) = (0u32, 0u64);
    let mut closing = session.closing();
    let mut room = RecorderRoom::default();
    loop {
        // A closing session stops reading too, so that the stream ends on both sides.
        // A station whose outgoing stream is gone (an Attach stream cancelled)
        // has left. The next message waits while the recorder drains a burst.
        let next = tokio::select! {
            m = async {
                room.wait(session.recorder()).await;
                inbound.message().await
            } => m,
            _ = closing.wait_for(Option::is_some) => return Ending::Ended,
            _ = tx.closed() => return Ending::Ended,
            e = &mut evicted => match e {
                Ok(e) => return Ending::Evicted(e),
                // Removed from the roster by whoever evicted it, past the wait.
                Err(_) => return Ending::Ended,
            },
            _ = check.tick() => {
                let waiting = tx.capacity() < OUTBOUND;
                match liveness.check(Instant::now(), waiting) {
                    Some(gone) => return Ending::Gone(gone),
                    None => continue,
                }
            }
        };
        liveness.heard(Instant::now());
        let message = match next {
            Ok(Some(m)) => m,
            Ok(None) => return Ending::Ended,
            Err(status) => {
                // A transport error, a message that does not decode or one over the
                // size limit: tell the station why, if it can still hear, with the
                // contract's code.
                let _ = tx.try_send(Err(contract_status(status)));
                return Ending::Ended;
            }
        };
        let now = start.elapsed().as_secs_f64();
        let result = match message.kind {
            Some(Kind::Pose(p)) => accept_pose(session, station, &mut claims.list, &p, now),
            Some(Kind::Heartbeat(_)) => Ok(()),
            Some(Kind::Leave(_)) => return Ending::Ended,
            Some(Kind::Open(_)) => Err((
                Rejection {
                    code: ErrorCode::AlreadyJoined,
                    message: "this stream has already joined".into(),
                },
                None,
                None,
            )),
            None => Err((
                Rejection {
                    code: ErrorCode::InvalidMessage,
                    message: "a message with nothing in it".into(),
                },
                None,
                None,
            )),
        };
        let Err((rejection, sequence, instrument)) = result else {
            continue;
        };
        session.stats.poses_rejected.fetch_add(1, Ordering::Relaxed);
        if now - window_start >= 1.0 {
            (window_start, rejected, rate_limited, events_this_second) = (now, 0, 0, 0);
        }
        rejected += 1;
        rate_limited += u32::from(rejection.code == ErrorCode::RateLimited);
        let error = v1::StationError {
            code: rejection.code as i32,
            message: rejection.message.clone(),
            sequence,
            instrument: instrument.clone(),
        };
        if let Some(m) = v1::ServerMessage::wrap(Item::Error(error)) {
            let _ = tx.try_send(Ok(m));
        }
        if events_this_second < REJECTION_EVENTS_PER_SECOND {
            events_this_second += 1;
            let detail = if unreported > 0 {
                format!(
                    "{} (and {unreported} more rejected before)",
                    rejection.message
                )
            } else {
                rejection.message.clone()
            };
            unreported = 0;
            session.publish(
                v1::EventKind::InputRejected,
                Some(station),
                instrument,
                detail,
            );
        } else {
            unreported += 1;
        }
        if rejected > ABUSE_LIMIT {
            let status = if 2 * rate_limited > rejected {
                Status::resource_exhausted(format!(
                    "more than {ABUSE_LIMIT} messages rejected within a second, most over the pose-rate limit"
                ))
            } else {
                Status::invalid_argument(format!(
                    "more than {ABUSE_LIMIT} messages rejected within a second; last: {}",
                    rejection.message
                ))
            };
            let _ = tx.send(Err(status)).await;
            return Ending::Ended;
        }
    }
}

type Refusal = (Rejection, Option<u64>, Option<String>);

/// Checks a pose and hands it to the mechanics thread.
fn accept_pose(
    session: &Session,
    station: u64,
    claims: &mut [Claim],
    p: &v1::DevicePose,
    now: f64,
) -> Result<(), Refusal> {
    let refuse = |code, message: String| {
        Err((
            Rejection { code, message },
            Some(p.sequence),
            // Echoed in the station's error and the rejection event: escaped.
            Some(printable(&p.instrument).into_owned()),
        ))
    };
    let Some(k) = session.instrument_index(&p.instrument) else {
        return refuse(
            ErrorCode::UnknownInstrument,
            format!(
                "no instrument `{}` in this session",
                printable(&p.instrument)
            ),
        );
    };
    let Some(claim) = claims.iter_mut().find(|c| c.index == k) else {
        return refuse(
            ErrorCode::InstrumentNotHeld,
            format!("this station does not hold `{}`", printable(&p.instrument)),
        );
    };
    if !claim.limit.admit(now) {
        return refuse(
            ErrorCode::RateLimited,
            format!(
                "poses of `{}` over the rate limit",
                printable(&p.instrument)
            ),
        );
    }
    match check_pose(p, &session.workspace, claim.last) {
        Ok(pose) => {
            claim.last = Some(p.sequence);
            session.submit_pose(
                k,
                PoseIn {
                    pose,
                    sequence: p.sequence,
                    station,
                },
            );
            session.record_pose(p);
            session.stats.poses_accepted.fetch_add(1, Ordering::Relaxed);
            Ok(())
        }
        Err(r) => Err((r, Some(p.sequence), Some(p.instrument.clone()))),
    }
}
