//! The command line's parsing: defaults, options, and bad values as usage errors.

use clap::error::ErrorKind;

use std::path::PathBuf;
use std::time::Duration;

use clap::Parser;

use super::recordings::RecordingsCommand;
use super::{Cli, Command};
use crate::haptics::force_loop::DEFAULT_RATE_HZ;
use crate::station::DEFAULT_POSE_RATE_HZ;

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
    assert_eq!(a.claimed(), vec!["left".to_owned()]);
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
fn the_connect_timeout_is_five_seconds_unless_given() {
    let Command::Observe(a) = parse(&["observe", "--server", "http://h:1", "--session", "s"])
        .unwrap()
        .command
    else {
        panic!("not observe")
    };
    assert_eq!(
        a.server.connect_config().connect_timeout,
        Duration::from_secs(5)
    );
    let Command::Recordings(RecordingsCommand::List { remote, .. }) = parse(&[
        "recordings",
        "list",
        "--server",
        "http://h:1",
        "--connect-timeout",
        "0.5",
    ])
    .unwrap()
    .command
    else {
        panic!("not recordings list")
    };
    let c = remote.connect_config().unwrap();
    assert_eq!(c.connect_timeout, Duration::from_millis(500));
    let e = parse(&["recordings", "list", "--connect-timeout", "1"]).unwrap_err();
    assert_eq!(e.kind(), ErrorKind::MissingRequiredArgument);
    let e = parse(&[
        "observe",
        "--server",
        "http://h:1",
        "--session",
        "s",
        "--connect-timeout",
        "0",
    ])
    .unwrap_err();
    assert_eq!(e.kind(), ErrorKind::ValueValidation);
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
    // Out of range far enough that a timer could not hold the period, or that the
    // number has hundreds of digits: refused, and echoed short, with the range.
    for (bad, said) in [
        (
            &["--pose-rate", "1e-300"][..],
            "1e-300 Hz: a pose rate must be between 0.1 and 100000 Hz",
        ),
        (
            &["--pose-rate", "1e300"],
            "1e300 Hz: a pose rate must be between",
        ),
        (
            &["--haptic-rate", "1e300"],
            "1e300 Hz: the haptic rate must be",
        ),
        (
            &["--seconds", "1e9"],
            "1000000000 s: a duration must be > 0 and below 1e9 s",
        ),
        (&["--seconds", "1e300"], "1e300 s: a duration must be"),
        (
            &["--seconds", "1e-300"],
            "1e-300 s: a duration must be at least 1 ns (1e-9 s)",
        ),
    ] {
        let args: Vec<&str> = base.iter().chain(bad).copied().collect();
        let e = parse(&args).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::ValueValidation, "{bad:?}");
        assert!(e.to_string().contains(said), "{bad:?}: {e}");
        assert!(e.to_string().len() < 300, "{bad:?}: {e}");
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
        let e = parse(&["replay", "r.mcap", "--plot", "f.png", "--plot-size", bad]).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::ValueValidation, "{bad}");
    }
    let e = parse(&["replay", "r.mcap", "--plot-size", "800x450"]).unwrap_err();
    assert_eq!(e.kind(), ErrorKind::MissingRequiredArgument);
}

#[test]
fn sessions_subcommands_parse_and_check_their_values() {
    use super::sessions::SessionsCommand;
    let url = "http://127.0.0.1:50051";
    let cli = parse(&[
        "sessions",
        "create",
        "--server",
        url,
        "--scene",
        "liver-20k",
        "--idle-timeout",
        "0",
        "--no-record",
    ])
    .unwrap();
    let Command::Sessions(SessionsCommand::Create { create, .. }) = cli.command else {
        panic!("not sessions create")
    };
    let request = create.request();
    assert_eq!(request.scene, "liver-20k");
    assert_eq!(request.idle_timeout_s, Some(0.0));
    assert_eq!(request.record, Some(false));
    let cli = parse(&["sessions", "create", "--server", url]).unwrap();
    let Command::Sessions(SessionsCommand::Create { create, .. }) = cli.command else {
        panic!("not sessions create")
    };
    // The server's defaults: its default scene, idle timeout and the scene's recording.
    assert_eq!(create.request().scene, "");
    assert_eq!(create.request().idle_timeout_s, None);
    assert_eq!(create.request().record, None);
    let cli = parse(&[
        "sessions",
        "evict",
        "--server",
        url,
        "s1",
        "7",
        "--reason",
        "hands off",
    ])
    .unwrap();
    let Command::Sessions(SessionsCommand::Evict {
        session,
        station,
        reason,
        ..
    }) = cli.command
    else {
        panic!("not sessions evict")
    };
    assert_eq!(
        (session.as_str(), station, reason.as_str()),
        ("s1", 7, "hands off")
    );
    for bad in [
        &[
            "sessions",
            "create",
            "--server",
            url,
            "--idle-timeout",
            "604801",
        ][..],
        &[
            "sessions",
            "create",
            "--server",
            url,
            "--idle-timeout",
            "-1",
        ],
        &[
            "sessions",
            "create",
            "--server",
            url,
            "--record",
            "--no-record",
        ],
        &["sessions", "evict", "--server", url, "s1", "-3"],
        &["sessions", "info", "--server", url],
        &["sessions", "list"],
    ] {
        let e = parse(bad).unwrap_err();
        assert_ne!(e.kind(), ErrorKind::DisplayHelp, "{bad:?}");
        assert_eq!(e.exit_code(), 2, "{bad:?}");
    }
}

#[test]
fn a_station_is_named_by_its_instruments_within_the_servers_limit() {
    use super::station::station_name;
    use laparo_server::service::limits::MAX_NAME_BYTES;
    let names = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    assert_eq!(
        station_name(&names(&["left", "right"])),
        "laparo station (left,right)"
    );
    // Four names of 73 characters, each valid, made a name of 312 bytes that the
    // server refused; a multi-byte character sits on the cut.
    let long = "é".repeat(40);
    for list in [
        vec!["x".repeat(73); 4],
        vec![long.clone(); 4],
        vec![long; 1],
    ] {
        let name = station_name(&list);
        assert!(name.len() <= MAX_NAME_BYTES, "{} bytes", name.len());
        assert!(name.starts_with("laparo station ("));
        assert!(name.ends_with(')'));
    }
}

#[test]
fn a_station_given_no_instrument_claims_none_and_watches() {
    let cli = parse(&[
        "station",
        "--server",
        "http://127.0.0.1:50051",
        "--session",
        "s1",
        "--instruments",
        "",
    ])
    .unwrap();
    let Command::Station(a) = cli.command else {
        panic!("not station")
    };
    // Sent as [""] before: refused as "no instrument ``".
    assert!(a.claimed().is_empty(), "{:?}", a.claimed());
}

#[test]
fn sessions_create_help_states_one_default_for_the_scene() {
    use clap::CommandFactory;
    let mut cli = Cli::command();
    let create = cli
        .find_subcommand_mut("sessions")
        .and_then(|s| s.find_subcommand_mut("create"))
        .expect("laparo sessions create");
    let help = create.render_long_help().to_string();
    // It also showed the empty string the parser stands for it with.
    assert_eq!(
        help.matches("[default: the server's default scene]")
            .count(),
        1,
        "{help}"
    );
    assert!(
        !help.contains("[default: ]") && !help.contains("[default: \"\"]"),
        "{help}"
    );
}
