//! An instructor's view of a live session: the `Observe.Observe` stream, condensed
//! into one status line per second (tick, simulated time, which instruments touch
//! the liver and with what force) and the events as they come. A recording the
//! server plays back (`Recordings.Replay`) is the same stream and is watched the
//! same way.

use std::collections::BTreeMap;
use std::fmt;
use std::time::{Duration, Instant};

use tokio::time::MissedTickBehavior;

use crate::connect::{ConnectConfig, connect};
use crate::proto::v1::{
    ContactState, Event, EventKind, InstrumentState, ObserveRequest, ReplayRequest,
    SceneDescription, observe_message,
};
use crate::station::{
    StationError, StopSignal, TickCounter, after, answered, call_limit, force_magnitude,
    when_stopped,
};

/// How often [`ObserveReport::Status`] is given.
pub const STATUS_PERIOD: Duration = Duration::from_secs(1);

/// What [`run_observe`] does.
pub struct ObserveConfig {
    /// The server.
    pub connect: ConnectConfig,
    /// Session to watch.
    pub session_id: String,
    /// Frame rate to ask for, Hz; `None` for the mechanics rate.
    pub frame_rate_hz: Option<f64>,
    /// How long to watch; `None` until stopped or the session closes.
    pub duration: Option<Duration>,
    /// Stops watching when it completes.
    pub stop: Option<StopSignal>,
    /// Watch this recording played back by the server instead of `session_id` (and
    /// `frame_rate_hz`).
    pub replay: Option<ReplayRequest>,
}

impl ObserveConfig {
    /// Watch `session_id` at `url` at the mechanics rate until it closes.
    pub fn new(url: impl Into<String>, session_id: impl Into<String>) -> Self {
        ObserveConfig {
            connect: ConnectConfig::new(url),
            session_id: session_id.into(),
            frame_rate_hz: None,
            duration: None,
            stop: None,
            replay: None,
        }
    }

    /// Watch the server at `url` play `request`'s recording back, to its end.
    pub fn replay(url: impl Into<String>, request: ReplayRequest) -> Self {
        ObserveConfig {
            replay: Some(request),
            ..ObserveConfig::new(url, String::new())
        }
    }
}

/// The state of one instrument as the status line shows it.
#[derive(Clone, Debug, PartialEq)]
pub struct InstrumentStatus {
    /// Which parts touch the liver.
    pub contact: ContactState,
    /// Server force |F|, N.
    pub force_n: f64,
    /// Station holding the instrument, if any.
    pub station_id: Option<u64>,
}

/// One status line: the session at the newest tick received.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StatusLine {
    /// Newest mechanics tick.
    pub tick: u64,
    /// Its simulated time, s.
    pub sim_time_s: f64,
    /// Surface frames received in the last period.
    pub frames: u64,
    /// Each instrument at its newest state, by name.
    pub instruments: BTreeMap<String, InstrumentStatus>,
}

impl fmt::Display for StatusLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "tick {:>7}  t {:>8.3} s  {:>3} frames/s",
            self.tick, self.sim_time_s, self.frames
        )?;
        for (name, s) in &self.instruments {
            let contact = match s.contact {
                ContactState::Tip => "tip",
                ContactState::Shaft => "shaft",
                ContactState::TipAndShaft => "tip+shaft",
                ContactState::None | ContactState::Unspecified => "free",
            };
            write!(f, "  {name}: {contact} {:.2} N", s.force_n)?;
        }
        Ok(())
    }
}

/// Formats an event on one line.
pub fn event_line(event: &Event) -> String {
    let kind = EventKind::try_from(event.kind)
        .map(|k| k.as_str_name().trim_start_matches("EVENT_KIND_").to_owned())
        .unwrap_or_else(|_| format!("UNKNOWN_{}", event.kind));
    let mut line = format!(
        "tick {:>7}  t {:>8.3} s  {kind}",
        event.tick, event.sim_time_s
    );
    if let Some(id) = event.station_id {
        line.push_str(&format!("  station {id}"));
    }
    if let Some(instrument) = &event.instrument {
        line.push_str(&format!("  {instrument}"));
    }
    if !event.detail.is_empty() {
        line.push_str(&format!("  ({})", event.detail));
    }
    line
}

