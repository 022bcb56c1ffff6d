//! `laparo sessions create|list|info|close|evict`: the sessions of a server, as an
//! instructor manages them. Every answer is printed from the server's `SessionInfo`
//! (names escaped: they come from other clients); a refusal is said in words (not
//! found, permission denied, a limit reached) with the server's message.

use clap::{Args, Subcommand};
use laparo_proto::text::printable;
use tonic::{Code, Status};

use super::BoxError;
use super::args::{ServerArgs, idle_seconds};
use super::out::say;
use crate::connect::{Connection, connect, failure, unary};
use crate::proto::v1::{
    CloseSessionRequest, CreateSessionRequest, EvictStationRequest, GetSessionRequest,
    ListSessionsRequest, Role, SessionInfo, StationInfo,
};

/// `laparo sessions …`.
#[derive(Subcommand, Debug, Clone)]
pub enum SessionsCommand {
    /// Start a session of a scene (instructor) and print it; its id is what
    /// `station --session` and `observe --session` take.
    Create {
        #[command(flatten)]
        server: ServerArgs,
        #[command(flatten)]
        create: CreateArgs,
    },
    /// The open sessions, one markdown table row each.
    List {
        #[command(flatten)]
        server: ServerArgs,
    },
    /// One session: scene, stations, who holds which instrument, tick rate, missed
    /// deadlines, recording.
    Info {
        #[command(flatten)]
        server: ServerArgs,
        /// The session's id.
        #[arg(value_name = "SESSION")]
        session: String,
    },
    /// Close a session (instructor): its streams end, its recording is finished.
    Close {
        #[command(flatten)]
        server: ServerArgs,
        /// The session's id.
        #[arg(value_name = "SESSION")]
        session: String,
        /// Why, for the session's streams and its recording.
        #[arg(long, value_name = "TEXT", default_value = "")]
        reason: String,
    },
    /// End a station's stream and free its instruments (instructor).
    Evict {
        #[command(flatten)]
        server: ServerArgs,
        /// The session's id.
        #[arg(value_name = "SESSION")]
        session: String,
        /// The station's id (`sessions info` lists them).
        #[arg(value_name = "STATION")]
        station: u64,
        /// Why, for the station and the session's streams.
        #[arg(long, value_name = "TEXT", default_value = "")]
        reason: String,
    },
}

/// What a new session is.
#[derive(Args, Debug, Clone, Default)]
pub struct CreateArgs {
    /// Scene to run [default: the server's default scene].
    #[arg(
        long,
        value_name = "NAME",
        default_value = "",
        hide_default_value = true
    )]
    pub scene: String,
    /// Close the session after this many seconds with nobody connected (0: never;
    /// at most 604800) [default: the server's].
    #[arg(long, value_name = "S", value_parser = idle_seconds)]
    pub idle_timeout: Option<f64>,
    /// Record the session [default: as the scene declares].
    #[arg(long, conflicts_with = "no_record")]
    pub record: bool,
    /// Do not record the session.
    #[arg(long)]
    pub no_record: bool,
}

impl CreateArgs {
    /// The request these arguments make.
    pub fn request(&self) -> CreateSessionRequest {
        CreateSessionRequest {
            scene: self.scene.clone(),
            idle_timeout_s: self.idle_timeout,
            record: match (self.record, self.no_record) {
                (true, _) => Some(true),
                (_, true) => Some(false),
                _ => None,
            },
        }
    }
}

/// Runs one `sessions` subcommand.
pub async fn run(command: SessionsCommand) -> Result<(), BoxError> {
    match command {
        SessionsCommand::Create { server, create } => {
            let c = dial(&server).await?;
            let info = c
                .sessions()
                .create_session(unary(create.request()))
                .await
                .map_err(|s| refused("creating a session", &s))?
                .into_inner();
            say!("created session {}", printable(&info.session_id));
            print_info(&info);
        }
        SessionsCommand::List { server } => {
            let c = dial(&server).await?;
            let listed = c
                .sessions()
                .list_sessions(unary(ListSessionsRequest {}))
                .await
                .map_err(|s| refused("listing the sessions", &s))?
                .into_inner();
            say!(
                "| session | scene | tick | rate (Hz) | stations | instruments held | observers | missed deadlines | recording |"
            );
            say!("|---|---|---|---|---|---|---|---|---|");
            for s in &listed.sessions {
                say!(
                    "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                    printable(&s.session_id),
                    printable(&s.scene),
                    s.tick,
                    rate(s),
                    s.stations.len(),
                    holders(s),
                    s.observer_count,
                    s.missed_deadlines,
                    recording(s)
                );
            }
        }
        SessionsCommand::Info { server, session } => {
            let c = dial(&server).await?;
            let info = c
                .sessions()
                .get_session(unary(GetSessionRequest {
                    session_id: session.clone(),
                }))
                .await
                .map_err(|s| refused(&format!("session {}", printable(&session)), &s))?
                .into_inner();
            print_info(&info);
        }
        SessionsCommand::Close {
            server,
            session,
            reason,
        } => {
            let c = dial(&server).await?;
            let closed = c
                .sessions()
                .close_session(unary(CloseSessionRequest {
                    session_id: session.clone(),
                    reason,
                }))
                .await
                .map_err(|s| refused(&format!("closing session {}", printable(&session)), &s))?
                .into_inner()
                .session
                .unwrap_or_default();
            say!(
                "closed session {} at tick {} ({:.3} s simulated); recording: {}",
                printable(&closed.session_id),
                closed.tick,
                closed.sim_time_s,
                recording(&closed)
            );
        }
        SessionsCommand::Evict {
            server,
            session,
            station,
            reason,
        } => {
            let c = dial(&server).await?;
            let evicted = c
                .sessions()
                .evict_station(unary(EvictStationRequest {
                    session_id: session.clone(),
                    station_id: station,
                    reason,
                }))
                .await
                .map_err(|s| {
                    refused(
                        &format!(
                            "evicting station {station} of session {}",
                            printable(&session)
                        ),
                        &s,
                    )
                })?
                .into_inner()
                .station
                .unwrap_or_default();
            say!(
                "evicted station {} from session {}; free now: {}",
                station_line(&evicted),
                printable(&session),
                list_or(&evicted.instruments, "no instrument")
            );
        }
    }
    Ok(())
}

