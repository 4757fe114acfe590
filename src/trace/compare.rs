//! Two tracers' answers for the same rays, side by side: the CPU twin against the GPU kernel
//! (`lancer check`, `tests/gpu_vs_cpu.rs`). Where the answers differ, the f64 oracle says
//! whether both are right (a genuine tie) or one is wrong.

use rayon::prelude::*;

use super::oracle::{judge, judge_any, Verdict};
use crate::accel::Query;
use crate::geometry::{Hit, Ray};
use crate::mesh::Mesh;

/// Largest difference in t, in units in the last place, still counted as agreement where
/// both answers name the same triangle (the GPU may fuse a multiply-add the CPU rounds twice).
pub const T_ULPS: u32 = 2;

/// One ray on which the two answers differ and the oracle finds one of them wrong.
#[derive(Clone, Debug, PartialEq)]
pub struct Disagreement {
    /// Index of the ray.
    pub ray: usize,
    /// The reference answer (the CPU twin's).
    pub reference: Hit,
    /// The other answer (the GPU's).
    pub other: Hit,
    /// What the oracle found wrong.
    pub why: String,
}

/// How two sets of answers compare.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Comparison {
    /// Rays answered bit for bit the same (t, triangle, u, v).
    pub identical: usize,
    /// Rays answered with the same triangle and t within [`T_ULPS`] (`identical` included;
    /// for [`compare_hits_independent`], any t the oracle accepts).
    pub agree: usize,
    /// Rays answered differently where the oracle names a genuine tie (both are right).
    pub ties: usize,
    /// Every other ray.
    pub disagree: Vec<Disagreement>,
}

fn ulps(a: f32, b: f32) -> u32 {
    (a.to_bits() as i64 - b.to_bits() as i64)
        .unsigned_abs()
        .min(u32::MAX as u64) as u32
}

fn bits(h: &Hit) -> [u32; 4] {
    [h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()]
}

/// Compares `other` with `reference`, the answers to `query` for `rays` on `mesh`.
/// Slices of different lengths compare up to the shorter.
pub fn compare_hits(
    mesh: &Mesh,
    rays: &[Ray],
    query: Query,
    reference: &[Hit],
    other: &[Hit],
) -> Comparison {
    compare(mesh, rays, query, reference, other, T_ULPS, false)
}

/// Like [`compare_hits`] for an independent tracer whose t comes from other arithmetic (the
/// driver's ray queries): the same triangle at a t more than [`T_ULPS`] away still agrees
/// when the oracle accepts that t.
pub fn compare_hits_independent(
    mesh: &Mesh,
    rays: &[Ray],
    query: Query,
    reference: &[Hit],
    other: &[Hit],
) -> Comparison {
    compare(mesh, rays, query, reference, other, T_ULPS, true)
}

/// Like [`compare_hits_independent`] with `t_ulps` for [`T_ULPS`]: the comparison `lancer
/// compare --mesh --rays` makes of a kernel of one's own (another triangle test gives a t a
/// few ulps away, which the oracle's error bound accepts).
pub fn compare_hits_judged(
    mesh: &Mesh,
    rays: &[Ray],
    query: Query,
    reference: &[Hit],
    other: &[Hit],
    t_ulps: u32,
) -> Comparison {
    compare(mesh, rays, query, reference, other, t_ulps, true)
}

fn compare(
    mesh: &Mesh,
    rays: &[Ray],
    query: Query,
    reference: &[Hit],
    other: &[Hit],
    t_ulps: u32,
    judge_same_triangle: bool,
) -> Comparison {
    enum One {
        Identical,
        Agree,
        Tie,
        Wrong(String),
    }
    let one = |r: &Ray, a: &Hit, b: &Hit| {
        if bits(a) == bits(b) {
            return One::Identical;
        }
        let judge_one = |h: &Hit| match query {
            Query::Closest => judge(mesh, r, h),
            Query::Any => judge_any(mesh, r, h),
        };
        if a.prim == b.prim {
            if !a.is_hit() || ulps(a.t, b.t) <= t_ulps {
                return One::Agree;
            }
            let why = format!("t {} vs {} ({} ulp)", a.t, b.t, ulps(a.t, b.t));
            if !judge_same_triangle {
                return One::Wrong(why);
            }
            return match judge_one(b) {
                Verdict::Wrong(w) => One::Wrong(format!("{why}: {w}")),
                _ => One::Agree,
            };
        }
        match (judge_one(a), judge_one(b)) {
            (Verdict::Wrong(w), _) => One::Wrong(format!("the reference is wrong: {w}")),
            (_, Verdict::Wrong(w)) => One::Wrong(w),
            _ => One::Tie,
        }
    };
    let verdicts: Vec<One> = rays
        .par_iter()
        .zip(reference)
        .zip(other)
        .map(|((r, a), b)| one(r, a, b))
        .collect();
    let mut c = Comparison::default();
    for (i, v) in verdicts.into_iter().enumerate() {
        match v {
            One::Identical => {
                c.identical += 1;
                c.agree += 1;
            }
            One::Agree => c.agree += 1,
            One::Tie => c.ties += 1,
            One::Wrong(why) => c.disagree.push(Disagreement {
                ray: i,
                reference: reference[i],
                other: other[i],
                why,
            }),
        }
    }
    c
}

