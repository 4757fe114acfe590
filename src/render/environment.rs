//! The environment light: radiance arriving from infinitely far away, the same from every
//! direction (`radiance = [r, g, b]`) or from an equirectangular map (`map = "sky.exr"`).
//! Rays that leave the scene see it, and every diffuse hit samples it in proportion to
//! its brightness (a piecewise-constant 2D distribution), combined with the BSDF's own
//! sampling by multiple importance sampling. shaders/lib/environment.wgsl is the same
//! code for the GPU.
//!
//! The map is placed as Mitsuba 3's `envmap` emitter places it: +Y is up, the map's top
//! row is straight up and its bottom row straight down (rows lie at θ = π·j/(rows − 1)),
//! column i lies at the azimuth φ = 2π·(i + ½)/width, and a direction of map space is
//! (sin φ sin θ, cos θ, −cos φ sin θ): the middle of the map looks along +Z, its left
//! edge along −Z. Between texels, radiance is interpolated bilinearly.

use std::path::Path;

use glam::{Mat3, Vec3};

use super::trig::{atan2_turns, sin_cos_turns};
use crate::error::{Error, Result};
use crate::geometry::dot;

/// The solid-angle density of a uniformly chosen direction: 1/(4π). WGSL
/// `UNIFORM_SPHERE_PDF`.
pub const UNIFORM_SPHERE_PDF: f32 = 0.25 * std::f32::consts::FRAC_1_PI;
/// A map direction's solid-angle density is its density in (u, v) times this, over
/// sin θ: 1/(2π²). WGSL `MAP_PDF_SCALE`.
pub const MAP_PDF_SCALE: f32 = 0.5 * std::f32::consts::FRAC_1_PI * std::f32::consts::FRAC_1_PI;

/// Light from infinitely far away.
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    /// The radiance from every direction (uniform), or what the map's texels are
    /// multiplied by (its `scale`), linear RGB.
    pub radiance: Vec3,
    /// The equirectangular map; None: uniform.
    pub map: Option<EnvMap>,
    /// The rows of the rotation from world space to map space.
    pub to_local: [Vec3; 3],
}

/// An equirectangular map of radiance and the distribution its samples are drawn from.
/// Only [`EnvMap::new`] (and [`read_map`]) make one, so its sizes always agree.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvMap {
    /// Texels a row (at least 2).
    pub(crate) width: u32,
    /// Rows (at least 2): the first straight up, the last straight down.
    pub(crate) height: u32,
    /// `width · height` texels, linear RGB, row-major from the top row.
    pub(crate) texels: Vec<Vec3>,
    /// The sampling distribution over the cells between texels (`width` cells a row,
    /// `height − 1` rows; a cell's weight is the mean luminance of its four texels times
    /// sin θ at its middle): the rows' CDF (`height` entries, from 0 to 1), then each
    /// row's CDF over its cells (`width + 1` entries each).
    pub(crate) cdf: Vec<f32>,
}

/// A direction chosen by [`Environment::sample`], with its solid-angle density.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvSample {
    /// Unit direction toward the environment, world space.
    pub dir: Vec3,
    /// Its solid-angle density (> 0).
    pub pdf: f32,
}

/// Rec. 709 luminance of linear RGB.
fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// The largest k in [0, n) with `cdf[base + k] ≤ u` (u in [0, 1), the entry at n being 1):
/// the cell u falls in; cells of zero width are never chosen. WGSL `env_find`.
fn find(cdf: &[f32], base: usize, n: u32, u: f32) -> u32 {
    let (mut lo, mut hi) = (0u32, n - 1);
    while lo < hi {
        let mid = (lo + hi).div_ceil(2);
        if cdf[base + mid as usize] <= u {
            lo = mid;
        } else {
            hi = mid - 1;
        }
    }
    lo
}

impl EnvMap {
    /// A map of `width × height` texels (row-major from the top row), with its sampling
    /// distribution; None when it is black everywhere, smaller than 2 × 2, or `texels`
    /// does not hold `width · height` texels.
    pub fn new(width: u32, height: u32, texels: Vec<Vec3>) -> Option<EnvMap> {
        if width < 2 || height < 2 || texels.len() as u64 != width as u64 * height as u64 {
            return None;
        }
        let (w, rows) = (width as usize, height as usize - 1);
        let at = |x: usize, y: usize| luminance(texels[y * w + x % w]).max(0.0) as f64;
        let mut cdf = Vec::with_capacity(rows + 1 + rows * (w + 1));
        cdf.resize(rows + 1, 0.0f32);
        let mut row_sums = Vec::with_capacity(rows);
        for j in 0..rows {
            let sin = (std::f64::consts::PI * (j as f64 + 0.5) / rows as f64).sin();
            let weights: Vec<f64> = (0..w)
                .map(|i| 0.25 * sin * (at(i, j) + at(i + 1, j) + at(i, j + 1) + at(i + 1, j + 1)))
                .collect();
            let sum: f64 = weights.iter().sum();
            row_sums.push(sum);
            push_cdf(&mut cdf, &weights, sum);
        }
        let total: f64 = row_sums.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let mut marginal = Vec::with_capacity(rows + 1);
        push_cdf(&mut marginal, &row_sums, total);
        cdf[..rows + 1].copy_from_slice(&marginal);
        Some(EnvMap {
            width,
            height,
            texels,
            cdf,
        })
    }

