//! Helpers shared by the integration tests: a seeded RNG, random soups and rays, models.
#![allow(dead_code)]

pub mod accel_check;
pub mod gpu_twin;
pub mod hard;
pub mod writers;

use std::path::PathBuf;
use std::sync::OnceLock;

use glam::Vec3;
use lancer::geometry::{Ray, Triangle};
use lancer::gpu::GpuContext;
use lancer::mesh::{load_obj, Mesh};
use lancer::Device;

/// xorshift64*: small, seeded, reproducible.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }
    pub fn vec3(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
    /// Uniform direction on the sphere.
    pub fn dir(&mut self) -> Vec3 {
        loop {
            let v = self.vec3(-1.0, 1.0);
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
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

/// Rays from random points around the scene towards random points inside it.
pub fn random_rays(rng: &mut Rng, n: usize, mesh: &Mesh) -> Vec<Ray> {
    let b = mesh.bounds();
    let c = b.center();
    let r = 0.5 * b.extent().length();
    (0..n)
        .map(|_| {
            let o = c + rng.dir() * r * rng.range(0.2, 2.0);
            let target = b.lo + (b.hi - b.lo) * Vec3::new(rng.f32(), rng.f32(), rng.f32());
            Ray::new(o, (target - o).normalize(), 0.0, 3.4e38)
        })
        .collect()
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
