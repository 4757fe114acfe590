//! The LBVH built on the GPU: `accel/bvh/lbvh.wgsl`'s kernels over the triangles. Read back
//! as the [`RadixTree`] the CPU twin (`accel::bvh::lbvh::radix_tree`) makes, or flattened
//! there into the dfs-sign layout that `DfsSign::flatten` makes of the CPU's LBVH.

use std::time::Instant;

use super::parted_array::{self, Access, PartedArray, MAX_PARTS, PART_BINDINGS};
use super::plumbing::{
    dynamic_uniform_entry, output_buffer, scoped, uniform_binding, Kernel, Readback,
};
use super::shaders::{constants_wgsl, Shared};
use super::GpuContext;
use crate::accel::bvh::layouts::{DfsSign, DFS_LEAF_TAG};
use crate::accel::bvh::lbvh::{radix_tree, RadixTree, CODE_BITS, LEAF_BIT, MAX_PRIMS};
use crate::accel::bvh::{build_from_radix_tree, BuildOptions, Bvh, MAX_DEPTH};
use crate::accel::GpuArrays;
use crate::error::{Error, Result};
use crate::geometry::{Aabb, Triangle};
use crate::mesh::Mesh;
use crate::util::human_bytes;

/// The kernels' source.
const SOURCE: &str = include_str!("../accel/bvh/lbvh.wgsl");

/// Bits of the code a sort pass orders by.
pub const RADIX_BITS: u32 = 4;
/// Sort passes: every code bit, an even number so that the sorted pairs end where the codes
/// were written.
const SORT_PASSES: u32 = (3 * CODE_BITS).div_ceil(RADIX_BITS).next_multiple_of(2);
/// Pairs one sort thread counts and moves, in order.
pub const SORT_TILE: u32 = 256;
/// Threads per workgroup of every kernel but the scan (`WORKGROUP` in the WGSL).
const WORKGROUP: u32 = 64;
/// Most workgroups of the bounds kernel (each thread folds every 65,536th triangle).
const BOUNDS_GROUPS: u32 = 1024;
/// Storage buffers the widest kernel binds (`emit_tris`), each array in one part.
const STORAGE_BUFFERS: u32 = 7;

/// A storage array of the kernels (declared, with its accessors, in front of the WGSL).
const fn array(name: &'static str, ty: &'static str, access: Access, binding: u32) -> PartedArray {
    PartedArray {
        name,
        ty,
        access,
        binding,
    }
}

// The triangles' vertices, three floats each: v0[3i..3i+3] is triangle i's first.
const V0: PartedArray = array("v0", "f32", Access::Read, 1);
const V1: PartedArray = array("v1", "f32", Access::Read, 2);
const V2: PartedArray = array("v2", "f32", Access::Read, 3);
/// Bounds of the doubled centroids, ordered-encoded: [0..3) the low corner's complement,
/// [3..6) the high corner (both only ever raised, from zero).
const CENTRE_BOUNDS: PartedArray = array("centre_bounds", "u32", Access::Atomic, 4);
/// (code, primitive) pairs: a sort pass reads one array and writes the other.
const PAIRS_IN: PartedArray = array("pairs_in", "vec2<u32>", Access::Read, 5);
const PAIRS_OUT: PartedArray = array("pairs_out", "vec2<u32>", Access::ReadWrite, 6);
/// Digit counts of every tile, digit-major, then their exclusive prefix sums.
const TABLE: PartedArray = array("table", "u32", Access::ReadWrite, 7);
/// Children of each inner node (LEAF_BIT | place for a leaf).
const KIDS: PartedArray = array("kids", "vec2<u32>", Access::ReadWrite, 8);
/// Parent of inner node i at i, of primitive p at n - 1 + p.
const PARENTS: PartedArray = array("parents", "u32", Access::ReadWrite, 9);
/// Inner node boxes, ordered-encoded as in CENTRE_BOUNDS, six words a node.
const NODE_BOXES: PartedArray = array("node_boxes", "u32", Access::Atomic, 10);
/// For the flatten into dfs-sign: the box of the primitive at each place, six floats.
const PLACE_BOXES: PartedArray = array("place_boxes", "f32", Access::ReadWrite, 12);
/// Per inner node, bottom-up: (primitives, nodes of the flattened subtree, SAH cost times
/// area as bits, axis | swap << 2 | leaf << 3).
const INFO: PartedArray = array("info", "vec4<u32>", Access::ReadWrite, 13);
/// Each inner node's height (a node of two leaves: 1).
const HEIGHTS: PartedArray = array("node_height", "u32", Access::Atomic, 14);
/// Per inner node, top-down: (dfs-sign index, first place in leaf order, hidden: inside a
/// leaf, unused).
const DOWN: PartedArray = array("down", "vec4<u32>", Access::ReadWrite, 15);
/// The inner nodes grouped by height, lowest first.
const BY_HEIGHT: PartedArray = array("by_height", "u32", Access::ReadWrite, 16);
/// Inner nodes of each height, then where the next of each height goes in BY_HEIGHT.
const CURSOR: PartedArray = array("cursor", "u32", Access::Atomic, 11);
/// Per place: (position in leaf order, dfs-sign index of its own leaf or NO_NODE).
const PLACE_DOWN: PartedArray = array("place_down", "vec2<u32>", Access::ReadWrite, 17);
/// The dfs-sign arrays: 8 words a node (`DfsNode`), 12 a triangle (`LeafTri`).
const OUT_NODES: PartedArray = array("out_nodes", "u32", Access::ReadWrite, 18);
/// Mesh triangle index of each primitive.
const IDS: PartedArray = array("ids", "u32", Access::Read, 19);
const OUT_TRIS: PartedArray = array("out_tris", "u32", Access::ReadWrite, 20);

