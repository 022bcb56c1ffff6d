//! `laparo`: the client command line. The arguments are defined in
//! [`laparo_client::cli`]; this file runs them and prints progress and summaries.
//!
//! Exit status: 0 on success, 1 when the run fails (server unreachable, session not
//! found, stream ended with an error status), 2 for a usage error.

use std::process::ExitCode;
use std::time::Duration;

use clap::Parser;
use laparo_client::cli::{
    Cli, Command, DemoArgs, LoadArgs, ObserveArgs, RecordingsCommand, ReplayArgs, ResimArgs,
    StationArgs,
};
use laparo_client::connect::ConnectConfig;
use laparo_client::load::{LoadConfig, LoadSummary, run_load};
use laparo_client::observe::{
    ObserveConfig, ObserveReport, ObserveSummary, event_line, run_observe,
};
use laparo_client::station::{StationConfig, StationProgress, StationSummary, run_station};
use tokio::sync::watch;

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let runtime = match tokio::runtime::Runtime::new() {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("laparo: cannot start the async runtime: {e}");
            return ExitCode::from(1);
        }
    };
    let result = runtime.block_on(async {
        match cli.command {
            Command::Demo(args) => demo(args).await,
            Command::Station(args) => station(args).await,
            Command::Observe(args) => observe(args).await,
            Command::Load(args) => load(args).await,
            Command::Replay(args) => replay(args).await,
            Command::Recordings(command) => recordings(command).await,
            Command::Resim(args) => resim(args),
        }
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("laparo: {e}");
            ExitCode::from(1)
        }
    }
}

type BoxError = Box<dyn std::error::Error>;

/// Completes on Ctrl-C (never if the signal cannot be watched).
fn ctrl_c() -> std::pin::Pin<Box<dyn std::future::Future<Output = ()> + Send>> {
    Box::pin(async {
        if tokio::signal::ctrl_c().await.is_err() {
            std::future::pending::<()>().await;
        }
    })
}

/// `laparo demo`: a server in this process, one station pressing the liver.
async fn demo(args: DemoArgs) -> Result<(), BoxError> {
    use laparo_client::connect::connect;
    use laparo_server::service::{ServeConfig, serve};
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
    let url = format!("http://{}", listener.local_addr()?);
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let recordings = args
        .recordings
        .clone()
        .unwrap_or_else(|| std::path::PathBuf::from("recordings"));
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
        .create_session(laparo_client::proto::v1::CreateSessionRequest {
            scene: "default".into(),
            idle_timeout_s: None,
            record: Some(true),
        })
        .await?
        .into_inner();
    println!(
        "demo: laparo-server in this process at {url}; session {} of the default scene (SOFA's liver at 0.19 m, E = 4.5 kPa)",
        session.session_id
    );
    println!(
        "demo: station with the left instrument and a 1 kHz force loop: tip press (0–4 s), then the shaft sideways (4–10 s)"
    );
    let (progress_tx, mut progress_rx) = watch::channel(StationProgress::default());
    let config = StationConfig {
        duration: Some(args.seconds),
        progress: Some(progress_tx),
        on_event: Some(Box::new(|e| println!("event  {}", event_line(e)))),
        stop: Some(ctrl_c()),
        gesture: Some(Box::new(laparo_client::gestures::tip_and_shaft)),
        client_name: "laparo demo".into(),
        ..StationConfig::new(url, session.session_id.clone(), vec!["left".into()])
    };
    let run = run_station(config);
    tokio::pin!(run);
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    tick.tick().await;
    let summary = loop {
        tokio::select! {
            result = &mut run => break result,
            _ = tick.tick() => print_progress(&progress_rx.borrow_and_update().clone()),
        }
    };
    let _ = stop.send(());
    let served = server.await;
    let summary = summary?;
    print_station_summary(&summary);
    match &session.recording_file {
        Some(file) => println!("  recording            {}", recordings.join(file).display()),
        None => println!(
            "  recording            none: {} could not be written (see the events above)",
            recordings.display()
        ),
    }
    served??;
    Ok(())
}

