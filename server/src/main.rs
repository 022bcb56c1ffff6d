//! `laparo-server`: the laparo training server.
//!
//! `laparo-server` (no subcommand) serves the gRPC contract; `laparo-server run` steps
//! a scene headless (no network) and can export the result for ParaView.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::Ordering;
use std::time::Instant;

use clap::{Args, Parser, Subcommand};
use laparo_proto::text::{Number, printable};
use laparo_server::engine::integrate::IntegratorKind;
use laparo_server::engine::scene::{Scene, same_file};
use laparo_server::engine::simulation::{Simulation, mesh_path};
use laparo_server::export::pvd::{self, PvdSeries};
use laparo_server::export::vtu::write_vtu;
use laparo_server::headless::trajectory::Trajectory;
use laparo_server::headless::{self, MAX_RUN_SECONDS, out};
use laparo_server::say;

#[derive(Parser, Debug)]
#[command(
    name = "laparo-server",
    version,
    about = "laparo training server: a deformable liver for laparoscopic training"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    serve: ServeArgs,
}

/// Serving (the default, without a subcommand).
#[derive(Args, Debug)]
struct ServeArgs {
    /// Address to listen on: IP:PORT, or HOST:PORT resolved at startup.
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:50051",
          value_parser = laparo_server::service::listen::listen_address)]
    listen: std::net::SocketAddr,
    /// Directory of scene files (.toml) offered besides the embedded default.
    #[arg(long, value_name = "DIR")]
    scene_dir: Option<PathBuf>,
    /// Bearer tokens and their roles (TOML, see the README); without it every caller
    /// is an instructor.
    #[arg(long, value_name = "FILE.toml")]
    tokens: Option<PathBuf>,
    /// TLS certificate (PEM).
    #[arg(long, value_name = "CERT.pem", requires = "tls_key")]
    tls_cert: Option<PathBuf>,
    /// TLS private key (PEM).
    #[arg(long, value_name = "KEY.pem", requires = "tls_cert")]
    tls_key: Option<PathBuf>,
    /// Close a session after this many seconds with nobody connected (0: never; at
    /// most 604800, 7 days).
    #[arg(long, default_value_t = 300.0, value_parser = idle_seconds)]
    idle_timeout: f64,
    /// Poses per second per instrument a station may send.
    #[arg(long, default_value_t = 2000.0, value_parser = positive_rate)]
    max_pose_rate: f64,
    /// Seconds a station may send nothing (no pose, no heartbeat), or take none of
    /// the server's messages, before it loses its instruments; an observer or a
    /// replay that takes none of its messages that long is ended (0.5 to 3600).
    #[arg(long, value_name = "S", default_value_t = 5.0, value_parser = station_timeout)]
    station_timeout: f64,
    /// Listen on a non-loopback address without TLS and tokens.
    #[arg(long)]
    insecure: bool,
    /// Directory sessions are recorded in (one MCAP file each).
    #[arg(long, value_name = "DIR", default_value = "recordings")]
    recordings: PathBuf,
    /// Record no session.
    #[arg(long, conflicts_with = "recordings")]
    no_recording: bool,
    /// Most sessions open at once [default: max(1, min(16 × cores, memory / 64 MiB))].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100_000))]
    max_sessions: Option<u32>,
    /// Most connections open at once; more are closed as they come [default:
    /// max(16, min(8 × sessions + 64, fd limit − 128 − 2 × sessions))].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    max_connections: Option<u32>,
    /// Most connections open at once from one address (an IPv6 /64 counts as one;
    /// loopback is not counted per address); more are closed as they come
    /// [default: max(8, max-connections / 4)].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    max_connections_per_peer: Option<u32>,
    /// Most replays streaming at once [default: max(1, min(32 × cores, memory / 4 / 16 MiB))].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100_000))]
    max_replays: Option<u32>,
    /// Close a connection with no open stream after this many seconds (at most 86400).
    #[arg(long, value_name = "SECONDS", value_parser = connection_seconds,
          default_value_t = laparo_server::service::connections::DEFAULT_IDLE_CONNECTION.as_secs_f64())]
    idle_connection: f64,
    /// Close a connection whose peer takes none of the bytes waiting for it
    /// (reads nothing) for this many seconds (at most 86400).
    #[arg(long, value_name = "SECONDS", value_parser = connection_seconds,
          default_value_t = laparo_server::service::connections::DEFAULT_WRITE_STALL.as_secs_f64())]
    write_stall: f64,
    /// An origin (`http://host:port`) whose pages may call the server from a
    /// browser (CORS); repeat for more. Without it only the console the server
    /// serves itself may.
    #[arg(long = "cors-origin", value_name = "ORIGIN", value_parser = cors_origin)]
    cors_origins: Vec<String>,
    /// A host name a browser may reach a server without tokens by (besides IP
    /// addresses, localhost and the hosts of --cors-origin); repeat for more. A
    /// browser's request naming another host is refused, against DNS rebinding.
    #[arg(long = "allowed-host", value_name = "NAME", value_parser = allowed_host)]
    allowed_hosts: Vec<String>,
}