/// Every storage array the kernels declare.
const ARRAYS: [&PartedArray; 20] = [
    &V0,
    &V1,
    &V2,
    &CENTRE_BOUNDS,
    &PAIRS_IN,
    &PAIRS_OUT,
    &TABLE,
    &KIDS,
    &PARENTS,
    &NODE_BOXES,
    &PLACE_BOXES,
    &INFO,
    &HEIGHTS,
    &DOWN,
    &BY_HEIGHT,
    &CURSOR,
    &PLACE_DOWN,
    &OUT_NODES,
    &IDS,
    &OUT_TRIS,
];

/// The constants the kernels share with Rust.
fn constants() -> Vec<(&'static str, Shared)> {
    vec![
        ("CODE_BITS", Shared::U32(CODE_BITS)), // accel::bvh::lbvh::CODE_BITS
        ("LEAF_BIT", Shared::U32(LEAF_BIT)),   // accel::bvh::lbvh::LEAF_BIT
        ("RADIX_BITS", Shared::U32(RADIX_BITS)), // gpu::lbvh_build::RADIX_BITS
        ("SORT_TILE", Shared::U32(SORT_TILE)), // gpu::lbvh_build::SORT_TILE
        ("DFS_LEAF_TAG", Shared::U32(DFS_LEAF_TAG)), // layouts::dfs_sign::LEAF_TAG
        ("HEIGHT_LIMIT", Shared::U32(HEIGHT_LIMIT)), // gpu::lbvh_build::HEIGHT_LIMIT
    ]
}

/// The full WGSL module, every array in one binding (for naga checks).
pub fn lbvh_source() -> String {
    source_with(&|_| 1, 31)
}

/// The WGSL module with each array in `parts(array)` parts of 2^`byte_shift` bytes.
fn source_with(parts: &dyn Fn(&PartedArray) -> u32, byte_shift: u32) -> String {
    let mut s = constants_wgsl("gpu::lbvh_build::constants", &constants());
    for a in ARRAYS {
        s += &a.wgsl(parts(a), byte_shift);
    }
    s + "\n" + SOURCE
}

// Every array's bindings distinct, part 0's below the parts', the last part's below wgpu's
// 1,000 bindings a group.
const _: () = {
    let mut i = 0;
    while i < ARRAYS.len() {
        let a = ARRAYS[i];
        assert!(a.binding > 0 && a.binding < PART_BINDINGS);
        assert!(a.part_binding(MAX_PARTS - 1) < 1000);
        let mut j = i + 1;
        while j < ARRAYS.len() {
            assert!(ARRAYS[j].binding != a.binding);
            j += 1;
        }
        i += 1;
    }
};

/// An array of the kernels and the buffer it is bound to.
type Bound<'b> = (&'static PartedArray, &'b wgpu::Buffer);

