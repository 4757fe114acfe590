//! WGSL sources. WGSL has no include: each kernel is `common.wgsl` followed by its own file.

pub const COMMON: &str = include_str!("../../shaders/common.wgsl");
pub const TRAVERSE: &str = include_str!("../../shaders/traverse.wgsl");

/// The traversal kernel's full source.
pub fn traverse_source() -> String {
    format!("{COMMON}\n{TRAVERSE}")
}

/// Every kernel's full source, by name (for validation and layout tests).
pub fn all() -> Vec<(&'static str, String)> {
    vec![("traverse", traverse_source())]
}
