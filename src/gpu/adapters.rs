//! Every adapter wgpu can open here, described for people (`lancer adapters`).

use super::context::instance;
use crate::error::Result;

/// One adapter: what it is and what lancer can use of it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AdapterSummary {
    /// The adapter's name.
    pub name: String,
    /// Discrete, integrated or virtual GPU, CPU (a software driver such as lavapipe), other.
    pub device_type: String,
    /// The API wgpu reaches it through (Vulkan, Metal, Dx12, Gl).
    pub backend: String,
    /// Driver name and version.
    pub driver: String,
    /// Largest storage buffer binding, bytes (bounds a BVH in buffers and a ray batch).
    pub max_storage_buffer_binding: u64,
    /// Largest 2D texture side, texels (bounds a BVH in textures).
    pub max_texture_dimension_2d: u32,
    /// Largest compute workgroup, invocations.
    pub max_workgroup_invocations: u32,
    /// Subgroup operations (`--mode subgroup`), with the subgroup sizes.
    pub subgroups: Option<(u32, u32)>,
    /// Timestamp queries (GPU times in the benches).
    pub timestamps: bool,
    /// The driver's own ray queries (wgpu's experimental feature): the `driver` reference
    /// row of `bench layouts` and `check`.
    pub ray_query: bool,
    /// f64 in shaders (lancer's SPIR-V divides and takes square roots through it).
    pub shader_f64: bool,
    /// lancer's kernels are compiled to round as the CPU does here: its own SPIR-V (Vulkan
    /// with passthrough shaders and f64; see `gpu::exact_spirv`), which holds on every
    /// driver tried so far (`lancer check` tests a driver). Elsewhere wgpu translates them
    /// and a driver may fuse a multiply-add or divide to within a few ulps.
    pub exact_arithmetic: bool,
}

/// Every adapter of the instance lancer opens (`WGPU_BACKEND` honoured), in wgpu's order.
pub fn adapters() -> Result<Vec<AdapterSummary>> {
    let instance = instance()?;
    let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
    Ok(adapters
        .iter()
        .map(|a| {
            let (info, limits, features) = (a.get_info(), a.limits(), a.features());
            AdapterSummary {
                name: info.name.clone(),
                device_type: format!("{:?}", info.device_type),
                backend: format!("{:?}", info.backend),
                driver: format!("{} {}", info.driver, info.driver_info)
                    .trim()
                    .to_string(),
                max_storage_buffer_binding: limits.max_storage_buffer_binding_size,
                max_texture_dimension_2d: limits.max_texture_dimension_2d,
                max_workgroup_invocations: limits.max_compute_invocations_per_workgroup,
                subgroups: features
                    .contains(wgpu::Features::SUBGROUP)
                    .then_some((info.subgroup_min_size, info.subgroup_max_size)),
                timestamps: features.contains(wgpu::Features::TIMESTAMP_QUERY),
                ray_query: features.contains(wgpu::Features::EXPERIMENTAL_RAY_QUERY),
                shader_f64: features.contains(wgpu::Features::SHADER_F64),
                exact_arithmetic: super::context::exact_spirv(info.backend, features)
                    && features.contains(wgpu::Features::SHADER_F64),
            }
        })
        .collect())
}