/// Per-dispatch parameters (`Params` in the WGSL).
#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    n: u32,
    tiles: u32,
    shift: u32,
    max_leaf: u32,
    t_cube: f32,
    t_obj: f32,
    first: u32,
    count: u32,
    /// Always 0 (`rounded` in the WGSL).
    zero: u32,
    pad: [u32; 2],
}

const PARAMS: u64 = std::mem::size_of::<Params>() as u64;

/// Builds the LBVH of the mesh's included triangles on the GPU and makes it lancer's tree
/// on the CPU (with `opts`' leaf rule, depth cap and optimiser; `opts.builder` is not
/// read). Equal to [`build`](crate::accel::bvh::build) with
/// [`Builder::Lbvh`](crate::accel::bvh::Builder).
pub fn build_lbvh(ctx: &GpuContext, mesh: &Mesh, opts: &BuildOptions) -> Result<Bvh> {
    let ids = mesh.included();
    let tree = radix_tree_of(ctx, ids.len(), &|i| mesh.triangles[ids[i] as usize])?;
    let t = Instant::now();
    let bvh = build_from_radix_tree(mesh, &ids, tree, opts).map_err(|e| {
        Error::Gpu(format!(
            "the GPU's LBVH is invalid (a bug: please report it with the adapter): {e}"
        ))
    })?;
    log::info!("GPU LBVH: lancer's tree made on the CPU in {:.0} ms", ms(t));
    Ok(bvh)
}

/// The radix tree over these triangles, built on the GPU.
pub fn lbvh_radix_tree(ctx: &GpuContext, triangles: &[Triangle]) -> Result<RadixTree> {
    radix_tree_of(ctx, triangles.len(), &|i| triangles[i])
}

/// The radix tree over `n` triangles, `triangle(i)` each, built on the GPU.
fn radix_tree_of(
    ctx: &GpuContext,
    n: usize,
    triangle: &(dyn Fn(usize) -> Triangle + Sync),
) -> Result<RadixTree> {
    if n < 2 {
        // No inner node: nothing for the kernels to do.
        let boxes: Vec<Aabb> = (0..n).map(|i| triangle(i).bbox()).collect();
        return Ok(radix_tree(&boxes, false));
    }
    let run = Run::new(ctx, n, triangle)?;
    let mut enc = run.encoder();
    run.record_build(&mut enc)?;
    let (n, inner) = (run.n as u64, run.n as u64 - 1);
    let readback = Readback::record(
        ctx,
        &mut enc,
        &[
            (&run.pairs[0], 8 * n),
            (&run.kids, 8 * inner),
            (&run.node_boxes, 24 * inner),
        ],
    );
    run.finish_with(enc, readback, "building the LBVH on the GPU", |b| {
        let pairs: Vec<[u32; 2]> = bytemuck::pod_collect_to_vec(b[0]);
        let words: Vec<[u32; 6]> = bytemuck::pod_collect_to_vec(b[2]);
        RadixTree {
            sorted: pairs.iter().map(|p| p[1]).collect(),
            kids: bytemuck::pod_collect_to_vec(b[1]),
            boxes: words
                .iter()
                .map(|w| Aabb {
                    lo: glam::Vec3::new(unordered(!w[0]), unordered(!w[1]), unordered(!w[2])),
                    hi: glam::Vec3::new(unordered(w[3]), unordered(w[4]), unordered(w[5])),
                })
                .collect(),
        }
    })
}

