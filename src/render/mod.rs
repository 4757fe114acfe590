//! Rendering on top of the tracers.

mod preview;

pub use preview::{preview, PreviewOptions};
