//! The `laparo` command line: its arguments, parsed and checked with clap.
//! `main.rs` runs the subcommands; keeping the definitions in the library lets them
//! be tested with [`Cli::try_parse_from`](clap::Parser::try_parse_from).

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, Parser, Subcommand};

use crate::connect::ConnectConfig;
use crate::haptics::force_loop::{DEFAULT_RATE_HZ, RATE_RANGE_HZ};
use crate::station::DEFAULT_POSE_RATE_HZ;

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
    Demo(DemoArgs),
    /// Join a session as a trainee station: drive instruments with simulated devices
    /// (a scripted press into the liver) through 1 kHz force loops, and report
    /// forces, rates and pose-to-state latency.
    Station(StationArgs),
    /// Watch a session: one status line per second and the events as they come.
    Observe(ObserveArgs),
    /// Load a session with N concurrent stations and report latency, frames and the
    /// session's tick times as a markdown table row.
    Load(LoadArgs),
    /// Summarise a recorded session: duration, ticks, per-instrument path length,
    /// time in contact, max and mean force, largest force jump, events; with
    /// --plot, draw the forces over time to a PNG. With `--server`, watch the
    /// server play one of its recordings back instead, as `observe` watches a
    /// session.
    Replay(ReplayArgs),
    /// The recordings on disk.
    #[command(subcommand)]
    Recordings(RecordingsCommand),
    /// Re-run a recording's physics from its recorded poses and report the largest
    /// deviation from the recorded surfaces and forces: zero with the same build and
    /// scene.
    Resim(ResimArgs),
}

/// `laparo resim`.
#[derive(Args, Debug, Clone)]
pub struct ResimArgs {
    /// A session recording (.mcap).
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    /// Folder the scene's mesh path resolves against [default: the one the server
    /// recorded].
    #[arg(long, value_name = "DIR")]
    pub scene_dir: Option<PathBuf>,
    /// Run the recorded hands on this scene instead (same mesh; another material or
    /// force model): the deviation then measures the change.
    #[arg(long, value_name = "FILE.toml")]
    pub scene: Option<PathBuf>,
}

/// `laparo replay`.
#[derive(Args, Debug, Clone)]
pub struct ReplayArgs {
    /// A session recording (.mcap); with `--server`, the name of one of the server's
    /// recordings (as `laparo recordings list --server` shows it).
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    /// Also plot |force| per instrument over simulated time, contact intervals
    /// shaded, to this PNG file.
    #[arg(long, value_name = "OUT.png", conflicts_with = "server")]
    pub plot: Option<PathBuf>,
    /// Size of the plot, pixels.
    #[arg(long, value_name = "WxH", value_parser = plot_size, default_value = "1200x600", requires = "plot")]
    pub plot_size: (u32, u32),
    #[command(flatten)]
    pub remote: RemoteArgs,
    /// Playback speed factor: 2 plays twice as fast (the server takes 0.01 to 100).
    #[arg(long, value_name = "S", requires = "server", value_parser = speed)]
    pub speed: Option<f64>,
    /// Where to start, s of simulated time from the start of the recording.
    #[arg(long, value_name = "T", requires = "server", value_parser = offset)]
    pub from: Option<f64>,
    /// Have the server re-run the recorded poses through the recorded scene and
    /// send that, instead of the recorded frames.
    #[arg(long, requires = "server")]
    pub resimulate: bool,
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
}

impl RemoteArgs {
    /// The connection settings, when a server is given.
    pub fn connect_config(&self) -> Option<ConnectConfig> {
        self.server.as_ref().map(|url| ConnectConfig {
            token: self.token.clone(),
            ca_file: self.ca.clone(),
            ..ConnectConfig::new(url.clone())
        })
    }
}

