//! How fast can a GPU kernel go that only *reads* as many BVH nodes per ray as the traversal
//! does, with no box or triangle test, no stack and no branch? Its rays/s is an upper bound
//! for the real traversal on the same adapter; on lavapipe it shows that storage-buffer loads
//! alone (a per-lane loop per load there) cap the primary-ray speed.
//!
//! `cargo run --release --example load_ceiling -- MESH.obj [WIDTH HEIGHT]`
//!
//! Prints, side by side in one run: the real closest-hit kernel with the BVH in buffers and in
//! textures (GPU time, timestamp queries) and the loads-only probe doing the mean number of node and triangle loads per ray over
//! the same buffers (wall time around submit + wait, no readback; one dispatch), and the probe
//! again over read-only storage textures holding the same words.

use std::path::PathBuf;
use std::time::Instant;

use lancer::accel::bvh::layouts::{flatten, LayoutKind};
use lancer::accel::bvh::{build, BuildOptions};
use lancer::accel::GpuForm;
use lancer::camera::Camera;
use lancer::geometry::Ray;
use lancer::gpu::{bindings, shaders, BvhMemory, GpuBvh, GpuContext, GpuTracer, TraceKernel};
use lancer::mesh::load_mesh;
use lancer::{RayStats, Result};

// Per invocation, the memory traffic of one traced ray in the load shapes of the default
// layout's traversal: read the Ray, NODES node visits (two vec4 words each), TRIS
// triangles (three vec4 each, load_tri), write a Hit. Each index comes from the words read
// before, so no load can be skipped or hoisted. The words come through traversal.wgsl's own
// node_word/tri_word, from buffers or textures as its BVH_TEXTURES override says.
const PROBE: &str = "
override NODES: u32 = 17u;
override TRIS: u32 = 4u;
override N_NODES: u32 = 1u;
override N_TRIS: u32 = 1u;
@group(0) @binding(BINDING_TRACE_RAYS) var<storage, read> rays: array<Ray>;
@group(0) @binding(BINDING_TRACE_HITS) var<storage, read_write> hits: array<Hit>;
@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= arrayLength(&rays) {
        return;
    }
    let r = rays[gid.x];
    var acc = bitcast<vec4<u32>>(vec4<f32>(r.dir, r.tmax));
    var idx = 0u;
    for (var k = 0u; k < NODES; k += 1u) {
        acc += node_word(2u * idx) ^ node_word(2u * idx + 1u);
        idx = (acc.x + acc.y + acc.z + acc.w) % N_NODES;
    }
    for (var k = 0u; k < TRIS; k += 1u) {
        let j = 3u * (idx % N_TRIS);
        acc += tri_word(j) ^ tri_word(j + 1u) ^ tri_word(j + 2u);
        idx = acc.x + acc.y + acc.z + acc.w;
    }
    hits[gid.x] = Hit(bitcast<f32>(acc.x), acc.y, bitcast<f32>(acc.z), bitcast<f32>(acc.w));
}
";

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(mesh_path) = args.first().map(PathBuf::from) else {
        eprintln!("usage: load_ceiling MESH.obj [WIDTH HEIGHT]");
        std::process::exit(2);
    };
    let dim = |i: usize| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(1024u32);
    let (w, h) = (dim(1), dim(2));
    let mesh = load_mesh(&mesh_path)?;
    let layout = flatten(
        LayoutKind::DfsSign,
        &build(&mesh, &BuildOptions::default()),
        &mesh,
    );
    let flat = layout.as_ref();
    let rays = Camera::default_view(&mesh.bounds(), w, h).primary_rays();
    let ctx = GpuContext::new()?;
    println!("adapter {}", ctx.adapter);

    // The real kernel, with statistics once for nodes/ray, then timed without.
    let mut tracer = GpuTracer::new(&ctx, flat, BvhMemory::Buffers)?;
    let counting = TraceKernel {
        stats: true,
        ..TraceKernel::default()
    };
    let (_, stats, _) = tracer.trace(&rays, counting)?;
    let stats = stats.unwrap_or_default();
    let mean = |f: fn(&RayStats) -> u32| {
        stats.iter().map(|s| f(s) as f64).sum::<f64>() / stats.len().max(1) as f64
    };
    let (nodes_per_ray, tris_per_ray) = (mean(|s| s.nodes), mean(|s| s.tris));
    let time = |tracer: &mut GpuTracer| -> Result<f64> {
        let (_, _, t) = tracer.trace(&rays, TraceKernel::default())?;
        Ok(t.gpu_ms.unwrap_or(t.wall_ms))
    };
    let buffers_ms = time(&mut tracer)?;
    let textures_ms = time(&mut GpuTracer::new(&ctx, flat, BvhMemory::Textures)?)?;

    let loads = (nodes_per_ray.round() as u32, tris_per_ray.round() as u32);
    let probe_ms = probe(&ctx, flat, &rays, loads, BvhMemory::Buffers)?;
    let texture_ms = probe(&ctx, flat, &rays, loads, BvhMemory::Textures)?;
    let mrays = |ms: f64| rays.len() as f64 / (ms * 1e3);
    println!(
        "{} primary rays, {nodes_per_ray:.2} nodes/ray, {tris_per_ray:.2} triangles/ray",
        rays.len()
    );
    println!(
        "closest-hit traversal, BVH in buffers:  {:7.2} Mrays/s (GPU time)",
        mrays(buffers_ms)
    );
    println!(
        "closest-hit traversal, BVH in textures: {:7.2} Mrays/s (GPU time)",
        mrays(textures_ms)
    );
    println!(
        "loads only ({} nodes, {} triangles): {:7.2} Mrays/s (no tests, no stack, no branches)",
        loads.0,
        loads.1,
        mrays(probe_ms)
    );
    println!(
        "the same loads from read-only storage textures: {:7.2} Mrays/s",
        mrays(texture_ms)
    );
    Ok(())
}

