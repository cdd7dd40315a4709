//! The `radiosity` command line; see `radiosity --help` and the README's "Command line".

use clap::Parser;

fn main() {
    let cli = radiosity::cli::Cli::parse();
    if let Err(e) = radiosity::cli::run(cli) {
        // One line naming the file and the problem (the error chain joined by ": ").
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
