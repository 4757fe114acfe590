//! The SAH collapse of a binary tree into a W-wide one (Ylitie, Karras & Laine 2017, §4.1),
//! which `bvh4` (four slots), `bvh8` and `cwbvh` (eight) decide their trees by. For every binary
//! node it decides whether it becomes a wide leaf, a wide internal node, or is spread over
//! its parent's slots. cost(n, i) is the cheapest way to hold n's subtree in at most i slots:
//!
//! ```text
//! cost(n, 1) = min(leaf: c_tri·A(n)·tris(n) if tris(n) ≤ max_leaf,  internal: c_node·A(n) + spread(n, W))
//! cost(n, i) = min(cost(n, i − 1), spread(n, i))            for i = 2..=W
//! spread(n, j) = min over 0 < k < j of cost(left, k) + cost(right, j − k)
//! ```
//!
//! A binary leaf is a wide leaf whatever its size. Every wide internal child is a strict
//! binary descendant, so the wide tree is never deeper than the binary one.

/// The binary tree the programme runs on, its nodes named by `Id`s that the plan's
/// decisions are indexed by.
pub(crate) trait BinaryTree {
    /// A node's name.
    type Id: Copy + Send + Sync;
    /// Node n's two children, none for a leaf.
    fn kids(&self, n: Self::Id) -> Option<[Self::Id; 2]>;
    /// Node n's place in the plan's decisions.
    fn index(&self, n: Self::Id) -> usize;
    /// Whether n's subtree is big enough to be written on several threads.
    fn big(&self, n: Self::Id) -> bool;
}

/// The programme's costs: of a wide node's visit and of a triangle test, and the most
/// triangles a wide leaf made of a binary inner node holds.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SahCosts {
    pub node: f32,
    pub tri: f32,
    pub max_leaf: u32,
}

/// The programme's decisions for one binary node, for W slots.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Entry<const W: usize> {
    /// cost(n, i + 1).
    cost: [f32; W],
    /// `[0]`: the left share k of spread(n, W) (an internal node's children); `[i − 1]`
    /// for i ≥ 2: the k of spread(n, i) when it beats cost(n, i − 1), else 0.
    split: [u8; W],
    /// Whether cost(n, 1) is the leaf's.
    leaf: bool,
    /// The wide nodes made within n's subtree when it is held in i + 1 slots (n's own
    /// included where it becomes a wide internal node).
    wide: [u32; W],
    /// The wide nodes of the wide subtree made from n as a wide internal node (the root
    /// is one whatever cost(n, 1) is).
    inner: u32,
}

impl<const W: usize> Entry<W> {
    /// The decisions for a node of this box area and triangle count, from its children's
    /// entries (none for a binary leaf).
    pub fn new(area: f32, n_tris: u32, kids: Option<[&Entry<W>; 2]>, costs: SahCosts) -> Self {
        let leaf_cost = costs.tri * area * n_tris as f32;
        let Some([l, r]) = kids else {
            return Entry {
                cost: [leaf_cost; W],
                split: [0; W],
                leaf: true,
                wide: [0; W],
                inner: 1,
            };
        };
        let (cl, cr) = (&l.cost, &r.cost);
        // spread(j) for every j at once, at index j − 1: the cheapest sum over the shares
        // k = 1, 2, … in turn, a later share kept only where strictly cheaper (the first
        // among equals). Without branches: which share wins is as good as random, and an
        // entry is made for every binary node. Where no sum is finite (a box whose area
        // overflows f32, built from triangles marked usable by hand) the first share is
        // kept: a node spread over j slots must give each side one, whatever the costs.
        let mut spread = [f32::INFINITY; W];
        let mut share = [1u8; W];
        if cl[0] == cl[W - 1] && cr[0] == cr[W - 1] {
            // Neither side's cost falls with more slots (leaves: about half the nodes where
            // the leaves hold one triangle each): every share sums to the same, the first
            // share's. (Neither side is NaN, which equals nothing, so neither is the sum.)
            spread = [cl[0] + cr[0]; W];
        } else {
            for k in 1..W {
                for j in k + 1..=W {
                    let c = cl[k - 1] + cr[j - k - 1];
                    let better = c < spread[j - 1];
                    spread[j - 1] = if better { c } else { spread[j - 1] };
                    share[j - 1] = if better { k as u8 } else { share[j - 1] };
                }
            }
        }
        // The wide nodes each spread makes: its two sides' at their shares.
        let made = |j: usize| {
            let k = share[j - 1] as usize;
            l.wide[k - 1] + r.wide[j - k - 1]
        };
        let mut cost = [0.0; W];
        let mut split = [0u8; W];
        let mut wide = [0u32; W];
        let internal = costs.node * area + spread[W - 1];
        let inner = 1 + made(W);
        let leaf = n_tris <= costs.max_leaf && leaf_cost <= internal;
        cost[0] = if leaf { leaf_cost } else { internal };
        split[0] = share[W - 1];
        wide[0] = if leaf { 0 } else { inner };
        for i in 2..=W {
            let better = spread[i - 1] < cost[i - 2];
            cost[i - 1] = if better { spread[i - 1] } else { cost[i - 2] };
            split[i - 1] = if better { share[i - 1] } else { 0 };
            wide[i - 1] = if better { made(i) } else { wide[i - 2] };
        }
        Entry {
            cost,
            split,
            leaf,
            wide,
            inner,
        }
    }