/// `laparo recordings …`.
#[derive(Subcommand, Debug, Clone)]
pub enum RecordingsCommand {
    /// List the recordings of a directory, or of a server with `--server`: session,
    /// scene, start, duration, size, and whether each is complete or still being
    /// recorded.
    List {
        /// The recordings directory.
        #[arg(
            long,
            value_name = "DIR",
            default_value = "recordings",
            conflicts_with = "server"
        )]
        dir: PathBuf,
        #[command(flatten)]
        remote: RemoteArgs,
    },
    /// Rewrite a truncated recording (a server killed mid-session) into a valid,
    /// indexed one, keeping every complete chunk.
    Recover {
        /// The truncated recording.
        #[arg(value_name = "FILE")]
        file: PathBuf,
        /// Where to write the recovered file [default: over FILE].
        #[arg(long, value_name = "OUT")]
        out: Option<PathBuf>,
    },
}

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
}

impl ServerArgs {
    /// The connection settings.
    pub fn connect_config(&self) -> ConnectConfig {
        ConnectConfig {
            token: self.token.clone(),
            ca_file: self.ca.clone(),
            ..ConnectConfig::new(self.server.clone())
        }
    }
}

/// `laparo station`.
#[derive(Args, Debug, Clone)]
pub struct StationArgs {
    #[command(flatten)]
    pub server: ServerArgs,
    /// Session to join.
    #[arg(long, value_name = "ID")]
    pub session: String,
    /// Instruments to claim, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "left",
        value_name = "NAMES"
    )]
    pub instruments: Vec<String>,
    /// Rate at which device poses are sent, Hz.
    #[arg(long, value_name = "HZ", default_value_t = DEFAULT_POSE_RATE_HZ, value_parser = positive_rate)]
    pub pose_rate: f64,
    /// Haptic rate of the force loops, Hz (300 to 4000).
    #[arg(long, value_name = "HZ", default_value_t = DEFAULT_RATE_HZ, value_parser = haptic_rate)]
    pub haptic_rate: f64,
    /// Surface frame rate to ask for, Hz (default: the mechanics rate).
    #[arg(long, value_name = "HZ", value_parser = positive_rate)]
    pub frame_rate: Option<f64>,
    /// How long to stay, s (default: until Ctrl-C or the session closes).
    #[arg(long, value_name = "T", value_parser = seconds)]
    pub seconds: Option<Duration>,
}

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

/// `laparo demo`.
#[derive(Args, Debug, Clone)]
pub struct DemoArgs {
    /// How long the demo runs, s (the gesture takes 10 s and repeats).
    #[arg(long, value_name = "T", value_parser = seconds, default_value = "10")]
    pub seconds: Duration,
    /// Where the session is recorded (MCAP) [default: ./recordings].
    #[arg(long, value_name = "DIR")]
    pub recordings: Option<std::path::PathBuf>,
}

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
    /// Pose rate of each posing station, Hz.
    #[arg(long, value_name = "HZ", value_parser = positive_rate)]
    pub pose_rate: f64,
    /// How long each station stays, s.
    #[arg(long, value_name = "T", value_parser = seconds)]
    pub seconds: Duration,
    /// Surface frame rate the stations ask for, Hz (default: the mechanics rate).
    #[arg(long, value_name = "HZ", value_parser = positive_rate)]
    pub frame_rate: Option<f64>,
    /// Scene of the session created (default: the server's default scene).
    #[arg(long, value_name = "NAME", conflicts_with = "session")]
    pub scene: Option<String>,
    /// Record the session created, or not (default: as its scene says).
    #[arg(long, value_name = "BOOL", conflicts_with = "session")]
    pub record: Option<bool>,
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
        Err(format!("{v} Hz: a rate must be finite and > 0"))
    }
}

/// A haptic rate in Hz, within the force loop's range.
pub fn haptic_rate(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if RATE_RANGE_HZ.contains(&v) {
        Ok(v)
    } else {
        Err(format!(
            "{v} Hz: the haptic rate must be between {} and {} Hz",
            RATE_RANGE_HZ.start(),
            RATE_RANGE_HZ.end()
        ))
    }
}

/// A replay speed factor: finite and > 0.
pub fn speed(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{v}: a speed factor must be finite and > 0"))
    }
}

