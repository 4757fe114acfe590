//! Peak heap memory of a piece of work: [`PeakAlloc`], a counting wrapper around the system
//! allocator that a program installs as its global allocator (the `lancer` binary does), and
//! [`peak_during`], which reads it. Exact bytes requested from the allocator, unlike the
//! process's resident set, which an allocator keeping freed pages hides; that too is here
//! ([`peak_resident`]), for what a whole command took.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicIsize, Ordering};

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
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