/// `laparo replay FILE`: the recording's summary; with `--server`, the server
/// plays it back and this watches it.
async fn replay(args: ReplayArgs) -> Result<(), BoxError> {
    if let Some(connect) = args.remote.connect_config() {
        return watch_replay(connect, &args).await;
    }
    use laparo_server::recording::summarize;
    let recording = open_recording(&args.file)?;
    let s = summarize(&recording)?;
    let meta = recording.meta();
    println!(
        "{}: session {} of scene `{}`, format {}",
        args.file.display(),
        meta.session_id,
        meta.scene,
        meta.format_version
    );
    println!("  duration             {:.3} s simulated", s.duration_s);
    println!("  ticks                {}", s.ticks);
    println!("  poses received       {}", s.poses);
    for (name, i) in &s.instruments {
        println!(
            "  {name}: path {:.1} mm, in contact {:.2} s, force max {:.3} N mean {:.3} N (in contact {:.3} N), largest jump {:.3} N",
            i.path_length_m * 1e3,
            i.time_in_contact_s,
            i.max_force_n,
            i.mean_force_n,
            i.mean_contact_force_n,
            i.max_force_jump_n
        );
    }
    for (kind, n) in &s.events {
        println!("  event {kind:<28} {n}");
    }
    if let Some(out) = &args.plot {
        use laparo_client::plot::{draw, force_series};
        let states = recording.instrument_states()?;
        let series = force_series(states.iter().map(|s| &s.message));
        let title = format!(
            "session {} of scene {}: force on each instrument",
            meta.session_id, meta.scene
        );
        let r = draw(&series, &title, out, args.plot_size)?;
        let plotted: Vec<&str> = series.iter().map(|s| s.instrument.as_str()).collect();
        let left_out: Vec<&str> = s
            .instruments
            .keys()
            .map(String::as_str)
            .filter(|name| !plotted.contains(name))
            .collect();
        println!(
            "  plot                 {} ({}x{} px): |force| {:.3}–{:.3} N over {:.3}–{:.3} s simulated, {}{}",
            out.display(),
            args.plot_size.0,
            args.plot_size.1,
            r.force_n.0,
            r.force_n.1,
            r.time_s.0,
            r.time_s.1,
            if plotted.is_empty() {
                "no instrument".to_string()
            } else {
                plotted.join(", ")
            },
            if left_out.is_empty() {
                String::new()
            } else {
                format!(" (left out, never posed: {})", left_out.join(", "))
            }
        );
    }
    Ok(())
}

/// Opens a recording; one cut short (a killed server, a session still recording)
/// is read up to its last complete chunk, with a note saying so.
fn open_recording(path: &std::path::Path) -> Result<laparo_server::recording::Recording, BoxError> {
    let recording = laparo_server::recording::Recording::open_unfinished(path)?;
    if !recording.is_complete() {
        eprintln!(
            "note: {} ends without its summary (a killed server, or still being recorded); \
             read up to its last complete chunk. `laparo recordings recover` rewrites it \
             into a complete file.",
            path.display(),
        );
    }
    Ok(recording)
}

/// `laparo resim`: the recorded poses through the recorded (or another) scene.
fn resim(args: ResimArgs) -> Result<(), BoxError> {
    use laparo_server::recording::resimulate_as;
    let recording = open_recording(&args.file)?;
    let mut meta = recording.meta().clone();
    if let Some(scene) = &args.scene {
        meta.scene_toml =
            std::fs::read_to_string(scene).map_err(|e| format!("{}: {e}", scene.display()))?;
        meta.scene_dir = scene.parent().map(std::path::Path::to_path_buf);
    }
    let total = recording
        .message_counts()
        .get(laparo_server::recording::TOPIC_SURFACE)
        .copied();
    // A progress line once a second, for long recordings.
    let mut next_line = std::time::Instant::now() + std::time::Duration::from_secs(1);
    let mut shown = false;
    let r = resimulate_as(&recording, &meta, args.scene_dir.as_deref(), |tick| {
        if std::time::Instant::now() >= next_line {
            eprint!("\r  tick {tick} of {}", total.unwrap_or(0));
            next_line += std::time::Duration::from_secs(1);
            shown = true;
        }
    })?;
    if shown {
        eprintln!();
    }
    println!(
        "{}: re-simulated {} recorded ticks ({:.3} s simulated) in {:.2} s wall ({:.1}× real time)",
        args.file.display(),
        r.ticks_compared,
        r.sim_time_s,
        r.elapsed_s,
        r.sim_time_s / r.elapsed_s.max(1e-9)
    );
    match r.worst_surface_tick {
        Some(t) => println!(
            "  largest surface deviation {:.3e} m (tick {t})",
            r.max_surface_deviation_m
        ),
        None => println!("  largest surface deviation 0 m"),
    }
    println!(
        "  largest force deviation   {:.3e} N",
        r.max_force_deviation_n
    );
    println!("  contact state mismatches  {}", r.contact_mismatches);
    if let Some(t) = r.first_missing_tick {
        println!(
            "  {} ticks are missing from the recording (the recorder fell behind), from tick {t}: deviations after it are expected",
            r.missing_ticks
        );
    }
    println!(
        "  {}",
        if r.is_exact() {
            "identical to the recording"
        } else {
            "differs from the recording"
        }
    );
    Ok(())
}