    /// Texels a row.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Rows of texels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The texels, linear RGB, row-major from the top row.
    pub fn texels(&self) -> &[Vec3] {
        &self.texels
    }

    /// The sampling distribution ([`EnvMap::new`]'s layout): the rows' CDF, then each
    /// row's CDF over its cells.
    pub fn cdf(&self) -> &[f32] {
        &self.cdf
    }

    /// Cells a row, rows of cells, as f32.
    fn cells(&self) -> (f32, f32) {
        (self.width as f32, (self.height - 1) as f32)
    }

    /// A map-space direction's map coordinates: (x, y) in texels, x in [0, width) (the
    /// texel columns at whole numbers), y in [0, height − 1]; and sin θ.
    fn coords(&self, l: Vec3) -> (f32, f32, f32) {
        let (w, rows) = self.cells();
        let mut u = atan2_turns(l.x, -l.z);
        if u < 0.0 {
            u += 1.0;
        }
        let sin_theta = (l.x * l.x + l.z * l.z).sqrt();
        let v = 2.0 * atan2_turns(sin_theta, l.y);
        let mut x = u * w - 0.5;
        if x < 0.0 {
            x += w;
        }
        (x, v * rows, sin_theta)
    }

    /// The cell of map coordinates (x, y).
    fn cell(&self, x: f32, y: f32) -> (u32, u32) {
        let i = (x.floor() as u32).min(self.width - 1);
        let j = (y.floor() as u32).min(self.height - 2);
        (i, j)
    }

    /// The probability of cell (i, j) in the distribution.
    fn cell_probability(&self, i: u32, j: u32) -> f32 {
        let rows = self.height as usize - 1;
        let base = rows + 1 + j as usize * (self.width as usize + 1);
        let c = &self.cdf;
        (c[j as usize + 1] - c[j as usize]) * (c[base + i as usize + 1] - c[base + i as usize])
    }

    /// The texels at map coordinates (x, y), interpolated bilinearly.
    fn lookup(&self, x: f32, y: f32) -> Vec3 {
        let (i, j) = self.cell(x, y);
        let (tx, ty) = (x - i as f32, y - j as f32);
        let w = self.width;
        let at = |i: u32, j: u32| self.texels[(j * w + i) as usize];
        let i1 = (i + 1) % w;
        let (a, b) = (at(i, j), at(i1, j));
        let (c, d) = (at(i, j + 1), at(i1, j + 1));
        let top = a + (b - a) * tx;
        let bottom = c + (d - c) * tx;
        top + (bottom - top) * ty
    }
}

/// Appends the CDF of `weights` (their running sums over `sum`, from 0 to exactly 1; even
/// steps where `sum` is 0).
fn push_cdf(cdf: &mut Vec<f32>, weights: &[f64], sum: f64) {
    let n = weights.len();
    let mut run = 0.0f64;
    cdf.push(0.0);
    for (k, w) in weights.iter().enumerate() {
        run += w;
        cdf.push(if k + 1 == n {
            1.0
        } else if sum > 0.0 {
            (run / sum) as f32
        } else {
            (k + 1) as f32 / n as f32
        });
    }
}

impl Environment {
    /// The same `radiance` from every direction.
    pub fn uniform(radiance: Vec3) -> Environment {
        Environment {
            radiance,
            map: None,
            to_local: [Vec3::X, Vec3::Y, Vec3::Z],
        }
    }

    /// `map` times `scale`, turned by `rotation` (map space to world space).
    pub fn mapped(map: EnvMap, scale: Vec3, rotation: Mat3) -> Environment {
        // The rows of the inverse rotation are the columns of the rotation.
        Environment {
            radiance: scale,
            map: Some(map),
            to_local: [rotation.x_axis, rotation.y_axis, rotation.z_axis],
        }
    }

