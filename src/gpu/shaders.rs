//! WGSL sources. WGSL has no include: each kernel is `common.wgsl`, then `bvh.wgsl` (the
//! traversal), then its own file.

pub const COMMON: &str = include_str!("../../shaders/common.wgsl");
pub const BVH: &str = include_str!("../../shaders/bvh.wgsl");
pub const TRAVERSE: &str = include_str!("../../shaders/traverse.wgsl");
pub const RENDER: &str = include_str!("../../shaders/render.wgsl");

/// The trace kernel's full source.
pub fn traverse_source() -> String {
    format!("{COMMON}\n{BVH}\n{TRAVERSE}")
}

/// The render kernel's full source.
pub fn render_source() -> String {
    format!("{COMMON}\n{BVH}\n{RENDER}")
}

/// Every kernel's full source, by name (for validation and layout tests).
pub fn all() -> Vec<(&'static str, String)> {
    vec![("traverse", traverse_source()), ("render", render_source())]
}
