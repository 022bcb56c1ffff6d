//! Arguments and value checks shared by the subcommands: how to reach a server, and
//! the rates, durations, offsets and sizes a user types, each checked into its range
//! (a value out of range is a usage error, status 2).

use std::ops::RangeInclusive;
use std::path::PathBuf;
use std::time::Duration;

use clap::Args;
use laparo_proto::text::Number;

use crate::connect::{ConnectConfig, DEFAULT_CONNECT_TIMEOUT};
use crate::haptics::force_loop::RATE_RANGE_HZ;
use crate::station::POSE_RATE_RANGE_HZ;

/// How to reach the server.
#[derive(Args, Debug, Clone)]
pub struct ServerArgs {
    /// Server URL, http://host:port or https://host:port.
    #[arg(long, value_name = "URL")]
    pub server: String,
    /// Bearer token sent with every call.
    #[arg(long, value_name = "TOKEN")]
    pub token: Option<String>,
    /// CA certificate (PEM) to trust for an https server.
    #[arg(long, value_name = "FILE")]
    pub ca: Option<PathBuf>,
    /// How long to wait for the server's first answer when connecting, s
    /// [default: 5].
    #[arg(long, value_name = "T", value_parser = seconds)]
    pub connect_timeout: Option<Duration>,
}

impl ServerArgs {
    /// The connection settings.
    pub fn connect_config(&self) -> ConnectConfig {
        ConnectConfig {
            token: self.token.clone(),
            ca_file: self.ca.clone(),
            connect_timeout: self.connect_timeout.unwrap_or(DEFAULT_CONNECT_TIMEOUT),
            ..ConnectConfig::new(self.server.clone())
        }
    }
}

/// A server to ask instead of reading files here.
#[derive(Args, Debug, Clone, Default)]
pub struct RemoteArgs {
    /// Server URL, http://host:port or https://host:port.
    #[arg(long, value_name = "URL")]
    pub server: Option<String>,
    /// Bearer token sent with every call.
    #[arg(long, value_name = "TOKEN", requires = "server")]
    pub token: Option<String>,
    /// CA certificate (PEM) to trust for an https server.
    #[arg(long, value_name = "FILE", requires = "server")]
    pub ca: Option<PathBuf>,
    /// How long to wait for the server's first answer when connecting, s
    /// [default: 5].
    #[arg(long, value_name = "T", value_parser = seconds, requires = "server")]
    pub connect_timeout: Option<Duration>,
}

impl RemoteArgs {
    /// The connection settings, when a server is given.
    pub fn connect_config(&self) -> Option<ConnectConfig> {
        self.server.as_ref().map(|url| ConnectConfig {
            token: self.token.clone(),
            ca_file: self.ca.clone(),
            connect_timeout: self.connect_timeout.unwrap_or(DEFAULT_CONNECT_TIMEOUT),
            ..ConnectConfig::new(url.clone())
        })
    }
}

fn number(s: &str) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .map_err(|_| format!("{s:?} is not a number"))
}

/// A rate in Hz: finite and > 0.
pub fn positive_rate(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{} Hz: a rate must be finite and > 0", Number(v)))
    }
}

/// A rate in Hz within `range`; `what` names it in the error ("the haptic rate").
fn rate_within(s: &str, range: &RangeInclusive<f64>, what: &str) -> Result<f64, String> {
    let v = number(s)?;
    if range.contains(&v) {
        Ok(v)
    } else {
        Err(format!(
            "{} Hz: {what} must be between {} and {} Hz",
            Number(v),
            range.start(),
            range.end()
        ))
    }
}

/// A station's pose rate in Hz, within [`POSE_RATE_RANGE_HZ`].
pub fn pose_rate(s: &str) -> Result<f64, String> {
    rate_within(s, &POSE_RATE_RANGE_HZ, "a pose rate")
}

/// A haptic rate in Hz, within the force loop's range.
pub fn haptic_rate(s: &str) -> Result<f64, String> {
    rate_within(s, &RATE_RANGE_HZ, "the haptic rate")
}

/// A replay speed factor: finite and > 0.
pub fn speed(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!(
            "{}: a speed factor must be finite and > 0",
            Number(v)
        ))
    }
}

/// A start offset in seconds: finite and ≥ 0.
pub fn offset(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(format!("{} s: an offset must be finite and ≥ 0", Number(v)))
    }
}

/// A picture's size, `WIDTHxHEIGHT` pixels, from 200×150 to 8000×8000.
pub fn plot_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("`{s}`: a plot size is WIDTHxHEIGHT in pixels, for example 1200x600");
    let (w, h) = s.split_once(['x', 'X', '×']).ok_or_else(bad)?;
    let (w, h): (u32, u32) = (
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    );
    if (200..=8000).contains(&w) && (150..=8000).contains(&h) {
        Ok((w, h))
    } else {
        Err(format!("{w}x{h}: a plot is 200x150 to 8000x8000 pixels"))
    }
}

/// A duration in seconds: > 0 and below 10⁹ s (31 years; far beyond any session, and
/// well within what `Duration` and `Instant` arithmetic hold).
pub fn seconds(s: &str) -> Result<Duration, String> {
    let v = number(s)?;
    if !(v.is_finite() && v > 0.0 && v < 1e9) {
        return Err(format!(
            "{} s: a duration must be > 0 and below 1e9 s",
            Number(v)
        ));
    }
    // A duration is held in whole nanoseconds: a smaller one would be 0, and a
    // timeout of 0 said as "within 0 s".
    match Duration::from_secs_f64(v) {
        d if d.is_zero() => Err(format!(
            "{} s: a duration must be at least 1 ns (1e-9 s)",
            Number(v)
        )),
        d => Ok(d),
    }
}

/// An idle timeout in seconds, within the range the server accepts: 0 (never) to
/// 604800 (7 days).
pub fn idle_seconds(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    laparo_server::session::idle_timeout(v)?;
    Ok(v)
}
