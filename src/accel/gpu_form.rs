//! A structure's GPU face: the arrays it uploads, the WGSL that walks them, and the CPU twin
//! that walks the same arrays in the same order ([`GpuForm`]). The BVH's flattened layouts
//! (`accel::bvh::layouts`), the kd-tree and the BIH implement it; the GPU tracer and renderer
//! take any `dyn GpuForm`.

use super::{Accel, LeafTri};

/// The byte arrays a GPU form uploads: nodes and leaf triangles, each a whole number of
/// 16-byte words (the GPU reads them as `vec4<u32>`).
#[derive(Clone, Copy, Debug)]
pub struct GpuArrays<'a> {
    /// The node array.
    pub nodes: &'a [u8],
    /// The triangles in leaf order ([`LeafTri`]s).
    pub tris: &'a [u8],
    /// Bytes allocated from the start of each array (see [`GpuArrays::room`]); set only
    /// where known true, so that safe code cannot make a device read past an allocation.
    room: [usize; 2],
}

impl<'a> GpuArrays<'a> {
    /// A node array and leaf triangles as bytes (the inverse of `records`), with no room
    /// past their ends.
    pub fn new(nodes: &'a [u8], tris: &'a [u8]) -> GpuArrays<'a> {
        GpuArrays {
            nodes,
            tris,
            room: [nodes.len(), tris.len()],
        }
    }

    /// The arrays of a node vector and a triangle vector, with the room their allocations
    /// have past their ends (their capacities).
    pub fn of<N: bytemuck::Pod>(nodes: &'a Vec<N>, tris: &'a Vec<LeafTri>) -> GpuArrays<'a> {
        GpuArrays {
            nodes: bytemuck::cast_slice(nodes),
            tris: bytemuck::cast_slice(tris),
            room: [
                nodes.capacity() * std::mem::size_of::<N>(),
                tris.capacity() * std::mem::size_of::<LeafTri>(),
            ],
        }
    }

    /// Bytes allocated from the start of the nodes and of the triangles (at least their
    /// lengths): a device whose memory is the host's reads an array in place only where
    /// the room holds what it maps (a texture's last rows, which a driver may pad).
    pub fn room(&self) -> [usize; 2] {
        self.room
    }
}

/// Elements to allocate for an array of `len` that a device may read in place: room for
/// [`ROOM_BYTES`] past its end where the array is at least [`ROOM_MIN_BYTES`] (a smaller
/// one is copied: the room would cost more than the copy saves).
pub(crate) fn capacity_for<T>(len: usize) -> usize {
    let size = std::mem::size_of::<T>().max(1);
    match len.saturating_mul(size) >= ROOM_MIN_BYTES {
        true => len + ROOM_BYTES.div_ceil(size),
        false => len,
    }
}

/// `len` zeroed values with room past them ([`capacity_for`]), cleared by the system
/// (fresh pages are zero; the room's are never written).
pub(crate) fn zeroed_with_room<T: bytemuck::Zeroable>(len: usize) -> Vec<T> {
    let mut v = bytemuck::zeroed_vec(capacity_for::<T>(len));
    v.truncate(len);
    v
}

/// `len` zeroed values with room past them ([`capacity_for`]), written on all threads
/// ([`zeroed_on_all_threads`](crate::util::zeroed_on_all_threads)).
pub(crate) fn zeroed_on_all_threads_with_room<T>(len: usize) -> Vec<T>
where
    T: bytemuck::Zeroable + Copy + Send + Sync,
{
    crate::util::zeroed_on_all_threads_in(len, capacity_for::<T>(len))
}

/// Bytes of room past a flattened array's end: eight 64 KiB texture rows (4096 16-byte
/// texels each), for the partial last row and the rows a driver pads a texture's height
/// with (llvmpipe: to a multiple of 4). The GPU side checks what the driver asks for. The
/// room is never written, so it costs address space rather than memory.
pub const ROOM_BYTES: usize = 8 << 16;

/// The smallest array the flattens allocate with [`ROOM_BYTES`] to spare (smaller ones are
/// copied to the device; a scene of many small meshes pays no room).
pub const ROOM_MIN_BYTES: usize = 1 << 20;

