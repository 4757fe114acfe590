//! The fuzz targets' entry points: the readers by target name, shared with the test suite's
//! regression cases (tests/common/readers.rs).

#[path = "../../tests/common/readers.rs"]
mod readers;

pub use readers::{run, TARGETS};
