//! `laparo`: the client command line. Each subcommand is a module of
//! [`laparo_client::cmd`] (its arguments, its runner, its printing); this file
//! parses, sets up logging and the runtime, dispatches, and turns the result into
//! the exit status.
//!
//! Exit status: 0 on success (and when the reader of standard output closes it,
//! as `laparo … | head -1` does), 1 when the run fails (server unreachable, session
//! not found, stream ended with an error status), 2 for a usage error.

use std::process::ExitCode;

use clap::Parser;
use laparo_client::cmd::{self, Cli, Command};

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
        .with_ansi(false)
        .with_writer(|| cmd::out::EscapedLog(std::io::stderr()))
        // A record that cannot be written is dropped: the default says so with
        // `eprintln!`, which panics when standard error itself failed.
        .log_internal_errors(false)
        .init();
    let runtime = match tokio::runtime::Runtime::new() {
        Ok(rt) => rt,
        Err(e) => {
            cmd::out::tell(format_args!("laparo: cannot start the async runtime: {e}"));
            return ExitCode::from(1);
        }
    };
    let result = runtime.block_on(async {
        match cli.command {
            Command::Demo(args) => cmd::demo::run(args).await,
            Command::Station(args) => cmd::station::run(args).await,
            Command::Observe(args) => cmd::observe::run(args).await,
            Command::Load(args) => cmd::load::run(args).await,
            Command::Replay(args) => cmd::replay::run(args).await,
            Command::Recordings(command) => cmd::recordings::run(command).await,
            Command::Sessions(command) => cmd::sessions::run(command).await,
            Command::Resim(args) => cmd::resim::run(args),
        }
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // The error may quote a path, a name or a server's text: `tell` escapes it.
            cmd::out::tell(format_args!("laparo: {e}"));
            ExitCode::from(1)
        }
    }
}
