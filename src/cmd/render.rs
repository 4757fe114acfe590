use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use clap::Args;
use indicatif::ProgressStyle;
use lancer::accel::bvh::Builder;
use lancer::render::{
    image_kind, AovSet, Crop, EffectSet, Environment, ImageKind, ImageSize, Progress,
    RenderOptions, RenderStats, Rendered, Renderer, Stop,
};
use lancer::{Error, RenderScene, Result, TraversalMode};

use super::out::{print_json, say, Say};
use super::{BuildArgs, DeviceArgs, RobustnessArgs, ViewArgs};

#[derive(Args)]
pub struct RenderCmd {
    /// Scene: a .toml scene file, or a mesh (.obj, .ply, .gltf, .glb) with its materials
    /// from its default view, on a ground plane under a sun.
    scene: PathBuf,
    /// Output image: .png (sRGB, 8-bit) or .exr (linear float).
    #[arg(short, long)]
    out: PathBuf,
    /// Image width (default: the scene's, 640 for a mesh); alone, the height follows the
    /// scene's aspect ratio.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    width: Option<u32>,
    /// Image height (default: the scene's, 480 for a mesh); alone, the width follows the
    /// scene's aspect ratio.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    height: Option<u32>,
    /// Scale the image size (the scene's, or --width/--height) by this factor, e.g. 0.25 for
    /// a quick preview.
    #[arg(long, value_parser = super::positive_finite)]
    scale: Option<f32>,
    #[command(flatten)]
    view: ViewArgs,
    /// Light the scene by this environment instead of its own (a mesh's uniform sky): an
    /// equirectangular map (.exr or .hdr, placed as Mitsuba 3's envmap), or R,G,B for a
    /// uniform radiance.
    #[arg(long, value_name = "MAP|R,G,B")]
    environment: Option<String>,
    /// What the --environment map's texels are multiplied by.
    #[arg(long, value_name = "S", default_value_t = 1.0, value_parser = super::non_negative_finite, requires = "environment")]
    environment_scale: f32,
    /// Turn the --environment map by these degrees about X, then Y, then Z.
    #[arg(long, value_name = "X,Y,Z", value_parser = super::point, allow_hyphen_values = true, requires = "environment")]
    environment_rotate: Option<glam::Vec3>,
    /// Samples per pixel (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    spp: Option<u32>,
    /// Random seed (default: the scene's).
    #[arg(long)]
    seed: Option<u32>,
    /// Stop after the last sample that fits in this many seconds (at least one sample;
    /// above 0, at most a year).
    #[arg(long, value_parser = time_limit)]
    time_limit: Option<f64>,
    /// Render only the tile of columns X0..X1 and rows Y0..Y1 of the image (half-open pixel
    /// bounds), with the full image's random numbers; an EXR tile records where it sits, and
    /// `lancer merge` joins the tiles into the full image.
    #[arg(long, num_args = 4, value_names = ["X0", "Y0", "X1", "Y1"])]
    crop: Option<Vec<u32>>,
    #[command(flatten)]
    device: DeviceArgs,
    /// Compile every effect in, whatever the scene calls for (for comparisons).
    #[arg(long)]
    all_effects: bool,
    /// PNG bits per channel (sRGB): 8 or 16.
    #[arg(long, default_value_t = 8, value_parser = png_bits)]
    png_bits: u8,
    /// EXR only: extra channels from the first hit of each pixel's first camera ray, for
    /// denoisers: depth (depth.Z, distance; inf for a miss), normal (normal.X/Y/Z, facing
    /// the camera), albedo (albedo.R/G/B), occlusion (occlusion.Y: the material's occlusion
    /// texture, glTF's occlusionTexture; 1 without one). Comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = ["depth", "normal", "albedo", "occlusion"])]
    aov: Vec<String>,
    /// Print build time, BVH statistics, effects, device, compile time and speed.
    #[arg(long)]
    stats: bool,
    /// With --stats: print them as one JSON object on stdout (the summary goes to stderr).
    #[arg(long, requires = "stats")]
    json: bool,
    #[command(flatten)]
    build: BuildArgs,
    /// Acceleration structure (all but the BVH, the kd-tree and the BIH render on the CPU).
    #[arg(long, value_parser = super::accel_arg(), default_value = "bvh")]
    accel: lancer::AccelKind,
    /// GPU traversal: one ray per invocation, or the lanes of a subgroup together (falls
    /// back to per-ray, with a warning, where the adapter or layout has no subgroup mode);
    /// the image is the same.
    #[arg(long, value_enum, default_value_t = TraversalMode::PerRay)]
    mode: TraversalMode,
    #[command(flatten)]
    robustness: RobustnessArgs,
    /// Render the scene flattened into one mesh where it places objects more than once
    /// (`copies`, `grid`); without it such a scene renders in two levels, a BVH per object
    /// under one over its copies.
    #[arg(long)]
    flatten: bool,
    /// Render frames A to B−1 of a scene whose objects move (`move`, `spin`, a glTF
    /// file's animation), each into the output's name numbered (out-0000.png, …); in two
    /// levels only the top level is built again from frame to frame. `A..` plays a glTF
    /// animation to its last key.
    #[arg(long, value_name = "A..B", value_parser = frame_range, conflicts_with = "flatten")]
    frames: Option<(u32, Option<u32>)>,
    /// Frames a second at which a glTF file's animation is played (frame f shows it at
    /// f ÷ FPS seconds).
    #[arg(long, default_value_t = lancer::render::DEFAULT_FRAME_RATE)]
    fps: f32,
    /// Where a one-level BVH is built: cpu, or gpu (--builder lbvh: the same tree, built by
    /// WGSL kernels on the GPU device and flattened there into dfs-sign, else read back and
    /// flattened on the CPU; without a GPU the CPU builds it, with a warning).
    #[arg(long, value_enum, default_value_t = lancer::trace::BuildOn::Cpu)]
    build_on: lancer::trace::BuildOn,
}