    /// What the wide tree is made from (the costs only serve the parent's entry).
    pub fn decision(&self) -> Decision<W> {
        let mut split = self.split;
        split[0] |= (self.leaf as u8) << LEAF_BIT;
        Decision {
            split,
            inner: self.inner,
        }
    }
}

/// The programme's decisions for one binary node, without the costs they were made from
/// (an [`Entry`]'s `split` and `inner`, and `leaf` as the `LEAF_BIT` of `split[0]`: twelve
/// bytes for eight slots, made for every binary node).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Decision<const W: usize> {
    split: [u8; W],
    inner: u32,
}

/// The bit of a decision's `split[0]` that holds `leaf` (a share is below W ≤ 8).
const LEAF_BIT: u32 = 7;

impl<const W: usize> Decision<W> {
    /// The share k of spread(n, i), or 0.
    fn split(&self, i: usize) -> usize {
        (self.split[i - 1] & !(1 << LEAF_BIT)) as usize
    }

    /// Whether cost(n, 1) is the leaf's.
    fn leaf(&self) -> bool {
        self.split[0] >> LEAF_BIT == 1
    }
}

// SAFETY: a byte array and a u32, for which all zeros is a valid value (an array of
// decisions written in full is allocated zeroed: `bytemuck::zeroed_vec`).
unsafe impl<const W: usize> bytemuck::Zeroable for Decision<W> {}

/// The programme's decisions for every binary node, for W slots.
pub(crate) struct Plan<const W: usize> {
    decisions: Vec<Decision<W>>,
}

impl<const W: usize> Plan<W> {
    /// A plan from every inner node's decisions, indexed by [`BinaryTree::index`] (a leaf's
    /// entry, where there is one, is never read).
    pub fn from_decisions(decisions: Vec<Decision<W>>) -> Plan<W> {
        Plan { decisions }
    }

    /// The children of the wide internal node made from `n`: (binary node, is a wide
    /// leaf), at most W. A binary leaf (a one-leaf tree) is its own only child.
    pub fn children<T: BinaryTree>(&self, tree: &T, n: T::Id) -> Children<T::Id, W> {
        let mut out = Children::new(n);
        match tree.kids(n) {
            None => out.push((n, true)),
            Some([l, r]) => {
                let k = self.decisions[tree.index(n)].split(1);
                self.collect(tree, l, k, &mut out);
                self.collect(tree, r, W - k, &mut out);
            }
        }
        out
    }

    /// The wide nodes of the wide subtree made from binary node `n` as a wide internal
    /// node (a wide internal child, or the root), its own included: where the writers split
    /// their output among the children. A binary leaf (a one-leaf tree's root) makes one.
    pub fn nodes<T: BinaryTree>(&self, tree: &T, n: T::Id) -> u32 {
        match tree.kids(n) {
            None => 1,
            Some(_) => self.decisions[tree.index(n)].inner,
        }
    }

    /// The at most `slots` subtrees that hold `n`'s subtree.
    /// A binary leaf is a wide leaf: its decision is not read (a tree may store none).
    fn collect<T: BinaryTree>(
        &self,
        tree: &T,
        n: T::Id,
        slots: usize,
        out: &mut Children<T::Id, W>,
    ) {
        let Some([l, r]) = tree.kids(n) else {
            out.push((n, true));
            return;
        };
        let decision = &self.decisions[tree.index(n)];
        let mut i = slots;
        while i > 1 && decision.split(i) == 0 {
            i -= 1;
        }
        if i == 1 {
            out.push((n, decision.leaf()));
            return;
        }
        let k = decision.split(i);
        self.collect(tree, l, k, out);
        self.collect(tree, r, i - k, out);
    }
}

