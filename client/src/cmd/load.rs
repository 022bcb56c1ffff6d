//! `laparo load`: N concurrent stations on one session; running totals once a
//! second, then the result as a markdown table row.

use std::time::Duration;

use clap::Args;

use super::BoxError;
use super::args::{ServerArgs, pose_rate, positive_rate, seconds};
use super::out::say;
use crate::load::{LoadConfig, LoadSummary, run_load};

/// `laparo load`.
#[derive(Args, Debug, Clone)]
pub struct LoadArgs {
    #[command(flatten)]
    pub server: ServerArgs,
    /// Session to load (default: create one from the default scene, closed at the
    /// end).
    #[arg(long, value_name = "ID")]
    pub session: Option<String>,
    /// Concurrent stations; the first ones hold one instrument each and send poses,
    /// the others only receive.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub stations: u32,
    /// Pose rate of each posing station, Hz (0.1 to 100,000).
    #[arg(long, value_name = "HZ", value_parser = pose_rate)]
    pub pose_rate: f64,
    /// How long each station stays, s.
    #[arg(long, value_name = "T", value_parser = seconds)]
    pub seconds: Duration,
    /// Surface frame rate the stations ask for, Hz (default: the mechanics rate).
    /// The instruments' states and local models come every tick whatever it is.
    #[arg(long, value_name = "HZ", value_parser = positive_rate)]
    pub frame_rate: Option<f64>,
    /// Scene of the session created (default: the server's default scene).
    #[arg(long, value_name = "NAME", conflicts_with = "session")]
    pub scene: Option<String>,
    /// Record the session created, or not (default: as its scene says).
    #[arg(long, value_name = "BOOL", conflicts_with = "session")]
    pub record: Option<bool>,
}

/// Runs the load test; fails (status 1) when a station failed.
pub async fn run(args: LoadArgs) -> Result<(), BoxError> {
    let config = LoadConfig {
        connect: args.server.connect_config(),
        session: args.session.clone(),
        stations: args.stations as usize,
        pose_rate_hz: args.pose_rate,
        duration: args.seconds,
        surface_frame_rate_hz: args.frame_rate,
        scene: args.scene.clone(),
        record: args.record,
    };
    say!(
        "load: {} station{} for {:.1} s at {}; the first ones (one per free instrument) send poses at {} Hz, the others only receive",
        args.stations,
        if args.stations == 1 { "" } else { "s" },
        args.seconds.as_secs_f64(),
        args.server.server,
        args.pose_rate
    );
    let summary = run_load(config, |p| {
        say!(
            "  {} joined  frames {:>8}  states {:>8}  poses {:>8}",
            p.joined,
            p.frames,
            p.states,
            p.poses_sent
        );
    })
    .await?;
    print_summary(&summary, args.pose_rate);
    if !summary.failures.is_empty() {
        return Err(format!("{} station(s) failed", summary.failures.len()).into());
    }
    Ok(())
}

/// The result of a load run, ending with its markdown table row.
fn print_summary(summary: &LoadSummary, asked_pose_rate_hz: f64) {
    say!();
    if summary.posing_stations > 0 && summary.pose_rate_hz < asked_pose_rate_hz {
        say!(
            "the server admits {} poses a second per instrument: the stations sent at that rate, not {asked_pose_rate_hz}",
            summary.pose_rate_hz
        );
    }
    say!(
        "session {}{}: {} of {} stations sent poses; pose-to-state {}",
        summary.session_id,
        if summary.created_session {
            " (created for this run, closed)"
        } else {
            ""
        },
        summary.posing_stations,
        summary.stations,
        summary.latency
    );
    if summary.poses_dropped > 0 {
        say!("poses dropped (queue full): {}", summary.poses_dropped);
    }
    for (code, n) in &summary.errors {
        say!("station errors {code}: {n}");
    }
    for failure in summary.failures_by_reason() {
        say!("failed: {failure}");
    }
    if let Some(why) = &summary.session_gone {
        say!("the session's tick and recorder figures are missing: {why}");
    }
    say!();
    for line in LoadSummary::markdown_header() {
        say!("{line}");
    }
    say!("{}", summary.markdown_row());
}