/// The LBVH of the mesh's included triangles built and flattened into dfs-sign on the GPU,
/// read back and validated: equal to `DfsSign::flatten` of
/// [`build`](crate::accel::bvh::build) with `Builder::Lbvh`. Refused with `opts.optimize`
/// (the optimiser runs on the CPU: [`build_lbvh`] then flatten) or a depth cap below
/// [`MAX_DEPTH`].
pub fn lbvh_dfs_sign(ctx: &GpuContext, mesh: &Mesh, opts: &BuildOptions) -> Result<DfsSign> {
    if opts.optimize || opts.max_depth < MAX_DEPTH {
        return Err(Error::Usage(
            "the GPU flattens the LBVH without --optimize and at the full depth only".into(),
        ));
    }
    let ids = mesh.included();
    if ids.len() < 2 {
        let bvh = crate::accel::bvh::build(mesh, opts);
        return Ok(DfsSign::flatten(&bvh, mesh));
    }
    let (n, inner) = (ids.len() as u64, ids.len() as u64 - 1);
    for (array, what, bytes) in [
        (&PLACE_BOXES, "the GPU LBVH's place boxes", 24 * n),
        (&INFO, "the GPU LBVH's node summaries", 16 * inner),
        (&OUT_TRIS, "the GPU LBVH's leaf triangles", 48 * n),
    ] {
        array.check(ctx, what, bytes)?;
    }
    let run = Run::new(ctx, ids.len(), &|i| mesh.triangles[ids[i] as usize])?;
    let storage = wgpu::BufferUsages::STORAGE;
    let mesh_ids = ctx.buffer_with("lbvh mesh indices", bytemuck::cast_slice(&ids), storage);
    let place_boxes = output_buffer(ctx, "lbvh place boxes", 24 * n);
    let info = output_buffer(ctx, "lbvh node info", 16 * inner);
    let by_height = output_buffer(ctx, "lbvh nodes by height", 4 * inner);
    let cursor = output_buffer(ctx, "lbvh height cursor", 4 * HEIGHT_LIMIT as u64);
    let down = output_buffer(ctx, "lbvh node down", 16 * inner);
    let place_down = output_buffer(ctx, "lbvh place down", 8 * n);
    let (v0, v1, v2) = run.vertices();
    let sorted = (&PAIRS_IN, &run.pairs[0]);
    let kids = (&KIDS, &run.kids);
    let node_boxes = (&NODE_BOXES, &run.node_boxes);
    let (place_boxes, info, down, place_down) = (
        (&PLACE_BOXES, &place_boxes),
        (&INFO, &info),
        (&DOWN, &down),
        (&PLACE_DOWN, &place_down),
    );
    let (heights, by_height, cursor) = (
        (&HEIGHTS, &run.heights),
        (&BY_HEIGHT, &by_height),
        (&CURSOR, &cursor),
    );
    let base = Params {
        n: run.n,
        max_leaf: opts.max_leaf.clamp(1, u32::MAX as usize) as u32,
        t_cube: opts.t_cube,
        t_obj: opts.t_obj,
        ..Params::default()
    };
    let (base_params, _) = uniforms(ctx, &[base]);
    let bound = |entry, bound: &[Bound]| run.bound_kernel(entry, &base_params, bound);

    // 1. The tree (with each inner node's height), each place's box, how many nodes have
    //    each height.
    let mut enc = run.encoder();
    run.record_build(&mut enc)?;
    let all = run.shape(run.n);
    let (pl, gl) = bound("leaf_boxes", &[sorted, v0, v1, v2, place_boxes])?;
    dispatch(&mut enc, &pl, &gl, 0, all, 0);
    let (pk, gk) = bound("count_heights", &[heights, cursor])?;
    dispatch(&mut enc, &pk, &gk, 0, run.shape(run.n - 1), 0);
    let readback = Readback::record(ctx, &mut enc, &[(cursor.1, 4 * HEIGHT_LIMIT as u64)]);
    let counts: Vec<u32> = run.finish_with(enc, readback, "building the LBVH on the GPU", |b| {
        bytemuck::pod_collect_to_vec(b[0])
    })?;
    // The root is the one node of the greatest height; a radix tree over distinct 62-bit
    // keys is at most 62 levels deep, so no height reaches the last bucket (which the
    // kernels clamp to), and none is 0 (a leaf's).
    let top = counts.iter().rposition(|&c| c > 0).unwrap_or(0);
    let bad = counts.len() != HEIGHT_LIMIT as usize || counts[0] != 0 || counts[top] != 1;
    if bad || top + 1 >= counts.len() || top > MAX_DEPTH {
        return Err(Error::Gpu(format!(
            "the GPU LBVH's node heights are inconsistent (root height {top}; a bug: please \
             report it); build on the CPU"
        )));
    }
    // Where each height's nodes start; the uniforms of each height's pass.
    let mut starts = vec![0u32; HEIGHT_LIMIT as usize];
    for h in 1..HEIGHT_LIMIT as usize {
        starts[h] = starts[h - 1] + counts[h - 1];
    }
    ctx.queue
        .write_buffer(cursor.1, 0, bytemuck::cast_slice(&starts));
    let mut all_params = vec![base];
    all_params.extend((1..=top).map(|h| Params {
        first: starts[h],
        count: counts[h],
        ..base
    }));
    let (params, align) = uniforms(ctx, &all_params);

    // 2. The nodes by height; bottom-up, one height a pass, the SAH's leaves.
    let mut enc = run.encoder();
    let (pb, gb) = bound("by_heights", &[heights, cursor, by_height])?;
    dispatch(&mut enc, &pb, &gb, 0, run.shape(run.n - 1), 0);
    let (pc, gc) = run.bound_kernel(
        "costs",
        &params,
        &[by_height, kids, node_boxes, place_boxes, info],
    )?;
    // Pass h reads uniform h (its height's nodes).
    for (h, &count) in counts.iter().enumerate().take(top + 1).skip(1) {
        dispatch(&mut enc, &pc, &gc, h as u32, run.shape(count), align);
    }
    let readback = Readback::record(ctx, &mut enc, &[(info.1, 16)]);
    // The root's summary: (primitives, nodes of the flattened tree, …).
    let root: Vec<u32> = run.finish_with(enc, readback, "flattening the LBVH on the GPU", |b| {
        bytemuck::pod_collect_to_vec(b[0])
    })?;
    let nodes = root.get(1).copied().unwrap_or(0) as u64;
    OUT_NODES.check(ctx, "the GPU LBVH's dfs-sign nodes", 32 * nodes)?;

    // 3. Top-down from the root's height: indices and leaf-order places; then the records.
    let out_nodes = output_buffer(ctx, "lbvh dfs-sign nodes", 32 * nodes);
    let out_tris = output_buffer(ctx, "lbvh leaf triangles", 48 * n);
    let (nodes_out, tris_out) = ((&OUT_NODES, &out_nodes), (&OUT_TRIS, &out_tris));
    let (pp, gp) = run.bound_kernel(
        "places",
        &params,
        &[by_height, kids, info, down, place_down],
    )?;
    let (pn, gn) = bound("emit_nodes", &[kids, node_boxes, info, down, nodes_out])?;
    let (pe, ge) = bound("emit_leaves", &[place_boxes, place_down, nodes_out])?;
    let (pt, gt) = bound(
        "emit_tris",
        &[sorted, v0, v1, v2, place_down, (&IDS, &mesh_ids), tris_out],
    )?;
    let mut enc = run.encoder();
    for (h, &count) in counts.iter().enumerate().take(top + 1).skip(1).rev() {
        dispatch(&mut enc, &pp, &gp, h as u32, run.shape(count), align);
    }
    dispatch(&mut enc, &pn, &gn, 0, run.shape(run.n - 1), 0);
    dispatch(&mut enc, &pe, &ge, 0, all, 0);
    dispatch(&mut enc, &pt, &gt, 0, all, 0);
    let readback = Readback::record(
        ctx,
        &mut enc,
        &[(&out_nodes, 32 * nodes), (&out_tris, 48 * n)],
    );
    let arrays = run.finish_with(enc, readback, "flattening the LBVH on the GPU", |b| {
        DfsSign::from_arrays(GpuArrays::new(b[0], b[1]))
    })?;
    log::info!(
        "GPU LBVH of {n} triangles flattened into dfs-sign ({nodes} nodes, {top} passes \
         each way) and read back in {:.0} ms since the upload",
        ms(run.started)
    );
    arrays.map_err(|e| {
        Error::Gpu(format!(
            "the GPU's dfs-sign layout is invalid (a bug: please report it): {e}"
        ))
    })
}

