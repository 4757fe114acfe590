//! `lancer compare A B`: two images, or two hit files.

use std::path::PathBuf;

use clap::Args;
use lancer::mesh::load_mesh;
use lancer::render::{compare_images, load_image};
use lancer::trace::compare::{compare_hits_judged, count_agreement, HitsReport, T_ULPS};
use lancer::trace::files::{read_hits, read_rays};
use lancer::{Error, Query, Result};

use super::out::{print_json, say, Say};

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
    /// Images: write the difference as a PNG (black where equal, yellow at --threshold × 10);
    /// none by default.
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
    /// Hit files: the same triangle at a t at most this many units in the last place
    /// apart agrees. With --mesh and --rays, a t further off still agrees where the f64
    /// oracle accepts it (within its error bound), as another kernel's arithmetic may give.
    #[arg(long, default_value_t = T_ULPS, value_parser = clap::value_parser!(u32).range(0..=1_000_000))]
    t_ulps: u32,
    /// Print the result as one JSON object on stdout, the text on stderr (keys: the
    /// book's JSON page, docs/src/reference/json.md).
    #[arg(long)]
    json: bool,
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
            if !(out.extension()).is_some_and(|e| e.eq_ignore_ascii_case("png")) {
                return Err(Error::input(
                    out,
                    None,
                    "the difference is a PNG: use a .png name",
                ));
            }
        }
        let (a, b) = (load_image(&self.a)?, load_image(&self.b)?);
        let d = compare_images(&a, &b, self.threshold)?;
        let say = Say::new(self.json);
        say!(say, "{}", d.summary());
        if let Some(out) = &self.out {
            d.write_picture(out, self.threshold * 10.0)?;
            say!(say, "difference -> {}", out.display());
        }
        if self.json {
            print_json(&d.report(self.tolerance, self.out.as_deref()))?;
        }
        if d.differ(self.tolerance) {
            return Err(Error::Differ(format!(
                "the images differ: {:.3} % of pixels over {:e}, more than the tolerance of {} %",
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
        let say = Say::new(self.json);
        let (Some(mesh), Some(rays)) = (&self.mesh, &self.rays) else {
            // No oracle: only identity and t within --t-ulps on the same triangle.
            let c = count_agreement(&a, &b, self.t_ulps);
            let report = HitsReport::unjudged(&c);
            say!(say, "{}", report.summary(self.t_ulps));
            if self.json {
                print_json(&report)?;
            }
            if c.differ() > 0 {
                return Err(Error::Differ(format!("{} answers differ", c.differ())));
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
        // Another kernel's t comes from other arithmetic: on the same triangle, the oracle
        // judges any t beyond --t-ulps.
        let c = compare_hits_judged(&mesh, &rays, query, &a, &b, self.t_ulps);
        let report = HitsReport::judged(rays.len(), &c);
        say!(say, "{}", report.summary(self.t_ulps));
        for d in c.disagree.iter().take(10) {
            say!(
                say,
                "  ray {}: {:?} vs {:?}: {}",
                d.ray,
                d.reference,
                d.other,
                d.why
            );
        }
        if self.json {
            print_json(&report)?;
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