/// What [`run_observe`] reports as it watches.
#[derive(Debug)]
pub enum ObserveReport<'a> {
    /// The scene, once, first.
    Scene(&'a SceneDescription),
    /// Every [`STATUS_PERIOD`], the newest state of the session.
    Status(&'a StatusLine),
    /// An event, as it arrives.
    Event(&'a Event),
}

/// What an observe run saw.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObserveSummary {
    /// Wall time watched, s.
    pub elapsed_s: f64,
    /// Distinct mechanics ticks seen.
    pub ticks: u64,
    /// Surface frames received.
    pub frames: u64,
    /// Instrument states received.
    pub states: u64,
    /// Events received.
    pub events: u64,
    /// Largest server force |F| on any instrument, N.
    pub max_force_n: f64,
    /// Whether the server ended the stream (the session closed, or the recording
    /// played back ended).
    pub server_closed: bool,
    /// What the server said when it ended a replay at the end of what it had
    /// rather than the recording's (`OUT_OF_RANGE`: a recording still being
    /// written, played to where it stood when the replay began).
    pub end_note: Option<String>,
}

fn update(line: &mut StatusLine, state: &InstrumentState) {
    line.instruments.insert(
        state.instrument.clone(),
        InstrumentStatus {
            contact: ContactState::try_from(state.contact).unwrap_or(ContactState::Unspecified),
            force_n: force_magnitude(state),
            station_id: state.station_id,
        },
    );
}

/// Watches a session, reporting the scene, a status line every second and the
/// events; see the [module documentation](self). A stream ended by the server with a
/// gRPC status is returned as [`StationError::Status`]. The configured duration
/// bounds the whole run, connecting included.
pub async fn run_observe(
    mut config: ObserveConfig,
    mut on_report: impl FnMut(ObserveReport<'_>),
) -> Result<ObserveSummary, StationError> {
    if let Some(rate) = config
        .frame_rate_hz
        .filter(|r| !(r.is_finite() && *r > 0.0))
    {
        return Err(StationError::Rate {
            field: "frame rate",
            value: rate,
            expected: "finite and > 0".to_owned(),
        });
    }
    let started = Instant::now();
    let duration = config.duration;
    let connection = connect(&config.connect.within(duration)).await?;
    let limit = call_limit(started, duration);
    let mut stream = match config.replay.take() {
        Some(request) => {
            let mut recordings = connection.recordings();
            answered("the replay", limit, async move {
                Ok(recordings.replay(request).await?)
            })
            .await?
        }
        None => {
            let mut observe = connection.observe();
            let request = ObserveRequest {
                session_id: config.session_id.clone(),
                frame_rate_hz: config.frame_rate_hz,
            };
            answered("the observe call", limit, async move {
                Ok(observe.observe(request).await?)
            })
            .await?
        }
    }
    .into_inner();
    let t0 = Instant::now();
    let mut summary = ObserveSummary::default();
    let mut ticks = TickCounter::default();
    let mut line = StatusLine::default();
    let mut status_tick =
        tokio::time::interval_at(tokio::time::Instant::now() + STATUS_PERIOD, STATUS_PERIOD);
    status_tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let deadline = after(duration.map(|d| d.saturating_sub(started.elapsed())));
    tokio::pin!(deadline);
    let stop = when_stopped(config.stop.take());
    tokio::pin!(stop);

    let mut heard = Instant::now();
    loop {
        tokio::select! {
            biased;
            _ = &mut stop => break,
            _ = &mut deadline => break,
            message = stream.message() => match message {
                Ok(Some(message)) => { heard = Instant::now(); match message.kind {
                    Some(observe_message::Kind::Scene(scene)) => {
                        on_report(ObserveReport::Scene(&scene));
                    }
                    Some(observe_message::Kind::SurfaceFrame(frame)) => {
                        summary.frames += 1;
                        line.frames += 1;
                        ticks.see(frame.tick, frame.sim_time_s);
                    }
                    Some(observe_message::Kind::InstrumentState(state)) => {
                        summary.states += 1;
                        ticks.see(state.tick, state.sim_time_s);
                        summary.max_force_n = summary.max_force_n.max(force_magnitude(&state));
                        update(&mut line, &state);
                    }
                    Some(observe_message::Kind::Event(event)) => {
                        summary.events += 1;
                        on_report(ObserveReport::Event(&event));
                    }
                    None => {}
                }},
                Ok(None) => {
                    summary.server_closed = true;
                    break;
                }
                Err(status) if status.code() == tonic::Code::OutOfRange => {
                    summary.server_closed = true;
                    summary.end_note = Some(status.message().to_string());
                    break;
                }
                Err(status) => {
                    return Err(StationError::after_silence(status, heard.elapsed()));
                }
            },
            _ = status_tick.tick() => {
                line.tick = ticks.last.unwrap_or(0);
                line.sim_time_s = ticks.sim_time_s;
                on_report(ObserveReport::Status(&line));
                line.frames = 0;
            }
        }
    }
    summary.elapsed_s = t0.elapsed().as_secs_f64();
    summary.ticks = ticks.ticks;
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::proto::v1::{Force, Vec3};

    #[test]
    fn status_line_shows_contact_and_force() {
        let mut line = StatusLine {
            tick: 120,
            sim_time_s: 2.0,
            frames: 30,
            ..Default::default()
        };
        update(
            &mut line,
            &InstrumentState {
                instrument: "left".into(),
                contact: ContactState::Tip as i32,
                force: Some(Force {
                    force: Some(Vec3 {
                        x: 0.0,
                        y: 3.0,
                        z: 4.0,
                    }),
                    ..Default::default()
                }),
                ..Default::default()
            },
        );
        let text = line.to_string();
        assert!(text.contains("left: tip 5.00 N"), "{text}");
        assert!(text.contains("tick     120"), "{text}");
    }

    #[test]
    fn event_line_names_the_kind() {
        let event = Event {
            tick: 3,
            kind: EventKind::ContactBegan as i32,
            instrument: Some("right".into()),
            ..Default::default()
        };
        let text = event_line(&event);
        assert!(text.contains("CONTACT_BEGAN  right"), "{text}");
    }
}
