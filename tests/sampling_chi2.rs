//! χ² goodness-of-fit tests of the renderer's sampling routines against the densities it
//! weights their samples by, as Mitsuba 3's own suite tests its samplers: directions are
//! counted in equal-area bins of (φ, cos θ); a bin's expected count is the density
//! integrated over it (the midpoint rule on a 16 × 16 sub-grid); bins expecting fewer than
//! 5 samples are pooled; the statistic's p-value (Wilson–Hilferty) must exceed 0.01 over
//! the number of tests (Bonferroni). A density that is not the sampler's fails. Sampled:
//! the cosine lobe, the environment (uniform and a map), and glTF's metallic-roughness
//! (a rough metal's visible normals, a plastic's two lobes).

use glam::{Mat3, Vec3};
use lancer::render::{cosine_direction, Bsdf, EnvMap, Environment, Principled, Rng};

const SAMPLES: u32 = 200_000;
const PHI_BINS: usize = 32;
const Z_BINS: usize = 16;
const SUB: usize = 16;
/// The tests in this file (for Bonferroni's correction).
const TESTS: f64 = 5.0;

/// The unit direction at azimuth φ and z = cos θ.
fn direction(phi: f64, z: f64) -> Vec3 {
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32)
}

/// The bin of a unit direction.
fn bin(d: Vec3) -> usize {
    let phi = (d.y as f64)
        .atan2(d.x as f64)
        .rem_euclid(std::f64::consts::TAU);
    let i = ((phi / std::f64::consts::TAU * PHI_BINS as f64) as usize).min(PHI_BINS - 1);
    let j = (((d.z as f64 + 1.0) * 0.5 * Z_BINS as f64) as usize).min(Z_BINS - 1);
    j * PHI_BINS + i
}

/// The p-value of the counts of `sample` (SAMPLES draws, None: no direction) against
/// `pdf` (solid-angle density).
fn p_value(mut sample: impl FnMut(&mut Rng) -> Option<Vec3>, pdf: impl Fn(Vec3) -> f64) -> f64 {
    let mut observed = vec![0.0f64; PHI_BINS * Z_BINS];
    let mut rng = Rng::new(7, 11, 13);
    for _ in 0..SAMPLES {
        if let Some(d) = sample(&mut rng) {
            observed[bin(d)] += 1.0;
        }
    }
    let (dphi, dz) = (std::f64::consts::TAU / PHI_BINS as f64, 2.0 / Z_BINS as f64);
    let mut expected = vec![0.0f64; PHI_BINS * Z_BINS];
    for j in 0..Z_BINS {
        for i in 0..PHI_BINS {
            let mut sum = 0.0;
            for b in 0..SUB {
                for a in 0..SUB {
                    let phi = (i as f64 + (a as f64 + 0.5) / SUB as f64) * dphi;
                    let z = -1.0 + (j as f64 + (b as f64 + 0.5) / SUB as f64) * dz;
                    sum += pdf(direction(phi, z));
                }
            }
            expected[j * PHI_BINS + i] = sum * dphi * dz / (SUB * SUB) as f64 * SAMPLES as f64;
        }
    }
    // Pool the bins expecting fewer than 5, sorted by their expectation.
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (mut stat, mut dof) = (0.0, 0i64);
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for k in order {
        if expected[k] < 5.0 {
            pool_o += observed[k];
            pool_e += expected[k];
            if pool_e >= 5.0 {
                stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
                dof += 1;
                (pool_o, pool_e) = (0.0, 0.0);
            }
        } else {
            stat += (observed[k] - expected[k]).powi(2) / expected[k];
            dof += 1;
        }
    }
    // Observed samples in bins expected empty: a density of 0 where the sampler goes.
    if pool_e < 5.0 && pool_o > pool_e + 5.0 {
        return 0.0;
    }
    let dof = (dof - 1).max(1) as f64;
    // Wilson–Hilferty: (χ²/k)^(1/3) is nearly normal with mean 1 − 2/(9k).
    let v = 2.0 / (9.0 * dof);
    let z = ((stat / dof).cbrt() - (1.0 - v)) / v.sqrt();
    let p = 0.5 * erfc(z / std::f64::consts::SQRT_2);
    println!("χ² = {stat:.1} over {dof} degrees of freedom: p = {p:.4}");
    p
}

/// The complementary error function (Numerical Recipes' erfcc, relative error < 1.2e-7).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let r = t
        * (-z * z - 1.265_512_23
            + t * (1.000_023_68
                + t * (0.374_091_96
                    + t * (0.096_784_18
                        + t * (-0.186_288_06
                            + t * (0.278_868_07
                                + t * (-1.135_203_98
                                    + t * (1.488_515_87
                                        + t * (-0.822_152_23 + t * 0.170_872_77)))))))))
            .exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

