//! `Recordings`: answered `UNIMPLEMENTED` until sessions are recorded (MCAP).

use laparo_proto::v1;
use tokio_stream::wrappers::ReceiverStream;
use tonic::{Request, Response, Status};

use super::auth::caller;

pub struct RecordingsService;

#[tonic::async_trait]
impl v1::recordings_server::Recordings for RecordingsService {
    type ReplayStream = ReceiverStream<Result<v1::ObserveMessage, Status>>;

    async fn list_recordings(
        &self,
        request: Request<v1::ListRecordingsRequest>,
    ) -> Result<Response<v1::ListRecordingsResponse>, Status> {
        caller(&request)?;
        Err(Status::unimplemented(
            "this server does not record sessions yet",
        ))
    }

    async fn replay(
        &self,
        request: Request<v1::ReplayRequest>,
    ) -> Result<Response<Self::ReplayStream>, Status> {
        caller(&request)?;
        Err(Status::unimplemented(
            "this server does not record sessions yet",
        ))
    }
}
