//! One renderer API for both devices: build the scene's acceleration structure once, then
//! render with a number of samples, a time limit, a cancel flag and a progress callback. The
//! progressive loop and the division by the sample count live here, not in callers.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::Vec3;
use rayon::prelude::*;

use super::aov::{Aovs, FirstHit};
use super::cpu::CpuRenderer;
use super::crop::{Crop, Tile};
use super::effects::EffectSet;
use super::gpu::GpuRenderer;
use super::image::Image;
use super::scene::RenderScene;
use crate::accel::bvh::layouts;
use crate::accel::bvh::{self, BuildOptions, BvhStats};
use crate::accel::instances::{GpuTwoLevel, TwoLevel};
use crate::accel::GpuForm;
use crate::accel::TraversalMode;
use crate::accel::{self, Accel, AccelKind};
use crate::device::Device;
use crate::error::{Error, Result};
use crate::geometry::Robustness;
use crate::gpu::BvhMemory;
use crate::trace::build_on::{gpu_built, GpuBuilt};
use crate::trace::BuildOn;

/// Where a render stands, for a progress callback.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Samples per pixel finished.
    pub done: u32,
    /// Samples per pixel asked for.
    pub total: u32,
    /// Time since the first sample started.
    pub elapsed: Duration,
    /// Camera rays per second so far (one per pixel per sample).
    pub camera_rays_per_s: f64,
}

/// A progress callback, called after every sample.
pub type ProgressFn = Arc<dyn Fn(&Progress) + Send + Sync>;

/// Everything a render takes besides the scene and the device.
#[derive(Clone, Default)]
pub struct RenderOptions {
    /// Samples per pixel (None: the scene's).
    pub spp: Option<u32>,
    /// Random seed (None: the scene's).
    pub seed: Option<u32>,
    /// Effects to simulate (None: exactly those the scene calls for).
    pub effects: Option<EffectSet>,
    /// Triangle and slab tests, secondary-ray offset.
    pub robustness: Robustness,
    /// Stop after the last sample that fits in this time (at least one sample runs).
    pub time_limit: Option<Duration>,
    /// Set to stop after the current sample (what has accumulated is kept).
    pub cancel: Option<Arc<AtomicBool>>,
    /// Called after every sample.
    pub progress: Option<ProgressFn>,
    /// BVH builder (used by [`Renderer::new`] for a BVH).
    pub build: BuildOptions,
    /// Acceleration structure, a BVH with its flattened layout (used by [`Renderer::new`]);
    /// None: a BVH in the device's fastest layout,
    /// [`default_layout`](crate::trace::default_layout) (bvh8 on the CPU, cwbvh on
    /// lavapipe, dfs-sign on a hardware GPU).
    pub accel: Option<AccelKind>,
    /// GPU: where the kernel reads the BVH from (used by [`Renderer::new`]).
    pub memory: BvhMemory,
    /// Render only these pixels of the image, with the full image's random numbers (used
    /// by [`Renderer::new`]; None: the whole image).
    pub crop: Option<Crop>,
    /// Compute the AOVs (first-hit depth, normal, albedo of sample 0's camera rays; used by
    /// [`Renderer::new`]).
    pub aovs: bool,
    /// GPU: how the render kernel walks the BVH (used by [`Renderer::new`]); a mode that
    /// cannot run falls back to per ray with a warning ([`Renderer::mode`]). The image is
    /// the same in every mode.
    pub mode: TraversalMode,
    /// A scene with placements in a BVH: the two levels of this scene at another frame
    /// ([`Renderer::two_level`]), whose meshes' bottom levels [`Renderer::new`] reuses,
    /// building only the top level (where the scene's meshes are that structure's and the
    /// layout is the same; else it builds both levels).
    pub two_level: Option<Arc<GpuTwoLevel>>,
    /// Where a one-level BVH is built (used by [`Renderer::new`]): on the CPU, or (with
    /// `build.builder` the LBVH) on the GPU device.
    pub build_on: BuildOn,
}

/// Why a render stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// Every sample asked for was taken.
    Complete,
    /// The time limit left no room for another sample.
    TimeLimit,
    /// The cancel flag was set.
    Cancelled,
}

