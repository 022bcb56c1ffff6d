//! `laparo demo`: a server in this process, one station pressing the liver with the
//! [`tip_and_shaft()`] gesture, progress and a summary.

use std::path::PathBuf;
use std::time::Duration;

use clap::Args;
use tokio::sync::watch;

use super::args::seconds;
use super::out::say;
use super::station::{print_summary, run_showing_progress};
use super::{BoxError, ctrl_c};
use crate::connect::{ConnectConfig, connect};
use crate::gestures::tip_and_shaft;
use crate::observe::event_line;
use crate::proto::v1::CreateSessionRequest;
use crate::station::{StationConfig, StationProgress};

/// `laparo demo`.
#[derive(Args, Debug, Clone)]
pub struct DemoArgs {
    /// How long the demo runs, s (the gesture takes 10 s and repeats).
    #[arg(long, value_name = "T", value_parser = seconds, default_value = "10")]
    pub seconds: Duration,
    /// Where the session is recorded (MCAP) [default: ./recordings].
    #[arg(long, value_name = "DIR")]
    pub recordings: Option<PathBuf>,
}

/// Serves on a free loopback port, runs one station on a recorded session of the
/// default scene, stops the server and prints the summary.
pub async fn run(args: DemoArgs) -> Result<(), BoxError> {
    use laparo_server::service::{ServeConfig, serve};
    // The session is recorded in this process: a reader that goes away early must
    // not cut the recording short.
    super::out::finish_when_closed();
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
    let url = format!("http://{}", listener.local_addr()?);
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let recordings = args
        .recordings
        .clone()
        .unwrap_or_else(|| PathBuf::from("recordings"));
    // A folder that cannot be one is said now, as the server would refuse the
    // recorded session: made when missing, and a directory.
    if let Err(what) = laparo_server::recording::space::usable_dir(&recordings) {
        return Err(format!(
            "--recordings {}: {what}, so the session cannot be recorded in it",
            recordings.display()
        )
        .into());
    }
    let config = ServeConfig {
        recordings: Some(recordings.clone()),
        ..ServeConfig::default()
    };
    let server = tokio::spawn(serve(config, listener, async {
        let _ = stopped.await;
    }));
    let connection = connect(&ConnectConfig::new(url.clone())).await?;
    let session = connection
        .sessions()
        .create_session(CreateSessionRequest {
            scene: "default".into(),
            idle_timeout_s: None,
            record: Some(true),
        })
        .await?
        .into_inner();
    say!(
        "demo: laparo-server in this process at {url}; session {} of the default scene (SOFA's liver at 0.19 m, E = 4.5 kPa)",
        session.session_id
    );
    say!("demo: console {url}/ (open it in a browser to watch the session live)");
    say!(
        "demo: station with the left instrument and a 1 kHz force loop: tip press (0–4 s), then the shaft sideways (4–10 s)"
    );
    let (progress_tx, progress_rx) = watch::channel(StationProgress::default());
    let config = StationConfig {
        duration: Some(args.seconds),
        progress: Some(progress_tx),
        on_event: Some(Box::new(|e| say!("event  {}", event_line(e)))),
        stop: Some(ctrl_c()),
        gesture: Some(Box::new(tip_and_shaft)),
        client_name: "laparo demo".into(),
        ..StationConfig::new(url, session.session_id.clone(), vec!["left".into()])
    };
    let summary = run_showing_progress(config, progress_rx).await;
    let _ = stop.send(());
    let served = server.await;
    let summary = summary?;
    print_summary(&summary);
    // The session names its file when it starts; whether the recorder could write it
    // is known once the session has ended.
    let written = session
        .recording_file
        .as_ref()
        .map(|file| recordings.join(file))
        .filter(|path| path.is_file());
    match &written {
        Some(path) => say!("  recording            {}", path.display()),
        None => say!(
            "  recording            none: {} could not be written (see the events above)",
            recordings.display()
        ),
    }
    served??;
    if written.is_none() {
        return Err(format!("the session was not recorded in {}", recordings.display()).into());
    }
    Ok(())
}