/// A connection's idle or write-stall limit in seconds: (0, 86400].
fn connection_seconds(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    if v.is_finite() && v > 0.0 && v <= 86_400.0 {
        Ok(v)
    } else {
        Err(format!("{s} is not a duration in (0, 86400] seconds"))
    }
}

/// An origin as CORS names it: `scheme://host[:port]`.
fn cors_origin(s: &str) -> Result<String, String> {
    laparo_server::console::parse_origin(s).map_err(|e| e.to_string())?;
    Ok(s.to_string())
}

/// A host name as `--allowed-host` takes it: no scheme, no port.
fn allowed_host(s: &str) -> Result<String, String> {
    laparo_server::console::parse_allowed_host(s).map_err(|e| e.to_string())?;
    Ok(s.to_string())
}

/// An idle timeout in seconds, within the range sessions accept.
fn idle_seconds(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    laparo_server::session::idle_timeout(v)?;
    Ok(v)
}

/// A station timeout in seconds, within the range the server accepts.
fn station_timeout(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    laparo_server::service::StationTimeout::from_secs(v)?;
    Ok(v)
}

/// Serves until SIGINT or SIGTERM.
fn serve(args: ServeArgs) -> Result<(), String> {
    use laparo_server::service::capacity::{Capacity, Machine};
    use laparo_server::service::shutdown::RUNTIME_GRACE;
    use laparo_server::service::{PoseLimits, ServeConfig, TlsFiles, Tokens, serve};
    let tokens = args
        .tokens
        .as_deref()
        .map(Tokens::load)
        .transpose()
        .map_err(|e| e.to_string())?;
    let config = ServeConfig {
        scene_dir: args.scene_dir,
        tokens,
        tls: args
            .tls_cert
            .zip(args.tls_key)
            .map(|(cert, key)| TlsFiles { cert, key }),
        idle_timeout: laparo_server::session::idle_timeout(args.idle_timeout)
            .map_err(|e| format!("--idle-timeout: {e}"))?,
        pose_limits: PoseLimits {
            rate_hz: args.max_pose_rate,
            burst: laparo_server::session::input::stall_burst(args.max_pose_rate),
        },
        station_timeout: laparo_server::service::StationTimeout::from_secs(args.station_timeout)
            .map_err(|e| format!("--station-timeout: {e}"))?,
        insecure: args.insecure,
        recordings: (!args.no_recording).then_some(args.recordings),
        recordings_min_free: None,
        capacity: {
            let machine = Machine::this();
            let mut capacity = Capacity::for_machine(machine);
            if let Some(n) = args.max_sessions {
                // The connection default follows the session limit.
                capacity = capacity.with_sessions(n as usize, machine);
            }
            if let Some(n) = args.max_connections {
                // The per-peer default follows the connection limit.
                capacity = capacity.with_connections(n as usize);
            }
            if let Some(n) = args.max_connections_per_peer {
                capacity.connections_per_peer = n as usize;
            }
            if let Some(n) = args.max_replays {
                capacity.replays = n as usize;
            }
            capacity
        },
        idle_connection: Some(std::time::Duration::from_secs_f64(args.idle_connection)),
        write_stall: Some(std::time::Duration::from_secs_f64(args.write_stall)),
        cors_origins: args.cors_origins,
        max_attached: None,
        allowed_hosts: args.allowed_hosts,
    };
    let runtime = tokio::runtime::Runtime::new().map_err(|e| e.to_string())?;
    let served = runtime.block_on(async move {
        let listener = tokio::net::TcpListener::bind(args.listen)
            .await
            .map_err(|e| format!("cannot listen on {}: {e}", args.listen))?;
        serve(config, listener, shutdown_signal())
            .await
            .map_err(|e| e.to_string())
    });
    // Tasks still running (a replay's read burst) get a bounded time, not forever:
    // part of the shutdown bound.
    runtime.shutdown_timeout(RUNTIME_GRACE);
    served
}

