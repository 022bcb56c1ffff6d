//! What a client or an operator's scene directory can ask of the server, over real gRPC
//! on loopback: durations out of range are refused, a broken scene file hides nothing
//! else and stops nothing, a scene that cannot tick is refused with the reason, and a
//! session with long ticks still closes.

use std::path::Path;
use std::time::Duration;

use laparo_proto::v1;
use laparo_server::service::ServeConfig;
use laparo_tests::server::*;
use tonic::Code;

/// A bound on each call, so that a hang fails the test instead of stalling it.
const WAIT: Duration = Duration::from_secs(30);

const LIVER: &str = include_str!("../../server/meshes/liver.msh");
const LIVER_5K: &str = include_str!("../../server/meshes/liver-5k.msh");
const DEFAULT: &str = include_str!("../../server/scenes/default.toml");

/// A scene on `mesh`, with `extra` TOML appended (tables after the material).
fn scene(name: &str, mesh: &str, extra: &str) -> String {
    format!(
        "name = \"{name}\"\ngravity = [0.0, -9.81, 0.0]\n[mesh]\nfile = \"{mesh}\"\n\
         scale = 0.03\ncenter = true\n[material]\nyoung_modulus = 3000.0\n\
         poisson_ratio = 0.3\ndensity = 1000.0\n[fixed]\nnodes = [3, 39, 64]\n{extra}"
    )
}

fn write(dir: &Path, file: &str, text: &str) {
    std::fs::write(dir.join(file), text).unwrap();
}