/// A finished (or stopped) render.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// The mean of the samples taken.
    pub image: Image,
    /// Samples per pixel taken.
    pub samples: u32,
    /// Samples per pixel asked for.
    pub requested: u32,
    /// Why it stopped.
    pub stop: Stop,
    /// The effects simulated.
    pub effects: EffectSet,
    /// Seconds spent sampling (pipeline compilation excluded).
    pub seconds: f64,
    /// GPU: milliseconds compiling the kernel's pipeline for the effects before the first
    /// sample (0 on the CPU, or when this renderer had compiled it already).
    pub compile_ms: f64,
    /// Milliseconds the first sample took (after compilation).
    pub first_sample_ms: f64,
    /// The AOVs, when asked for ([`RenderOptions::aovs`]).
    pub aovs: Option<Aovs>,
    /// The traversal mode the GPU kernel ran (per ray on the CPU).
    pub mode: TraversalMode,
    /// Pixels whose GPU samples the driver cut short (a loop-iteration cap, see
    /// [`INCOMPLETE`](crate::gpu::INCOMPLETE)), rendered again on the CPU: they are the CPU
    /// reference's, bit for bit.
    pub cpu_pixels: usize,
}

/// A scene's acceleration structure built and (on a GPU) uploaded with the render kernel.
pub struct Renderer<'a> {
    /// The scene it was made for, or (after [`Renderer::move_to`]) that scene at another
    /// frame.
    scene: std::borrow::Cow<'a, RenderScene>,
    kind: AccelKind,
    /// What the CPU traces: the structure, or the GPU form's twin.
    accel: Arc<dyn Accel>,
    stats: Option<BvhStats>,
    build_ms: f64,
    upload_ms: f64,
    crop: Crop,
    aovs: bool,
    gpu: Option<GpuRenderer<'a>>,
    two_level: Option<Arc<GpuTwoLevel>>,
}

impl<'a> Renderer<'a> {
    /// Builds the scene's structure `options.accel` (a BVH with `options.build`, flattened
    /// in its layout), and on a GPU its GPU form, uploaded (in `options.memory`) with the
    /// scene. A structure without a GPU kernel on a GPU device, and a crop that is empty or
    /// reaches outside the image, are [`Error::Usage`]s.
    pub fn new(
        scene: &'a RenderScene,
        device: &'a Device,
        options: &RenderOptions,
    ) -> Result<Self> {
        Self::made(std::borrow::Cow::Borrowed(scene), device, options)
    }

    /// [`Renderer::new`] taking the scene (a frame made by [`RenderScene::at_frame`], say).
    pub fn new_owned(
        scene: RenderScene,
        device: &'a Device,
        options: &RenderOptions,
    ) -> Result<Self> {
        Self::made(std::borrow::Cow::Owned(scene), device, options)
    }

