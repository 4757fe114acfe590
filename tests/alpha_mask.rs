//! Alpha masks (glTF's `MASK`): a hit where a masked material's alpha is below its cutoff is
//! skipped inside the traversal, by closest-hit and any-hit queries alike, on the CPU and
//! the GPU. A card cut away everywhere renders exactly as no card (its shadow gone too); a
//! card cut on one half shows the wall through that half, placed copies render as the
//! flattened scene, and the effect is compiled in only where a material is masked. A
//! blended card (stochastic transparency) stops rays in proportion to its alpha.

mod common;

use common::alike::assert_alike;
use common::gpu_device;
use common::scratch::Scratch;
use glam::Vec3;
use lancer::accel::{Query, RayStats};
use lancer::render::{render, AlphaMask, EffectSet, RenderOptions, RenderScene};
use lancer::{AccelKind, Device, Error, LayoutKind, Ray, Robustness};

/// A quad in the plane z = `z`, `half` wide each way, facing +Z, texture coordinates
/// u = (x/half + 1)/2, v = (y/half + 1)/2.
fn quad_obj(dir: &Scratch, name: &str, half: f32, z: f32) {
    let mut text = String::new();
    for (x, y) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        text += &format!("v {} {} {z}\n", x * half, y * half);
    }
    for (u, v) in [(0, 0), (1, 0), (1, 1), (0, 1)] {
        text += &format!("vt {u} {v}\n");
    }
    text += "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
    dir.write(name, text);
}

/// A 2 × 1 RGBA PNG, white, alpha 0 on the left texel and 255 on the right: bilinear with
/// wrap-around, its alpha is ≥ 0.5 for u in [0.5, 1] and at u = 0 (the wrap's midpoint).
fn half_mask(dir: &Scratch) {
    let img = image::RgbaImage::from_fn(2, 1, |x, _| image::Rgba([255, 255, 255, 255 * x as u8]));
    img.save(dir.path("half.png")).unwrap();
}

