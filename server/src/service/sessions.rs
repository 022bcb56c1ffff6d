//! `Sessions`: create, inspect, list and close sessions; evict a station.

use std::sync::Arc;

use laparo_proto::text::printable;
use laparo_proto::v1;
use laparo_proto::v1::sessions_server::Sessions;
use tonic::{Request, Response, Status};

use super::auth::caller;
use super::limits;
use super::registry::Registry;
use crate::session::{Session, idle_timeout};

pub struct SessionsService {
    pub registry: Arc<Registry>,
}

#[tonic::async_trait]
impl Sessions for SessionsService {
    async fn create_session(
        &self,
        request: Request<v1::CreateSessionRequest>,
    ) -> Result<Response<v1::SessionInfo>, Status> {
        caller(&request)?.require_instructor("creating a session")?;
        let r = request.get_ref();
        limits::check_name("scene", &r.scene)?;
        let idle = match r.idle_timeout_s {
            None => self.registry.idle_timeout,
            Some(t) => idle_timeout(t)
                .map_err(|e| Status::invalid_argument(format!("idle_timeout_s: {e}")))?,
        };
        let scene = if r.scene.is_empty() {
            "default"
        } else {
            &r.scene
        };
        let session = self.registry.create(scene, idle, r.record)?;
        Ok(Response::new(described(&session)))
    }

    async fn get_session(
        &self,
        request: Request<v1::GetSessionRequest>,
    ) -> Result<Response<v1::SessionInfo>, Status> {
        caller(&request)?;
        limits::check_name("session_id", &request.get_ref().session_id)?;
        let session = self.registry.get(&request.get_ref().session_id)?;
        Ok(Response::new(described(&session)))
    }

    async fn list_sessions(
        &self,
        request: Request<v1::ListSessionsRequest>,
    ) -> Result<Response<v1::ListSessionsResponse>, Status> {
        caller(&request)?;
        let sessions = self.registry.list().iter().map(|s| described(s)).collect();
        Ok(Response::new(v1::ListSessionsResponse { sessions }))
    }

    async fn close_session(
        &self,
        request: Request<v1::CloseSessionRequest>,
    ) -> Result<Response<v1::CloseSessionResponse>, Status> {
        caller(&request)?.require_instructor("closing a session")?;
        let r = request.get_ref();
        limits::check_name("session_id", &r.session_id)?;
        limits::check_reason("reason", &r.reason)?;
        let reason = if r.reason.is_empty() {
            "closed by an instructor".into()
        } else {
            // Escaped: it goes into the closing event and every stream's status.
            printable(&r.reason)
        };
        let session = self.registry.close(&r.session_id, &reason)?;
        Ok(Response::new(v1::CloseSessionResponse {
            session: Some(described(&session)),
        }))
    }

    async fn evict_station(
        &self,
        request: Request<v1::EvictStationRequest>,
    ) -> Result<Response<v1::EvictStationResponse>, Status> {
        let who = caller(&request)?;
        who.require_instructor("evicting a station")?;
        let r = request.get_ref();
        limits::check_name("session_id", &r.session_id)?;
        limits::check_reason("reason", &r.reason)?;
        let reason = if r.reason.is_empty() {
            "no reason given".into()
        } else {
            // Escaped: it goes into an event and the evicted station's status.
            printable(&r.reason)
        };
        let session = self.registry.get(&r.session_id)?;
        let station = session
            .evict(r.station_id, &printable(&who.name), &reason)
            .await
            .ok_or_else(|| {
                Status::not_found(format!(
                    "session `{}` has no station {}",
                    session.id, r.station_id
                ))
            })?;
        Ok(Response::new(v1::EvictStationResponse {
            station: Some(station),
        }))
    }
}

/// A session as the contract describes it, with the limits this service holds it
/// to (the session itself does not know them).
fn described(session: &Session) -> v1::SessionInfo {
    v1::SessionInfo {
        max_stations: limits::MAX_STATIONS_PER_SESSION as u32,
        ..session.info()
    }
}
