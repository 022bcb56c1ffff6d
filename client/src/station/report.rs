//! What a station reports: live progress while it runs, a summary at the end.

use std::collections::BTreeMap;

use crate::haptics::LoopStats;
use crate::latency::LatencySummary;

/// Live figures of a running station.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StationProgress {
    /// Wall time since the station joined, s.
    pub elapsed_s: f64,
    /// Newest mechanics tick received.
    pub tick: u64,
    /// Simulated time of that tick, s.
    pub sim_time_s: f64,
    /// Surface frames received.
    pub frames: u64,
    /// Instrument states received (all instruments).
    pub states: u64,
    /// Events received.
    pub events: u64,
    /// Station errors received.
    pub errors: u64,
    /// Device poses sent.
    pub poses_sent: u64,
    /// Server force |F| on each granted instrument at the newest state, N, in the
    /// order of [`StationSummary::instruments`].
    pub forces_n: Vec<(String, f64)>,
    /// Achieved haptic rate of each force loop, Hz, same order.
    pub haptic_rates_hz: Vec<f64>,
    /// Median pose-to-state latency so far, ms.
    pub latency_p50_ms: f64,
    /// 99th percentile pose-to-state latency so far, ms.
    pub latency_p99_ms: f64,
    /// Local models missing or invalid, skipped.
    pub models_invalid: u64,
}

/// How a station run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StationEnd {
    /// The configured duration elapsed.
    Duration,
    /// The stop signal completed.
    Stopped,
    /// The server ended the stream normally.
    ServerClosed,
}

impl std::fmt::Display for StationEnd {
    /// How the summary says it: "station 1 in session s1: its time was up after 2.0 s".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            StationEnd::Duration => "its time was up",
            StationEnd::Stopped => "stopped",
            StationEnd::ServerClosed => "the server ended the stream",
        })
    }
}

/// The figures of one instrument at the end.
#[derive(Clone, Debug, PartialEq)]
pub struct InstrumentSummary {
    /// Instrument name.
    pub name: String,
    /// Local models written to the force loop.
    pub models_applied: u64,
    /// Local models missing or invalid, skipped.
    pub models_invalid: u64,
    /// Largest server force |F| received, N.
    pub max_force_n: f64,
    /// The force loop's final figures.
    pub loop_stats: LoopStats,
}

/// What a station run saw.
#[derive(Clone, Debug, PartialEq)]
pub struct StationSummary {
    /// Id the server gave the station.
    pub station_id: u64,
    /// Session joined.
    pub session_id: String,
    /// Instruments granted: all those claimed (a join is granted whole, or refused
    /// with a status and the station does not run).
    pub instruments: Vec<String>,
    /// How the run ended.
    pub end: StationEnd,
    /// Wall time from joining to the end, s.
    pub elapsed_s: f64,
    /// Distinct mechanics ticks seen (in frames or states).
    pub ticks: u64,
    /// Newest mechanics tick seen.
    pub last_tick: u64,
    /// Surface frames received.
    pub frames: u64,
    /// Instrument states received (all instruments).
    pub states: u64,
    /// Events received.
    pub events: u64,
    /// Station errors received, by code name.
    pub errors: BTreeMap<String, u64>,
    /// Device poses sent.
    pub poses_sent: u64,
    /// Poses per second per instrument they were sent at: the configured rate, or
    /// the server's limit if lower ([`sending_rate`](super::sending_rate)).
    pub pose_rate_hz: f64,
    /// Device poses dropped because the outgoing queue was full.
    pub poses_dropped: u64,
    /// Largest server force |F| on any granted instrument, N.
    pub max_force_n: f64,
    /// Pose-to-state latency.
    pub latency: LatencySummary,
    /// Per granted instrument.
    pub per_instrument: Vec<InstrumentSummary>,
}