/// Most frames one `render --frames` run renders (an animation's last key may lie far
/// off).
const MAX_FRAMES: u32 = 1_000_000;

/// `--frames A..B`: first frame, one past the last (None: to the animation's end).
fn frame_range(s: &str) -> std::result::Result<(u32, Option<u32>), String> {
    let (a, b) = s
        .split_once("..")
        .ok_or_else(|| format!("{s}: give frames as A..B (B excluded), e.g. 0..24"))?;
    let parse = |x: &str| x.trim().parse::<u32>().map_err(|e| format!("{s}: {e}"));
    let a = parse(a)?;
    if b.trim().is_empty() {
        return Ok((a, None));
    }
    let b = parse(b)?;
    if a >= b {
        return Err(format!("{s}: no frame in {a}..{b} (B is excluded)"));
    }
    Ok((a, Some(b)))
}

/// `out` numbered for frame `frame`: out-0007.png.
fn numbered(out: &std::path::Path, frame: u32) -> std::path::PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match out.extension() {
        Some(e) => format!("{stem}-{frame:04}.{}", e.to_string_lossy()),
        None => format!("{stem}-{frame:04}"),
    };
    out.with_file_name(name)
}

/// 8 or 16.
fn png_bits(s: &str) -> std::result::Result<u8, String> {
    match s {
        "8" => Ok(8),
        "16" => Ok(16),
        _ => Err(format!("{s}: PNG bits are 8 or 16")),
    }
}

