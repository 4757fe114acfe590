//! Small helpers every module may use: formatting for messages, big zeroed arrays.

/// A size for people: bytes, KiB, MiB or GiB.
pub fn human_bytes(bytes: u64) -> String {
    match bytes {
        b if b >= 1 << 30 => format!("{:.1} GiB", b as f64 / 1073741824.0),
        b if b >= 1 << 20 => format!("{:.1} MiB", b as f64 / 1048576.0),
        b if b >= 1 << 10 => format!("{:.1} KiB", b as f64 / 1024.0),
        b => format!("{b} bytes"),
    }
}

/// `len` zeroed values, written on all threads: the arrays a flatten fills in full. A
/// big allocation is mostly memory the process freed before (the builder's), which a
/// zeroed allocation clears on one thread; here each thread clears its share.
pub(crate) fn zeroed_on_all_threads<T: bytemuck::Zeroable + Copy + Send + Sync>(
    len: usize,
) -> Vec<T> {
    zeroed_on_all_threads_in(len, len)
}

/// [`zeroed_on_all_threads`] in a vector of `capacity` (at least `len`).
pub(crate) fn zeroed_on_all_threads_in<T: bytemuck::Zeroable + Copy + Send + Sync>(
    len: usize,
    capacity: usize,
) -> Vec<T> {
    use rayon::prelude::*;
    let mut v = Vec::with_capacity(capacity.max(len));
    v.par_extend(rayon::iter::repeat_n(T::zeroed(), len));
    v
}
