//! The LBVH built on the GPU: `accel/bvh/lbvh.wgsl`'s kernels over the triangles, read back
//! as the same [`RadixTree`] the CPU twin (`accel::bvh::lbvh::radix_tree`) makes, then made
//! into a [`Bvh`] on the CPU like every builder's tree.

use super::plumbing::{
    buffer_binding, dynamic_uniform_entry, output_buffer, storage_entry, uniform_binding, Kernel,
    Readback,
};
use super::shaders::{constants_wgsl, Shared};
use super::GpuContext;
use crate::accel::bvh::lbvh::{radix_tree, RadixTree, CODE_BITS, LEAF_BIT, MAX_PRIMS};
use crate::accel::bvh::{build_from_radix_tree, BuildOptions, Bvh};
use crate::error::{Error, Result};
use crate::geometry::Aabb;
use crate::mesh::Mesh;

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

/// The constants the kernels share with Rust.
fn constants() -> Vec<(&'static str, Shared)> {
    vec![
        ("CODE_BITS", Shared::U32(CODE_BITS)), // accel::bvh::lbvh::CODE_BITS
        ("LEAF_BIT", Shared::U32(LEAF_BIT)),   // accel::bvh::lbvh::LEAF_BIT
        ("RADIX_BITS", Shared::U32(RADIX_BITS)), // gpu::lbvh_build::RADIX_BITS
        ("SORT_TILE", Shared::U32(SORT_TILE)), // gpu::lbvh_build::SORT_TILE
    ]
}

/// The full WGSL module (for naga checks).
pub fn lbvh_source() -> String {
    format!(
        "{}\n{SOURCE}",
        constants_wgsl("gpu::lbvh_build::constants", &constants())
    )
}

/// Per-dispatch parameters (`Params` in the WGSL).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    n: u32,
    tiles: u32,
    shift: u32,
    pad: u32,
}

/// Builds the LBVH of the mesh's included triangles on the GPU and makes it lancer's tree
/// (with `opts`' leaf rule and depth cap; `opts.builder` is not read). Equal to
/// [`build`](crate::accel::bvh::build) with [`Builder::Lbvh`](crate::accel::bvh::Builder).
pub fn build_lbvh(ctx: &GpuContext, mesh: &Mesh, opts: &BuildOptions) -> Result<Bvh> {
    let ids = mesh.included();
    let tris: Vec<_> = ids.iter().map(|&i| mesh.triangles[i as usize]).collect();
    let tree = lbvh_radix_tree(ctx, &tris)?;
    drop(tris);
    Ok(build_from_radix_tree(mesh, &ids, tree, opts))
}