/// `laparo replay FILE --server URL`: the server's recording FILE, played back.
async fn watch_replay(connect: ConnectConfig, args: &ReplayArgs) -> Result<(), BoxError> {
    use laparo_client::proto::v1::{ReplayMode, ReplayRequest};
    let file = args
        .file
        .to_str()
        .ok_or_else(|| format!("{}: not a UTF-8 file name", args.file.display()))?
        .to_string();
    let request = ReplayRequest {
        file: file.clone(),
        speed: args.speed,
        start_offset_s: args.from,
        mode: if args.resimulate {
            ReplayMode::Resimulate
        } else {
            ReplayMode::Recorded
        } as i32,
    };
    let config = ObserveConfig {
        connect,
        stop: Some(ctrl_c()),
        ..ObserveConfig::replay(args.remote.server.clone().unwrap_or_default(), request)
    };
    let what = format!(
        "replaying {file} at {}x from {} s",
        args.speed.unwrap_or(1.0),
        args.from.unwrap_or(0.0)
    );
    let summary = run_observe(config, print_report(what)).await?;
    print_watch_summary(&summary, "the recording ended");
    Ok(())
}

/// One row of `laparo recordings list`, from a directory or a server alike.
fn recording_row(
    file: &str,
    session: &str,
    scene: &str,
    start_unix_s: f64,
    duration_s: f64,
    size_bytes: u64,
    state: &str,
) {
    println!(
        "| {file} | {session} | {scene} | {start_unix_s:.0} | {duration_s:.2} | {size_bytes} | {state} |"
    );
}

/// `laparo recordings list|recover`.
async fn recordings(command: RecordingsCommand) -> Result<(), BoxError> {
    use laparo_server::recording::{FileState, list, recover};
    match command {
        RecordingsCommand::List { dir, remote } => {
            println!(
                "| file | session | scene | start (unix s) | duration (s) | size (bytes) | state |"
            );
            println!("|---|---|---|---|---|---|---|");
            if let Some(connect) = remote.connect_config() {
                let connection = laparo_client::connect::connect(&connect).await?;
                let listed = connection
                    .recordings()
                    .list_recordings(laparo_client::proto::v1::ListRecordingsRequest {})
                    .await?
                    .into_inner();
                for r in listed.recordings {
                    let start = r
                        .start
                        .map_or(0.0, |t| t.seconds as f64 + t.nanos as f64 * 1e-9);
                    recording_row(
                        &r.file,
                        &r.session_id,
                        &r.scene,
                        start,
                        r.duration_s,
                        r.size_bytes,
                        if r.in_progress {
                            "in progress"
                        } else {
                            "complete"
                        },
                    );
                }
                return Ok(());
            }
            let listed = list(&dir, |_| false).map_err(|e| format!("{}: {e}", dir.display()))?;
            for l in listed {
                match &l.entry {
                    Ok(e) => recording_row(
                        &l.file,
                        &e.session_id,
                        &e.scene,
                        e.start_unix_ns as f64 * 1e-9,
                        e.duration_s,
                        l.size_bytes,
                        match e.state {
                            FileState::Complete => "complete",
                            FileState::InProgress => "in progress",
                            FileState::Unfinished => {
                                "no footer: still being recorded, or cut short (`recordings recover` completes it)"
                            }
                        },
                    ),
                    Err(e) => println!("| {} | — | — | — | — | {} | {e} |", l.file, l.size_bytes),
                }
            }
            Ok(())
        }
        RecordingsCommand::Recover { file, out } => {
            let out = out.unwrap_or_else(|| file.clone());
            let r = recover(&file, &out)?;
            println!(
                "{} → {}: {} chunks, {} messages kept ({} bytes), {} bytes after the last complete chunk left out{}",
                file.display(),
                out.display(),
                r.chunks,
                r.messages,
                r.bytes_kept,
                r.bytes_dropped,
                if r.was_complete {
                    "; it was complete"
                } else {
                    ""
                }
            );
            Ok(())
        }
    }
}