/// The connection to the server of `server`.
async fn dial(server: &ServerArgs) -> Result<Connection, BoxError> {
    Ok(connect(&server.connect_config()).await?)
}

/// A refusal or failure of `what`, in words: what the server's code means for a
/// user, then its message.
pub fn refused(what: &str, status: &Status) -> String {
    if let Some(lost) = failure::lost(status) {
        return format!("{what}: {lost}");
    }
    let words = match status.code() {
        Code::NotFound => "not found",
        Code::PermissionDenied => "permission denied (this needs an instructor token)",
        Code::Unauthenticated => "not authenticated (a missing or unknown token)",
        Code::ResourceExhausted => "a server limit is reached",
        Code::InvalidArgument | Code::OutOfRange => "the server refused the request",
        Code::FailedPrecondition => "the scene cannot run",
        Code::Unavailable => "the server cannot do it now",
        Code::DeadlineExceeded => "no answer in time",
        _ => "the server answered an error",
    };
    format!("{what}: {words}: {}", printable(status.message()))
}

/// The mechanics rate of a session, from its tick and simulated time (the time is
/// tick / rate); `—` before its first tick.
fn rate(info: &SessionInfo) -> String {
    if info.tick > 0 && info.sim_time_s > 0.0 {
        format!("{:.0}", info.tick as f64 / info.sim_time_s)
    } else {
        "—".into()
    }
}

/// `left: station 1, right: free`.
fn holders(info: &SessionInfo) -> String {
    let held: Vec<String> = info
        .instruments
        .iter()
        .map(|h| match h.station_id {
            Some(id) => format!("{}: station {id}", printable(&h.instrument)),
            None => format!("{}: free", printable(&h.instrument)),
        })
        .collect();
    list_or(&held, "no instrument")
}

/// Whether and where the session records.
fn recording(info: &SessionInfo) -> String {
    match (&info.recording_file, &info.recording_error) {
        (Some(file), None) => printable(file).into_owned(),
        (Some(file), Some(e)) => format!("{} (stopped: {})", printable(file), printable(e)),
        (None, Some(e)) => format!("none (failed: {})", printable(e)),
        (None, None) => "not recorded".into(),
    }
}

/// `3 (trainee, "laparo station")`.
fn station_line(s: &StationInfo) -> String {
    let role = match Role::try_from(s.role) {
        Ok(Role::Trainee) => "trainee",
        Ok(Role::Instructor) => "instructor",
        _ => "unknown role",
    };
    format!(
        "{} ({role}, \"{}\")",
        s.station_id,
        printable(&s.client_name)
    )
}

/// The items joined by `, `, or `none` when there are none.
pub(crate) fn list_or<S: AsRef<str>>(items: &[S], none: &str) -> String {
    if items.is_empty() {
        none.into()
    } else {
        items
            .iter()
            .map(|s| printable(s.as_ref()).into_owned())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// A session, one property a line.
fn print_info(info: &SessionInfo) {
    let created = info
        .created_at
        .as_ref()
        .map_or("—".into(), |t| t.to_string());
    say!("session            {}", printable(&info.session_id));
    say!("scene              {}", printable(&info.scene));
    say!("created            {created}");
    say!(
        "tick               {} ({:.3} s simulated, {} Hz)",
        info.tick,
        info.sim_time_s,
        rate(info)
    );
    say!(
        "tick time          p50 {:.3} ms, p99 {:.3} ms; missed deadlines {}",
        info.tick_time_p50_ms,
        info.tick_time_p99_ms,
        info.missed_deadlines
    );
    say!("stations           {}", info.stations.len());
    for s in &info.stations {
        say!(
            "  station {}  holds {}",
            station_line(s),
            list_or(&s.instruments, "no instrument (watching)")
        );
    }
    say!("instruments        {}", holders(info));
    say!("observers          {}", info.observer_count);
    say!(
        "idle timeout       {}",
        info.idle_timeout_s
            .map_or("never".into(), |t| format!("{t} s"))
    );
    say!(
        "poses              {} accepted, {} rejected",
        info.poses_accepted,
        info.poses_rejected
    );
    say!("recording          {}", recording(info));
    if info.recording_file.is_some() {
        say!(
            "recorder           {} items left out, backlog at most {}, lag at most {:.1} ms",
            info.recorder_dropped,
            info.recorder_max_backlog,
            info.recorder_max_lag_ms
        );
    }
    say!(
        "simulation         {}",
        info.simulation_error
            .as_deref()
            .map_or("running".into(), |e| format!("halted: {}", printable(e)))
    );
}
