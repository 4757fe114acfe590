//! Sine, cosine and arctangent as polynomials in + − × ÷ and `floor`, shared operation for
//! operation with shaders/lib/environment.wgsl: a GPU's `sin`, `cos` and `atan2` are its
//! own approximations, so the environment light would look up and sample other texels on
//! the CPU than on the GPU. These give the same bits on both, within 2·10⁻⁶ of the true
//! angle (a texel of a 4096-wide map spans 1.5·10⁻³ radians).

/// Taylor coefficients of sin(a)/a − 1 in powers of a² (a in [−π/4, π/4]: the next term
/// is below 3·10⁻⁸). WGSL `SIN_C1` … `SIN_C4`.
pub const SIN_C: [f32; 4] = [-1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362_880.0];
/// Taylor coefficients of cos(a) − 1 in powers of a². WGSL `COS_C1` … `COS_C4`.
pub const COS_C: [f32; 4] = [-0.5, 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40_320.0];
/// A minimax fit of atan(a)/a on [0, 1] in powers of a² (error below 1.7·10⁻⁶ radians).
/// WGSL `ATAN_C0` … `ATAN_C5`.
pub const ATAN_C: [f32; 6] = [
    0.999_977_26,
    -0.332_623_47,
    0.193_543_46,
    -0.116_432_87,
    0.052_653_32,
    -0.011_721_2,
];

/// 1/(2π): radians to turns. WGSL `INV_TAU`.
pub const INV_TAU: f32 = 0.5 * std::f32::consts::FRAC_1_PI;

/// (sin, cos) of the angle of `t` turns (2π·t radians). WGSL `sin_cos_turns`.
pub fn sin_cos_turns(t: f32) -> (f32, f32) {
    // The nearest quarter turn q, and what is left of it: r in [−½, ½] quarter turns.
    let t4 = 4.0 * t;
    let q = (t4 + 0.5).floor();
    let a = (t4 - q) * std::f32::consts::FRAC_PI_2;
    let a2 = a * a;
    let s = a + a * a2 * (SIN_C[0] + a2 * (SIN_C[1] + a2 * (SIN_C[2] + a2 * SIN_C[3])));
    let c = 1.0 + a2 * (COS_C[0] + a2 * (COS_C[1] + a2 * (COS_C[2] + a2 * COS_C[3])));
    match (q as i32) & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// The angle of (x, y) from the +x axis in turns, in [−½, ½] (0 at the origin). WGSL
/// `atan2_turns`.
pub fn atan2_turns(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let hi = ax.max(ay);
    if hi == 0.0 {
        return 0.0;
    }
    let a = ax.min(ay) / hi;
    let s = a * a;
    let c = &ATAN_C;
    let mut r = a * (c[0] + s * (c[1] + s * (c[2] + s * (c[3] + s * (c[4] + s * c[5])))));
    if ay > ax {
        r = std::f32::consts::FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = std::f32::consts::PI - r;
    }
    if y < 0.0 {
        r = -r;
    }
    r * INV_TAU
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sine_and_cosine_are_within_their_bound_over_a_turn_and_beyond() {
        let mut worst = 0.0f64;
        for k in -4000..=8000 {
            let t = k as f32 / 4000.0;
            let (s, c) = sin_cos_turns(t);
            let a = std::f64::consts::TAU * t as f64;
            worst = worst.max((s as f64 - a.sin()).abs().max((c as f64 - a.cos()).abs()));
        }
        assert!(worst < 4e-7, "worst error {worst}");
        // Exact at the quarter turns, where the directions of a map's rows and columns
        // meet the axes.
        assert_eq!(sin_cos_turns(0.0), (0.0, 1.0));
        assert_eq!(sin_cos_turns(0.25), (1.0, -0.0));
        assert_eq!(sin_cos_turns(0.5).1, -1.0);
    }

    #[test]
    fn arctangent_is_within_its_bound_in_every_octant() {
        let mut worst = 0.0f64;
        for k in 0..20_000 {
            let a = std::f64::consts::TAU * k as f64 / 20_000.0 - std::f64::consts::PI;
            for r in [1e-3f64, 1.0, 7e4] {
                let (x, y) = ((r * a.cos()) as f32, (r * a.sin()) as f32);
                let want = (y as f64).atan2(x as f64) / std::f64::consts::TAU;
                worst = worst.max((atan2_turns(y, x) as f64 - want).abs());
            }
        }
        // 1.7e-6 radians is 2.7e-7 turns; f32 rounding adds a little.
        assert!(worst < 4e-7, "worst error {worst} turns");
        assert_eq!(atan2_turns(0.0, 0.0), 0.0);
        assert_eq!(atan2_turns(0.0, -1.0), 0.5);
        assert_eq!(atan2_turns(1.0, 0.0), 0.25);
    }
}
