//! The `laparo` command line, one module per thing a user types: its arguments
//! (clap), its runner and its printing. `main.rs` parses [`Cli`] and hands the
//! [`Command`] to the runner of its module.
//!
//! - [`demo`]: a server in this process and one station pressing the liver.
//! - [`station`]: a trainee station with force loops on a live session.
//! - [`observe`]: a live session, one status line a second and its events.
//! - [`load`]: N concurrent stations on one session, as a markdown table row.
//! - [`replay`]: a recording's summary and plot, or a server playing it back.
//! - [`recordings`]: the recordings of a directory or a server; recovery.
//! - [`sessions`]: a server's sessions: create, list, describe, close; evict a
//!   station.
//! - [`resim`]: a recording's physics re-run from its recorded poses.
//!
//! Shared: [`args`] (how to reach a server, value checks) and [`out`] (standard
//! output that ends quietly when its reader closes the pipe).
//!
//! Keeping the definitions in the library lets them be tested with
//! [`Cli::try_parse_from`](clap::Parser::try_parse_from).

use std::future::Future;
use std::pin::Pin;

use clap::{Parser, Subcommand};

pub mod args;
pub mod demo;
pub mod load;
pub mod observe;
pub mod out;
pub mod recordings;
pub mod replay;
pub mod resim;
pub mod sessions;
pub mod station;

#[cfg(test)]
mod tests;

/// What a subcommand's runner fails with: printed as `laparo: {error}`, status 1.
pub type BoxError = Box<dyn std::error::Error>;

/// laparo client: trainee stations with force loops, live observation, load tests.
#[derive(Parser, Debug)]
#[command(name = "laparo", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// The main job as a newcomer sees it: start a server in this process on a free
    /// loopback port, join the default scene as a station with a 1 kHz force loop,
    /// press the liver with the tip and then sideways with the shaft, show live
    /// progress, and print a summary.
    Demo(demo::DemoArgs),
    /// Join a session as a trainee station: drive instruments with simulated devices
    /// (a scripted press into the liver) through 1 kHz force loops, and report
    /// forces, rates and pose-to-state latency.
    Station(station::StationArgs),
    /// Watch a session: one status line per second and the events as they come.
    Observe(observe::ObserveArgs),
    /// Load a session with N concurrent stations and report latency, frames and the
    /// session's tick times as a markdown table row.
    Load(load::LoadArgs),
    /// Summarise a recorded session: duration, ticks, per-instrument path length,
    /// time in contact, max and mean force, largest force jump, events; with
    /// --plot, draw the forces over time to a PNG. With `--server`, watch the
    /// server play one of its recordings back instead, as `observe` watches a
    /// session.
    Replay(replay::ReplayArgs),
    /// The recordings on disk.
    #[command(subcommand)]
    Recordings(recordings::RecordingsCommand),
    /// A server's sessions: create one (its id is what `station` and `observe`
    /// take), list them, describe one, close one, evict a station.
    #[command(subcommand)]
    Sessions(sessions::SessionsCommand),
    /// Re-run a recording's physics from its recorded poses and report the largest
    /// deviation from the recorded surfaces and forces: zero with the same build and
    /// scene.
    Resim(resim::ResimArgs),
}

/// Completes on Ctrl-C (never if the signal cannot be watched).
pub fn ctrl_c() -> Pin<Box<dyn Future<Output = ()> + Send>> {
    Box::pin(async {
        if tokio::signal::ctrl_c().await.is_err() {
            std::future::pending::<()>().await;
        }
    })
}