/// A structure's GPU form: its arrays (nodes and leaf triangles, in either BVH memory), its
/// WGSL traversal, and its CPU twin (the [`Accel`] supertrait), which walks the same arrays
/// in the same order as the WGSL. A flattened BVH ([`LayoutKind`](crate::LayoutKind)) or
/// another structure with a GPU kernel (the kd-tree, the BIH).
pub trait GpuForm: Accel {
    /// Its name, for messages, tests and benches (a BVH layout's
    /// [`LayoutKind::name`](crate::LayoutKind::name)).
    fn name(&self) -> &'static str;

    /// The arrays to upload.
    fn arrays(&self) -> GpuArrays<'_>;

    /// Its WGSL traversal (with its own constants generated in front): defines
    /// `traverse(r: Ray, any_hit: bool) -> Hit`.
    fn wgsl(&self) -> String;

    /// The depth of tree its WGSL's traversal stack is sized for ([`GpuForm::wgsl`] and
    /// [`GpuForm::subgroup_wgsl`] hold the walk of this tree and of any shallower one in the
    /// same layout); 0 where the stack does not depend on the tree. A two-level form takes
    /// the WGSL of its deepest bottom level.
    fn stack_depth(&self) -> usize {
        0
    }

    /// Its subgroup-coherent WGSL traversal ([`TraversalMode::Subgroup`]), if it has one:
    /// like [`GpuForm::wgsl`], `traverse(r: Ray, any_hit: bool) -> Hit`, but called by every
    /// invocation of a subgroup together (those past the end of the rays with an invalid
    /// ray), so it may use subgroup operations. Subgroups are whole (the workgroup is a
    /// multiple of the adapter's largest subgroup); a traversal that meets lanes it cannot
    /// use leaves `traversal_done` false and the host traces those rays again. Same hits as
    /// the per-ray traversal: closest hits bit for bit, any hits judged by the oracle.
    ///
    /// [`TraversalMode::Subgroup`]: crate::accel::TraversalMode::Subgroup
    fn subgroup_wgsl(&self) -> Option<String> {
        None
    }

    /// Whether its WGSL defines the kernels' `trace_ray(r: Ray, any_hit: bool) -> Hit` itself
    /// (a two-level form, walking its top level over the bottom level's `traverse`);
    /// otherwise the kernels' `trace_ray` is its `traverse`.
    fn defines_trace_ray(&self) -> bool {
        false
    }

    /// Override constants its WGSL declares, with their values for this instance.
    fn overrides(&self) -> Vec<(&'static str, f64)> {
        Vec::new()
    }

    /// Checks every invariant the traversal relies on: structure (indices in range, depth
    /// within the stack, every node reached once) and, for the BVH layouts, geometry
    /// (every box holds every triangle vertex below it, exactly in f32 on the boxes as the
    /// traversal reads them; the leaves refer to every triangle record once), so that the
    /// arrays trace right answers, not only safely. Run before trusted (unchecked) shader
    /// modules see the arrays; the error names the first bad node.
    fn validate(&self) -> Result<(), String>;

    /// Bytes of one node record: what a traversal loads per node it counts in
    /// [`RayStats::nodes`](crate::accel::RayStats), so nodes × this + triangles × 48 is the
    /// memory traffic of a ray.
    fn node_bytes(&self) -> usize;

    /// Bytes the GPU holds for this layout.
    fn bytes(&self) -> usize {
        let a = self.arrays();
        a.nodes.len() + a.tris.len()
    }

    /// Triangles referenced by leaves.
    fn triangles(&self) -> usize {
        self.arrays().tris.len() / std::mem::size_of::<LeafTri>()
    }
}

/// A layout's arrays as records of node type `N` and [`LeafTri`]s (copied: the bytes need
/// not be aligned); refused unless both are whole records.
pub(crate) fn records<N: bytemuck::Pod>(
    arrays: GpuArrays<'_>,
) -> Result<(Vec<N>, Vec<LeafTri>), String> {
    let whole = |what: &str, bytes: &[u8], size: usize| {
        if bytes.len().is_multiple_of(size) {
            Ok(())
        } else {
            Err(format!(
                "{what} array of {} bytes is not whole {size}-byte records",
                bytes.len()
            ))
        }
    };
    whole("node", arrays.nodes, std::mem::size_of::<N>())?;
    whole("triangle", arrays.tris, std::mem::size_of::<LeafTri>())?;
    Ok((
        bytemuck::pod_collect_to_vec(arrays.nodes),
        bytemuck::pod_collect_to_vec(arrays.tris),
    ))
}