/// SIGINT (Ctrl-C) or SIGTERM; Ctrl-C alone where SIGTERM cannot be watched.
async fn shutdown_signal() {
    #[cfg(unix)]
    if let Ok(mut signals) = headless::signal::StopSignals::install() {
        return signals.recv().await;
    }
    let _ = tokio::signal::ctrl_c().await;
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Step a scene headless (no network), print progress and timing, optionally export.
    Run(RunArgs),
}

#[derive(Args, Debug)]
struct RunArgs {
    /// Scene file (TOML); the embedded default scene if omitted.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Simulated seconds to run [default: the trajectory's length, or 2].
    #[arg(long, value_parser = positive_seconds, conflicts_with = "static_solve")]
    seconds: Option<f64>,
    /// Drive the instruments from a CSV file: t, instrument, tip x y z, axis x y z (SI).
    #[arg(long, value_name = "FILE.csv", conflicts_with = "static_solve")]
    trajectory: Option<PathBuf>,
    /// Solve the static equilibrium instead of stepping in time.
    #[arg(long = "static")]
    static_solve: bool,
    /// Write the final deformed volume mesh as VTK XML unstructured grid (.vtu).
    #[arg(long, value_name = "OUT.vtu")]
    export: Option<PathBuf>,
    /// Write a time series for ParaView: a frame every T simulated seconds (and the
    /// start and the end), as OUT_000000.vtu, ... beside OUT.pvd, which lists them.
    #[arg(long, num_args = 2, value_names = ["T", "OUT.pvd"], conflicts_with = "static_solve")]
    export_every: Option<Vec<OsString>>,
}

fn positive_rate(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    if v.is_finite() && v > 0.0 && v <= 1e6 {
        Ok(v)
    } else {
        Err(format!("{s} is not a rate in (0, 1e6] per second"))
    }
}

fn positive_seconds(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    if v.is_finite() && v > 0.0 && v <= MAX_RUN_SECONDS {
        Ok(v)
    } else {
        Err(format!(
            "{s} is not a duration in (0, {MAX_RUN_SECONDS:e}] seconds"
        ))
    }
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        // A record that cannot be written is dropped: the default says so with
        // `eprintln!`, which panics when standard error itself is what failed
        // (`headless::out`).
        .log_internal_errors(false)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Run(args)) => run(args),
        None => serve(cli.serve),
    };
    match (result, out::failure()) {
        (Ok(()), None) => ExitCode::SUCCESS,
        (Ok(()), Some(e)) => {
            out::tell(format_args!(
                "laparo-server: cannot write to standard output: {e} (the run went to its end and wrote its files)"
            ));
            ExitCode::FAILURE
        }
        (Err(message), _) => {
            out::tell(format_args!("laparo-server: {message}"));
            ExitCode::FAILURE
        }
    }
}