/// The radix tree over these triangles, built on the GPU.
pub fn lbvh_radix_tree(
    ctx: &GpuContext,
    triangles: &[crate::geometry::Triangle],
) -> Result<RadixTree> {
    let n = triangles.len();
    if n < 2 {
        // No inner node: nothing for the kernels to do.
        let boxes: Vec<Aabb> = triangles.iter().map(|t| t.bbox()).collect();
        return Ok(radix_tree(&boxes, false));
    }
    if n > MAX_PRIMS {
        return Err(Error::Gpu(format!(
            "the GPU LBVH takes at most {MAX_PRIMS} triangles, not {n}; build on the CPU"
        )));
    }
    let tiles = (n as u32).div_ceil(SORT_TILE);
    let inner = n as u64 - 1;
    let sizes = [
        ("the GPU LBVH's vertices", 12 * n as u64),
        ("the GPU LBVH's sort pairs", 8 * n as u64),
        ("the GPU LBVH's node boxes", 24 * inner),
        ("the GPU LBVH's parents", 4 * (inner + n as u64)),
        (
            "the GPU LBVH's sort table",
            4 * (1u64 << RADIX_BITS) * tiles as u64,
        ),
    ];
    for (what, bytes) in sizes {
        ctx.check_binding(what, bytes)?;
    }
    if ctx.limits.max_storage_buffers_per_shader_stage < 5 {
        return Err(Error::Gpu(
            "the GPU LBVH binds 5 storage buffers per kernel; the device allows fewer".into(),
        ));
    }
    let storage = wgpu::BufferUsages::STORAGE;
    let vertex = |k: usize| {
        let words: Vec<f32> = triangles.iter().flat_map(|t| t.v[k].to_array()).collect();
        ctx.buffer_with("lbvh vertices", bytemuck::cast_slice(&words), storage)
    };
    let v = [vertex(0), vertex(1), vertex(2)];
    let bounds = output_buffer(ctx, "lbvh centre bounds", 24);
    let pairs = [
        output_buffer(ctx, "lbvh pairs", 8 * n as u64),
        output_buffer(ctx, "lbvh pairs (other)", 8 * n as u64),
    ];
    let table = output_buffer(
        ctx,
        "lbvh sort table",
        4 * (1u64 << RADIX_BITS) * tiles as u64,
    );
    let kids = output_buffer(ctx, "lbvh kids", 8 * inner);
    let parents = output_buffer(ctx, "lbvh parents", 4 * (inner + n as u64));
    let node_boxes = output_buffer(ctx, "lbvh node boxes", 24 * inner);

    // One uniform per dispatch kind: [0] the base, [1 + k] sort pass k.
    let align = (std::mem::size_of::<Params>() as u32)
        .next_multiple_of(ctx.limits.min_uniform_buffer_offset_alignment.max(1));
    let mut uniforms = vec![0u8; ((1 + SORT_PASSES) * align) as usize];
    for k in 0..=SORT_PASSES {
        let p = Params {
            n: n as u32,
            tiles,
            shift: k.saturating_sub(1) * RADIX_BITS,
            pad: 0,
        };
        let at = (k * align) as usize;
        uniforms[at..at + 16].copy_from_slice(bytemuck::bytes_of(&p));
    }
    let params = ctx.buffer_with("lbvh params", &uniforms, wgpu::BufferUsages::UNIFORM);

    let source = lbvh_source();
    // Each kernel's bindings: (binding, read-only) and the buffer bound there.
    let kernel =
        |entry: &'static str, slots: &[(u32, bool)]| -> Result<(Kernel, wgpu::ComputePipeline)> {
            let mut entries = vec![dynamic_uniform_entry(0, 16)];
            entries.extend(slots.iter().map(|&(b, ro)| storage_entry(b, ro)));
            let k = Kernel::new(ctx, "lbvh", entry, &source, &entries, false)?;
            let p = k.pipeline(ctx, &[], false)?;
            Ok((k, p))
        };
    let bind = |k: &Kernel, bufs: &[(u32, &wgpu::Buffer)]| -> Result<wgpu::BindGroup> {
        let mut entries = vec![uniform_binding(0, &params, 16)];
        entries.extend(bufs.iter().map(|&(b, buf)| buffer_binding(b, buf)));
        k.bind(ctx, &entries)
    };
    let verts = [(1, true), (2, true), (3, true)];
    let (kb, pb) = kernel("bounds", &[verts[0], verts[1], verts[2], (4, false)])?;
    let (kc, pc) = kernel(
        "codes",
        &[verts[0], verts[1], verts[2], (4, false), (6, false)],
    )?;
    let (kh, ph) = kernel("histogram", &[(5, true), (7, false)])?;
    let (ks, ps) = kernel("scan", &[(7, false)])?;
    let (kx, px) = kernel("scatter", &[(5, true), (6, false), (7, false)])?;
    let (kt, pt) = kernel("hierarchy", &[(5, true), (8, false), (9, false)])?;
    let (ko, po) = kernel(
        "boxes",
        &[verts[0], verts[1], verts[2], (9, false), (10, false)],
    )?;
    let vb = [(1, &v[0]), (2, &v[1]), (3, &v[2])];
    let gb = bind(&kb, &[vb[0], vb[1], vb[2], (4, &bounds)])?;
    let gc = bind(&kc, &[vb[0], vb[1], vb[2], (4, &bounds), (6, &pairs[0])])?;
    let gh = [
        bind(&kh, &[(5, &pairs[0]), (7, &table)])?,
        bind(&kh, &[(5, &pairs[1]), (7, &table)])?,
    ];
    let gs = bind(&ks, &[(7, &table)])?;
    let gx = [
        bind(&kx, &[(5, &pairs[0]), (6, &pairs[1]), (7, &table)])?,
        bind(&kx, &[(5, &pairs[1]), (6, &pairs[0]), (7, &table)])?,
    ];
    let gt = bind(&kt, &[(5, &pairs[0]), (8, &kids), (9, &parents)])?;
    let go = bind(
        &ko,
        &[vb[0], vb[1], vb[2], (9, &parents), (10, &node_boxes)],
    )?;

    let per_dim = ctx.limits.max_compute_workgroups_per_dimension.max(1);
    let shape = |threads: u32| {
        let groups = threads.div_ceil(WORKGROUP).max(1);
        if groups <= per_dim {
            (groups, 1)
        } else {
            (per_dim, groups.div_ceil(per_dim))
        }
    };
    let mut enc = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("lbvh"),
        });
    let mut dispatch = |pipeline: &wgpu::ComputePipeline,
                        group: &wgpu::BindGroup,
                        uniform: u32,
                        (x, y): (u32, u32)| {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("lbvh"),
            timestamp_writes: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, group, &[uniform * align]);
        pass.dispatch_workgroups(x, y, 1);
    };
    let n32 = n as u32;
    dispatch(&pb, &gb, 0, shape(n32));
    dispatch(&pc, &gc, 0, shape(n32));
    for k in 0..SORT_PASSES {
        let from = (k % 2) as usize;
        dispatch(&ph, &gh[from], 1 + k, shape(tiles));
        dispatch(&ps, &gs, 1 + k, (1, 1));
        dispatch(&px, &gx[from], 1 + k, shape(tiles));
    }
    dispatch(&pt, &gt, 0, shape(n32 - 1));
    dispatch(&po, &go, 0, shape(n32));
    let readback = Readback::record(
        ctx,
        &mut enc,
        &[
            (&pairs[0], 8 * n as u64),
            (&kids, 8 * inner),
            (&node_boxes, 24 * inner),
        ],
    );
    let done = super::plumbing::scoped(ctx, "building the LBVH on the GPU", || {
        ctx.queue.submit([enc.finish()]);
    });
    done?;
    let bytes = readback.read(ctx)?;
    let pairs: &[[u32; 2]] = bytemuck::cast_slice(&bytes[0]);
    let words: &[u32] = bytemuck::cast_slice(&bytes[2]);
    let unordered = |u: u32| {
        f32::from_bits(if u & 0x8000_0000 != 0 {
            u & 0x7fff_ffff
        } else {
            !u
        })
    };
    let boxes = words
        .chunks_exact(6)
        .map(|w| Aabb {
            lo: glam::Vec3::new(unordered(!w[0]), unordered(!w[1]), unordered(!w[2])),
            hi: glam::Vec3::new(unordered(w[3]), unordered(w[4]), unordered(w[5])),
        })
        .collect();
    Ok(RadixTree {
        sorted: pairs.iter().map(|p| p[1]).collect(),
        kids: bytemuck::cast_slice(&bytes[1]).to_vec(),
        boxes,
    })
}