    fn made(
        owned: std::borrow::Cow<'a, RenderScene>,
        device: &'a Device,
        options: &RenderOptions,
    ) -> Result<Self> {
        let scene: &RenderScene = &owned;
        scene.check()?;
        if options.spp == Some(0) {
            return Err(Error::Usage("spp must be at least 1".into()));
        }
        let (w, h) = (scene.camera.width, scene.camera.height);
        // Pixel indices of the full image seed the random numbers: they must fit a u32.
        // The size is the scene file's [camera] or the caller's (--width/--height/--scale).
        let smaller = "use a smaller image (--width/--height/--scale, or the scene file's \
                       [camera] width and height)";
        crate::limits::check_image(w, h, 0, smaller)?;
        let crop = options.crop.unwrap_or(Crop::full(w, h));
        crop.check(w, h)?;
        // Accumulator, image and encoding: about 48 bytes a pixel on either device.
        crate::limits::check_image(
            crop.width(),
            crop.height(),
            48,
            &format!("{smaller} or render tiles (--crop)"),
        )?;
        let kind =
            (options.accel).unwrap_or_else(|| AccelKind::Bvh(crate::trace::default_layout(device)));
        let start = Instant::now();
        // The tree's statistics are taken before it is flattened (which consumes it), and
        // their time is not the build's.
        let mut stats_time = std::time::Duration::ZERO;
        let placed = scene.placements.as_ref().map(|p| p.set());
        let mut two_level = None;
        let (accel, gpu_form, stats): (Arc<dyn Accel>, Option<Arc<dyn GpuForm>>, _) =
            match (placed, kind) {
                // Placements: two levels, a bottom level per object and a top level over its
                // copies (accel::instances); at another frame, the same bottom levels.
                (Some(set), AccelKind::Bvh(layout_kind)) => {
                    if options.build_on == BuildOn::Gpu {
                        log::warn!(
                        "a scene in two levels builds its levels on the CPU (not --build-on gpu)"
                    );
                    }
                    let reuse = (options.two_level.as_ref())
                        .filter(|t| t.name() == layout_kind.name() && t.places(set));
                    let two = Arc::new(match reuse {
                        Some(t) => {
                            let maps: Vec<_> = set.instances.iter().map(|i| i.to_world).collect();
                            t.moved(&maps, &options.build)?
                        }
                        None => GpuTwoLevel::build(layout_kind, set, &options.build)?,
                    });
                    two_level = Some(two.clone());
                    (two.clone(), Some(two as Arc<dyn GpuForm>), None)
                }
                (Some(set), _) if device.is_cpu() => {
                    let two = TwoLevel::build(kind, set, &options.build)?;
                    (Arc::new(two), None, None)
                }
                (Some(_), _) => {
                    return Err(Error::Usage(format!(
                        "a scene with copies renders on the GPU through a BVH, not the {kind}: \
                     use a BVH, or render it flattened (--flatten)"
                    )))
                }
                (None, AccelKind::Bvh(layout_kind)) => {
                    let on_gpu = match options.build_on {
                        BuildOn::Gpu => {
                            gpu_built(device, &scene.mesh, &options.build, layout_kind, true)?
                        }
                        BuildOn::Cpu => None,
                    };
                    match on_gpu {
                        Some(GpuBuilt { layout, tree, .. }) => {
                            let stats_start = Instant::now();
                            let stats = tree.map(|t| BvhStats::of(&t, &options.build));
                            stats_time = stats_start.elapsed();
                            (layout.clone(), Some(layout), stats)
                        }
                        None => {
                            let tree = bvh::build(&scene.mesh, &options.build);
                            let stats_start = Instant::now();
                            let stats = BvhStats::of(&tree, &options.build);
                            stats_time = stats_start.elapsed();
                            // The tree goes into the layout: the two are never held at once.
                            let flat: Arc<dyn GpuForm> =
                                layouts::try_flatten_owned(layout_kind, tree, &scene.mesh)?.into();
                            (flat.clone(), Some(flat), Some(stats))
                        }
                    }
                }
                _ if device.is_cpu() => (
                    accel::build(kind, &scene.mesh, &options.build)?.into(),
                    None,
                    None,
                ),
                _ => match accel::build_gpu(kind, &scene.mesh, &options.build)? {
                    Some(flat) => (flat.clone(), Some(flat), None),
                    None => {
                        return Err(Error::Usage(format!(
                            "the {kind} structure runs on the CPU only (only the BVH, the kd-tree \
                         and the BIH have GPU kernels): use --device cpu"
                        )))
                    }
                },
            };
        let build_ms = (start.elapsed() - stats_time).as_secs_f64() * 1e3;
        let start = Instant::now();
        // A scene in two levels moves by writing over its top level; any other is read in
        // place where the device's memory is the host's.
        let gpu = match (device.gpu_context(), &gpu_form) {
            (Some(ctx), Some(flat)) => Some(match two_level.is_some() {
                true => GpuRenderer::new(
                    ctx,
                    scene,
                    flat.as_ref(),
                    options.memory,
                    crop,
                    options.aovs,
                    options.mode,
                )?,
                false => GpuRenderer::new_shared(
                    ctx,
                    scene,
                    flat,
                    options.memory,
                    crop,
                    options.aovs,
                    options.mode,
                )?,
            }),
            _ => None,
        };
        if gpu.is_none() && options.mode != TraversalMode::PerRay {
            log::warn!(
                "no {} traversal (the CPU traces one ray at a time): rendering per ray",
                options.mode
            );
        }
        let upload_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(Renderer {
            scene: owned,
            kind,
            accel,
            stats,
            build_ms,
            upload_ms,
            crop,
            aovs: options.aovs,
            gpu,
            two_level,
        })
    }

    /// Moves the renderer to `scene`: the scene it renders at another frame
    /// ([`RenderScene::at_frame`]), whose placements (and view) moved. Only the top level is
    /// built again (with `options.build`); on a GPU its words, the placements, the emitters,
    /// the view and the fixed offset are written over what was uploaded, and no kernel is
    /// made again. The renderer keeps the other options it was made with (structure,
    /// memory, crop, AOVs, mode); with those, the next [`Renderer::render`] renders `scene`
    /// as a renderer made for it would, bit for bit. Refused, the renderer unchanged, where
    /// [`Renderer::can_move_to`] says no (then make a renderer for it).
    pub fn move_to(&mut self, scene: RenderScene, options: &RenderOptions) -> Result<()> {
        scene.check()?;
        let (Some(two), Some(pl)) = (&self.two_level, &scene.placements) else {
            return Err(Error::Usage(
                "move_to moves a renderer of a scene with placements in two levels".into(),
            ));
        };
        if !self.can_move_to(&scene) {
            return Err(Error::Usage(
                "the scene moved to does not place the same meshes, emitters and image size: \
                 make a renderer for it"
                    .into(),
            ));
        }
        let start = Instant::now();
        let maps: Vec<_> = pl.set().instances.iter().map(|i| i.to_world).collect();
        let moved = Arc::new(two.moved(&maps, &options.build)?);
        let build_ms = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        if let Some(gpu) = &mut self.gpu {
            let (first, top) = moved.top_words();
            gpu.move_to(&scene, (first, &top))?;
        }
        (self.build_ms, self.upload_ms) = (build_ms, start.elapsed().as_secs_f64() * 1e3);
        self.accel = moved.clone();
        self.two_level = Some(moved);
        self.scene = std::borrow::Cow::Owned(scene);
        Ok(())
    }