fn passes(p: f64) -> bool {
    p > 0.01 / TESTS
}

#[test]
fn the_cosine_lobe_draws_cos_theta_over_pi_and_not_the_uniform_hemisphere() {
    let n = Vec3::new(0.3, -0.5, 0.8).normalize();
    let lobe = |rng: &mut Rng| Some(cosine_direction(n, rng));
    let p = p_value(lobe, |d| {
        (n.dot(d).max(0.0) * std::f32::consts::FRAC_1_PI) as f64
    });
    assert!(passes(p), "cosine sampling against its density: p = {p}");
    // The test can fail: the uniform hemisphere's density is not the lobe's.
    let p = p_value(lobe, |d| {
        if n.dot(d) > 0.0 {
            0.5 / std::f64::consts::PI
        } else {
            0.0
        }
    });
    assert!(
        !passes(p),
        "the uniform density passes for the cosine lobe: p = {p}"
    );
}

#[test]
fn a_uniform_environment_draws_the_uniform_sphere() {
    let env = Environment::uniform(Vec3::ONE);
    let p = p_value(
        |r| env.sample(r.next_f32(), r.next_f32()).map(|s| s.dir),
        |d| env.pdf(d) as f64,
    );
    assert!(passes(p), "p = {p}");
}

#[test]
fn a_turned_map_draws_the_density_its_pdf_gives() {
    // A sky brighter toward one side and overhead, with a hot patch: 24 × 12 texels.
    let (w, h) = (24u32, 12u32);
    let texels = (0..w * h)
        .map(|k| {
            let (x, y) = (k % w, k / w);
            let hot = (10..13).contains(&x) && (3..5).contains(&y);
            Vec3::new(0.2 + x as f32 / w as f32, 1.0 - y as f32 / h as f32, 0.3)
                * if hot { 20.0 } else { 1.0 }
        })
        .collect();
    let map = EnvMap::new(w, h, texels).unwrap();
    let env = Environment::mapped(
        map,
        Vec3::ONE,
        Mat3::from_rotation_x(0.4) * Mat3::from_rotation_y(1.1),
    );
    let p = p_value(
        |r| env.sample(r.next_f32(), r.next_f32()).map(|s| s.dir),
        |d| env.pdf(d) as f64,
    );
    assert!(passes(p), "p = {p}");
}

/// The view `deg` degrees from the normal +z.
fn view(deg: f32) -> Vec3 {
    let t = deg.to_radians();
    Vec3::new(t.sin(), 0.0, t.cos())
}

#[test]
fn a_rough_metal_draws_its_visible_normals_and_not_all_its_normals() {
    let (n, wo) = (Vec3::Z, view(60.0));
    // α = 0.25: a lobe some 15° wide, away from the normal.
    let metal = Principled::new(Vec3::new(0.9, 0.6, 0.3), 1.0, 0.5);
    let bsdf = Bsdf::Principled(metal);
    let draw = |r: &mut Rng| bsdf.sample(n, wo, r).map(|s| s.dir);
    let p = p_value(draw, |d| bsdf.eval(n, wo, d).1 as f64);
    assert!(
        passes(p),
        "visible-normal sampling against its density: p = {p}"
    );
    // The test can fail: the density of normals drawn from D(h)·cos θh (not those seen
    // from wo), taken to the reflected direction, is not the sampler's.
    let a2 = (metal.alpha as f64).powi(2);
    let all_normals = |d: Vec3| {
        let (wo, wi) = (wo.as_dvec3(), d.as_dvec3());
        if wi.z <= 0.0 {
            return 0.0;
        }
        let h = (wo + wi).normalize();
        let k = h.z * h.z * (a2 - 1.0) + 1.0;
        let dh = a2 / (std::f64::consts::PI * k * k);
        dh * h.z / (4.0 * wo.dot(h))
    };
    let p = p_value(draw, all_normals);
    assert!(
        !passes(p),
        "the density of all normals passes for the visible ones: p = {p}"
    );
}

#[test]
fn a_rough_plastic_draws_the_mixture_of_its_two_lobes() {
    let (n, wo) = (Vec3::Z, view(35.0));
    let plastic = Bsdf::Principled(Principled::new(Vec3::new(0.8, 0.3, 0.2), 0.0, 0.7));
    let p = p_value(
        |r| plastic.sample(n, wo, r).map(|s| s.dir),
        |d| plastic.eval(n, wo, d).1 as f64,
    );
    assert!(passes(p), "p = {p}");
}