async fn station(args: StationArgs) -> Result<(), BoxError> {
    let (progress_tx, mut progress_rx) = watch::channel(StationProgress::default());
    let config = StationConfig {
        connect: args.server.connect_config(),
        pose_rate_hz: args.pose_rate,
        haptic_rate_hz: args.haptic_rate,
        surface_frame_rate_hz: args.frame_rate,
        duration: args.seconds,
        progress: Some(progress_tx),
        on_event: Some(Box::new(|e| println!("event  {}", event_line(e)))),
        stop: Some(ctrl_c()),
        client_name: format!("laparo station ({})", args.instruments.join(",")),
        ..StationConfig::new(
            args.server.server.clone(),
            args.session.clone(),
            args.instruments.clone(),
        )
    };
    println!(
        "station: joining session {} at {} with {:?}, poses at {} Hz, force loops at {} Hz",
        args.session, args.server.server, args.instruments, args.pose_rate, args.haptic_rate
    );
    let run = run_station(config);
    tokio::pin!(run);
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    tick.tick().await;
    let summary = loop {
        tokio::select! {
            result = &mut run => break result?,
            _ = tick.tick() => {
                let p = progress_rx.borrow_and_update().clone();
                print_progress(&p);
            }
        }
    };
    print_station_summary(&summary);
    Ok(())
}

fn print_progress(p: &StationProgress) {
    let forces: Vec<String> = p
        .forces_n
        .iter()
        .zip(&p.haptic_rates_hz)
        .map(|((name, f), hz)| format!("{name} {f:.2} N @ {hz:.0} Hz"))
        .collect();
    println!(
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

fn print_station_summary(s: &StationSummary) {
    println!();
    println!(
        "station {} in session {}: {:?} after {:.1} s",
        s.station_id, s.session_id, s.end, s.elapsed_s
    );
    println!("  instruments granted  {:?}", s.instruments);
    println!("  ticks seen           {} (last {})", s.ticks, s.last_tick);
    println!("  surface frames       {}", s.frames);
    println!("  instrument states    {}", s.states);
    println!("  events               {}", s.events);
    println!(
        "  poses sent           {} ({} dropped, queue full)",
        s.poses_sent, s.poses_dropped
    );
    if s.errors.is_empty() {
        println!("  station errors       none");
    } else {
        for (code, n) in &s.errors {
            println!("  station errors       {code}: {n}");
        }
    }
    println!("  max |force|          {:.3} N", s.max_force_n);
    println!("  pose-to-state        {}", s.latency);
    for i in &s.per_instrument {
        let l = &i.loop_stats;
        println!(
            "  {}: models {} applied, {} invalid; max |F| {:.3} N; force loop {} ticks at {:.1} Hz, \
             jitter p50 {:.1} µs p99 {:.1} µs max {:.1} µs, {} missed deadlines, {} clamped, max model age {:.1} ms",
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
            l.max_model_age_s * 1e3,
        );
    }
}

async fn observe(args: ObserveArgs) -> Result<(), BoxError> {
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
fn print_report(what: String) -> impl FnMut(ObserveReport<'_>) {
    move |report| match report {
        ObserveReport::Scene(scene) => {
            let s = scene.summary.clone().unwrap_or_default();
            let names: Vec<&str> = scene.instruments.iter().map(|i| i.name.as_str()).collect();
            println!(
                "{what}: scene {:?}, {} tetrahedra, mechanics {} Hz, instruments {:?}",
                s.name, s.tetrahedron_count, s.mechanics_rate_hz, names
            );
        }
        ObserveReport::Status(line) => println!("{line}"),
        ObserveReport::Event(event) => println!("event  {}", event_line(event)),
    }
}

/// The last lines of an observe or replay run; `ended` says why the server ended it.
fn print_watch_summary(summary: &ObserveSummary, ended: &str) {
    println!();
    println!(
        "watched {:.1} s: {} ticks, {} frames, {} states, {} events, max |force| {:.3} N{}",
        summary.elapsed_s,
        summary.ticks,
        summary.frames,
        summary.states,
        summary.events,
        summary.max_force_n,
        if summary.server_closed {
            format!("; {ended}")
        } else {
            String::new()
        }
    );
}

async fn load(args: LoadArgs) -> Result<(), BoxError> {
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
    println!(
        "load: {} stations for {:.1} s at {}; the first ones (one per free instrument) send poses at {} Hz, the others only receive",
        args.stations,
        args.seconds.as_secs_f64(),
        args.server.server,
        args.pose_rate
    );
    let summary = run_load(config, |p| {
        println!(
            "  {} joined  frames {:>8}  states {:>8}  poses {:>8}",
            p.joined, p.frames, p.states, p.poses_sent
        );
    })
    .await?;
    println!();
    println!(
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
        println!("poses dropped (queue full): {}", summary.poses_dropped);
    }
    for (code, n) in &summary.errors {
        println!("station errors {code}: {n}");
    }
    for failure in &summary.failures {
        println!("failed: {failure}");
    }
    println!();
    println!("{}", LoadSummary::markdown_header());
    println!("{}", summary.markdown_row());
    if !summary.failures.is_empty() {
        return Err(format!("{} station(s) failed", summary.failures.len()).into());
    }
    Ok(())
}
