//! Texture lookups: bilinear with wrap-around, of a texture's colour and of its alpha. WGSL
//! `texture_taps`, `sample_texture` and `sample_alpha` (shaders/kernels/render.wgsl) are the
//! same arithmetic.

use glam::{Vec2, Vec3};

use super::scene::Texture;

/// The four texels of a bilinear lookup at uv with wrap-around (row-major indices: top
/// left, top right, bottom left, bottom right) and the weights between them. WGSL:
/// `texture_taps`.
fn texture_taps(width: u32, height: u32, uv: Vec2) -> ([usize; 4], f32, f32) {
    let (w, h) = (width as i32, height as i32);
    let u = uv.x - uv.x.floor();
    let v = uv.y - uv.y.floor();
    let x = u * w as f32 - 0.5;
    let y = (1.0 - v) * h as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let wrap = |i: i32, n: i32| ((i % n) + n) % n;
    let (ix0, iy0) = (wrap(x0 as i32, w), wrap(y0 as i32, h));
    let (ix1, iy1) = ((ix0 + 1) % w, (iy0 + 1) % h);
    let at = |x: i32, y: i32| (y * w + x) as usize;
    (
        [at(ix0, iy0), at(ix1, iy0), at(ix0, iy1), at(ix1, iy1)],
        fx,
        fy,
    )
}

/// Where a texture is read at interpolated coordinates `uv`: moved by its material slot's
/// map ([`Material::uv_transforms`](super::scene::Material::uv_transforms)), if any. WGSL:
/// `slot_uv`.
pub fn texture_uv(map: Option<[[f32; 3]; 2]>, uv: Vec2) -> Vec2 {
    match map {
        Some([a, b]) => Vec2::new(
            a[0] * uv.x + a[1] * uv.y + a[2],
            b[0] * uv.x + b[1] * uv.y + b[2],
        ),
        None => uv,
    }
}

/// Bilinear lookup with wrap-around, in linear RGB, of a whole texture
/// ([`RenderScene::check_arrays`](super::RenderScene::check_arrays)).
pub(crate) fn sample_texture(t: &Texture, uv: Vec2) -> Vec3 {
    let ([a, b, c, d], fx, fy) = texture_taps(t.width, t.height, uv);
    let lerp = |a: Vec3, b: Vec3, f: f32| a + (b - a) * f;
    let x = &t.texels;
    lerp(lerp(x[a], x[b], fx), lerp(x[c], x[d], fx), fy)
}

/// Bilinear lookup of a texture's alpha with wrap-around (1 where it has none). WGSL:
/// `sample_alpha`.
pub(crate) fn sample_alpha(t: &Texture, uv: Vec2) -> f32 {
    // (An alpha channel of another size than the colours is none: the GPU's upload agrees.)
    if t.alpha.len() != t.texels.len() {
        return 1.0;
    }
    let ([a, b, c, d], fx, fy) = texture_taps(t.width, t.height, uv);
    let lerp = |a: f32, b: f32, f: f32| a + (b - a) * f;
    let x = &t.alpha;
    lerp(lerp(x[a], x[b], fx), lerp(x[c], x[d], fx), fy)
}
