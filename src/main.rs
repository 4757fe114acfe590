//! The lancer command line: parse, call the library, print.

mod cmd;

use clap::Parser;

// Builders allocate a node (and bins) at a time from several threads and free whole trees
// at once: mimalloc does both faster than the system allocator.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    let cli = cmd::Cli::parse();
    if let Err(e) = cmd::run(cli) {
        eprintln!("error: {e}");
        std::process::exit(e.exit_code());
    }
}