    /// The map in the file `path` (OpenEXR or Radiance HDR) times `scale`, turned by
    /// `rotate` degrees about X, then Y, then Z (as an object's `rotate`); None where the
    /// map or the scale is black (with a warning for the map).
    pub fn from_map_file(path: &Path, scale: f32, rotate: [f32; 3]) -> Result<Option<Environment>> {
        if !(scale.is_finite() && scale >= 0.0 && rotate.iter().all(|x| x.is_finite())) {
            return Err(Error::input(
                path,
                None,
                format!(
                    "an environment map's scale must be finite and ≥ 0 and its rotation \
                     finite, got {scale} and {rotate:?}"
                ),
            ));
        }
        let Some(map) = read_map(path)? else {
            log::warn!(
                "{}: the environment map is black: no environment light",
                path.display()
            );
            return Ok(None);
        };
        let [rx, ry, rz] = rotate.map(f32::to_radians);
        let rotation =
            Mat3::from_rotation_z(rz) * Mat3::from_rotation_y(ry) * Mat3::from_rotation_x(rx);
        Ok((scale > 0.0).then(|| Environment::mapped(map, Vec3::splat(scale), rotation)))
    }

    /// A world-space direction in map space.
    fn local(&self, d: Vec3) -> Vec3 {
        let r = &self.to_local;
        Vec3::new(dot(r[0], d), dot(r[1], d), dot(r[2], d))
    }

    /// The radiance arriving along the unit direction `-dir` (seen looking along `dir`).
    /// WGSL `env_eval`.
    pub fn eval(&self, dir: Vec3) -> Vec3 {
        match &self.map {
            None => self.radiance,
            Some(m) => {
                let (x, y, _) = m.coords(self.local(dir));
                self.radiance * m.lookup(x, y)
            }
        }
    }

    /// The solid-angle density with which [`Environment::sample`] picks `dir` (unit).
    /// WGSL `env_pdf`.
    pub fn pdf(&self, dir: Vec3) -> f32 {
        match &self.map {
            None => UNIFORM_SPHERE_PDF,
            Some(m) => {
                let (x, y, sin_theta) = m.coords(self.local(dir));
                if sin_theta.is_nan() || sin_theta <= 0.0 {
                    return 0.0;
                }
                let (i, j) = m.cell(x, y);
                let (w, rows) = m.cells();
                m.cell_probability(i, j) * (w * rows) * MAP_PDF_SCALE / sin_theta
            }
        }
    }

    /// A direction toward the environment from two uniform numbers in [0, 1): uniform
    /// over the sphere, or in proportion to the map's brightness; None where the sample
    /// lands on a pole of the map (of density zero). WGSL `env_sample`.
    pub fn sample(&self, u1: f32, u2: f32) -> Option<EnvSample> {
        let Some(m) = &self.map else {
            let y = 1.0 - 2.0 * u1;
            let r = (1.0 - y * y).max(0.0).sqrt();
            let (s, c) = sin_cos_turns(u2);
            return Some(EnvSample {
                dir: Vec3::new(r * s, y, -r * c),
                pdf: UNIFORM_SPHERE_PDF,
            });
        };
        let (w, rows) = m.cells();
        let c = &m.cdf;
        let j = find(c, 0, m.height - 1, u1);
        let p_row = c[j as usize + 1] - c[j as usize];
        let dv = (u1 - c[j as usize]) / p_row;
        let base = m.height as usize + j as usize * (m.width as usize + 1);
        let i = find(c, base, m.width, u2);
        let p_col = c[base + i as usize + 1] - c[base + i as usize];
        let du = (u2 - c[base + i as usize]) / p_col;
        let mut u = (i as f32 + du + 0.5) / w;
        if u >= 1.0 {
            u -= 1.0;
        }
        let v = (j as f32 + dv) / rows;
        let (sin_theta, cos_theta) = sin_cos_turns(0.5 * v);
        if sin_theta.is_nan() || sin_theta <= 0.0 {
            return None;
        }
        let (sin_phi, cos_phi) = sin_cos_turns(u);
        let l = Vec3::new(sin_phi * sin_theta, cos_theta, -cos_phi * sin_theta);
        let r = &self.to_local;
        Some(EnvSample {
            dir: r[0] * l.x + r[1] * l.y + r[2] * l.z,
            pdf: p_row * p_col * (w * rows) * MAP_PDF_SCALE / sin_theta,
        })
    }
}

