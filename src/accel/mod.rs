//! Acceleration structures.

pub mod bvh;