    /// Whether [`Renderer::move_to`] takes `scene`: this renderer renders in two levels,
    /// and `scene` places the same meshes as many times, with as many emitters, at the
    /// same image size, with the same settings and as many lights, materials and textures
    /// and an environment alike (what an [`RenderScene::at_frame`] keeps; what it moves is
    /// written over what was uploaded, the rest is not).
    pub fn can_move_to(&self, scene: &RenderScene) -> bool {
        let (Some(two), Some(pl)) = (&self.two_level, &scene.placements) else {
            return false;
        };
        let kept = |a: &RenderScene| {
            let counts = (a.lights.len(), a.materials.len(), a.textures.len());
            let size = (a.camera.width, a.camera.height, a.emitters.len());
            (size, counts, a.environment.is_some(), a.settings.clone())
        };
        two.places(pl.set()) && kept(scene) == kept(&self.scene)
    }

    /// The scene it renders.
    pub fn scene(&self) -> &RenderScene {
        &self.scene
    }

    /// A scene with placements rendered through a BVH: its two levels, to hand to the
    /// renderer of the same scene at another frame ([`RenderOptions::two_level`]).
    pub fn two_level(&self) -> Option<Arc<GpuTwoLevel>> {
        self.two_level.clone()
    }

    /// The BVH's shape and cost (None for the other structures).
    pub fn bvh_stats(&self) -> Option<&BvhStats> {
        self.stats.as_ref()
    }

    /// Milliseconds spent building (and flattening) the structure; after
    /// [`Renderer::move_to`], building the moved top level.
    pub fn build_ms(&self) -> f64 {
        self.build_ms
    }

    /// GPU: milliseconds spent uploading the structure and the scene and creating the shader
    /// module (parsed and validated; the driver compiles it per effect set, see
    /// [`Rendered::compile_ms`]); after [`Renderer::move_to`], writing what moved. 0 on the
    /// CPU.
    pub fn upload_ms(&self) -> f64 {
        self.upload_ms
    }

    /// The traversal mode the GPU kernel runs: the one asked for, or per ray where it
    /// cannot run (and always on the CPU, which traces one ray at a time).
    pub fn mode(&self) -> TraversalMode {
        self.gpu
            .as_ref()
            .map_or(TraversalMode::PerRay, GpuRenderer::mode)
    }

    /// The scene's placements, rendered in two levels (None: one level).
    pub fn placements(&self) -> Option<&crate::render::Placements> {
        self.scene.placements.as_ref()
    }

    /// The structure rendered through.
    pub fn structure(&self) -> AccelKind {
        self.kind
    }

    /// The structure the CPU traces (on a GPU, the twin of the GPU kernel's).
    pub fn accel(&self) -> &dyn Accel {
        self.accel.as_ref()
    }

    /// The pixels rendered: the crop asked for, or the whole image.
    pub fn crop(&self) -> Crop {
        self.crop
    }

    /// Adds sample `sample` of every pixel of the crop to `accum` (CPU) or to the device's
    /// accumulator (GPU) and returns the milliseconds it took. For benches;
    /// [`Renderer::render`] runs the whole loop.
    pub fn add_sample(
        &mut self,
        fx: EffectSet,
        robustness: Robustness,
        seed: u32,
        sample: u32,
        accum: &mut [Vec3],
    ) -> Result<f64> {
        let start = Instant::now();
        match &mut self.gpu {
            Some(g) => {
                g.add_sample(fx, robustness, seed, sample)?;
            }
            None => {
                let cpu = CpuRenderer::new(&self.scene, self.accel.as_ref(), robustness);
                cpu.accumulate(fx, seed, self.crop, accum, sample, 1);
            }
        }
        Ok(start.elapsed().as_secs_f64() * 1e3)
    }