async fn create(
    channel: tonic::transport::Channel,
    scene: &str,
    idle_timeout_s: Option<f64>,
) -> Result<v1::SessionInfo, tonic::Status> {
    let mut client = v1::sessions_client::SessionsClient::new(channel);
    let call = client.create_session(v1::CreateSessionRequest {
        scene: scene.into(),
        idle_timeout_s,
        record: Some(false),
    });
    tokio::time::timeout(WAIT, call)
        .await
        .expect("CreateSession answers")
        .map(|r| r.into_inner())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idle_timeouts_out_of_range_are_invalid_arguments_naming_the_field_and_range() {
    let server = TestServer::start(ServeConfig::default()).await;
    let channel = server.channel().await;
    for bad in [1.85e19, 1e20, f64::MAX, -1.0, f64::INFINITY, f64::NAN] {
        let status = create(channel.clone(), "default", Some(bad))
            .await
            .unwrap_err();
        assert_eq!(status.code(), Code::InvalidArgument, "{bad}: {status:?}");
        assert!(
            status.message().contains("idle_timeout_s") && status.message().contains("604800"),
            "{bad}: {}",
            status.message()
        );
    }
    let info = create(channel.clone(), "default", Some(3600.0))
        .await
        .unwrap();
    assert_eq!(info.idle_timeout_s, Some(3600.0));
    let never = create(channel, "default", Some(0.0)).await.unwrap();
    assert_eq!(never.idle_timeout_s, None);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn list_scenes_lists_what_builds_and_reports_every_broken_file_beside_it() {
    let root = tempfile::tempdir().unwrap();
    // A mesh beside the scene directory, which its scenes must not reach.
    write(root.path(), "liver.msh", LIVER);
    let d = &root.path().join("scenes");
    std::fs::create_dir(d).unwrap();
    write(d, "liver.msh", LIVER);
    write(d, "good.toml", &scene("good", "liver.msh", ""));
    // A copy of the default scene: same name, the embedded one is kept.
    write(d, "copy.toml", DEFAULT);
    write(d, "missing.toml", &scene("missing", "nowhere.msh", ""));
    let fifo = std::process::Command::new("mkfifo")
        .arg(d.join("pipe.msh"))
        .status()
        .unwrap();
    assert!(fifo.success());
    write(d, "fifo.toml", &scene("fifo", "pipe.msh", ""));
    write(d, "zero.toml", &scene("zero", "/dev/zero", ""));
    write(d, "up.toml", &scene("up", "../liver.msh", ""));
    write(
        d,
        "stiff.toml",
        &scene("stiff", "liver.msh", "").replace("3000.0", "1e308"),
    );
    write(
        d,
        "slow.toml",
        &scene(
            "slow",
            "liver.msh",
            "[mechanics]\nintegrator = \"explicit\"\nrate_hz = 1.0\n",
        )
        .replace("young_modulus = 3000.0", "young_modulus = 1e12")
        .replace("density = 1000.0", "density = 0.01"),
    );
    write(d, "typo.toml", "name = \"typo\"\n[mesh\n");
    let server = TestServer::start(ServeConfig {
        scene_dir: Some(d.clone()),
        ..ServeConfig::default()
    })
    .await;
    let channel = server.channel().await;
    let mut scenes = v1::scenes_client::ScenesClient::new(channel.clone());
    let list = tokio::time::timeout(WAIT, scenes.list_scenes(v1::ListScenesRequest {}))
        .await
        .expect("ListScenes answers")
        .unwrap()
        .into_inner();
    let names: Vec<&str> = list.scenes.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["default", "good"]);
    let problem = |file: &str| {
        list.unavailable
            .iter()
            .find(|p| p.file == file)
            .unwrap_or_else(|| panic!("{file} is not reported: {:#?}", list.unavailable))
    };
    for (file, name, words) in [
        (
            "copy.toml",
            "default",
            "already offered by builtin:default.toml",
        ),
        ("missing.toml", "missing", "nowhere.msh"),
        ("fifo.toml", "fifo", "FIFO"),
        ("zero.toml", "zero", "outside the scene directory"),
        ("up.toml", "up", "outside the scene directory"),
        ("stiff.toml", "", "material.young_modulus"),
        ("slow.toml", "slow", "substeps a tick"),
        ("typo.toml", "", "typo.toml"),
    ] {
        let p = problem(file);
        assert_eq!(p.name, name, "{file}");
        assert!(p.error.contains(words), "{file}: {}", p.error);
    }
    assert_eq!(list.unavailable.len(), 8, "{:#?}", list.unavailable);
    // A scene that does not build cannot start a session; the reason comes along.
    let slow = create(channel.clone(), "slow", None).await.unwrap_err();
    assert_eq!(slow.code(), Code::FailedPrecondition);
    assert!(
        slow.message().contains("substeps a tick"),
        "{}",
        slow.message()
    );
    create(channel, "good", None).await.unwrap();
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_session_with_long_ticks_still_closes_and_the_server_still_shuts_down() {
    // liver-5k (1408 vertices) asking for a residual it cannot reach, at the most CG
    // iterations its tick may do: each tick is as long as a scene may make it.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "liver-5k.msh", LIVER_5K);
    write(
        d,
        "long.toml",
        &scene(
            "long",
            "liver-5k.msh",
            "[mechanics]\ncg_tolerance = 1e-12\ncg_max_iterations = 71000\n",
        ),
    );
    let server = TestServer::start(ServeConfig {
        scene_dir: Some(d.to_path_buf()),
        ..ServeConfig::default()
    })
    .await;
    let channel = server.channel().await;
    let first = create(channel.clone(), "long", None).await.unwrap();
    let mut sessions = v1::sessions_client::SessionsClient::new(channel.clone());
    let close = sessions.close_session(v1::CloseSessionRequest {
        session_id: first.session_id.clone(),
        reason: String::new(),
    });
    let closed = tokio::time::timeout(WAIT, close)
        .await
        .expect("CloseSession answers")
        .unwrap();
    assert_eq!(
        closed.into_inner().session.unwrap().session_id,
        first.session_id
    );
    let listed = v1::sessions_client::SessionsClient::new(channel.clone())
        .list_sessions(v1::ListSessionsRequest {})
        .await
        .unwrap()
        .into_inner();
    assert!(listed.sessions.is_empty());
    // Another one left running when the server shuts down.
    create(channel, "long", None).await.unwrap();
    server.shutdown().await.unwrap();
}
