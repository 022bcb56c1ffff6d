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
    /// Scene `name` described (mesh sizes and the rest surface need the mesh, so
    /// the first call builds it; the catalog keeps the answer).
    fn describe(&self, name: &str) -> Result<v1::SceneDescription, Status> {
        let described = tokio::task::block_in_place(|| {
            self.registry.catalog.described(name, |scene| {
                let sim = scene
                    .build()
                    .map_err(|e| format!("scene `{name}` does not build: {e}"))?;
                Ok(description::description(scene, &sim))
            })
        });
        match described {
            None => Err(Status::not_found(format!("no scene `{}`", printable(name)))),
            Some(Ok(description)) => Ok(description),
            Some(Err(e)) => Err(Status::failed_precondition(e)),
        }
    }
}

#[tonic::async_trait]
impl Scenes for ScenesService {
    async fn list_scenes(
        &self,
        request: Request<v1::ListScenesRequest>,
    ) -> Result<Response<v1::ListScenesResponse>, Status> {
        caller(&request)?;
        let catalog = &self.registry.catalog;
        let mut scenes = Vec::with_capacity(catalog.scenes.len());
        let mut unavailable = catalog.unavailable.clone();
        for (name, scene) in &catalog.scenes {
            // A scene whose mesh does not build is reported beside the others.
            match self.describe(name) {
                Ok(description) => scenes.extend(description.summary),
                Err(status) => {
                    tracing::warn!(scene = %name, "scene not offered: {}", status.message());
                    unavailable.push(v1::SceneProblem {
                        name: name.clone(),
                        file: std::path::Path::new(&scene.source)
                            .file_name()
                            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
                        error: status.message().to_string(),
                    });
                }
            }
        }
        Ok(Response::new(v1::ListScenesResponse {
            scenes,
            unavailable,
        }))
    }

    async fn get_scene(
        &self,
        request: Request<v1::GetSceneRequest>,
    ) -> Result<Response<v1::SceneDescription>, Status> {
        caller(&request)?;
        super::limits::check_name("name", &request.get_ref().name)?;
        Ok(Response::new(self.describe(&request.get_ref().name)?))
    }
}