impl RenderCmd {
    pub fn run(self) -> Result<()> {
        let builder = self.build.options().builder;
        if self.build_on == lancer::trace::BuildOn::Gpu && builder != Builder::Lbvh {
            return Err(Error::Usage(format!(
                "--build-on gpu builds with --builder lbvh only, not {}",
                builder.name()
            )));
        }
        let kind = image_kind(&self.out)?;
        let aovs = AovSet {
            depth: self.aov.iter().any(|a| a == "depth"),
            normal: self.aov.iter().any(|a| a == "normal"),
            albedo: self.aov.iter().any(|a| a == "albedo"),
            occlusion: self.aov.iter().any(|a| a == "occlusion"),
        };
        if aovs.any() && kind != ImageKind::Exr {
            return Err(Error::Usage(format!(
                "--aov writes extra EXR channels: give an .exr output, not {}",
                self.out.display()
            )));
        }
        if self.png_bits != 8 && kind != ImageKind::Png {
            return Err(Error::Usage(format!(
                "--png-bits is for PNG outputs, not {}",
                self.out.display()
            )));
        }
        let time_limit = self.time_limit.map(Duration::from_secs_f64);
        let size = ImageSize {
            width: self.width,
            height: self.height,
            scale: self.scale,
        };
        let mut scene = RenderScene::open(&self.scene, &size, &self.view.change())?;
        scene.set_frame_rate(self.fps)?;
        if let Some(spec) = &self.environment {
            scene.environment = match super::point(spec) {
                Ok(rgb) if rgb.min_element() >= 0.0 => {
                    (rgb != glam::Vec3::ZERO).then(|| Environment::uniform(rgb))
                }
                Ok(rgb) => {
                    return Err(Error::Usage(format!(
                        "--environment {spec}: a radiance is ≥ 0, got {rgb}"
                    )))
                }
                Err(_) => {
                    let map = PathBuf::from(spec);
                    scene.mesh.sources.push(map.clone());
                    let rotate = self.environment_rotate.unwrap_or_default().to_array();
                    Environment::from_map_file(&map, self.environment_scale, rotate)?
                }
            };
        }
        // A sequence writes numbered files only (checked below), never this name itself.
        if self.frames.is_none() {
            lancer::output::check_output(&self.out, &scene.mesh.sources)?;
        }
        if self.flatten {
            scene = scene.flattened()?;
        }
        let crop = match self.crop.as_deref() {
            Some(&[x0, y0, x1, y1]) => Some(Crop { x0, y0, x1, y1 }),
            _ => None,
        };
        if let Some(c) = crop {
            c.check(scene.camera.width, scene.camera.height)?;
        }
        let device = self.device.open_for(self.accel)?;
        let layout = self.build.layout_on(&device);
        let cancel = Arc::new(AtomicBool::new(false));
        // Ctrl-C from here on stops the samples and saves what accumulated (a second one
        // while saving changes nothing).
        super::interrupt::tell(cancel.clone());
        let spp = self.spp.unwrap_or(scene.settings.spp);
        let bar = super::out::progress_bar(spp as u64);
        bar.set_style(
            ProgressStyle::with_template("{bar:30} {pos}/{len} spp  {msg}  {elapsed_precise}")
                .expect("valid template"),
        );
        let progress = {
            let bar = bar.clone();
            Arc::new(move |p: &Progress| {
                bar.set_message(format!("{:.2} M camera rays/s", p.camera_rays_per_s * 1e-6));
                bar.set_position(p.done as u64);
            })
        };
        let options = RenderOptions {
            spp: self.spp,
            seed: self.seed,
            effects: self.all_effects.then_some(EffectSet::ALL),
            time_limit,
            cancel: Some(cancel),
            progress: Some(progress),
            build: self.build.options(),
            accel: Some(self.accel.with_layout(layout)),
            memory: self.device.bvh_memory,
            robustness: self.robustness.robustness(),
            crop,
            aovs: aovs.any(),
            mode: self.mode,
            two_level: None,
            build_on: self.build_on,
        };
        let frames: Vec<Option<u32>> = match self.frames {
            None => vec![None],
            Some((a, b)) => {
                if !scene.moves() {
                    log::warn!(
                        "{}: nothing moves (no object has 'move' or 'spin', no glTF animation \
                         moves a mesh): every frame is the same image",
                        self.scene.display()
                    );
                }
                let last = scene.animation_frames();
                if let Some(n) = last {
                    log::info!(
                        "{}: its animation ends at frame {n} ({} frames a second)",
                        self.scene.display(),
                        self.fps
                    );
                }
                let b = match (b, last) {
                    (Some(b), _) => b,
                    (None, Some(n)) if n >= a => n.saturating_add(1),
                    (None, Some(n)) => {
                        return Err(Error::Usage(format!(
                            "--frames {a}..: {}'s animation ends at frame {n} ({} frames a \
                             second): start at or before it",
                            self.scene.display(),
                            self.fps
                        )))
                    }
                    (None, None) => {
                        return Err(Error::Usage(format!(
                            "--frames {a}..: {} plays no glTF animation; give the last frame \
                             (A..B)",
                            self.scene.display()
                        )))
                    }
                };
                if b - a > MAX_FRAMES {
                    return Err(Error::Usage(format!(
                        "--frames {a}..{b}: {} frames, more than one run renders ({MAX_FRAMES}): \
                         split the range (or lower --fps)",
                        b - a
                    )));
                }
                for f in a..b {
                    lancer::output::check_output(&numbered(&self.out, f), &scene.mesh.sources)?;
                }
                (a..b).map(Some).collect()
            }
        };
        // One renderer for every frame: from frame to frame only the top level is built
        // again and, on a GPU, written over what was uploaded (Renderer::move_to).
        let mut current: Option<Renderer> = None;
        let last_frame = frames.last().copied().flatten();
        for frame in frames {
            let (out, at_frame) = match frame {
                Some(f) => (numbered(&self.out, f), Some(scene.at_frame(f)?)),
                None => (self.out.clone(), None),
            };
            let renderer = match (current.take(), at_frame) {
                (Some(mut r), Some(moved)) if r.can_move_to(&moved) => {
                    r.move_to(moved, &options)?;
                    r
                }
                (_, Some(moved)) => Renderer::new_owned(moved, &device, &options)?,
                (_, None) => Renderer::new(&scene, &device, &options)?,
            };
            let renderer = current.insert(renderer);
            let full = (
                renderer.scene().camera.width,
                renderer.scene().camera.height,
            );
            bar.reset();
            let done = renderer.render(&options);
            bar.finish_and_clear();
            let done = done?;
            self.save(&done, &out, kind, aovs)?;
            let (w, h) = (done.image.width, done.image.height);
            let tile = match crop {
                Some(c) => format!(
                    " tile {} {} {} {} of {}x{}",
                    c.x0, c.y0, c.x1, c.y1, full.0, full.1
                ),
                None => String::new(),
            };
            let why = match done.stop {
                Stop::Cancelled => " (interrupted: saved what had accumulated)",
                Stop::TimeLimit => " (time limit)",
                Stop::Complete => "",
            };
            // With --json the JSON object is stdout's only line; people read the rest on
            // stderr.
            let to = Say::new(self.json);
            let say = |line: String| say!(to, "{line}");
            say(format!(
                "{w}x{h}{tile} {}/{} spp -> {} ({device}, {:.2} s){why}",
                done.samples,
                done.requested,
                out.display(),
                done.seconds
            ));
            if self.stats {
                let stats =
                    RenderStats::new(renderer, &done, &device, &options, full, layout, &out);
                stats.text().into_iter().for_each(say);
                if self.json {
                    print_json(&stats)?;
                }
            }
            if done.stop == Stop::Cancelled {
                let rest = match (frame, last_frame) {
                    (Some(f), Some(last)) if f < last => {
                        format!("; frames {}..{} not rendered", f + 1, last + 1)
                    }
                    _ => String::new(),
                };
                return Err(Error::Cancelled(format!(
                    "interrupted after {} of {} samples; saved {}{rest}",
                    done.samples,
                    done.requested,
                    out.display()
                )));
            }
        }
        Ok(())
    }

    /// Writes a finished render to `out`: PNG (8 or 16 bits), or EXR with the AOVs asked for.
    fn save(
        &self,
        done: &Rendered,
        out: &std::path::Path,
        kind: ImageKind,
        aovs: AovSet,
    ) -> Result<()> {
        match (kind, &done.aovs) {
            (ImageKind::Png, _) if self.png_bits == 16 => done.image.save_png16(out),
            (ImageKind::Exr, Some(a)) => {
                let mut exr = done.image.to_exr();
                exr.channels.extend(a.channels(aovs));
                exr.write(out)
            }
            _ => done.image.save(out),
        }
    }
}

/// `--time-limit`: seconds above 0 and at most a year (a Duration holds any such number; a
/// longer limit is no limit a render can reach).
fn time_limit(s: &str) -> std::result::Result<f64, String> {
    const YEAR: f64 = 365.25 * 24.0 * 3600.0;
    match s.parse::<f64>() {
        Ok(t) if t > 0.0 && t <= YEAR => Ok(t),
        Ok(t) => Err(format!(
            "{t} is not a number of seconds above 0 and at most a year ({YEAR})"
        )),
        Err(e) => Err(e.to_string()),
    }
}
