//! Binding numbers of group 0, shared by the Rust bind groups and the WGSL declarations
//! (generated into the prelude; the kernels write `@binding(BINDING_…)`).

/// Where a word array is bound: part 0 of its buffer at `words` (the binding its WGSL source
/// declares), part k ≥ 1 at `parts + k`, its texture (where it may live in one) at `texels`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArrayBindings {
    /// Part 0 of the buffer.
    pub words: u32,
    /// One below part 1's binding.
    pub parts: u32,
    /// The texture (None: the array lives in buffer memory only).
    pub texels: Option<u32>,
}

/// The layout's node words in a storage buffer.
pub const NODE_WORDS: u32 = 0;
/// The leaf triangles' words in a storage buffer.
pub const TRI_WORDS: u32 = 1;
/// The layout's node words in a storage texture.
pub const NODE_TEXELS: u32 = 10;
/// The leaf triangles' words in a storage texture.
pub const TRI_TEXELS: u32 = 11;

/// The node words' bindings: part k ≥ 1 of an array bigger than one storage binding at
/// `100 + k` (buffer memory, `gpu::word_array`).
pub const NODE_ARRAY: ArrayBindings = ArrayBindings {
    words: NODE_WORDS,
    parts: 100,
    texels: Some(NODE_TEXELS),
};
/// The leaf triangles' bindings (parts from 201).
pub const TRI_ARRAY: ArrayBindings = ArrayBindings {
    words: TRI_WORDS,
    parts: 200,
    texels: Some(TRI_TEXELS),
};
/// The render kernel's shading words' bindings (parts from 301).
pub const SHADE_ARRAY: ArrayBindings = ArrayBindings {
    words: RENDER_SHADES,
    parts: 300,
    texels: Some(RENDER_SHADE_TEXELS),
};
/// The render kernel's texels (textures, coordinate maps, the environment map and its CDF),
/// in buffer memory whatever the BVH's (parts from 401).
pub const TEXEL_ARRAY: ArrayBindings = ArrayBindings {
    words: RENDER_TEXELS,
    parts: 400,
    texels: None,
};

/// The render kernel's accumulator (parts from 501).
pub const ACCUM_ARRAY: ArrayBindings = ArrayBindings {
    words: RENDER_ACCUM,
    parts: 500,
    texels: None,
};

/// Trace kernel: rays.
pub const TRACE_RAYS: u32 = 2;
/// Trace kernel: hits.
pub const TRACE_HITS: u32 = 3;
/// Trace kernel: per-ray statistics.
pub const TRACE_STATS: u32 = 4;
/// Trace kernel: the dispatch's uniform.
pub const TRACE_PARAMS: u32 = 5;

/// Driver trace kernel: the driver's acceleration structure.
pub const DRIVER_SCENE: u32 = 12;

/// Render kernel: shading triangles' words in a storage buffer.
pub const RENDER_SHADES: u32 = 2;
/// Render kernel: shading triangles' words in a storage texture (the BVH's memory).
pub const RENDER_SHADE_TEXELS: u32 = 13;
/// Render kernel: materials.
pub const RENDER_MATERIALS: u32 = 3;
/// Render kernel: point and directional lights.
pub const RENDER_LIGHTS: u32 = 4;
/// Render kernel: emitting triangles and their area CDF.
pub const RENDER_EMITTERS: u32 = 5;
/// Render kernel: texture texels.
pub const RENDER_TEXELS: u32 = 6;
/// Render kernel: the accumulator.
pub const RENDER_ACCUM: u32 = 7;
/// Render kernel: the dispatch's uniform.
pub const RENDER_PARAMS: u32 = 8;

/// Every binding by its WGSL name.
pub const ALL: &[(&str, u32)] = &[
    ("BINDING_NODE_WORDS", NODE_WORDS),
    ("BINDING_TRI_WORDS", TRI_WORDS),
    ("BINDING_NODE_TEXELS", NODE_TEXELS),
    ("BINDING_TRI_TEXELS", TRI_TEXELS),
    ("BINDING_TRACE_RAYS", TRACE_RAYS),
    ("BINDING_TRACE_HITS", TRACE_HITS),
    ("BINDING_TRACE_STATS", TRACE_STATS),
    ("BINDING_TRACE_PARAMS", TRACE_PARAMS),
    ("BINDING_DRIVER_SCENE", DRIVER_SCENE),
    ("BINDING_RENDER_SHADES", RENDER_SHADES),
    ("BINDING_RENDER_SHADE_TEXELS", RENDER_SHADE_TEXELS),
    ("BINDING_RENDER_MATERIALS", RENDER_MATERIALS),
    ("BINDING_RENDER_LIGHTS", RENDER_LIGHTS),
    ("BINDING_RENDER_EMITTERS", RENDER_EMITTERS),
    ("BINDING_RENDER_TEXELS", RENDER_TEXELS),
    ("BINDING_RENDER_ACCUM", RENDER_ACCUM),
    ("BINDING_RENDER_PARAMS", RENDER_PARAMS),
];
