//! `laparo station`: a trainee station on a live session, with a progress line a
//! second and a summary at the end.

use std::time::Duration;

use clap::Args;
use tokio::sync::watch;

use super::args::{ServerArgs, haptic_rate, pose_rate, positive_rate, seconds};
use super::out::say;
use super::sessions::list_or;
use super::{BoxError, ctrl_c};
use crate::haptics::force_loop::DEFAULT_RATE_HZ;
use crate::observe::event_line;
use crate::station::{
    DEFAULT_POSE_RATE_HZ, StationConfig, StationError, StationProgress, StationSummary, run_station,
};
use laparo_server::service::limits::MAX_NAME_BYTES;

/// `laparo station`.
#[derive(Args, Debug, Clone)]
pub struct StationArgs {
    #[command(flatten)]
    pub server: ServerArgs,
    /// Session to join.
    #[arg(long, value_name = "ID")]
    pub session: String,
    /// Instruments to claim, comma-separated; `""` claims none and only watches
    /// (an instructor's token).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "left",
        value_name = "NAMES"
    )]
    pub instruments: Vec<String>,
    /// Rate at which device poses are sent, Hz.
    #[arg(long, value_name = "HZ", default_value_t = DEFAULT_POSE_RATE_HZ, value_parser = pose_rate)]
    pub pose_rate: f64,
    /// Haptic rate of the force loops, Hz (300 to 4000).
    #[arg(long, value_name = "HZ", default_value_t = DEFAULT_RATE_HZ, value_parser = haptic_rate)]
    pub haptic_rate: f64,
    /// Surface frame rate to ask for, Hz (default: the mechanics rate). The
    /// instruments' states and local models come every tick whatever it is.
    #[arg(long, value_name = "HZ", value_parser = positive_rate)]
    pub frame_rate: Option<f64>,
    /// How long to stay, s (default: until Ctrl-C or the session closes).
    #[arg(long, value_name = "T", value_parser = seconds)]
    pub seconds: Option<Duration>,
}

/// Joins the session as the arguments say, prints progress and the summary.
pub async fn run(args: StationArgs) -> Result<(), BoxError> {
    let instruments = args.claimed();
    let (progress_tx, progress_rx) = watch::channel(StationProgress::default());
    let config = StationConfig {
        connect: args.server.connect_config(),
        pose_rate_hz: args.pose_rate,
        haptic_rate_hz: args.haptic_rate,
        surface_frame_rate_hz: args.frame_rate,
        duration: args.seconds,
        progress: Some(progress_tx),
        on_event: Some(Box::new(|e| say!("event  {}", event_line(e)))),
        stop: Some(ctrl_c()),
        client_name: station_name(&instruments),
        ..StationConfig::new(
            args.server.server.clone(),
            args.session.clone(),
            instruments.clone(),
        )
    };
    say!(
        "station: joining session {} at {} with {}, poses at {} Hz, force loops at {} Hz",
        args.session,
        args.server.server,
        list_or(&instruments, "no instrument (watching)"),
        args.pose_rate,
        args.haptic_rate
    );
    let summary = run_showing_progress(config, progress_rx).await?;
    print_summary(&summary);
    Ok(())
}

impl StationArgs {
    /// The instruments to claim: `--instruments ""` (an empty name, which no scene
    /// has) claims none, so that the station watches.
    pub fn claimed(&self) -> Vec<String> {
        self.instruments
            .iter()
            .filter(|name| !name.is_empty())
            .cloned()
            .collect()
    }
}

/// The name the station joins by: `laparo station (left,right)`, within the server's
/// [`MAX_NAME_BYTES`]: instrument names may each take that much, so a list too long
/// is cut at a character boundary and ends `…)`.
pub fn station_name(instruments: &[String]) -> String {
    let full = format!("laparo station ({})", instruments.join(","));
    if full.len() <= MAX_NAME_BYTES {
        return full;
    }
    let tail = "…)";
    let mut cut = MAX_NAME_BYTES - tail.len();
    while !full.is_char_boundary(cut) {
        cut -= 1;
    }
    format!("{}{tail}", &full[..cut])
}

/// Runs the station, printing its progress once a second until it ends.
pub(crate) async fn run_showing_progress(
    config: StationConfig,
    mut progress: watch::Receiver<StationProgress>,
) -> Result<StationSummary, StationError> {
    let run = run_station(config);
    tokio::pin!(run);
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    tick.tick().await;
    loop {
        tokio::select! {
            result = &mut run => return result,
            _ = tick.tick() => print_progress(&progress.borrow_and_update().clone()),
        }
    }
}

/// One progress line.
pub(crate) fn print_progress(p: &StationProgress) {
    let forces: Vec<String> = p
        .forces_n
        .iter()
        .zip(&p.haptic_rates_hz)
        .map(|((name, f), hz)| format!("{name} {f:.2} N @ {hz:.0} Hz"))
        .collect();
    say!(
        "{:>6.1} s  tick {:>7}  t {:>8.3} s  frames {:>6}  poses {:>7}  latency p50 {:.2} ms p99 {:.2} ms  {}{}",
        p.elapsed_s,
        p.tick,
        p.sim_time_s,
        p.frames,
        p.poses_sent,
        p.latency_p50_ms,
        p.latency_p99_ms,
        forces.join("  "),
        if p.errors > 0 || p.models_invalid > 0 {
            format!("  errors {} invalid models {}", p.errors, p.models_invalid)
        } else {
            String::new()
        }
    );
}

/// The summary of a station run.
pub(crate) fn print_summary(s: &StationSummary) {
    say!();
    say!(
        "station {} in session {}: {} after {:.1} s",
        s.station_id,
        s.session_id,
        s.end,
        s.elapsed_s
    );
    say!(
        "  instruments granted  {}",
        list_or(&s.instruments, "none (watching)")
    );
    say!("  ticks seen           {} (last {})", s.ticks, s.last_tick);
    say!("  surface frames       {}", s.frames);
    say!("  instrument states    {}", s.states);
    say!("  events               {}", s.events);
    say!(
        "  poses sent           {} at {} Hz ({} dropped, queue full)",
        s.poses_sent,
        s.pose_rate_hz,
        s.poses_dropped
    );
    if s.errors.is_empty() {
        say!("  station errors       none");
    } else {
        for (code, n) in &s.errors {
            say!("  station errors       {code}: {n}");
        }
    }
    say!("  max |force|          {:.3} N", s.max_force_n);
    say!("  pose-to-state        {}", s.latency);
    for i in &s.per_instrument {
        let l = &i.loop_stats;
        say!(
            "  {}: models {} applied, {} invalid; max |F| {:.3} N; force loop {} ticks at {:.1} Hz, \
             jitter p50 {:.1} µs p99 {:.1} µs max {:.1} µs, {} missed deadlines, {} clamped, {} damped, max model age {:.1} ms",
            i.name,
            i.models_applied,
            i.models_invalid,
            i.max_force_n,
            l.ticks,
            l.rate_hz,
            l.jitter.p50 * 1e6,
            l.jitter.p99 * 1e6,
            l.jitter.max * 1e6,
            l.missed_deadlines,
            l.clamped_ticks,
            l.damped_ticks,
            l.max_model_age_s * 1e3,
        );
    }
}
