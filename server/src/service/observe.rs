//! `Observe`: an instructor's read-only view of a session, every instrument.

use std::sync::Arc;
use std::time::Instant;

use laparo_proto::v1;
use tokio::sync::{mpsc, watch};
use tonic::{Request, Response, Status};

use super::auth::caller;
use super::limits::MAX_OBSERVERS_PER_SESSION;
use super::liveness::{Liveness, Outbound, StationTimeout, Taken};
use super::registry::Registry;
use super::stream::{OUTBOUND, States, frame_rate, pump};
use crate::session::Session;

pub struct ObserveService {
    pub registry: Arc<Registry>,
    /// How long an observer may take none of the messages waiting for it before
    /// its stream is cut (the server's station timeout, applied as to a station's
    /// outgoing queue; an observer sends nothing, so only taking counts).
    pub timeout: StationTimeout,
}

/// Counts an observer in the roster while its stream lasts.
struct Observer(Arc<Session>);

impl Drop for Observer {
    fn drop(&mut self) {
        let mut roster = self.0.roster();
        roster.observers = roster.observers.saturating_sub(1);
    }
}

#[tonic::async_trait]
impl v1::observe_server::Observe for ObserveService {
    type ObserveStream = Outbound<v1::ObserveMessage>;

    async fn observe(
        &self,
        request: Request<v1::ObserveRequest>,
    ) -> Result<Response<Self::ObserveStream>, Status> {
        caller(&request)?.require_instructor("observing a session")?;
        let r = request.get_ref();
        super::limits::check_name("session_id", &r.session_id)?;
        let session = self.registry.get(&r.session_id)?;
        let rate = frame_rate(r.frame_rate_hz, session.scene.mechanics.rate_hz)?;
        let (tx, rx) = mpsc::channel(OUTBOUND);
        let scene = v1::ObserveMessage {
            kind: Some(v1::observe_message::Kind::Scene(
                session.description.clone(),
            )),
        };
        let _ = tx.try_send(Ok(scene));
        for event in session.recording_events() {
            let _ = tx.try_send(Ok(v1::ObserveMessage {
                kind: Some(v1::observe_message::Kind::Event(event)),
            }));
        }
        {
            let mut roster = session.roster();
            if roster.observers >= MAX_OBSERVERS_PER_SESSION {
                return Err(Status::resource_exhausted(format!(
                    "session `{}` has {MAX_OBSERVERS_PER_SESSION} observers already \
                     (MAX_OBSERVERS_PER_SESSION)",
                    session.id
                )));
            }
            roster.observers += 1;
        }
        let observer = Observer(session.clone());
        let connected = session.connect();
        let taken = Taken::new(Instant::now());
        let (outbound, cut) = Outbound::new(rx, taken.clone());
        let mut liveness = Liveness::new(self.timeout, Instant::now(), taken);
        let period = self.timeout.check_period();
        tokio::spawn(async move {
            let (_observer, _connected) = (observer, connected);
            // A frozen observer (it no longer reads, its HTTP/2 window full) is cut:
            // it kept its place among the session's observers, and the session
            // copied every frame for it, for ever.
            let queue = tx.clone();
            let (_done_tx, done) = watch::channel(false);
            let pumping = pump(session, tx, rate, States::WithSurfaces, done);
            tokio::pin!(pumping);
            let mut check = tokio::time::interval(period);
            check.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
            loop {
                tokio::select! {
                    _ = &mut pumping => break,
                    _ = check.tick() => {
                        let now = Instant::now();
                        liveness.heard(now);
                        if let Some(gone) = liveness.check(now, queue.capacity() < OUTBOUND) {
                            let _ = cut.send(Status::deadline_exceeded(format!(
                                "this observer {gone}: its stream ends"
                            )));
                            break;
                        }
                    }
                }
            }
        });
        Ok(Response::new(outbound))
    }
}
