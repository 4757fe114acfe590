//! Sizes that would not fit are refused up front, naming the size and the limit, instead of
//! ending in an allocation abort minutes later.

use crate::error::{Error, Result};
use crate::util::human_bytes;

/// The largest vertex coordinate magnitude lancer traces: the watertight test forms products
/// of three coordinates relative to the ray origin (about 42·R³ at most for relative
/// coordinates up to R), which must stay below f32::MAX ≈ 3.4e38, so R < 1.2e12. Vertices
/// within ±1e11 and ray origins within ±[`MAX_ORIGIN`] keep R below that, the default
/// view's camera included. Vertices beyond are left out of the BVH and counted.
pub const MAX_COORD: f32 = 1e11;

/// The largest ray-origin coordinate magnitude: rays from further out are invalid (misses).
pub const MAX_ORIGIN: f32 = 1e12;

/// The smallest largest-component of a ray direction: rays whose every component is smaller
/// are invalid (misses). Slab tests treat a component below 2e-30 as parallel (its reciprocal
/// is floored to stay finite); with one component at least this large, such an axis drifts by
/// under 2e-10 of the ray's travel along its main axis, where with all of them tiny the ray
/// would be treated as parallel to every axis and miss what it hits.
pub const MIN_DIR: f32 = 1e-20;

/// The smallest mesh (bounding-box diagonal) lancer traces correctly from its default view:
/// below it those products fall below f32's normal range and hits are lost.
pub const MIN_EXTENT: f32 = 1e-12;

/// Memory this process may still allocate: `MemAvailable` on Linux, or less where the
/// process's cgroup (v2) caps it lower (`memory.max` − `memory.current`, as in a container);
/// None where unknown.
pub fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    let machine = kib * 1024;
    Some(cgroup_headroom().map_or(machine, |c| c.min(machine)))
}

/// What the cgroup v2 this process is in may still allocate, where it sets a limit.
fn cgroup_headroom() -> Option<u64> {
    // "0::/PATH" names the process's cgroup under the unified hierarchy.
    let own = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let rel = own.lines().find_map(|l| l.strip_prefix("0::"))?;
    let dir = std::path::Path::new("/sys/fs/cgroup").join(rel.trim_start_matches('/'));
    let read = |name: &str| std::fs::read_to_string(dir.join(name)).ok();
    let max: u64 = read("memory.max")?.trim().parse().ok()?; // "max": no limit
    let current: u64 = read("memory.current")?.trim().parse().ok()?;
    Some(max.saturating_sub(current))
}

/// Most bounces a render follows after the primary hit (`max_bounces`): paths are not ended
/// at random (no Russian roulette), so every sample of a closed scene follows this many;
/// Blender Cycles' bounce settings stop at the same number.
pub const MAX_BOUNCES: u32 = 1024;

/// The largest texture side lancer decodes: what GPUs take as a 2D texture side (16384);
/// a larger texture is refused by its header, before it is decoded.
pub const MAX_TEXTURE_SIDE: u32 = 16_384;

/// Refuses work that needs `bytes` of memory (what for, in `what`) when that is more than the
/// machine has available; `hint` says what to do instead.
pub fn check_memory(what: &str, bytes: u128, hint: &str) -> Result<()> {
    let Some(available) = available_memory() else {
        return Ok(());
    };
    if bytes > available as u128 {
        let need = u64::try_from(bytes).map_or("more than 16 EiB".into(), human_bytes);
        return Err(Error::Usage(format!(
            "{what} needs {need} of memory but {} is available: {hint}",
            human_bytes(available)
        )));
    }
    Ok(())
}

/// Decodes an image whose size, read from its header, [`check_image`] has passed for
/// `bytes` of memory. The image crate's own cap (512 MiB a decode) becomes that size: the
/// default would refuse textures within [`MAX_TEXTURE_SIDE`] on a machine with room for
/// them, and lancer's check is the memory the machine has.
pub(crate) fn decode_checked<R: std::io::BufRead + std::io::Seek>(
    mut reader: image::ImageReader<R>,
    bytes: u64,
) -> image::ImageResult<image::DynamicImage> {
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(limits.max_alloc.unwrap_or(0).max(bytes));
    reader.limits(limits);
    reader.decode()
}

/// Refuses an image whose pixel count does not fit the u32 pixel index the kernels use or
/// whose buffers (`bytes_per_pixel`) do not fit in memory.
pub fn check_image(width: u32, height: u32, bytes_per_pixel: u64, hint: &str) -> Result<()> {
    let pixels = width as u64 * height as u64;
    if pixels > u32::MAX as u64 {
        return Err(Error::Usage(format!(
            "a {width}×{height} image has {pixels} pixels, more than the {} one run can \
             address: {hint}",
            u32::MAX
        )));
    }
    check_memory(
        &format!("a {width}×{height} image"),
        pixels as u128 * bytes_per_pixel as u128,
        hint,
    )
}