/// Heights the flatten counts nodes of (`HEIGHT_LIMIT` in the WGSL): a radix tree over
/// distinct 62-bit keys (code, place) is at most 62 levels deep.
pub const HEIGHT_LIMIT: u32 = 64;

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// A float from its order-preserving encoding (`unordered` in the WGSL).
fn unordered(u: u32) -> f32 {
    f32::from_bits(if u & 0x8000_0000 != 0 {
        u & 0x7fff_ffff
    } else {
        !u
    })
}

/// A uniform buffer of one `Params` per dispatch kind, each at the device's alignment.
fn uniforms(ctx: &GpuContext, all: &[Params]) -> (wgpu::Buffer, u32) {
    let align =
        (PARAMS as u32).next_multiple_of(ctx.limits.min_uniform_buffer_offset_alignment.max(1));
    let mut bytes = vec![0u8; all.len() * align as usize];
    for (k, p) in all.iter().enumerate() {
        let at = k * align as usize;
        bytes[at..at + PARAMS as usize].copy_from_slice(bytemuck::bytes_of(p));
    }
    let buffer = ctx.buffer_with("lbvh params", &bytes, wgpu::BufferUsages::UNIFORM);
    (buffer, align)
}

/// Records one dispatch in a compute pass of its own (the next reads what it wrote).
fn dispatch(
    enc: &mut wgpu::CommandEncoder,
    pipeline: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    uniform: u32,
    (x, y): (u32, u32),
    align: u32,
) {
    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some("lbvh"),
        timestamp_writes: None,
    });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, group, &[uniform * align]);
    pass.dispatch_workgroups(x, y, 1);
}