/// The period and path of `--export-every T OUT.pvd`, checked.
/// Taken as raw arguments, so that bytes that are not UTF-8 get this message rather
/// than the parser's. The series' name must be text: its frames are named after it,
/// in an XML index.
fn export_every(values: &[OsString]) -> Result<(f64, PathBuf), String> {
    let [period, path] = values else {
        return Err("--export-every takes a period in seconds and a .pvd path".into());
    };
    let Some(period) = period.to_str() else {
        return Err(format!(
            "--export-every {}: the period is not a number of seconds",
            period.to_string_lossy()
        ));
    };
    if path.to_str().is_none() {
        return Err(format!(
            "--export-every {period} {}: the series' path must be UTF-8 text (its frames \
             are named after it in the .pvd, an XML file)",
            path.to_string_lossy()
        ));
    }
    let seconds = positive_seconds(period).map_err(|e| format!("--export-every {period}: {e}"))?;
    Ok((seconds, PathBuf::from(path)))
}

/// Checks that `path`, written by `option`, is named as a `.{ext}` file (so that a
/// slip of the command line cannot write VTK XML over a scene, a mesh or a script).
fn output_name(option: &str, path: &Path, ext: &str) -> Result<(), String> {
    if !path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case(ext))
    {
        return Err(format!(
            "{option} {}: the output is a .{ext} file, so its name must end in .{ext}",
            path.display()
        ));
    }
    // Said before the run, not after it has run for nothing.
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(format!(
            "{option} {}: there is no directory {} to write it in",
            path.display(),
            dir.display()
        ));
    }
    Ok(())
}

/// Ticks between the frames of `--export-every T` at ticks of `dt`: `T / dt`
/// rounded, at least one (a period below the tick exports every tick).
fn frame_interval(period: f64, dt: f64) -> u64 {
    (period / dt).round().clamp(1.0, u64::MAX as f64) as u64
}

/// Frames a series writes over a run of `ticks` ticks with a frame every `interval`:
/// the start, every `interval`-th tick, and the end unless it is one of those.
fn series_frames(ticks: u64, interval: u64) -> u64 {
    1 + ticks / interval + u64::from(!ticks.is_multiple_of(interval))
}

/// A time series being written by `run --export-every`.
struct Series {
    frames: PvdSeries,
    /// Ticks from one frame to the next ([`frame_interval`]).
    interval: u64,
    /// The tick of the first frame.
    first: u64,
    /// Simulated time of the newest frame, s.
    last: f64,
    path: PathBuf,
    /// Why a frame could not be written (the run stops there).
    error: Option<String>,
}

