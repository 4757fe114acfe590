//! Helpers shared by the integration tests: a seeded RNG, random soups and rays, models.
#![allow(dead_code)]

pub mod accel_check;
pub mod alike;
pub mod furnace;
pub mod gpu_twin;
pub mod hard;
pub mod readers;
pub mod scratch;
pub mod speed;
pub mod writers;

use std::path::PathBuf;
use std::sync::OnceLock;

use glam::Vec3;
use lancer::geometry::{Ray, Triangle};
use lancer::gpu::GpuContext;
use lancer::mesh::{load_obj, Mesh};
use lancer::Device;

/// The library's random stream ([`lancer::render::Rng`], the renderer's PCG hash) with the
/// draws the tests need: one RNG in the crate, seeded per test.
pub struct Rng(lancer::render::Rng);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(lancer::render::Rng::new(
            seed as u32,
            (seed >> 32) as u32,
            0x7e57,
        ))
    }
    pub fn u32(&mut self) -> u32 {
        self.0.next_u32()
    }
    pub fn u64(&mut self) -> u64 {
        (u64::from(self.u32()) << 32) | u64::from(self.u32())
    }
    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        self.0.next_f32()
    }
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }
    pub fn vec3(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
    /// Uniform direction on the sphere.
    pub fn dir(&mut self) -> Vec3 {
        lancer::accuracy::random_dir(&mut self.0)
    }
}

/// `n` random triangles in [-1, 1]³ with edges up to `size`.
pub fn soup(rng: &mut Rng, n: usize, size: f32) -> Mesh {
    let tris = (0..n)
        .map(|_| {
            let c = rng.vec3(-1.0, 1.0);
            Triangle::new(
                c + rng.vec3(-size, size),
                c + rng.vec3(-size, size),
                c + rng.vec3(-size, size),
            )
        })
        .collect();
    Mesh::from_triangles(tris)
}

/// `n` random rays through `mesh` ([`lancer::bench::rays::random_rays`]), seeded from `rng`.
pub fn random_rays(rng: &mut Rng, n: usize, mesh: &Mesh) -> Vec<Ray> {
    lancer::bench::rays::random_rays(mesh, n, rng.u32())
}

/// Path of a shared test model, or None (with a printed reason) when ../shared is absent.
pub fn model(name: &str) -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/models")
        .join(name);
    if p.exists() {
        Some(p)
    } else {
        assert!(
            std::env::var("CI").is_err(),
            "{} is missing in CI: ../shared/models must be beside the checkout",
            p.display()
        );
        eprintln!("skipping: {} not found", p.display());
        None
    }
}

pub fn load_model(name: &str) -> Option<Mesh> {
    model(name).map(|p| load_obj(&p).expect("model loads"))
}

/// The adapter for this test binary, as a [`Device`]. A GPU test never passes without one.
pub fn gpu_device() -> &'static Device {
    static DEVICE: OnceLock<Device> = OnceLock::new();
    DEVICE.get_or_init(|| match GpuContext::new() {
        Ok(c) => {
            println!("adapter: {}", c.adapter);
            Device::gpu(c)
        }
        Err(e) => panic!(
            "GPU tests need an adapter{}: {e}",
            if std::env::var("CI").is_ok() {
                " in CI"
            } else {
                ""
            }
        ),
    })
}

/// The adapter's context.
pub fn gpu() -> &'static GpuContext {
    gpu_device().gpu_context().expect("a GPU device")
}

/// proptest's settings for the integration test `name`: `cases` cases, and the failures it
/// finds kept in proptest-regressions/tests/NAME.txt, the one folder the library's unit
/// tests keep theirs in too (proptest would put them beside the test file).
pub fn proptest_config(name: &str, cases: u32) -> proptest::test_runner::Config {
    let path: &'static str = Box::leak(
        format!(
            "{}/proptest-regressions/tests/{name}.txt",
            env!("CARGO_MANIFEST_DIR")
        )
        .into_boxed_str(),
    );
    proptest::test_runner::Config {
        cases,
        failure_persistence: Some(Box::new(
            proptest::test_runner::FileFailurePersistence::Direct(path),
        )),
        ..proptest::test_runner::Config::default()
    }
}
