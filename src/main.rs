//! The lancer command line: parse, call the library, print.

mod cmd;

use std::io::Write;

use clap::Parser;

fn main() {
    let cli = cmd::Cli::parse();
    let level = match (cli.quiet, cli.verbose) {
        (true, _) => log::LevelFilter::Error,
        (false, 0) => log::LevelFilter::Warn,
        (false, 1) => log::LevelFilter::Info,
        _ => log::LevelFilter::Debug,
    };
    // The library logs; people read "warning: …" lines on stderr. Other crates (wgpu,
    // naga) only speak from -v on.
    let others = if cli.verbose > 0 {
        level
    } else {
        log::LevelFilter::Error
    };
    env_logger::Builder::new()
        .filter_level(others)
        .filter_module("lancer", level)
        .format(|f, r| {
            let kind = match r.level() {
                log::Level::Error => "error",
                log::Level::Warn => "warning",
                log::Level::Info => "info",
                _ => "debug",
            };
            writeln!(f, "{kind}: {}", r.args())
        })
        .init();
    if let Err(e) = cmd::run(cli) {
        eprintln!("error: {e}");
        std::process::exit(e.exit_code());
    }
}