/// How two hit files' answers compare without the oracle: identity, and the same triangle
/// at a t within a number of ulps (`lancer compare` without `--mesh` and `--rays`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HitCounts {
    /// Answers compared.
    pub rays: usize,
    /// Answers equal bit for bit (t, triangle, u, v).
    pub identical: usize,
    /// Answers on the same triangle with t within the ulps given (identical ones and
    /// misses on both sides included).
    pub agree: usize,
}

impl HitCounts {
    /// Answers that do not agree.
    pub fn differ(&self) -> usize {
        self.rays - self.agree
    }
}

/// Counts how `other` compares with `reference` without judging: identical answers, and
/// those naming the same triangle (or both a miss) at a t at most `t_ulps` apart. Slices of
/// different lengths compare up to the shorter.
pub fn count_agreement(reference: &[Hit], other: &[Hit], t_ulps: u32) -> HitCounts {
    let pairs = || reference.iter().zip(other);
    HitCounts {
        rays: pairs().count(),
        identical: pairs().filter(|(a, b)| bits(a) == bits(b)).count(),
        agree: pairs()
            .filter(|(a, b)| a.prim == b.prim && (!a.is_hit() || ulps(a.t, b.t) <= t_ulps))
            .count(),
    }
}

/// `compare --json` on two hit files: one object a run.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct HitsReport {
    /// "hits".
    pub kind: &'static str,
    /// Answers compared.
    pub rays: usize,
    /// Answers equal bit for bit.
    pub identical: usize,
    /// Same triangle, t within --t-ulps (with the oracle: or at a t it accepts); identical
    /// ones included.
    pub agree: usize,
    /// Different answers the f64 oracle finds both right (null without the oracle).
    pub genuine_ties: Option<usize>,
    /// Wrong answers (without the oracle: every answer that does not agree).
    pub disagree: usize,
    /// Whether the f64 oracle judged the differences.
    pub judged: bool,
}

impl HitsReport {
    /// The report of a comparison without the oracle.
    pub fn unjudged(c: &HitCounts) -> HitsReport {
        HitsReport {
            kind: "hits",
            rays: c.rays,
            identical: c.identical,
            agree: c.agree,
            genuine_ties: None,
            disagree: c.differ(),
            judged: false,
        }
    }

    /// The line `lancer compare` prints: the counts, and what agreement meant (`t_ulps`).
    pub fn summary(&self, t_ulps: u32) -> String {
        match self.genuine_ties {
            None => format!(
                "{} rays: {} identical, {} agree (same triangle, t within {t_ulps} ulp), {} \
                 differ (give --mesh and --rays to have the oracle judge them)",
                self.rays, self.identical, self.agree, self.disagree
            ),
            Some(ties) => format!(
                "{} rays: {} identical, {} agree (same triangle, t within {t_ulps} ulp or \
                 accepted by the f64 oracle), {ties} genuine ties (the oracle finds both right), \
                 {} disagree",
                self.rays, self.identical, self.agree, self.disagree
            ),
        }
    }

    /// The report of a comparison the oracle judged ([`compare_hits_judged`]) of `rays`
    /// answers.
    pub fn judged(rays: usize, c: &Comparison) -> HitsReport {
        HitsReport {
            kind: "hits",
            rays,
            identical: c.identical,
            agree: c.agree,
            genuine_ties: Some(c.ties),
            disagree: c.disagree.len(),
            judged: true,
        }
    }
}
