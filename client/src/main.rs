//! `laparo`: the client command line.

use clap::Parser;

/// laparo client: stations, force loop, observer, replay and demo.
///
/// No subcommand is available yet: the station, observe, replay and demo commands
/// arrive with the server and recording work. Until then, run the simulation
/// headless with `laparo-server run`.
#[derive(Parser, Debug)]
#[command(name = "laparo", version, about)]
struct Cli {}

fn main() {
    let _cli = Cli::parse();
    eprintln!(
        "laparo: no client command yet; run the simulation headless with `laparo-server run`"
    );
    std::process::exit(2);
}