/// The device buffers of one GPU build, and what compiles and binds its kernels.
struct Run<'c> {
    ctx: &'c GpuContext,
    started: Instant,
    n: u32,
    tiles: u32,
    v: [wgpu::Buffer; 3],
    bounds: wgpu::Buffer,
    pairs: [wgpu::Buffer; 2],
    table: wgpu::Buffer,
    kids: wgpu::Buffer,
    parents: wgpu::Buffer,
    node_boxes: wgpu::Buffer,
    heights: wgpu::Buffer,
    /// The build's uniforms: [0] the base, [1 + k] sort pass k.
    params: wgpu::Buffer,
    align: u32,
}

impl<'c> Run<'c> {
    /// Checks the sizes against the device, uploads the `n` triangles (`triangle(i)` each)
    /// and makes the buffers.
    fn new(
        ctx: &'c GpuContext,
        n: usize,
        triangle: &(dyn Fn(usize) -> Triangle + Sync),
    ) -> Result<Run<'c>> {
        let started = Instant::now();
        if n > MAX_PRIMS {
            return Err(Error::Gpu(format!(
                "the GPU LBVH takes at most {MAX_PRIMS} triangles, not {n}; build on the CPU"
            )));
        }
        if ctx.limits.max_storage_buffers_per_shader_stage < STORAGE_BUFFERS {
            return Err(Error::Gpu(format!(
                "the GPU LBVH binds {STORAGE_BUFFERS} storage buffers per kernel; {} allows {}",
                ctx.adapter.name, ctx.limits.max_storage_buffers_per_shader_stage
            )));
        }
        let tiles = (n as u32).div_ceil(SORT_TILE);
        let (n64, inner) = (n as u64, n as u64 - 1);
        let radix = 1u64 << RADIX_BITS;
        for (array, what, bytes) in [
            (&V0, "the GPU LBVH's vertices", 12 * n64),
            (&PAIRS_IN, "the GPU LBVH's sort pairs", 8 * n64),
            (&NODE_BOXES, "the GPU LBVH's node boxes", 24 * inner),
            (&PARENTS, "the GPU LBVH's parents", 4 * (inner + n64)),
            (
                &TABLE,
                "the GPU LBVH's sort table",
                4 * radix * tiles as u64,
            ),
        ] {
            array.check(ctx, what, bytes)?;
        }
        let storage = wgpu::BufferUsages::STORAGE;
        let vertex = |k: usize| {
            let words: Vec<f32> = (0..n).flat_map(|i| triangle(i).v[k].to_array()).collect();
            ctx.buffer_with("lbvh vertices", bytemuck::cast_slice(&words), storage)
        };
        let v = [vertex(0), vertex(1), vertex(2)];
        let base = Params {
            n: n as u32,
            tiles,
            ..Params::default()
        };
        let all: Vec<Params> = (0..=SORT_PASSES)
            .map(|k| Params {
                shift: k.saturating_sub(1) * RADIX_BITS,
                ..base
            })
            .collect();
        let (params, align) = uniforms(ctx, &all);
        log::info!(
            "GPU LBVH of {n} triangles: uploaded in {:.0} ms",
            ms(started)
        );
        Ok(Run {
            ctx,
            started,
            n: n as u32,
            tiles,
            v,
            bounds: output_buffer(ctx, "lbvh centre bounds", 24),
            pairs: [
                output_buffer(ctx, "lbvh pairs", 8 * n64),
                output_buffer(ctx, "lbvh pairs (other)", 8 * n64),
            ],
            table: output_buffer(ctx, "lbvh sort table", 4 * radix * tiles as u64),
            kids: output_buffer(ctx, "lbvh kids", 8 * inner),
            parents: output_buffer(ctx, "lbvh parents", 4 * (inner + n64)),
            node_boxes: output_buffer(ctx, "lbvh node boxes", 24 * inner),
            heights: output_buffer(ctx, "lbvh node heights", 4 * inner),
            params,
            align,
        })
    }

    /// The vertex arrays, bound.
    fn vertices(&self) -> (Bound<'_>, Bound<'_>, Bound<'_>) {
        ((&V0, &self.v[0]), (&V1, &self.v[1]), (&V2, &self.v[2]))
    }

    fn encoder(&self) -> wgpu::CommandEncoder {
        self.ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("lbvh"),
            })
    }

    /// The kernel `entry` over these arrays (each in as many parts as its buffer needs);
    /// refused where the parts outnumber the storage buffers the device allows a stage.
    fn kernel(
        &self,
        entry: &'static str,
        bound: &[Bound],
    ) -> Result<(Kernel, wgpu::ComputePipeline)> {
        let ctx = self.ctx;
        let parts = |a: &PartedArray| {
            bound
                .iter()
                .find(|(b, _)| b.binding == a.binding)
                .map_or(1, |(_, buf)| parted_array::parts(ctx, buf.size()))
        };
        let source = source_with(&parts, parted_array::byte_shift(ctx));
        let mut entries = vec![dynamic_uniform_entry(0, PARAMS)];
        for (a, buf) in bound {
            entries.extend(a.layout_entries(ctx, buf.size()));
        }
        let (need, max) = (
            entries.len() as u32 - 1,
            ctx.limits.max_storage_buffers_per_shader_stage,
        );
        if need > max {
            return Err(Error::Gpu(format!(
                "the GPU LBVH's {entry} kernel would bind {need} storage buffers (arrays bigger \
                 than one binding of {} are bound in parts), but {} allows {max} a shader \
                 stage (max_storage_buffers_per_shader_stage); build on the CPU",
                human_bytes(1 << parted_array::byte_shift(ctx)),
                ctx.adapter.name
            )));
        }
        let k = Kernel::new(ctx, "lbvh", entry, &source, &entries, false)?;
        let p = k.pipeline(ctx, &[], false)?;
        Ok((k, p))
    }

    /// A bind group of `k` over these arrays (the buffers' sizes as when `k` was made).
    fn bind(&self, k: &Kernel, params: &wgpu::Buffer, bound: &[Bound]) -> Result<wgpu::BindGroup> {
        let mut entries = vec![uniform_binding(0, params, PARAMS)];
        for (a, buf) in bound {
            entries.extend(a.bind_entries(self.ctx, buf));
        }
        k.bind(self.ctx, &entries)
    }

    /// The kernel `entry` over these arrays and its one bind group.
    fn bound_kernel(
        &self,
        entry: &'static str,
        params: &wgpu::Buffer,
        bound: &[Bound],
    ) -> Result<(wgpu::ComputePipeline, wgpu::BindGroup)> {
        let (k, p) = self.kernel(entry, bound)?;
        Ok((p, self.bind(&k, params, bound)?))
    }

    /// Workgroups for `threads` threads, two-dimensional beyond the per-dimension limit.
    fn shape(&self, threads: u32) -> (u32, u32) {
        let per_dim = self.ctx.limits.max_compute_workgroups_per_dimension.max(1);
        let groups = threads.div_ceil(WORKGROUP).max(1);
        if groups <= per_dim {
            (groups, 1)
        } else {
            (per_dim, groups.div_ceil(per_dim))
        }
    }

    /// Records the radix tree's build: bounds, codes, the sort, the tree, the boxes.
    fn record_build(&self, enc: &mut wgpu::CommandEncoder) -> Result<()> {
        let t = Instant::now();
        let p = &self.params;
        let (v0, v1, v2) = self.vertices();
        let bounds = (&CENTRE_BOUNDS, &self.bounds);
        let table = (&TABLE, &self.table);
        let (pb, gb) = self.bound_kernel("bounds", p, &[v0, v1, v2, bounds])?;
        let (pc, gc) = self.bound_kernel(
            "codes",
            p,
            &[v0, v1, v2, bounds, (&PAIRS_OUT, &self.pairs[0])],
        )?;
        // The sort's passes read one pair array and write the other, in turn.
        let from = |k: usize| (&PAIRS_IN, &self.pairs[k]);
        let to = |k: usize| (&PAIRS_OUT, &self.pairs[1 - k]);
        let (kh, ph) = self.kernel("histogram", &[from(0), table])?;
        let gh = [
            self.bind(&kh, p, &[from(0), table])?,
            self.bind(&kh, p, &[from(1), table])?,
        ];
        let (ps, gs) = self.bound_kernel("scan", p, &[table])?;
        let (kx, px) = self.kernel("scatter", &[from(0), to(0), table])?;
        let gx = [
            self.bind(&kx, p, &[from(0), to(0), table])?,
            self.bind(&kx, p, &[from(1), to(1), table])?,
        ];
        let (pt, gt) = self.bound_kernel(
            "hierarchy",
            p,
            &[from(0), (&KIDS, &self.kids), (&PARENTS, &self.parents)],
        )?;
        let (po, go) = self.bound_kernel(
            "boxes",
            p,
            &[
                v0,
                v1,
                v2,
                (&PARENTS, &self.parents),
                (&NODE_BOXES, &self.node_boxes),
                (&HEIGHTS, &self.heights),
            ],
        )?;
        log::info!("GPU LBVH: kernels compiled in {:.0} ms", ms(t));
        let a = self.align;
        let per_dim = self.ctx.limits.max_compute_workgroups_per_dimension.max(1);
        let bound_groups = self.n.div_ceil(WORKGROUP).min(BOUNDS_GROUPS).min(per_dim);
        dispatch(enc, &pb, &gb, 0, (bound_groups, 1), a);
        dispatch(enc, &pc, &gc, 0, self.shape(self.n), a);
        for k in 0..SORT_PASSES {
            let read = (k % 2) as usize;
            dispatch(enc, &ph, &gh[read], 1 + k, self.shape(self.tiles), a);
            dispatch(enc, &ps, &gs, 1 + k, (1, 1), a);
            dispatch(enc, &px, &gx[read], 1 + k, self.shape(self.tiles), a);
        }
        dispatch(enc, &pt, &gt, 0, self.shape(self.n - 1), a);
        dispatch(enc, &po, &go, 0, self.shape(self.n), a);
        Ok(())
    }

    /// Submits `enc` and hands `f` what `readback` copied, in the mapped memory.
    fn finish_with<T>(
        &self,
        enc: wgpu::CommandEncoder,
        readback: Readback,
        what: &str,
        f: impl FnOnce(&[&[u8]]) -> T,
    ) -> Result<T> {
        let t = Instant::now();
        scoped(self.ctx, what, || {
            self.ctx.queue.submit([enc.finish()]);
        })?;
        let value = readback.read_with(self.ctx, f)?;
        log::info!("{what}: {:.0} ms on the device", ms(t));
        Ok(value)
    }
}

#[cfg(test)]
mod tests {
    use std::mem::{offset_of, size_of};

    use super::*;

    #[test]
    fn the_wgsl_params_match_the_rust_params() {
        let fields = [
            ("n", offset_of!(Params, n)),
            ("tiles", offset_of!(Params, tiles)),
            ("shift", offset_of!(Params, shift)),
            ("max_leaf", offset_of!(Params, max_leaf)),
            ("t_cube", offset_of!(Params, t_cube)),
            ("t_obj", offset_of!(Params, t_obj)),
            ("first", offset_of!(Params, first)),
            ("count", offset_of!(Params, count)),
            ("zero", offset_of!(Params, zero)),
            ("pad1", offset_of!(Params, pad)),
            ("pad2", offset_of!(Params, pad) + 4),
        ];
        super::super::shaders::check_struct(&lbvh_source(), "Params", size_of::<Params>(), &fields)
            .unwrap();
    }
}