fn run(args: RunArgs) -> Result<(), String> {
    let series = args.export_every.as_deref().map(export_every).transpose()?;
    let mut outputs = Vec::new();
    if let Some(path) = &args.export {
        output_name("--export", path, "vtu")?;
        outputs.push(("--export", path.as_path()));
    }
    if let Some((_, path)) = &series {
        output_name("--export-every", path, "pvd")?;
        outputs.push(("--export-every", path.as_path()));
    }
    let scene = match &args.scene {
        Some(path) => Scene::load(path).map_err(|e| e.to_string())?,
        None => Scene::default_scene(),
    };
    // Nothing this run reads is written over.
    let mesh = mesh_path(&scene);
    let inputs = [
        ("scene", args.scene.as_deref()),
        ("mesh", mesh.as_deref()),
        ("trajectory", args.trajectory.as_deref()),
    ];
    for (option, output) in &outputs {
        for (what, input) in inputs {
            if input.is_some_and(|input| same_file(output, input)) {
                return Err(format!(
                    "{option} {}: that is the {what} file this run reads; writing it would \
                     destroy it",
                    output.display()
                ));
            }
        }
    }
    // An output that is a directory, a link or a device is refused now, not after
    // the run (writing it refuses it too).
    for (option, output) in &outputs {
        laparo_server::output::writable_over(output).map_err(|e| format!("{option}: {e}"))?;
    }
    // Nor do the series' frames, beside its index, write over an input or --export.
    if let Some((_, path)) = &series {
        let frames = PvdSeries::new(path);
        let others = inputs
            .iter()
            .map(|&(what, p)| (format!("the {what} file this run reads"), p))
            .chain([("--export".to_string(), args.export.as_deref())]);
        for (what, other) in others {
            if let Some(other) = other.filter(|p| frames.may_write(p)) {
                return Err(format!(
                    "--export-every {}: its frames are named {}_NNNNNN.vtu beside it, and \
                     one would write over {} ({what}); name the series otherwise",
                    path.display(),
                    path.file_stem().unwrap_or_default().to_string_lossy(),
                    other.display()
                ));
            }
        }
    }
    let built = Instant::now();
    let mut sim = scene.build().map_err(|e| e.to_string())?;
    let script = match &args.trajectory {
        Some(path) => {
            let traj = Trajectory::load(path).map_err(|e| e.to_string())?;
            let names: Vec<&str> = sim.instruments.iter().map(|i| i.name.as_str()).collect();
            let tracks = traj
                .match_instruments(&names, &path.display().to_string())
                .map_err(|e| e.to_string())?;
            Some((traj, tracks))
        }
        None => None,
    };
    let seconds = args.seconds.unwrap_or(match &script {
        Some((traj, _)) => traj.end_time().max(1e-3),
        None => 2.0,
    });
    say!(
        "scene {}: {} vertices, {} tetrahedra, {} surface triangles, {} fixed; {:?} at {} Hz; built in {:.1} ms",
        printable(&sim.scene.name),
        sim.mesh.vertex_count(),
        sim.mesh.tets.len(),
        sim.mesh.surface.triangles.len(),
        sim.fixed.len(),
        sim.integrator.config().kind,
        sim.scene.mechanics.rate_hz,
        built.elapsed().as_secs_f64() * 1e3,
    );
    if sim.integrator.config().kind == IntegratorKind::Explicit {
        say!(
            "explicit: {} substeps per tick (stability bound of mesh and material)",
            sim.integrator.explicit_substeps(sim.dt)
        );
    }
    // From here on Ctrl-C ends the run cleanly (see `headless::signal`).
    let stop = headless::signal::stop_flag();
    sim.integrator.set_interrupt(stop.clone());
    let unwritten = if args.export.is_some() {
        "; --export not written"
    } else {
        ""
    };
    let interrupted = |at: &Simulation, what: &str| {
        format!(
            "interrupted at tick {} (t = {:.3} s){what}{unwritten}",
            at.tick, at.time
        )
    };
    if args.static_solve {
        if !sim.supports_hold_rigid_motion() {
            return Err(format!(
                "scene {}: a static solve needs three fixed vertices not on one line (`fixed` in the scene)",
                printable(&sim.scene.name)
            ));
        }
        let start = Instant::now();
        let report = sim.solve_static();
        if stop.load(Ordering::Relaxed) {
            return Err(interrupted(&sim, " during the static solve"));
        }
        say!(
            "static: {} CG iterations, relative residual {:.1e}{}, {:.1} ms; largest displacement {:.3} mm",
            report.cg_iterations,
            report.relative_residual,
            match report.stopped_by {
                Some(why) if !report.converged =>
                    format!(" (NOT converged: {why}; the state is the last iterate)"),
                _ => String::new(),
            },
            start.elapsed().as_secs_f64() * 1e3,
            sim.max_displacement() * 1e3,
        );
        // A diverged state is no answer: said as a time-stepped run says it, and not
        // exported.
        if let Some(fault) = headless::fault(&sim) {
            return Err(format!("static solve: {fault}"));
        }
    } else {
        let script = script.as_ref().map(|(t, m)| (t, m.as_slice()));
        let mut pvd: Option<Series> = None;
        if let Some((period, path)) = &series {
            // Counted by the rule that writes them, so that a run that would pass the
            // bound is refused here, not stopped at its end.
            let interval = frame_interval(*period, sim.dt);
            let frames = series_frames(headless::tick_count(seconds, sim.dt), interval);
            if frames > pvd::MAX_FRAMES {
                return Err(format!(
                    "--export-every {}: {frames} frames over {} s (one every {interval} \
                     ticks); at most {} (raise T)",
                    Number(*period),
                    Number(seconds),
                    pvd::MAX_FRAMES
                ));
            }
            let mut series = PvdSeries::new(path);
            series
                .frames_writable(frames)
                .map_err(|e| format!("--export-every {}: {e}", path.display()))?;
            series
                .write_frame(&sim)
                .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            pvd = Some(Series {
                frames: series,
                interval,
                first: sim.tick,
                last: sim.time,
                path: path.clone(),
                error: None,
            });
        }
        let mut frame_due = |sim: &Simulation| -> bool {
            // A tick a signal cut short is no frame.
            if stop.load(Ordering::Relaxed) {
                return false;
            }
            let Some(s) = &mut pvd else {
                return true;
            };
            if !(sim.tick - s.first).is_multiple_of(s.interval) {
                return true;
            }
            s.last = sim.time;
            match s.frames.write_frame(sim) {
                Ok(()) => true,
                Err(e) => {
                    s.error = Some(format!("cannot write {}: {e}", s.path.display()));
                    false
                }
            }
        };
        let summary = headless::run_observed(
            &mut sim,
            seconds,
            script,
            |sim, report| {
                let mut contact = String::new();
                for ins in sim.instruments.iter().filter(|i| i.current.is_some()) {
                    contact += &format!(
                        "  {}: {} held, {:.3} N",
                        ins.name,
                        ins.held.len(),
                        ins.report.reaction.norm()
                    );
                }
                say!(
                    "tick {:>6}  t = {:>7.3} s  max displacement {:>8.3} mm  substeps {:>5}  CG iterations {:>4}{contact}",
                    sim.tick,
                    sim.time,
                    sim.max_displacement() * 1e3,
                    report.substeps,
                    report.cg_iterations
                );
            },
            &mut frame_due,
        );
        say!(
            "ran {} ticks ({:.3} s simulated) in {:.3} s: tick median {:.3} ms, p99 {:.3} ms, max {:.3} ms; {:.1}x real time",
            summary.ticks,
            summary.sim_seconds,
            summary.wall_seconds,
            summary.tick_median * 1e3,
            summary.tick_p99 * 1e3,
            summary.tick_max * 1e3,
            summary.sim_seconds / summary.wall_seconds.max(1e-12),
        );
        say!(
            "mean CG iterations per tick {:.1}; ticks at the iteration cap {}; largest displacement at the end {:.3} mm",
            summary.mean_cg_iterations,
            summary.unconverged,
            summary.max_displacement * 1e3
        );
        if stop.load(Ordering::Relaxed) {
            let kept = pvd.as_ref().map_or(String::new(), |s| {
                format!(
                    "; {} holds the {} frames written before it",
                    s.path.display(),
                    s.frames.len()
                )
            });
            return Err(interrupted(&sim, &kept));
        }
        if let Some(mut s) = pvd {
            if let Some(e) = s.error {
                return Err(e);
            }
            // A diverged state is not a frame: the series ends with the last good one.
            if s.last < sim.time && summary.fault.is_none() {
                s.frames
                    .write_frame(&sim)
                    .map_err(|e| format!("cannot write {}: {e}", s.path.display()))?;
            }
            say!("wrote {} ({} frames)", s.path.display(), s.frames.len());
        }
        if let Some(fault) = summary.fault {
            return Err(format!(
                "stopped at {fault}; a served session would have halted there \
                 (SIMULATION_HALTED)"
            ));
        }
    }
    if let Some(path) = &args.export {
        write_vtu(&sim, path).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        say!("wrote {}", path.display());
    }
    Ok(())
}