/// A white wall at z = −1 and, with `card` (material keys), a red card at z = 0 in front
/// of it, under a point light off to the side (the card's shadow falls on the wall).
fn scene(dir: &Scratch, card: Option<&str>, copies: &str) -> RenderScene {
    quad_obj(dir, "wall.obj", 3.0, -1.0);
    quad_obj(dir, "card.obj", 1.0, 0.0);
    half_mask(dir);
    let mut text = r#"
[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov = 40.0
width = 32
height = 32

[render]
integrator = "direct"
spp = 1

[materials.wall]
type = "diffuse"
albedo = [0.8, 0.8, 0.8]

[[objects]]
mesh = "wall.obj"
material = "wall"

[[lights]]
type = "point"
position = [1.5, 0.5, 3.0]
intensity = 8.0
"#
    .to_string();
    if let Some(keys) = card {
        text += &format!(
            "\n[materials.card]\ntype = \"diffuse\"\nalbedo = [1.0, 0.0, 0.0]\n{keys}\n\n\
             [[objects]]\nmesh = \"card.obj\"\nmaterial = \"card\"\n{copies}\n"
        );
    }
    RenderScene::from_file(&dir.write("scene.toml", text)).unwrap()
}

fn pixels(scene: &RenderScene, device: &Device, effects: Option<EffectSet>) -> Vec<Vec3> {
    let options = RenderOptions {
        effects,
        ..RenderOptions::default()
    };
    render(scene, device, &options).unwrap().image.pixels
}

fn bits(px: &[Vec3]) -> Vec<[u32; 3]> {
    px.iter().map(|c| c.to_array().map(f32::to_bits)).collect()
}

#[test]
fn a_card_cut_away_everywhere_renders_as_no_card() {
    let dir = Scratch::new();
    let cut = scene(
        &dir,
        Some("texture = \"half.png\"\nalpha = 0.0\nalpha_cutoff = 0.5"),
        "",
    );
    let fx = EffectSet::of(&cut);
    assert!(fx.alpha_mask, "{fx}");
    let none = scene(&dir, None, "");
    for (device, name) in [(&Device::cpu(), "cpu"), (gpu_device(), "gpu")] {
        let want = pixels(&none, device, None);
        let got = pixels(&cut, device, None);
        // Camera rays pass through the card, and so do shadow rays (any hit): the wall's
        // shadow of the card is gone too. The same triangles' tests give the same bits.
        assert_eq!(bits(&got), bits(&want), "{name}: a cut card still shows");
        // The test can fail: without the effect the card is opaque — red where it is seen
        // and a shadow on the wall.
        let mut off = fx;
        off.alpha_mask = false;
        let opaque = pixels(&cut, device, Some(off));
        let red = opaque.iter().filter(|c| c.x > 0.0 && c.y == 0.0).count();
        let darker = (opaque.iter().zip(&want))
            .filter(|(o, w)| o.y < 0.5 * w.y)
            .count();
        println!("{name}: opaque card: {red} red pixels, {darker} pixels shadowed or covered");
        assert!(
            red > 300 && darker > red,
            "{name}: {red} red, {darker} darker"
        );
    }
}

#[test]
fn a_half_cut_card_shows_the_wall_through_its_cut_half() {
    let dir = Scratch::new();
    let s = scene(&dir, Some("texture = \"half.png\"\nalpha_cutoff = 0.5"), "");
    let cpu = pixels(&s, &Device::cpu(), None);
    let gpu = pixels(&s, gpu_device(), None);
    assert_alike("half-cut card, CPU vs GPU", &cpu, &gpu);
    // The card spans columns 5..27 (x in [−1, 1] at distance 4 under a 40° field, 32
    // pixels): red on its right half (u ≥ 0.5, x ≥ 0), the wall on its left.
    let row = &cpu[16 * 32..17 * 32];
    let red = |c: &Vec3| c.x > 0.0 && c.y == 0.0;
    let kept: Vec<usize> = (0..32).filter(|&x| red(&row[x])).collect();
    println!("red columns of the middle row: {kept:?}");
    assert!((17..=25).all(|x| kept.contains(&x)), "{kept:?}");
    assert!(kept.iter().all(|&x| x >= 16), "{kept:?}");
    // Through the cut half the wall is seen (x in [−1.25, 0] at z = −1: columns 5..16),
    // lit where the card's cut half would have shadowed it (columns 5..11) and dark in the
    // shadow of its kept half (wall x in [−0.5, 0.83] from the light at x = 1.5: columns
    // 12..), so shadow rays pass the cut half and stop at the kept one.
    assert!((6..=10).all(|x| row[x].y > 0.0), "{:?}", &row[6..11]);
    assert!(
        (13..=15).all(|x| row[x] == Vec3::ZERO),
        "{:?}",
        &row[13..16]
    );
    // A cutoff above every alpha cuts it all; one of 0 cuts nothing.
    for (cutoff, want) in [(1.0, 0..0), (0.0, 5..27)] {
        let keys = format!("texture = \"half.png\"\nalpha_cutoff = {cutoff:.1}");
        let s = scene(&dir, Some(&keys), "");
        let px = pixels(&s, &Device::cpu(), None);
        let n = px[16 * 32..17 * 32].iter().filter(|c| red(c)).count();
        println!("cutoff {cutoff}: {n} red columns");
        assert!(
            n >= want.len() && n <= want.len() + 1,
            "cutoff {cutoff}: {n}"
        );
    }
}

/// Every GPU form's traversal asks the mask (its leaf step is test_tri's, or the kd-tree's
/// and cwbvh's own): each renders the half-cut card as the CPU does.
#[test]
fn every_gpu_form_cuts_the_card_as_the_cpu_does() {
    let dir = Scratch::new();
    let s = scene(&dir, Some("texture = \"half.png\"\nalpha_cutoff = 0.5"), "");
    let kinds = (LayoutKind::ALL.iter().map(|&k| AccelKind::Bvh(k)))
        .chain([AccelKind::KdTree, AccelKind::Bih]);
    for kind in kinds {
        let options = RenderOptions {
            accel: Some(kind),
            ..RenderOptions::default()
        };
        let cpu = render(&s, &Device::cpu(), &options).unwrap().image.pixels;
        let gpu = render(&s, gpu_device(), &options).unwrap().image.pixels;
        let red = cpu.iter().filter(|c| c.x > 0.0 && c.y == 0.0).count();
        assert!(red > 100, "{kind:?}: {red} red pixels");
        assert_alike(&format!("{kind:?}, CPU vs GPU"), &cpu, &gpu);
    }
}

#[test]
fn placed_copies_of_a_masked_card_render_as_the_flattened_scene() {
    let dir = Scratch::new();
    let copies = "\n[[objects.copies]]\ntranslate = [-0.6, 0.2, 0.0]\n\n\
                  [[objects.copies]]\nscale = [-1.0, 1.0, 1.0]\ntranslate = [0.6, -0.2, 0.5]\n";
    let placed = scene(
        &dir,
        Some("texture = \"half.png\"\nalpha_cutoff = 0.5"),
        copies,
    );
    assert!(placed.placements.is_some());
    let flat = placed.clone().flattened().unwrap();
    let a = pixels(&placed, &Device::cpu(), None);
    let b = pixels(&flat, &Device::cpu(), None);
    let g = pixels(&placed, gpu_device(), None);
    let red = a.iter().filter(|c| c.x > 0.0 && c.y == 0.0).count();
    assert!(red > 100, "{red} red pixels");
    assert_eq!(bits(&a), bits(&b), "placed vs flattened (CPU)");
    assert_alike("masked copies, CPU vs GPU", &a, &g);
}

#[test]
fn a_blended_card_stops_rays_in_proportion_to_its_alpha() {
    let dir = Scratch::new();
    let s = scene(&dir, Some("alpha = 0.3\nalpha_blend = true"), "");
    assert!(EffectSet::of(&s).alpha_mask);
    // Rays toward the card's middle from the camera, jittered over a pixel-sized square:
    // each stops on the card with probability 0.3 (a hash of its hit).
    let accel = lancer::accel::build(
        AccelKind::Bvh(LayoutKind::DfsSign),
        &s.mesh,
        &Default::default(),
    )
    .unwrap();
    let mask = AlphaMask::new(&s, EffectSet::of(&s)).unwrap();
    let card = s.material_of[2];
    let eye = Vec3::new(0.0, 0.0, 4.0);
    let n = 20_000;
    let mut stopped = 0;
    for i in 0..n {
        let (x, y) = (
            (i % 141) as f32 / 141.0 - 0.5,
            (i / 141) as f32 / 142.0 - 0.5,
        );
        let dir = (Vec3::new(x, y, 0.0) - eye).normalize();
        let r = Ray::new(eye, dir, 0.0, 1e30);
        let h = accel.intersect_masked(
            &r,
            Query::Closest,
            &Robustness::default(),
            Some(&mask),
            &mut RayStats::default(),
        );
        stopped += (s.material_of[h.prim as usize] == card) as usize;
    }
    let p = stopped as f64 / n as f64;
    let sigma = (0.3 * 0.7 / n as f64).sqrt();
    println!("blend at alpha 0.3: {p:.4} of {n} rays stop on the card (σ {sigma:.4})");
    assert!((p - 0.3).abs() < 5.0 * sigma, "{p}");
    // The same bits on both devices: the GPU renders the blend as the CPU does.
    let cpu = pixels(&s, &Device::cpu(), None);
    let gpu = pixels(&s, gpu_device(), None);
    assert_alike("blended card, CPU vs GPU", &cpu, &gpu);
    // The test can fail: a mask at the same alpha cuts every ray.
    let masked = scene(&dir, Some("alpha = 0.3\nalpha_cutoff = 0.5"), "");
    let px = pixels(&masked, &Device::cpu(), None);
    assert!(px.iter().all(|c| !(c.x > 0.0 && c.y == 0.0)));
    assert!(cpu.iter().any(|c| c.x > 0.0 && c.y == 0.0));
}

#[test]
fn alpha_masks_are_an_effect_only_where_a_material_is_masked() {
    let dir = Scratch::new();
    let plain = scene(&dir, Some("texture = \"half.png\""), "");
    assert!(!EffectSet::of(&plain).alpha_mask);
    let masked = scene(&dir, Some("alpha = 0.4\nalpha_cutoff = 0.5"), "");
    assert!(EffectSet::of(&masked).alpha_mask);
    // Untextured: the alpha alone decides (0.4 < 0.5: the card is not there).
    let px = pixels(&masked, &Device::cpu(), None);
    assert!(px.iter().all(|c| !(c.x > 0.0 && c.y == 0.0)));
    // At the cutoff the surface is there (glTF: opaque where alpha ≥ cutoff); one ulp
    // above, it is cut — on both devices.
    let above = f32::from_bits(0.5f32.to_bits() + 1);
    for (cutoff, shown) in [(0.5f32, true), (above, false)] {
        let keys = format!("alpha = 0.5\nalpha_cutoff = {cutoff:?}");
        let s = scene(&dir, Some(&keys), "");
        for device in [&Device::cpu(), gpu_device()] {
            let px = pixels(&s, device, None);
            let red = px.iter().filter(|c| c.x > 0.0 && c.y == 0.0).count();
            assert_eq!(red > 300, shown, "cutoff {cutoff:?}: {red} red pixels");
        }
    }
}

#[test]
fn alpha_keys_are_checked() {
    let dir = Scratch::new();
    quad_obj(&dir, "wall.obj", 3.0, -1.0);
    for (keys, says) in [
        (
            "alpha = 0.5",
            "'alpha' is read by an alpha mask or blend only",
        ),
        (
            "alpha_blend = true\nalpha_cutoff = 0.5",
            "'alpha_blend' and 'alpha_cutoff' exclude each other",
        ),
        ("alpha_cutoff = 1.5", "alpha_cutoff must be in [0, 1]"),
        (
            "alpha = -0.5\nalpha_cutoff = 0.5",
            "alpha must be in [0, 1]",
        ),
    ] {
        let text = format!(
            "[camera]\nposition = [0.0, 0.0, 4.0]\nlook_at = [0.0, 0.0, 0.0]\n\n\
             [materials.m]\ntype = \"diffuse\"\n{keys}\n\n\
             [[objects]]\nmesh = \"wall.obj\"\nmaterial = \"m\"\n"
        );
        let e = RenderScene::from_file(&dir.write("bad.toml", text)).unwrap_err();
        println!("{e}");
        assert!(matches!(e, Error::Input { .. }), "{keys}: {e}");
        assert!(e.to_string().contains(says), "{keys}: {e}");
        assert!(e.to_string().contains("bad.toml:"), "{keys}: {e}");
    }
    let text = "[camera]\nposition = [0.0, 0.0, 4.0]\nlook_at = [0.0, 0.0, 0.0]\n\n\
                [materials.m]\ntype = \"emissive\"\nemission = [1.0, 1.0, 1.0]\nalpha_cutoff = 0.5\n\n\
                [[objects]]\nmesh = \"wall.obj\"\nmaterial = \"m\"\n";
    let e = RenderScene::from_file(&dir.write("bad.toml", text)).unwrap_err();
    assert!(e.to_string().contains("applies to non-emissive"), "{e}");
}