/// A start offset in seconds: finite and ≥ 0.
pub fn offset(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(format!("{v} s: an offset must be finite and ≥ 0"))
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

/// A duration in seconds: finite and > 0.
pub fn seconds(s: &str) -> Result<Duration, String> {
    let v = number(s)?;
    if v.is_finite() && v > 0.0 && v < 1e9 {
        Ok(Duration::from_secs_f64(v))
    } else {
        Err(format!("{v} s: a duration must be > 0"))
    }
}

#[cfg(test)]
mod tests {
    use clap::error::ErrorKind;

    use super::*;

    fn parse(args: &[&str]) -> Result<Cli, clap::Error> {
        Cli::try_parse_from(std::iter::once("laparo").chain(args.iter().copied()))
    }

    #[test]
    fn station_defaults_and_options() {
        let cli = parse(&[
            "station",
            "--server",
            "http://127.0.0.1:50051",
            "--session",
            "s1",
        ])
        .unwrap();
        let Command::Station(a) = cli.command else {
            panic!("not station")
        };
        assert_eq!(a.instruments, vec!["left".to_owned()]);
        assert_eq!(a.pose_rate, DEFAULT_POSE_RATE_HZ);
        assert_eq!(a.haptic_rate, DEFAULT_RATE_HZ);
        assert_eq!(a.seconds, None);
        assert_eq!(a.server.connect_config().token, None);

        let cli = parse(&[
            "station",
            "--server",
            "https://sim.example:443",
            "--session",
            "s1",
            "--instruments",
            "left,right",
            "--pose-rate",
            "500",
            "--seconds",
            "2.5",
            "--token",
            "t0k",
            "--ca",
            "ca.pem",
            "--haptic-rate",
            "2000",
        ])
        .unwrap();
        let Command::Station(a) = cli.command else {
            panic!("not station")
        };
        assert_eq!(a.instruments, vec!["left".to_owned(), "right".to_owned()]);
        assert_eq!(a.pose_rate, 500.0);
        assert_eq!(a.haptic_rate, 2000.0);
        assert_eq!(a.seconds, Some(Duration::from_millis(2500)));
        let c = a.server.connect_config();
        assert_eq!(c.token.as_deref(), Some("t0k"));
        assert_eq!(c.ca_file, Some(PathBuf::from("ca.pem")));
    }

    #[test]
    fn observe_and_load_parse() {
        let cli = parse(&[
            "observe",
            "--server",
            "http://h:1",
            "--session",
            "s",
            "--rate",
            "10",
            "--seconds",
            "3",
        ])
        .unwrap();
        let Command::Observe(a) = cli.command else {
            panic!("not observe")
        };
        assert_eq!(
            (a.rate, a.seconds),
            (Some(10.0), Some(Duration::from_secs(3)))
        );

        let cli = parse(&[
            "load",
            "--server",
            "http://h:1",
            "--stations",
            "8",
            "--pose-rate",
            "250",
            "--seconds",
            "10",
        ])
        .unwrap();
        let Command::Load(a) = cli.command else {
            panic!("not load")
        };
        assert_eq!((a.stations, a.pose_rate, a.session), (8, 250.0, None));
    }

    #[test]
    fn replay_and_list_read_files_here_or_ask_a_server() {
        let Command::Replay(a) = parse(&["replay", "r.mcap"]).unwrap().command else {
            panic!("not replay")
        };
        assert!(a.remote.connect_config().is_none());
        let Command::Replay(a) = parse(&[
            "replay",
            "r.mcap",
            "--server",
            "http://h:1",
            "--speed",
            "4",
            "--from",
            "1.5",
            "--token",
            "t0k",
        ])
        .unwrap()
        .command
        else {
            panic!("not replay")
        };
        assert_eq!((a.speed, a.from), (Some(4.0), Some(1.5)));
        let c = a.remote.connect_config().unwrap();
        assert_eq!(
            (c.url.as_str(), c.token.as_deref()),
            ("http://h:1", Some("t0k"))
        );
        let Command::Recordings(RecordingsCommand::List { dir, remote }) =
            parse(&["recordings", "list"]).unwrap().command
        else {
            panic!("not recordings list")
        };
        assert_eq!((dir, remote.server), (PathBuf::from("recordings"), None));
        let Command::Recordings(RecordingsCommand::List { remote, .. }) =
            parse(&["recordings", "list", "--server", "http://h:1"])
                .unwrap()
                .command
        else {
            panic!("not recordings list")
        };
        assert_eq!(remote.server.as_deref(), Some("http://h:1"));
    }

    #[test]
    fn bad_values_are_usage_errors() {
        let base = ["station", "--server", "http://h:1", "--session", "s"];
        for bad in [
            &["--pose-rate", "0"][..],
            &["--pose-rate=-5"],
            &["--pose-rate", "fast"],
            &["--pose-rate", "inf"],
            &["--haptic-rate", "100"],
            &["--seconds", "0"],
        ] {
            let args: Vec<&str> = base.iter().chain(bad).copied().collect();
            let e = parse(&args).unwrap_err();
            assert_eq!(e.kind(), ErrorKind::ValueValidation, "{bad:?}");
            assert_eq!(e.exit_code(), 2);
        }
        let e = parse(&[
            "observe",
            "--server",
            "http://h:1",
            "--session",
            "s",
            "--rate",
            "0",
        ])
        .unwrap_err();
        assert_eq!(e.kind(), ErrorKind::ValueValidation);
        let e = parse(&[
            "load",
            "--server",
            "http://h:1",
            "--pose-rate",
            "250",
            "--seconds",
            "1",
        ])
        .unwrap_err();
        assert_eq!(e.kind(), ErrorKind::MissingRequiredArgument);
        let e = parse(&[
            "load",
            "--server",
            "http://h:1",
            "--stations",
            "0",
            "--pose-rate",
            "250",
            "--seconds",
            "1",
        ])
        .unwrap_err();
        assert_eq!(e.kind(), ErrorKind::ValueValidation);
        for bad in [
            &["replay", "f.mcap", "--speed", "2"][..],
            &["replay", "f.mcap", "--server", "http://h:1", "--speed", "0"],
            &[
                "replay",
                "f.mcap",
                "--server",
                "http://h:1",
                "--speed",
                "nan",
            ],
            &["replay", "f.mcap", "--server", "http://h:1", "--from=-1"],
            &["recordings", "list", "--token", "t"],
            &["recordings", "list", "--dir", "d", "--server", "http://h:1"],
        ] {
            assert!(parse(bad).is_err(), "{bad:?}");
        }
        let Command::Demo(demo) = parse(&["demo"]).unwrap().command else {
            panic!("demo parses");
        };
        assert_eq!(demo.seconds, Duration::from_secs(10));
        assert!(parse(&["demo", "--seconds", "-1"]).is_err());
    }

    #[test]
    fn replay_plots_on_request() {
        let Command::Replay(a) = parse(&["replay", "r.mcap"]).unwrap().command else {
            panic!("not replay")
        };
        assert_eq!((a.plot, a.plot_size), (None, (1200, 600)));
        let Command::Replay(a) = parse(&[
            "replay",
            "r.mcap",
            "--plot",
            "f.png",
            "--plot-size",
            "800x450",
        ])
        .unwrap()
        .command
        else {
            panic!("not replay")
        };
        assert_eq!(a.plot, Some(PathBuf::from("f.png")));
        assert_eq!(a.plot_size, (800, 450));
        for bad in [
            "800", "800x", "x450", "0x450", "100x100", "9000x450", "wide",
        ] {
            let e =
                parse(&["replay", "r.mcap", "--plot", "f.png", "--plot-size", bad]).unwrap_err();
            assert_eq!(e.kind(), ErrorKind::ValueValidation, "{bad}");
        }
        let e = parse(&["replay", "r.mcap", "--plot-size", "800x450"]).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::MissingRequiredArgument);
    }
}
