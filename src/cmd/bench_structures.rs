//! `lancer bench structures`: every acceleration structure on one mesh, side by side in one
//! run: build time, memory, duplicated references, work and speed per ray on the CPU.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lancer::accel::bih::Bih;
use lancer::accel::bvh::{build, BuildOptions, BvhStats};
use lancer::accel::grid::{GridStats, HashedGrid, TwoLevelGrid, UniformGrid};
use lancer::accel::kdtree::KdTree;
use lancer::accel::octree::Octree;
use lancer::camera::Camera;
use lancer::layout::{flatten, LayoutKind};
use lancer::mesh::load_mesh;
use lancer::trace::files::{default_light, shadow_rays};
use lancer::{Accel, AccelKind, Query, Ray, RayStats, Result, Robustness};

#[derive(Args)]
pub struct BenchStructures {
    /// OBJ mesh.
    mesh: PathBuf,
    /// Image width of the default view's primary rays.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Image height of the default view's primary rays.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    /// Timed runs per structure and ray set (the median is reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    repeat: u64,
}

/// A built structure with its memory and reference counts.
struct Built {
    accel: Box<dyn Accel>,
    build_ms: f64,
    bytes: u64,
    duplicated: u64,
    depth: String,
}

fn build_one(kind: AccelKind, mesh: &lancer::Mesh) -> Result<Built> {
    let start = Instant::now();
    let grid = |s: GridStats| (s.bytes, s.duplicated, "–".to_string());
    let (accel, (bytes, duplicated, depth)): (Box<dyn Accel>, _) = match kind {
        AccelKind::Bvh(layout) => {
            let opts = BuildOptions::default();
            let tree = build(mesh, &opts);
            let depth = BvhStats::of(&tree, &opts).max_depth.to_string();
            let flat = flatten(layout, &tree, mesh);
            let bytes = flat.bytes() as u64;
            (flat, (bytes, 0, depth))
        }
        AccelKind::KdTree => {
            let t = KdTree::build(mesh, &Default::default())?;
            let s = t.stats();
            let info = (
                s.bytes as u64,
                s.duplicated_references as u64,
                s.max_depth.to_string(),
            );
            (Box::new(t), info)
        }
        AccelKind::UniformGrid => {
            let g = UniformGrid::build(mesh, &Default::default())?;
            let info = grid(g.stats());
            (Box::new(g), info)
        }
        AccelKind::TwoLevelGrid => {
            let g = TwoLevelGrid::build(mesh, &Default::default())?;
            let info = grid(g.stats());
            (Box::new(g), info)
        }
        AccelKind::HashedGrid => {
            let g = HashedGrid::build(mesh, &Default::default())?;
            let info = grid(g.stats());
            (Box::new(g), info)
        }
        AccelKind::Bih => {
            let t = Bih::build(mesh, &Default::default())?;
            let s = t.stats();
            (Box::new(t), (s.bytes as u64, 0, s.max_depth.to_string()))
        }
        AccelKind::Octree => {
            let t = Octree::build(mesh, &Default::default())?;
            let s = t.stats();
            let info = (
                s.bytes as u64,
                s.duplicated_references as u64,
                s.max_depth.to_string(),
            );
            (Box::new(t), info)
        }
    };
    Ok(Built {
        accel,
        build_ms: start.elapsed().as_secs_f64() * 1e3,
        bytes,
        duplicated,
        depth,
    })
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

impl BenchStructures {
    pub fn run(self) -> Result<()> {
        let mesh = load_mesh(&self.mesh)?;
        lancer::limits::check_image(
            self.width,
            self.height,
            200,
            "use a smaller --width/--height",
        )?;
        let primary = Camera::default_view(&mesh.bounds(), self.width, self.height).primary_rays();
        let rob = Robustness::default();
        let bvh = flatten(
            LayoutKind::default(),
            &build(&mesh, &BuildOptions::default()),
            &mesh,
        );
        let (hits, _) = bvh.trace_batch(&primary, Query::Closest, &rob);
        let shadow = shadow_rays(&primary, &hits, default_light(&mesh.bounds()));
        let sets: [(&str, Query, &[Ray]); 2] = [
            ("primary", Query::Closest, &primary),
            ("shadow", Query::Any, &shadow),
        ];
        let kinds = AccelKind::ALL;
        let bar = ProgressBar::new((kinds.len() * (1 + 2 * self.repeat as usize)) as u64);
        bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} {msg}").unwrap());
        let mut rows = Vec::new();
        for &kind in kinds {
            bar.set_message(format!("building {kind}"));
            let b = build_one(kind, &mesh)?;
            bar.inc(1);
            let mut cells = Vec::new();
            for (name, query, rays) in sets {
                bar.set_message(format!("{kind}, {name} rays"));
                let mut times = Vec::new();
                let mut stats: Vec<RayStats> = Vec::new();
                for _ in 0..self.repeat {
                    let t0 = Instant::now();
                    let (_, s) = b.accel.trace_batch(rays, query, &rob);
                    times.push(t0.elapsed().as_secs_f64());
                    stats = s;
                    bar.inc(1);
                }
                let (nodes, tris) = RayStats::means(&stats);
                let rate = rays.len() as f64 / median(times) / 1e6;
                cells.push(format!("{rate:.2} | {nodes:.1} | {tris:.2}"));
            }
            rows.push(format!(
                "| {kind} | {:.1} | {:.1} | {} | {} | {} |",
                b.build_ms,
                b.bytes as f64 / 1048576.0,
                b.duplicated,
                b.depth,
                cells.join(" | ")
            ));
        }
        bar.finish_and_clear();
        println!(
            "mesh {}  {} triangles  {}x{} primary, {} shadow rays  cpu ({} threads)",
            self.mesh.display(),
            mesh.included().len(),
            self.width,
            self.height,
            shadow.len(),
            rayon::current_num_threads()
        );
        println!("| structure | build ms | MiB | duplicated refs | max depth | primary Mrays/s | nodes or cells/ray | tris/ray | shadow Mrays/s | nodes or cells/ray | tris/ray |");
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
        for r in rows {
            println!("{r}");
        }
        Ok(())
    }
}
