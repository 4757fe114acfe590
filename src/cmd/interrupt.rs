//! Ctrl-C (and SIGTERM, SIGHUP) for every command. A command that can save what it has done
//! so far (`render`) asks to be told ([`tell`]): the signal only raises its flag, and it saves
//! and exits with 130. Any other command ends at once with exit code 130, its outputs as they
//! were: the temporary files it was writing are removed first.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

/// The flag of the command that saves on an interrupt, once it has asked.
static TOLD: Mutex<Option<Arc<AtomicBool>>> = Mutex::new(None);

/// Takes the signals for the rest of the run (before any command starts).
pub fn install() {
    if let Err(e) = ctrlc::set_handler(interrupted) {
        log::warn!(
            "Ctrl-C: cannot take the signal ({e}); an interrupted run may leave temporary files"
        );
    }
}

/// From now on an interrupt raises `flag` instead of ending the run.
pub fn tell(flag: Arc<AtomicBool>) {
    *TOLD.lock().unwrap_or_else(|e| e.into_inner()) = Some(flag);
}

/// The handler (on a thread of its own, not in the signal's context).
fn interrupted() {
    if let Some(flag) = TOLD.lock().unwrap_or_else(|e| e.into_inner()).as_ref() {
        flag.store(true, Ordering::SeqCst);
        return;
    }
    let removed = lancer::output::remove_temporaries();
    let unfinished = match removed {
        0 => String::new(),
        n => format!(
            " ({n} unfinished output file{} removed)",
            if n == 1 { "" } else { "s" }
        ),
    };
    eprintln!("interrupted: nothing saved{unfinished}");
    std::process::exit(130);
}
