//! How the benches time: medians of repeated runs, and runs paired with a reference
//! tracer's (Embree 3) right after each, so that a slow or fast minute of the machine moves
//! both sides of a ratio.

use crate::accel::Query;
use crate::error::Result;
use crate::geometry::Ray;
use crate::trace::Tracer;

use super::Ticker;

/// The median: the middle value, or the mean of the two middle ones (NaN when empty, or
/// when a middle value is NaN).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// The smallest and the largest value (∞ and 0 when empty).
pub fn min_max(v: &[f64]) -> (f64, f64) {
    (
        v.iter().copied().fold(f64::INFINITY, f64::min),
        v.iter().copied().fold(0.0, f64::max),
    )
}

/// Million rays per second: `rays` traced in `seconds`.
pub fn mrays(rays: usize, seconds: f64) -> f64 {
    rays as f64 / seconds / 1e6
}

/// Wall seconds of one run of a tracer on these rays.
pub type TimeRun = Box<dyn Fn(&[Ray], Query) -> f64>;

/// The reference tracer every timed run is paired with (Embree 3, the `embree` feature).
pub struct Reference {
    /// One timed run.
    pub time: TimeRun,
    /// Wall time of its scene build.
    pub build_ms: f64,
    /// Its version ("3.13.5").
    pub version: String,
}

/// The runs of one row: seconds of each timed run of the measured tracer and of the
/// reference right after it (empty without one).
#[derive(Clone, Debug, Default)]
pub struct Paired {
    /// Seconds of each timed run.
    pub runs: Vec<f64>,
    /// Seconds of the reference's run right after each (empty without a reference).
    pub reference: Vec<f64>,
}

impl Paired {
    /// Mrays/s of the measured tracer on `n` rays: the median run.
    pub fn mrays(&self, n: usize) -> f64 {
        mrays(n, median(self.runs.clone()))
    }

    /// The median of the paired ratios of rays/s (reference seconds ÷ measured seconds),
    /// where there is a reference.
    pub fn ratio(&self) -> Option<f64> {
        (!self.reference.is_empty()).then(|| {
            median(
                (self.runs.iter().zip(&self.reference))
                    .map(|(t, r)| r / t)
                    .collect(),
            )
        })
    }
}

/// Runs a timed repetition takes: the measured one, and the reference's beside it.
pub(crate) fn runs_per_repeat(reference: Option<&Reference>) -> usize {
    1 + reference.is_some() as usize
}

/// `repeat` timed runs (`run` gives one's seconds), each followed by a timed run of the
/// reference on the same rays. Each timed run comes right after an untimed run of the same
/// tracer on the same rays (the first also compiles a GPU kernel), so that both sides of a
/// pair run with their own data in the caches: without it, Embree timed right after
/// lavapipe ran up to 4% slower than right after a CPU twin on the bunny's primary rays.
pub(crate) fn time_paired(
    mut run: impl FnMut() -> Result<f64>,
    reference: Option<&Reference>,
    rays: &[Ray],
    query: Query,
    repeat: usize,
    ticker: &Ticker,
) -> Result<Paired> {
    let mut paired = Paired::default();
    for _ in 0..repeat {
        run()?;
        paired.runs.push(run()?);
        ticker.inc(1);
        if let Some(r) = reference {
            (r.time)(rays, query);
            paired.reference.push((r.time)(rays, query));
            ticker.inc(1);
        }
    }
    Ok(paired)
}

/// Seconds of one run of `tracer`: GPU time where the adapter reports it, else wall time.
pub(crate) fn seconds(tracer: &mut Tracer, rays: &[Ray], query: Query) -> Result<f64> {
    let t = tracer.trace(rays, query)?.timings;
    Ok(t.gpu_ms.unwrap_or(t.wall_ms) * 1e-3)
}

/// [`time_paired`] for a tracer, its statistics off while timed.
pub(crate) fn time_tracer(
    tracer: &mut Tracer,
    reference: Option<&Reference>,
    rays: &[Ray],
    query: Query,
    repeat: usize,
    ticker: &Ticker,
) -> Result<Paired> {
    let o = *tracer.options();
    tracer.set_kernel(o.robustness, o.workgroup_size, false);
    let paired = time_paired(
        || seconds(tracer, rays, query),
        reference,
        rays,
        query,
        repeat,
        ticker,
    );
    tracer.set_kernel(o.robustness, o.workgroup_size, o.stats);
    paired
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_even_and_empty() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!(median(Vec::new()).is_nan());
    }

    #[test]
    fn paired_ratio_is_the_median_of_the_pairs() {
        let p = Paired {
            runs: vec![1.0, 2.0, 4.0],
            reference: vec![2.0, 2.0, 2.0],
        };
        assert_eq!(p.ratio(), Some(1.0));
        assert_eq!(p.mrays(2_000_000), 1.0);
        assert_eq!(Paired::default().ratio(), None);
    }
}
