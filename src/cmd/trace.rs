use std::path::PathBuf;

use clap::{Args, ValueEnum};
use lancer::accel::bvh::{build, FlatBvh};
use lancer::geometry::TriangleTest;
use lancer::scene::load_mesh;
use lancer::trace::rays::{read_rays, write_hits};
use lancer::trace::{trace_batch, Query};
use lancer::Result;

use super::BuildArgs;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Device {
    Cpu,
}

#[derive(Args)]
pub struct TraceCmd {
    /// OBJ mesh.
    mesh: PathBuf,
    /// Input ray file (32 bytes a ray).
    #[arg(long)]
    rays: PathBuf,
    /// Output hit file (16 bytes a ray).
    #[arg(long)]
    out: PathBuf,
    #[arg(long, value_enum, default_value_t = Device::Cpu)]
    device: Device,
    /// Any hit (occlusion) instead of the closest hit.
    #[arg(long)]
    any_hit: bool,
    /// Triangle test.
    #[arg(long, value_enum, default_value_t = TriangleTest::Watertight)]
    triangle_test: TriangleTest,
    /// Print traversal statistics.
    #[arg(long)]
    stats: bool,
    #[command(flatten)]
    build: BuildArgs,
}

impl TraceCmd {
    pub fn run(self) -> Result<()> {
        let mesh = load_mesh(&self.mesh)?;
        let rays = read_rays(&self.rays)?;
        let flat = FlatBvh::new(&build(&mesh, &self.build.options()), &mesh);
        let query = if self.any_hit {
            Query::Any
        } else {
            Query::Closest
        };
        let (hits, stats) = trace_batch(&flat, &rays, query, self.triangle_test);
        write_hits(&self.out, &hits)?;
        let n = rays.len().max(1) as f64;
        let hit_count = hits.iter().filter(|h| h.is_hit()).count();
        println!(
            "{} rays, {} hits, written to {}",
            rays.len(),
            hit_count,
            self.out.display()
        );
        if self.stats {
            let nodes: u64 = stats.iter().map(|s| s.nodes as u64).sum();
            let tris: u64 = stats.iter().map(|s| s.tris as u64).sum();
            println!(
                "nodes/ray {:.2}  triangles/ray {:.2}",
                nodes as f64 / n,
                tris as f64 / n
            );
        }
        Ok(())
    }
}
