//! `laparo observe`: a live session, one status line a second and its events as
//! they come. The printing is shared with `laparo replay --server`, which watches
//! the same stream.

use std::time::Duration;

use clap::Args;

use super::args::{ServerArgs, positive_rate, seconds};
use super::out::say;
use super::{BoxError, ctrl_c};
use crate::observe::{ObserveConfig, ObserveReport, ObserveSummary, event_line, run_observe};

/// `laparo observe`.
#[derive(Args, Debug, Clone)]
pub struct ObserveArgs {
    #[command(flatten)]
    pub server: ServerArgs,
    /// Session to watch.
    #[arg(long, value_name = "ID")]
    pub session: String,
    /// Frame rate to ask for, Hz (default: the mechanics rate).
    #[arg(long, value_name = "HZ", value_parser = positive_rate)]
    pub rate: Option<f64>,
    /// How long to watch, s (default: until Ctrl-C or the session closes).
    #[arg(long, value_name = "T", value_parser = seconds)]
    pub seconds: Option<Duration>,
}

/// Watches the session until it closes, the time is up or Ctrl-C.
pub async fn run(args: ObserveArgs) -> Result<(), BoxError> {
    let config = ObserveConfig {
        connect: args.server.connect_config(),
        frame_rate_hz: args.rate,
        duration: args.seconds,
        stop: Some(ctrl_c()),
        ..ObserveConfig::new(args.server.server.clone(), args.session.clone())
    };
    let summary = run_observe(config, print_report(format!("observing {}", args.session))).await?;
    print_watch_summary(&summary, "the session closed");
    Ok(())
}

/// Prints what an observe or replay stream reports; `what` says what is watched.
pub(crate) fn print_report(what: String) -> impl FnMut(ObserveReport<'_>) {
    move |report| match report {
        ObserveReport::Scene(scene) => {
            let s = scene.summary.clone().unwrap_or_default();
            let names: Vec<&str> = scene.instruments.iter().map(|i| i.name.as_str()).collect();
            say!(
                "{what}: scene {:?}, {} tetrahedra, mechanics {} Hz, instruments {:?}",
                s.name,
                s.tetrahedron_count,
                s.mechanics_rate_hz,
                names
            );
        }
        ObserveReport::Status(line) => say!("{line}"),
        ObserveReport::Event(event) => say!("event  {}", event_line(event)),
    }
}

/// The last lines of an observe or replay run; `ended` says why the server ended it.
pub(crate) fn print_watch_summary(summary: &ObserveSummary, ended: &str) {
    say!();
    say!(
        "watched {:.1} s: {} ticks, {} frames, {} states, {} events, max |force| {:.3} N{}",
        summary.elapsed_s,
        summary.ticks,
        summary.frames,
        summary.states,
        summary.events,
        summary.max_force_n,
        if summary.server_closed {
            format!("; {}", summary.end_note.as_deref().unwrap_or(ended))
        } else {
            String::new()
        }
    );
}
