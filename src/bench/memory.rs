//! Peak heap memory of a piece of work: [`PeakAlloc`], a counting wrapper around the system
//! allocator that a program installs as its global allocator (the `lancer` binary does), and
//! [`peak_during`], which reads it. Exact bytes requested from the allocator, unlike the
//! process's resident set, which an allocator keeping freed pages hides; that too is here
//! ([`peak_resident`]), for what a whole command took. And [`fresh_memory`], which times
//! work on memory fresh from the system, where the program says how to get it.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicIsize, Ordering};
use std::sync::OnceLock;

/// Bytes allocated minus bytes freed since [`peak_during`] started (counted only then).
static NET: AtomicIsize = AtomicIsize::new(0);
static PEAK: AtomicIsize = AtomicIsize::new(0);
static COUNTING: AtomicBool = AtomicBool::new(false);

/// An allocator (the system's by default) counting bytes allocated and freed inside
/// [`peak_during`]. Install it with `#[global_allocator] static ALLOC: PeakAlloc =
/// PeakAlloc(std::alloc::System);` to make [`peak_during`] measure. Outside it, the cost is
/// one relaxed load of a flag that never changes there (no shared cache line is written).
pub struct PeakAlloc<A = System>(pub A);

// SAFETY: every call is passed on unchanged to the inner allocator; the counters only
// observe.
unsafe impl<A: GlobalAlloc> GlobalAlloc for PeakAlloc<A> {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = self.0.alloc(layout);
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = self.0.alloc_zeroed(layout);
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        self.0.dealloc(ptr, layout);
        shrank(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = self.0.realloc(ptr, layout, new_size);
        if !p.is_null() {
            shrank(layout.size());
            grew(new_size);
        }
        p
    }
}

#[inline]
fn grew(bytes: usize) {
    if COUNTING.load(Ordering::Relaxed) {
        let net = NET.fetch_add(bytes as isize, Ordering::Relaxed) + bytes as isize;
        PEAK.fetch_max(net, Ordering::Relaxed);
    }
}

#[inline]
fn shrank(bytes: usize) {
    if COUNTING.load(Ordering::Relaxed) {
        NET.fetch_sub(bytes as isize, Ordering::Relaxed);
    }
}

/// Runs `work` and returns its result with the most heap bytes it held at once beyond what
/// was live when it started (what it returns included; memory it frees that was allocated
/// before counts against it), or None when [`PeakAlloc`] is not
/// the global allocator. Other threads' allocations meanwhile count too: measure alone.
pub fn peak_during<T>(work: impl FnOnce() -> T) -> (T, Option<u64>) {
    NET.store(0, Ordering::Relaxed);
    PEAK.store(0, Ordering::Relaxed);
    COUNTING.store(true, Ordering::Relaxed);
    // A probe allocation tells whether the counter is the global allocator.
    drop(std::hint::black_box(Box::new(0u64)));
    let installed = PEAK.swap(0, Ordering::Relaxed) > 0;
    let out = work();
    COUNTING.store(false, Ordering::Relaxed);
    let peak = PEAK.load(Ordering::Relaxed).max(0) as u64;
    (out, installed.then_some(peak))
}

/// The most memory this process has held resident so far (Linux's `VmHWM`): everything it
/// allocated and touched, the allocator's retained pages, and a software GPU's buffers
/// included. None where the system does not say.
pub fn peak_resident() -> Option<u64> {
    status_bytes("VmHWM:")
}

/// The memory this process holds resident now (Linux's `VmRSS`); None where the system
/// does not say.
pub fn resident() -> Option<u64> {
    status_bytes("VmRSS:")
}

/// A size in `/proc/self/status` (given there in KiB), in bytes.
fn status_bytes(key: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(key))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Starts [`peak_resident`]'s count anew from what the process holds now (Linux: writing
/// 5 to `/proc/self/clear_refs`); false where the system does not allow it, and the peak
/// then still counts from the process's start.
pub fn reset_peak_resident() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// The program's switch for its allocator: on, freed memory goes back to the system at
/// once; off, as the allocator does by default. Set by [`set_fresh_memory_switch`].
static FRESH_MEMORY_SWITCH: OnceLock<fn(bool)> = OnceLock::new();

/// Tells [`fresh_memory`] how to make the program's allocator hand freed memory back to
/// the system at once (`true`) and how to restore its default (`false`). The `lancer`
/// binary sets mimalloc's purge delay: its default keeps freed pages for a second, for
/// reuse. Only the first switch set counts.
pub fn set_fresh_memory_switch(switch: fn(bool)) {
    // A second call is ignored, as documented.
    let _ = FRESH_MEMORY_SWITCH.set(switch);
}

/// What the footnotes of benches that time builds in [`fresh_memory`] say of it.
pub const FRESH_MEMORY_NOTE: &str = "lancer's allocator hands freed memory back at once while \
    it times, as a command run once would find it; Embree allocates its own anew.";

/// Runs `work` with the allocator handing freed memory back to the system at once (where a
/// switch is set), so that what `work` allocates is faulted in fresh, as in a command run
/// once. Timed builds repeated in one process would otherwise reuse the pages the build
/// before freed, or not, depending on how long ago that was.
pub fn fresh_memory<T>(work: impl FnOnce() -> T) -> T {
    let switch = FRESH_MEMORY_SWITCH.get();
    if let Some(on) = switch {
        on(true);
    }
    let out = work();
    if let Some(on) = switch {
        on(false);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicU32;

    /// Whether the test's switch is on, and how many times it was turned.
    static ON: AtomicBool = AtomicBool::new(false);
    static TURNS: AtomicU32 = AtomicU32::new(0);

    fn switch(on: bool) {
        ON.store(on, Ordering::SeqCst);
        TURNS.fetch_add(1, Ordering::SeqCst);
    }

    #[test]
    fn fresh_memory_is_on_for_the_work_and_off_after() {
        set_fresh_memory_switch(switch);
        let inside = fresh_memory(|| ON.load(Ordering::SeqCst));
        assert!(inside, "the switch is on while the work runs");
        assert!(!ON.load(Ordering::SeqCst), "and off after it");
        assert_eq!(TURNS.load(Ordering::SeqCst), 2);
    }
}
