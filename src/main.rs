//! The `meshtracer` binary: parse options, run, print the error chain once, exit non-zero.

use clap::Parser;
use meshtracer::cli::Cli;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = Cli::parse();
    match meshtracer::app::run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if e.is::<meshtracer::render::Cancelled>() {
                eprintln!("meshtracer: interrupted; no output written");
                return ExitCode::from(130);
            }
            if let Some(stopped) = e.downcast_ref::<meshtracer::app::Interrupted>() {
                eprintln!("meshtracer: {stopped}");
                return ExitCode::from(130);
            }
            eprintln!("meshtracer: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
