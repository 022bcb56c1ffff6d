//! `Observe`: an instructor's read-only view of a session, every instrument.

use std::sync::Arc;

use laparo_proto::v1;
use tokio::sync::{mpsc, watch};
use tokio_stream::wrappers::ReceiverStream;
use tonic::{Request, Response, Status};

use super::auth::caller;
use super::limits::MAX_OBSERVERS_PER_SESSION;
use super::registry::Registry;
use super::stream::{OUTBOUND, frame_rate, pump};
use crate::session::Session;

pub struct ObserveService {
    pub registry: Arc<Registry>,
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
    type ObserveStream = ReceiverStream<Result<v1::ObserveMessage, Status>>;

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
        let (_done_tx, done) = watch::channel(false);
        tokio::spawn(async move {
            let (_observer, _connected, _done_tx) = (observer, connected, _done_tx);
            pump(session, tx, rate, done).await;
        });
        Ok(Response::new(ReceiverStream::new(rx)))
    }
}
