//! `Scenes`: what the server can run.

use std::sync::Arc;

use laparo_proto::text::printable;
use laparo_proto::v1;
use laparo_proto::v1::scenes_server::Scenes;
use tonic::{Request, Response, Status};

use super::auth::caller;
use super::registry::Registry;
use crate::frame::description;

pub struct ScenesService {
    pub registry: Arc<Registry>,
}

impl ScenesService {
    /// Builds scene `name` to describe it (mesh sizes and the rest surface need the
    /// mesh).
    fn describe(&self, name: &str) -> Result<v1::SceneDescription, Status> {
        let scene = self
            .registry
            .catalog
            .scenes
            .get(name)
            .ok_or_else(|| Status::not_found(format!("no scene `{}`", printable(name))))?;
        let sim = tokio::task::block_in_place(|| scene.build()).map_err(|e| {
            Status::failed_precondition(format!("scene `{name}` does not build: {e}"))
        })?;
        Ok(description::description(scene, &sim))
    }
}

#[tonic::async_trait]
impl Scenes for ScenesService {
    async fn list_scenes(
        &self,
        request: Request<v1::ListScenesRequest>,
    ) -> Result<Response<v1::ListScenesResponse>, Status> {
        caller(&request)?;
        let names: Vec<String> = self.registry.catalog.scenes.keys().cloned().collect();
        let mut scenes = Vec::with_capacity(names.len());
        for name in names {
            if let Some(summary) = self.describe(&name)?.summary {
                scenes.push(summary);
            }
        }
        Ok(Response::new(v1::ListScenesResponse { scenes }))
    }

    async fn get_scene(
        &self,
        request: Request<v1::GetSceneRequest>,
    ) -> Result<Response<v1::SceneDescription>, Status> {
        caller(&request)?;
        Ok(Response::new(self.describe(&request.get_ref().name)?))
    }
}
