//! The BIH's node: 16 bytes, one `vec4<u32>` texel for a GPU traversal, in depth-first
//! order (an inner node's left child is the next node).

/// Low two bits of [`BihNode::link`] equal to this mark a leaf; otherwise they are the axis.
pub const BIH_LEAF_TAG: u32 = 3;

/// [`BihNode::link`] holds the right child or first triangle shifted left by this.
pub const BIH_LINK_SHIFT: u32 = 2;

/// Largest node index or first-triangle position a [`BihNode::link`] can hold (30 bits).
pub const BIH_INDEX_MAX: u32 = u32::MAX >> BIH_LINK_SHIFT;

/// Bytes of one [`BihNode`].
pub const BIH_NODE_BYTES: usize = 16;

/// One node of a [`Bih`](super::Bih), 16 bytes.
///
/// Inner: `clip` = [the left child's maximum, the right child's minimum] on the axis;
/// `link` = right child index << 2 | axis (0 = x, 1 = y, 2 = z); the left child is the next
/// node; `count` = 0. A one-sided node (it cuts off empty space) has one child, the next
/// node, as both children: its right child index is its own + 1 and the plane of the
/// absent side is −f32::MAX (left) or f32::MAX (right).
/// Leaf: `clip` = [0, 0]; `link` = first triangle << 2 | [`BIH_LEAF_TAG`]; `count` = its
/// triangles (at least one, except the one empty leaf of an empty mesh).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BihNode {
    /// The two clip planes (inner nodes).
    pub clip: [f32; 2],
    /// Right child or first triangle, << 2, | axis or [`BIH_LEAF_TAG`].
    pub link: u32,
    /// Triangles of a leaf.
    pub count: u32,
}

const _: () = assert!(std::mem::size_of::<BihNode>() == BIH_NODE_BYTES);

impl BihNode {
    /// A leaf over `count` triangles from position `first`.
    pub(crate) fn leaf(first: u32, count: u32) -> BihNode {
        BihNode {
            clip: [0.0; 2],
            link: (first << BIH_LINK_SHIFT) | BIH_LEAF_TAG,
            count,
        }
    }

    /// An inner node splitting on `axis`: the left child ends at `left_max`, the right
    /// child (node `right`) starts at `right_min`.
    pub(crate) fn inner(axis: usize, left_max: f32, right_min: f32, right: u32) -> BihNode {
        BihNode {
            clip: [left_max, right_min],
            link: (right << BIH_LINK_SHIFT) | axis as u32,
            count: 0,
        }
    }

    /// A one-sided node cutting off empty space on `axis`: its only child, the next node
    /// (`child`), ends at `plane` (`keep_left`) or starts there. The absent side's plane is
    /// ∓f32::MAX, a side no ray reaches (ray intervals stay within ±2e12 of the origin's
    /// plane distances), and its link is the same child, so the walk needs no special case.
    pub(crate) fn one_sided(axis: usize, plane: f32, keep_left: bool, child: u32) -> BihNode {
        let clip = if keep_left {
            [plane, f32::MAX]
        } else {
            [-f32::MAX, plane]
        };
        BihNode {
            clip,
            link: (child << BIH_LINK_SHIFT) | axis as u32,
            count: 0,
        }
    }

    /// Whether this is a leaf.
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.link & 3 == BIH_LEAF_TAG
    }

    /// The split axis of an inner node.
    #[inline(always)]
    pub fn axis(&self) -> usize {
        (self.link & 3) as usize
    }

    /// The right child of an inner node, or the first triangle of a leaf.
    #[inline(always)]
    pub fn index(&self) -> usize {
        (self.link >> BIH_LINK_SHIFT) as usize
    }

    /// This node moved `by` places later in the array: its right child moves too.
    pub(crate) fn shifted(self, by: u32) -> BihNode {
        if self.is_leaf() {
            self
        } else {
            BihNode {
                link: self.link + (by << BIH_LINK_SHIFT),
                ..self
            }
        }
    }
}