/// Milliseconds of the probe over one invocation per ray (best of 3), with the BVH's words
/// in the given memory.
fn probe(
    ctx: &GpuContext,
    flat: &dyn GpuForm,
    rays: &[Ray],
    (nodes, tris): (u32, u32),
    memory: BvhMemory,
) -> Result<f64> {
    let dev = &ctx.device;
    let bvh = GpuBvh::upload(ctx, flat, memory)?;
    let ray_buf = ctx.buffer_with(
        "rays",
        bytemuck::cast_slice(rays),
        wgpu::BufferUsages::STORAGE,
    );
    let hit_buf = ctx.buffer_with(
        "hits",
        &vec![0u8; rays.len() * 16],
        wgpu::BufferUsages::STORAGE,
    );
    let source = format!(
        "{}\n{}\n{PROBE}\n{}",
        shaders::library_source(),
        shaders::KEEP_EVERY_HIT,
        bvh.parts().bvh_wgsl()
    );
    let module = dev.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("load probe"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let constants = [
        ("NODES", nodes as f64),
        ("TRIS", tris as f64),
        // 32-byte visits over the node words, whatever the layout's node shape.
        ("N_NODES", (flat.arrays().nodes.len() / 32).max(1) as f64),
        ("N_TRIS", flat.triangles().max(1) as f64),
        bvh.override_constant(),
    ];
    let pipeline = dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("load probe"),
        layout: None,
        module: &module,
        entry_point: Some("probe"),
        compilation_options: wgpu::PipelineCompilationOptions {
            constants: &constants,
            ..Default::default()
        },
        cache: None,
    });
    let mut entries = bvh.bind_entries();
    entries.push(wgpu::BindGroupEntry {
        binding: bindings::TRACE_RAYS,
        resource: ray_buf.as_entire_binding(),
    });
    entries.push(wgpu::BindGroupEntry {
        binding: bindings::TRACE_HITS,
        resource: hit_buf.as_entire_binding(),
    });
    let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("load probe"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    });
    let run = || {
        let mut enc = dev.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((rays.len() as u32).div_ceil(64), 1, 1);
        }
        let start = Instant::now();
        ctx.queue.submit([enc.finish()]);
        dev.poll(wgpu::PollType::wait_indefinitely())
            .expect("the GPU did not finish");
        start.elapsed().as_secs_f64() * 1e3
    };
    run(); // compile and warm up
    Ok((0..3).map(|_| run()).fold(f64::INFINITY, f64::min))
}
