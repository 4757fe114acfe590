//! `lancer compare A B`: two images, or two hit files.

use std::path::PathBuf;

use clap::Args;
use lancer::mesh::load_mesh;
use lancer::render::{compare_images, load_image};
use lancer::trace::compare::{compare_hits, T_ULPS};
use lancer::trace::files::{read_hits, read_rays};
use lancer::{Error, Query, Result};

#[derive(Args)]
pub struct CompareCmd {
    /// First file: an image (.png, .exr) or a hit file (16 bytes a ray); the reference.
    a: PathBuf,
    /// Second file, of the same kind.
    b: PathBuf,
    /// Images: a pixel differs when a channel differs by more than this (linear radiance;
    /// PNG values are linearised first).
    #[arg(long, default_value_t = 0.01, value_parser = super::non_negative_finite)]
    threshold: f32,
    /// Images: exit with code 1 when more than this percentage of pixels differ.
    #[arg(long, default_value_t = 0.0, value_parser = super::non_negative_finite)]
    tolerance: f32,
    /// Images: write the difference as a PNG (black where equal, yellow at --threshold × 10).
    #[arg(short, long)]
    out: Option<PathBuf>,
    /// Hit files: the mesh that was traced; with --rays, differences are judged by the f64
    /// oracle (a genuine tie is not a disagreement).
    #[arg(long, requires = "rays")]
    mesh: Option<PathBuf>,
    /// Hit files: the ray file that was traced.
    #[arg(long, requires = "mesh")]
    rays: Option<PathBuf>,
    /// Hit files: the answers are any-hit (occlusion) answers.
    #[arg(long)]
    any_hit: bool,
}

impl CompareCmd {
    pub fn run(self) -> Result<()> {
        let image = |p: &PathBuf| lancer::render::image_kind(p).is_ok();
        match (image(&self.a), image(&self.b)) {
            (true, true) => self.images(),
            (false, false) => self.hits(),
            _ => Err(Error::Usage(format!(
                "{} and {} are not of one kind: compare two images (.png, .exr) or two hit files",
                self.a.display(),
                self.b.display()
            ))),
        }
    }

    fn images(&self) -> Result<()> {
        if let Some(out) = &self.out {
            lancer::output::check_output(out, &[self.a.clone(), self.b.clone()])?;
            if lancer::render::image_kind(out)? != lancer::render::ImageKind::Png {
                return Err(Error::input(
                    out,
                    None,
                    "the difference is a PNG: use a .png name",
                ));
            }
        }
        let (a, b) = (load_image(&self.a)?, load_image(&self.b)?);
        let d = compare_images(&a, &b, self.threshold)?;
        println!(
            "{}×{} pixels: max difference {:.6}, mean {:.6}, RMSE {:.6}; {} pixels ({:.3} %) \
             over {}",
            d.width,
            d.height,
            d.max,
            d.mean,
            d.rmse,
            d.over,
            d.over_percent(),
            d.threshold
        );
        if let Some(out) = &self.out {
            let picture = d.picture(self.threshold * 10.0);
            lancer::output::write_atomic(out, |w| {
                picture
                    .write_to(w, image::ImageFormat::Png)
                    .map_err(std::io::Error::other)
            })?;
            println!("difference -> {}", out.display());
        }
        if d.over_percent() > self.tolerance as f64 {
            return Err(Error::Differ(format!(
                "the images differ: {:.3} % of pixels over {}, more than the tolerance of {} %",
                d.over_percent(),
                d.threshold,
                self.tolerance
            )));
        }
        Ok(())
    }

    fn hits(&self) -> Result<()> {
        if self.out.is_some() {
            return Err(Error::Usage(
                "--out draws an image difference; hit files have none".into(),
            ));
        }
        let (a, b) = (read_hits(&self.a)?, read_hits(&self.b)?);
        if a.len() != b.len() {
            return Err(Error::Usage(format!(
                "{} holds {} answers and {} holds {}: compare answers to one ray file",
                self.a.display(),
                a.len(),
                self.b.display(),
                b.len()
            )));
        }
        let query = if self.any_hit {
            Query::Any
        } else {
            Query::Closest
        };
        let (Some(mesh), Some(rays)) = (&self.mesh, &self.rays) else {
            // No oracle: only identity and t within T_ULPS on the same triangle.
            let same = |x: &lancer::Hit, y: &lancer::Hit| {
                x.prim == y.prim
                    && (!x.is_hit()
                        || (x.t.to_bits() as i64 - y.t.to_bits() as i64).abs() <= T_ULPS as i64)
            };
            let identical = (a.iter().zip(&b))
                .filter(|(x, y)| {
                    x.t.to_bits() == y.t.to_bits()
                        && x.prim == y.prim
                        && x.u.to_bits() == y.u.to_bits()
                        && x.v.to_bits() == y.v.to_bits()
                })
                .count();
            let agree = a.iter().zip(&b).filter(|(x, y)| same(x, y)).count();
            println!(
                "{} rays: {identical} identical, {agree} agree (same triangle, t within {T_ULPS} \
                 ulp), {} differ (give --mesh and --rays to have the oracle judge them)",
                a.len(),
                a.len() - agree
            );
            if agree < a.len() {
                return Err(Error::Differ(format!("{} answers differ", a.len() - agree)));
            }
            return Ok(());
        };
        let mesh = load_mesh(mesh)?;
        let rays = read_rays(rays)?;
        if rays.len() != a.len() {
            return Err(Error::Usage(format!(
                "the ray file holds {} rays and the hit files {} answers: give the rays that were traced",
                rays.len(),
                a.len()
            )));
        }
        let c = compare_hits(&mesh, &rays, query, &a, &b);
        println!(
            "{} rays: {} identical, {} agree (same triangle, t within {T_ULPS} ulp), {} genuine \
             ties (the f64 oracle finds both right), {} disagree",
            rays.len(),
            c.identical,
            c.agree,
            c.ties,
            c.disagree.len()
        );
        for d in c.disagree.iter().take(10) {
            println!(
                "  ray {}: {:?} vs {:?}: {}",
                d.ray, d.reference, d.other, d.why
            );
        }
        if !c.disagree.is_empty() {
            return Err(Error::Differ(format!(
                "{} answers disagree (the first listed above)",
                c.disagree.len()
            )));
        }
        Ok(())
    }
}