/// Reads an equirectangular map: OpenEXR (.exr) or Radiance RGBE (.hdr), linear RGB, by
/// its content; its size is checked from its header before it is decoded. None when it
/// is black everywhere.
pub fn read_map(path: &Path) -> Result<Option<EnvMap>> {
    let bytes = crate::input::read(path)?;
    let bad = |e: String| Error::input(path, None, format!("cannot read the environment map: {e}"));
    let reader = || {
        image::ImageReader::new(std::io::Cursor::new(&bytes))
            .with_guessed_format()
            .map_err(|e| bad(e.to_string()))
    };
    let (width, height) = (reader()?.into_dimensions()).map_err(|e| bad(e.to_string()))?;
    let side = crate::limits::MAX_TEXTURE_SIDE;
    if width > side || height > side {
        return Err(bad(format!(
            "a {width}×{height} map is larger than {side} a side: scale it down"
        )));
    }
    if width < 2 || height < 2 {
        return Err(bad(format!(
            "a {width}×{height} map: an environment map has at least 2×2 texels"
        )));
    }
    // The decoded image (up to 16 bytes a texel), its RGB f32 copy, the texels and the
    // distribution.
    crate::limits::check_image(width, height, 16 + 12 + 12 + 4, "scale the map down")
        .map_err(|e| bad(e.to_string()))?;
    let img = crate::limits::decode_checked(reader()?, 16 * width as u64 * height as u64)
        .map_err(|e| bad(e.to_string()))?
        .to_rgb32f();
    let texels: Vec<Vec3> = img.pixels().map(|p| Vec3::from(p.0)).collect();
    if let Some(i) = texels
        .iter()
        .position(|t| !t.is_finite() || t.min_element() < 0.0)
    {
        let (x, y) = (i as u32 % width, i as u32 / width);
        return Err(bad(format!(
            "texel ({x}, {y}) is {} (radiance must be finite and ≥ 0)",
            texels[i]
        )));
    }
    Ok(EnvMap::new(width, height, texels))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A map whose every texel differs: a bright patch on a dim sky.
    fn patchy(width: u32, height: u32) -> EnvMap {
        let texels = (0..width * height)
            .map(|k| {
                let (x, y) = (k % width, k / width);
                let hot = x == width / 3 && y == height / 3;
                Vec3::new(0.1 + x as f32 * 0.01, 0.2 + y as f32 * 0.02, 0.3)
                    * if hot { 50.0 } else { 1.0 }
            })
            .collect();
        EnvMap::new(width, height, texels).expect("not black")
    }

    #[test]
    fn texel_centres_look_where_mitsuba_puts_them() {
        let m = patchy(8, 5);
        let env = Environment::mapped(m.clone(), Vec3::ONE, Mat3::IDENTITY);
        // Column i at φ = 2π(i + ½)/8, row j at θ = πj/4.
        for (i, j) in [(0u32, 1u32), (3, 2), (5, 3), (7, 1)] {
            let phi = std::f32::consts::TAU * (i as f32 + 0.5) / 8.0;
            let theta = std::f32::consts::PI * j as f32 / 4.0;
            let d = Vec3::new(
                phi.sin() * theta.sin(),
                theta.cos(),
                -phi.cos() * theta.sin(),
            );
            let want = m.texels[(j * 8 + i) as usize];
            let got = env.eval(d);
            assert!(
                (got - want).abs().max_element() < 1e-4 * want.max_element(),
                "{got} {want}"
            );
        }
        // Straight up is the top row's (every texel of it blends there).
        assert!(env.eval(Vec3::Y).y < 0.3);
    }

    #[test]
    fn samples_have_the_density_pdf_gives_them() {
        let env = Environment::mapped(
            patchy(16, 9),
            Vec3::ONE,
            Mat3::from_rotation_y(0.7) * Mat3::from_rotation_x(0.3),
        );
        let mut rng = crate::render::sampling::Rng::new(1, 2, 3);
        let (mut n, mut off) = (0, 0);
        for _ in 0..2000 {
            let (u1, u2) = (rng.next_f32(), rng.next_f32());
            let Some(s) = env.sample(u1, u2) else {
                continue;
            };
            assert!((s.dir.length() - 1.0).abs() < 1e-5);
            n += 1;
            // A sample on a cell's edge may be looked up in its neighbour: rarely.
            off += ((env.pdf(s.dir) - s.pdf).abs() > 1e-3 * s.pdf) as u32;
        }
        assert!(
            n > 1990 && off < 20,
            "{off} of {n} samples have another density"
        );
    }

    #[test]
    fn a_black_map_is_no_map_and_cdfs_end_at_one() {
        assert!(EnvMap::new(4, 3, vec![Vec3::ZERO; 12]).is_none());
        assert!(EnvMap::new(4, 1, vec![Vec3::ONE; 4]).is_none());
        assert!(EnvMap::new(4, 3, vec![Vec3::ONE; 11]).is_none());
        let m = patchy(6, 4);
        assert_eq!(m.cdf.len(), 4 + 3 * 7);
        assert_eq!(m.cdf[3], 1.0);
        for j in 0..3 {
            assert_eq!(m.cdf[4 + j * 7], 0.0);
            assert_eq!(m.cdf[4 + j * 7 + 6], 1.0);
        }
        assert!(m.cdf.windows(2).take(3).all(|w| w[0] <= w[1]));
    }
}
