//! The lancer command line: parse, call the library, print.

mod cmd;

use std::io::Write;

use clap::Parser;

/// On a headless Linux machine with XDG_RUNTIME_DIR unset, the Wayland client library that
/// wgpu's Vulkan backend probes prints "error: XDG_RUNTIME_DIR is invalid or not set" (twice)
/// on every successful GPU run. lancer never opens a window: an absolute path where no
/// display socket exists makes that probe fail quietly instead. Set before any thread starts.
fn quiet_window_system_probe() {
    if cfg!(target_os = "linux")
        && std::env::var_os("XDG_RUNTIME_DIR").is_none()
        && std::env::var_os("WAYLAND_DISPLAY").is_none()
    {
        std::env::set_var(
            "XDG_RUNTIME_DIR",
            std::env::temp_dir().join("lancer-headless"),
        );
    }
}

/// Help and version go out as clap writes them; a usage error becomes one `error:` line
/// (clap's hint and usage lines folded away) and exit code 2.
fn usage_error(e: clap::Error) -> ! {
    use clap::error::ErrorKind;
    if matches!(
        e.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        e.exit();
    }
    let text = e.render().to_string();
    let parts: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with("Usage:") && !l.starts_with("For more"))
        .collect();
    eprintln!("{} (see --help)", parts.join(" "));
    std::process::exit(2);
}

/// mimalloc: the builders and flattening allocate big arrays and many small nodes, which the
/// system allocator hands back to the kernel and faults in again on every build. Counted,
/// so that `bench builders` can report each build's peak memory.
#[global_allocator]
static ALLOC: lancer::bench::memory::PeakAlloc<mimalloc::MiMalloc> =
    lancer::bench::memory::PeakAlloc(mimalloc::MiMalloc);

/// mimalloc's `mi_option_purge_delay` (its header's `mi_option_e`; libmimalloc-sys names
/// the options around it but not this one).
const MI_OPTION_PURGE_DELAY: libmimalloc_sys::mi_option_t = 15;

/// How long freed memory stays with mimalloc before it goes back to the system, in ms.
/// Its default, a second, spans a command's phases: the peak of one build, flatten and
/// upload would hold the build's freed memory and the upload's at once (4M triangles on
/// lavapipe: 936 MB against 740 MB). At 0 every phase faults in and zeroes fresh pages
/// (about a third slower there); 50 ms keeps what the next step takes at once.
const PURGE_DELAY_MS: std::ffi::c_long = 50;

/// mimalloc's `mi_option_arena_eager_commit` (its header's `mi_option_e`; libmimalloc-sys
/// names the options around it but not this one).
const MI_OPTION_ARENA_EAGER_COMMIT: libmimalloc_sys::mi_option_t = 4;

/// Commit arena memory as it is used, not a whole arena at once: the default (2: at once
/// where the OS overcommits) made a command's big allocations fault their pages in several
/// times slower, erratically (reading a 196 MB PLY: 300 to 1,090 ms; 375 to 407 ms
/// committed as used). Set before `main`, as the process loads: mimalloc reserves its first
/// arena at the first allocation, which the Rust runtime makes before `main`.
#[cfg(target_os = "linux")]
#[used]
#[unsafe(link_section = ".init_array")]
static COMMIT_ARENAS_AS_USED: extern "C" fn() = {
    extern "C" fn commit_arenas_as_used() {
        extern "C" {
            fn getenv(name: *const std::ffi::c_char) -> *const std::ffi::c_char;
        }
        // mimalloc's own variable still decides where it is set (read without allocating:
        // the first allocation would reserve the arena).
        // SAFETY: a NUL-terminated name; nothing else runs this early.
        if !unsafe { getenv(c"MIMALLOC_ARENA_EAGER_COMMIT".as_ptr()) }.is_null() {
            return;
        }
        // SAFETY: setting an option is allowed at any time.
        unsafe { libmimalloc_sys::mi_option_set(MI_OPTION_ARENA_EAGER_COMMIT, 0) };
    }
    commit_arenas_as_used
};

/// `bench builders` times builds and flattens on fresh memory (`bench::memory::fresh_memory`):
/// freed memory goes back at once while they run, then the delay it had before again.
fn fresh_memory_switch(on: bool) {
    use std::sync::atomic::{AtomicI64, Ordering};
    /// The delay before the switch went on, restored when it goes off.
    static BEFORE: AtomicI64 = AtomicI64::new(0);
    // SAFETY: reading and setting an option are allowed at any time.
    unsafe {
        if on {
            let delay = libmimalloc_sys::mi_option_get(MI_OPTION_PURGE_DELAY);
            BEFORE.store(delay as i64, Ordering::Relaxed);
            libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, 0);
        } else {
            let delay = BEFORE.load(Ordering::Relaxed) as std::ffi::c_long;
            libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, delay);
        }
    }
}

/// One-shot commands return freed memory soon (see [`PURGE_DELAY_MS`]); the benches keep
/// mimalloc's default (their repeated runs reuse those pages), except where they time on
/// fresh memory ([`fresh_memory_switch`]).
fn release_freed_memory_soon() {
    // SAFETY: setting an option is allowed at any time.
    unsafe { libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, PURGE_DELAY_MS) };
}

fn main() {
    quiet_window_system_probe();
    let cli = match cmd::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => usage_error(e),
    };
    cmd::set_quiet(cli.quiet);
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
    // The worker threads start now (rayon would otherwise start them at first use, and
    // panic there where the system refuses them).
    let pool = rayon::ThreadPoolBuilder::new().num_threads(cli.threads.into());
    if let Err(e) = pool.build_global() {
        match cli.threads {
            0 => eprintln!("error: cannot start the worker threads ({e}): try --threads 1"),
            n => eprintln!(
                "error: --threads {n}: cannot start that many threads ({e}): ask for fewer"
            ),
        }
        std::process::exit(2);
    }
    if !cli.is_bench() {
        release_freed_memory_soon();
    }
    lancer::bench::memory::set_fresh_memory_switch(fresh_memory_switch);
    cmd::interrupt::install();
    if let Err(e) = cmd::run(cli) {
        eprintln!("error: {e}");
        std::process::exit(e.exit_code());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Arenas are committed as used from before `main` (unless the environment says
    /// otherwise); mimalloc's default is 2.
    #[test]
    fn arenas_are_committed_as_used() {
        if std::env::var_os("MIMALLOC_ARENA_EAGER_COMMIT").is_some() {
            return;
        }
        // SAFETY: reading an option is allowed at any time.
        let eager = unsafe { libmimalloc_sys::mi_option_get(MI_OPTION_ARENA_EAGER_COMMIT) };
        assert_eq!(eager, 0);
    }

    /// The option number is mimalloc's purge delay: it holds that option's default, 1000 ms
    /// in the mimalloc 3 that libmimalloc-sys builds (unless the environment sets it).
    #[test]
    fn the_purge_delay_option_is_the_one_set() {
        if std::env::var_os("MIMALLOC_PURGE_DELAY").is_some() {
            return;
        }
        // SAFETY: reading an option is allowed at any time.
        let delay = unsafe { libmimalloc_sys::mi_option_get(MI_OPTION_PURGE_DELAY) };
        assert_eq!(delay, 1000);
    }
}
