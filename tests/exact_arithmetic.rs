//! The kernels' arithmetic rounds as the CPU's does (gpu::exact_spirv): multiply-adds, a
//! box's half area (the SAH's sum of products), divisions and square roots of random f32s,
//! bit for bit, on the test adapter. wgpu's own translation of the same WGSL (a context
//! with `exact_spirv` off) is shown to differ on lavapipe, which fuses the half area's
//! products and sums into fused multiply-adds (one rounding where the CPU makes two): what
//! the exact SPIR-V prevents.

mod common;

use common::gpu;
use lancer::gpu::plumbing::{storage_entry, wait, Kernel, Readback};
use lancer::gpu::wgpu;
use lancer::gpu::wgpu::util::DeviceExt;
use lancer::gpu::GpuContext;

const SOURCE: &str = "
@group(0) @binding(0) var<storage, read> inputs: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> outputs: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= arrayLength(&inputs) {
        return;
    }
    let x = inputs[id.x];
    let e = x.xyz - vec3<f32>(x.w);
    outputs[id.x] = vec4<f32>(x.x * x.y + x.z, e.x * e.y + e.y * e.z + e.z * e.x, x.x / x.y, sqrt(abs(x.z)));
}";

/// The CPU's answer for one input, in the kernel's operations (Rust never fuses): the
/// second is the half area of the box of extent `x.xyz - x.w`.
fn on_cpu(x: [f32; 4]) -> [f32; 4] {
    [
        x[0] * x[1] + x[2],
        {
            let e = [x[0] - x[3], x[1] - x[3], x[2] - x[3]];
            e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
        },
        x[0] / x[1],
        x[2].abs().sqrt(),
    ]
}

/// Finite f32s of exponents −20…20 and either sign, from a xorshift generator; the third
/// of each four near the product of the first two, where a fused multiply-add and two
/// roundings differ most often.
fn inputs(n: usize) -> Vec<[f32; 4]> {
    let mut s = 0x9e37_79b9_7f4a_7c15_u64;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s
    };
    let mut value = || {
        let r = next();
        let exponent = (127 - 20 + (r >> 32) % 41) as u32;
        let bits = ((r as u32) & 0x807f_ffff) | (exponent << 23);
        f32::from_bits(bits)
    };
    let mut all: Vec<[f32; 4]> = (0..n)
        .map(|_| {
            let (a, b, d) = (value(), value(), value());
            let c = -(a * b) * (1.0 + value().fract() * 1e-3);
            [a, b, c, d]
        })
        .collect();
    // Zeros of both signs, a division by zero, the largest and smallest normal f32s.
    let (max, min) = (f32::MAX, f32::MIN_POSITIVE);
    all.extend([
        [0.0, 1.0, -0.0, 0.0],
        [-0.0, 3.0, 0.0, -0.0],
        [1.0, 0.0, 2.0, 1.0],
        [-1.0, -0.0, 4.0, 2.0],
        [max, 0.5, max, 1.0],
        [min, 2.0, min, min],
        [max, min, 1.0, max],
    ]);
    all
}

/// The kernel's answers on `ctx` (its pipelines from lancer's SPIR-V or from wgpu's
/// translation, as `ctx.exact_spirv` says).
fn on_gpu(ctx: &GpuContext, data: &[[f32; 4]]) -> Vec<[f32; 4]> {
    let entries = [storage_entry(0, true), storage_entry(1, false)];
    let kernel = Kernel::new(ctx, "arithmetic", "main", SOURCE, &entries, false).unwrap();
    let pipeline = kernel.pipeline(ctx, &[], false).unwrap();
    let size = std::mem::size_of_val(data) as u64;
    let input = ctx
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("inputs"),
            contents: bytemuck::cast_slice(data),
            usage: wgpu::BufferUsages::STORAGE,
        });
    let output = lancer::gpu::plumbing::output_buffer(ctx, "outputs", size);
    let bind = kernel
        .bind(
            ctx,
            &[
                lancer::gpu::plumbing::buffer_binding(0, &input),
                lancer::gpu::plumbing::buffer_binding(1, &output),
            ],
        )
        .unwrap();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups((data.len() as u32).div_ceil(64), 1, 1);
    }
    let readback = Readback::record(ctx, &mut enc, &[(&output, size)]);
    ctx.queue.submit([enc.finish()]);
    wait(ctx).unwrap();
    let bytes = readback.read(ctx).unwrap();
    bytemuck::cast_slice(&bytes[0]).to_vec()
}

/// How many answers of each of the four columns differ from the CPU's in any bit.
fn differences(data: &[[f32; 4]], gpu: &[[f32; 4]]) -> [usize; 4] {
    let mut off = [0; 4];
    for (x, g) in data.iter().zip(gpu) {
        let c = on_cpu(*x);
        for k in 0..4 {
            off[k] += (c[k].to_bits() != g[k].to_bits()) as usize;
        }
    }
    off
}

#[test]
fn multiply_adds_divisions_and_roots_round_as_on_the_cpu() {
    let ctx = gpu();
    if !ctx.exact_spirv {
        // CI's lavapipe always takes it: the test may not pass without checking there.
        assert!(
            std::env::var("CI").is_err(),
            "{}: a Vulkan adapter takes lancer's own SPIR-V",
            ctx.adapter
        );
        println!("skipping: {} takes wgpu's translation", ctx.adapter);
        return;
    }
    let data = inputs(1 << 14);
    let off = differences(&data, &on_gpu(ctx, &data));
    println!(
        "{} (exact SPIR-V, f64 division {}): {off:?} of {} differ",
        ctx.adapter,
        ctx.exact_division,
        data.len()
    );
    assert_eq!(off, [0; 4], "a*b+c, half area, a/b, sqrt(|c|)");
}

#[test]
fn wgpus_own_translation_fuses_on_lavapipe() {
    let mut ctx = GpuContext::new().unwrap();
    if !ctx.adapter.software {
        println!("{}: not lavapipe, nothing to show", ctx.adapter);
        return;
    }
    ctx.exact_spirv = false;
    let data = inputs(1 << 14);
    let off = differences(&data, &on_gpu(&ctx, &data));
    println!("{} (wgpu's WGSL translation): {off:?} differ", ctx.adapter);
    assert!(
        off[1] > 0,
        "wgpu's translation rounded every multiply-add as the CPU does ({off:?}): this test no \
         longer shows what the exact SPIR-V prevents"
    );
}