    /// Renders the scene: samples 0, 1, … until `spp`, the time limit or the cancel flag,
    /// then the mean of the samples taken. Cancelled before the first sample finished, it
    /// returns [`Error::Cancelled`].
    pub fn render(&mut self, options: &RenderOptions) -> Result<Rendered> {
        let settings = &self.scene.settings;
        let spp = options.spp.unwrap_or(settings.spp);
        if spp == 0 {
            return Err(Error::Usage("spp must be at least 1".into()));
        }
        let seed = options.seed.unwrap_or(settings.seed);
        let fx = options
            .effects
            .unwrap_or_else(|| EffectSet::of(&self.scene));
        let rob = options.robustness;
        let (w, h) = (self.scene.camera.width, self.scene.camera.height);
        let crop = self.crop;
        let pixels = crop.pixels();
        let mut accum = vec![Vec3::ZERO; if self.gpu.is_some() { 0 } else { pixels }];
        let mut compile_ms = 0.0;
        if let Some(g) = &mut self.gpu {
            g.clear()?;
            compile_ms = g.prepare(fx, rob)?;
        }
        let mut first_sample_ms = 0.0;
        let cancelled = || (options.cancel.as_ref()).is_some_and(|c| c.load(Ordering::SeqCst));
        let start = Instant::now();
        let mut done = 0u32;
        let mut stop = Stop::Complete;
        while done < spp {
            if cancelled() {
                stop = Stop::Cancelled;
                break;
            }
            let elapsed = start.elapsed().as_secs_f64();
            if let Some(limit) = options.time_limit {
                // Stop when one more sample at the mean rate would pass the limit.
                if done > 0 && elapsed * (done + 1) as f64 / done as f64 > limit.as_secs_f64() {
                    stop = Stop::TimeLimit;
                    break;
                }
            }
            let ms = self.add_sample(fx, rob, seed, done, &mut accum)?;
            if done == 0 {
                first_sample_ms = ms;
            }
            done += 1;
            if let Some(p) = &options.progress {
                let elapsed = start.elapsed();
                p(&Progress {
                    done,
                    total: spp,
                    elapsed,
                    camera_rays_per_s: done as f64 * pixels as f64 / elapsed.as_secs_f64(),
                });
            }
        }
        let seconds = start.elapsed().as_secs_f64();
        if done == 0 {
            return Err(Error::Cancelled(
                "interrupted before the first sample finished: nothing to save".into(),
            ));
        }
        let mut cpu_pixels = 0;
        let cpu = CpuRenderer::new(&self.scene, self.accel.as_ref(), rob);
        let mut aovs = None;
        if self.aovs && self.gpu.is_none() {
            let hits: Vec<FirstHit> = (0..pixels)
                .into_par_iter()
                .map(|i| {
                    let (x, y) = crop.pixel(i);
                    cpu.first_hit(fx, seed, x, y)
                })
                .collect();
            aovs = Some(Aovs::of(&hits));
        }
        if let Some(g) = &self.gpu {
            let (sums, cut) = g.read_accum()?;
            accum = sums;
            let mut hits = if self.aovs {
                g.read_aovs()?
            } else {
                Vec::new()
            };
            let redo: Vec<usize> = (0..cut.len()).filter(|&i| cut[i] > 0).collect();
            if !redo.is_empty() {
                log::warn!(
                    "{} pixels needed more loop iterations than the GPU driver runs; \
                     rendered them again on the CPU",
                    redo.len()
                );
                for &i in &redo {
                    let (x, y) = crop.pixel(i);
                    accum[i] = (0..done).fold(Vec3::ZERO, |a, s| a + cpu.sample(fx, seed, x, y, s));
                    if let Some(h) = hits.get_mut(i) {
                        *h = cpu.first_hit(fx, seed, x, y);
                    }
                }
            }
            cpu_pixels = redo.len();
            if self.aovs {
                aovs = Some(Aovs::of(&hits));
            }
        }
        let inv = 1.0 / done as f32;
        Ok(Rendered {
            image: Image {
                width: crop.width(),
                height: crop.height(),
                pixels: accum.iter().map(|c| *c * inv).collect(),
                tile: (crop != Crop::full(w, h)).then_some(Tile {
                    bounds: crop,
                    full_width: w,
                    full_height: h,
                }),
            },
            samples: done,
            requested: spp,
            stop,
            effects: fx,
            seconds,
            compile_ms,
            first_sample_ms,
            aovs,
            mode: self.mode(),
            cpu_pixels,
        })
    }
}

/// Builds the scene's structure on `device` and renders it: [`Renderer::new`] then
/// [`Renderer::render`].
pub fn render(scene: &RenderScene, device: &Device, options: &RenderOptions) -> Result<Rendered> {
    Renderer::new(scene, device, options)?.render(options)
}
