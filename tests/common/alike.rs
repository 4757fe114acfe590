//! Two images of one scene that must agree up to rounding: the GPU's and the CPU's (the
//! same operations on the same random numbers, where lavapipe may fuse a multiply-add and
//! move a value by an ulp, but no path may go another way), or a placed scene's and its
//! flattened copy's.

use glam::Vec3;
use lancer::render::{render, RenderOptions, RenderScene};
use lancer::Device;

use super::gpu_device;

/// Asserts that at most 1 % of the pixels of `a` and `b` differ by more than 10⁻⁴
/// (relative, against at least 0.01), printing how many are bit-identical and the worst.
pub fn assert_alike(what: &str, a: &[Vec3], b: &[Vec3]) {
    assert_eq!(a.len(), b.len(), "{what}: image sizes");
    let off = |x: &Vec3, y: &Vec3| ((*x - *y).abs() / x.max(Vec3::splat(0.01))).max_element();
    let same = a.iter().zip(b).filter(|(x, y)| x == y).count();
    let far = a.iter().zip(b).filter(|(x, y)| off(x, y) > 1e-4).count();
    let worst = a.iter().zip(b).map(|(x, y)| off(x, y)).fold(0.0, f32::max);
    println!(
        "{what}: {same} of {} pixels bit-identical, {far} off by more than 1e-4, worst {worst:e}",
        a.len()
    );
    assert!(
        far * 100 <= a.len(),
        "{what}: {far} of {} pixels differ",
        a.len()
    );
}

/// Renders `scene` with `options` on the CPU and on the test's GPU and asserts the two
/// images alike ([`assert_alike`]): a scene whose GPU kernel must do as the CPU does.
pub fn assert_gpu_renders_as_cpu(what: &str, scene: &RenderScene, options: &RenderOptions) {
    let cpu = render(scene, &Device::cpu(), options).unwrap().image.pixels;
    let gpu = render(scene, gpu_device(), options).unwrap().image.pixels;
    assert_alike(what, &cpu, &gpu);
}