/// A wide node's children as the plan gives them: (binary node, is a wide leaf), at most W,
/// held in place (a wide node is made for every few triangles: no allocation each).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Children<Id, const W: usize> {
    items: [(Id, bool); W],
    len: usize,
}

impl<Id: Copy, const W: usize> Children<Id, W> {
    /// None yet; `filler` only fills the unused places.
    fn new(filler: Id) -> Self {
        Children {
            items: [(filler, false); W],
            len: 0,
        }
    }

    /// Appends a child; the programme never spreads a node over more than W slots.
    fn push(&mut self, child: (Id, bool)) {
        self.items[self.len] = child;
        self.len += 1;
    }
}

impl<Id, const W: usize> std::ops::Deref for Children<Id, W> {
    type Target = [(Id, bool)];

    fn deref(&self) -> &[(Id, bool)] {
        &self.items[..self.len]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The programme's step as its formula reads, one spread at a time with a branch per
    /// sum: what `Entry::new` must give, bit for bit.
    fn reference<const W: usize>(
        area: f32,
        n_tris: u32,
        [l, r]: [&Entry<W>; 2],
        costs: SahCosts,
    ) -> ([f32; W], [u8; W], bool) {
        let spread = |j: usize| {
            let mut best = (f32::INFINITY, 1u8);
            for k in 1..j {
                let c = l.cost[k - 1] + r.cost[j - k - 1];
                if c < best.0 {
                    best = (c, k as u8);
                }
            }
            best
        };
        let leaf_cost = costs.tri * area * n_tris as f32;
        let (mut cost, mut split) = ([0.0; W], [0u8; W]);
        let (c_all, k_all) = spread(W);
        let internal = costs.node * area + c_all;
        let leaf = n_tris <= costs.max_leaf && leaf_cost <= internal;
        cost[0] = if leaf { leaf_cost } else { internal };
        split[0] = k_all;
        for i in 2..=W {
            let (c, k) = spread(i);
            if c < cost[i - 2] {
                (cost[i - 1], split[i - 1]) = (c, k);
            } else {
                cost[i - 1] = cost[i - 2];
            }
        }
        (cost, split, leaf)
    }

    /// A child's entry: costs that never rise with more slots, drawn from a few values
    /// (ties between shares), now and then all alike (a leaf), infinite or not a number.
    fn child<const W: usize>() -> impl Strategy<Value = Entry<W>> {
        let value = prop_oneof![
            4 => (0u32..6).prop_map(|v| v as f32 * 0.25),
            2 => 0.0f32..3.0,
            1 => Just(f32::INFINITY),
            1 => Just(f32::NAN),
        ];
        (prop::collection::vec(value, W), any::<bool>()).prop_map(|(mut c, flat)| {
            c.sort_by(|a, b| b.total_cmp(a));
            if flat {
                let first = c[0];
                c.fill(first);
            }
            Entry {
                cost: c.try_into().unwrap(),
                split: [0; W],
                leaf: flat,
                wide: [0; W],
                inner: 1,
            }
        })
    }

    fn same<const W: usize>(
        area: f32,
        n_tris: u32,
        l: &Entry<W>,
        r: &Entry<W>,
    ) -> Result<(), TestCaseError> {
        let costs = SahCosts {
            node: 1.0,
            tri: 0.3,
            max_leaf: 3,
        };
        let e = Entry::new(area, n_tris, Some([l, r]), costs);
        let (cost, split, leaf) = reference(area, n_tris, [l, r], costs);
        prop_assert_eq!(e.cost.map(f32::to_bits), cost.map(f32::to_bits));
        prop_assert_eq!(e.split, split);
        prop_assert_eq!(e.leaf, leaf);
        Ok(())
    }

    proptest! {
        /// Every sum, tie and infinity decided as the formula's plain reading decides it,
        /// for four and eight slots.
        #[test]
        fn entries_are_the_formulas(
            area in prop_oneof![0.0f32..4.0, Just(f32::INFINITY)],
            n_tris in 2u32..6,
            (l8, r8) in (child::<8>(), child::<8>()),
            (l4, r4) in (child::<4>(), child::<4>()),
        ) {
            same(area, n_tris, &l8, &r8)?;
            same(area, n_tris, &l4, &r4)?;
        }
    }
}
