//! The memory a build may use: [`GridOptions::max_bytes`](super::GridOptions::max_bytes) (or
//! another structure's own option, [`Budget::with_knobs`]) and the memory available on the
//! machine. Builds reserve what they are about to allocate (the structure and its
//! temporaries) before allocating it, so a structure that would not fit ends in an error
//! naming its size and the limit, never in an allocation abort.

use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Error, Result};
use crate::limits::available_memory;
use crate::util::human_bytes;

/// Most references a grid holds: cell ranges are u32 offsets.
pub(crate) const MAX_REFS: u64 = u32::MAX as u64;

/// A memory limit shared by the parts of one build (parallel ones included).
#[derive(Debug)]
pub(crate) struct Budget {
    /// The structure being built, for messages ("a uniform grid of 64×64×64 cells").
    what: String,
    /// Bytes the build may reserve.
    limit: u64,
    /// Where the limit comes from, for messages.
    source: &'static str,
    /// The option that sets the limit, and what to change instead, for messages.
    option: &'static str,
    hint: &'static str,
    /// Bytes reserved so far.
    used: AtomicU64,
}

impl Budget {
    /// The limit for one grid build: `max_bytes` or the available memory, the smaller.
    pub fn new(what: String, max_bytes: Option<u64>) -> Budget {
        Budget::with_knobs(
            what,
            max_bytes,
            "GridOptions::max_bytes",
            "lower the grid's density or its max_cells / max_resolution",
        )
    }

    /// The limit for one build of any structure: `max_bytes` (the option named `option`) or
    /// the available memory, the smaller; `hint` says what to lower instead.
    pub fn with_knobs(
        what: String,
        max_bytes: Option<u64>,
        option: &'static str,
        hint: &'static str,
    ) -> Budget {
        let avail = available_memory();
        let (limit, source) = match (max_bytes, avail) {
            (Some(m), Some(a)) if a < m => (a, "the memory available"),
            (Some(m), _) => (m, option),
            (None, Some(a)) => (a, "the memory available"),
            (None, None) => (u64::MAX, "the address space"),
        };
        Budget {
            what,
            limit,
            source,
            option,
            hint,
            used: AtomicU64::new(0),
        }
    }

    /// Bytes not yet reserved.
    pub fn left(&self) -> u64 {
        self.limit.saturating_sub(self.used.load(Ordering::Relaxed))
    }

    /// Reserves `bytes`, or refuses (reserving nothing) when they do not fit.
    pub fn reserve(&self, bytes: u128) -> Result<()> {
        let b = u64::try_from(bytes).unwrap_or(u64::MAX);
        let mut used = self.used.load(Ordering::Relaxed);
        loop {
            let total = used.saturating_add(b);
            if total > self.limit {
                return Err(self.too_big(used as u128 + bytes));
            }
            match self
                .used
                .compare_exchange_weak(used, total, Ordering::Relaxed, Ordering::Relaxed)
            {
                Ok(_) => return Ok(()),
                Err(u) => used = u,
            }
        }
    }

    /// The error for a build that needs at least `bytes`.
    pub fn too_big(&self, bytes: u128) -> Error {
        let need = u64::try_from(bytes).map_or("more than 16 EiB".into(), human_bytes);
        Error::Usage(format!(
            "{} needs at least {need} of memory, over the limit of {} ({}): {}, or raise {}",
            self.what,
            human_bytes(self.limit),
            self.source,
            self.hint,
            self.option,
        ))
    }

    /// The error for a build whose references pass the u32 offsets of its cells.
    pub fn too_many_refs(&self, refs: u64) -> Error {
        Error::Usage(format!(
            "{} needs more than {refs} triangle references, over the limit of {MAX_REFS} \
             (u32 cell offsets): {}",
            self.what, self.hint
        ))
    }
}
