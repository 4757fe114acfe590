//! A scene that places meshes more than once: its meshes and their placements (the
//! [`InstanceSet`] the renderer traces in two levels, `accel::instances`), and what shading
//! needs at a hit: the instance a triangle number falls in, the triangle in world space,
//! and the rounding the placements add to the hit point's error bound.
//!
//! The error bound. A hit point p is interpolated from the world vertices W = fl(A·V) of
//! an object-space triangle V, and a ray leaving p is moved back into object space by the
//! f32 inverse B before it meets V again. Two roundings lie between p and the surface the
//! traversal tests, per coordinate i:
//! - the vertices' images: |W − A·V|ᵢ ≤ γ₄ (|A|·|V|max + |b|)ᵢ (three products, three sums);
//! - the origin's image in object space, off by γ₅ (|B|·|p| + |b'|) (the same sums plus B's
//!   own rounding to f32), which is |A|·that in world space.
//!
//! [`TRANSFORM_ERROR`] = γ₆ covers both with the interpolation's weights (which sum to one
//! within a few ulps) and the f32 evaluation of the bound itself. The renderer adds it to
//! the interpolation's own bound ([`point_error`](crate::render::point_error)) before it
//! offsets a secondary ray's origin, on the CPU and in WGSL (`placed_error`) alike.

use std::sync::Arc;

use glam::{DMat3, DVec3, Vec3};

use crate::geometry::{gamma, Aabb, Affine};
use crate::mesh::{GltfAnimation, GltfCamera, Instance, InstanceSet};

/// The relative rounding of a placement in a hit point's error bound (see the module
/// comment).
pub const TRANSFORM_ERROR: f32 = gamma(6.0);

/// A scene's meshes placed by instances, with where each mesh's shading triangles start in
/// [`RenderScene::mesh`](super::RenderScene::mesh).
#[derive(Clone, Debug)]
pub struct Placements {
    set: InstanceSet,
    mesh_base: Vec<u32>,
    first_prims: Vec<u32>,
    to_object: Vec<Affine>,
    /// Each instance's motion per frame and its map at frame 0; empty when nothing moves.
    motions: Vec<(Motion, Affine)>,
    /// A glTF animation that moves some instances, where the scene has one.
    animation: Option<Animated>,
}

/// Frames a second of an animation in seconds (a glTF file's) unless set
/// ([`Placements::set_frame_rate`]).
pub const DEFAULT_FRAME_RATE: f32 = 24.0;

/// A glTF animation placing instances `first..` (as many as it places), frame f at f ÷ `fps`
/// seconds.
#[derive(Clone, Debug)]
struct Animated {
    first: usize,
    clip: Arc<GltfAnimation>,
    fps: f32,
    /// The file's camera the scene is seen from, where the animation moves it.
    camera: Option<GltfCamera>,
}

impl Animated {
    /// The time of frame `frame`, seconds.
    fn time(&self, frame: u32) -> f32 {
        (frame as f64 / self.fps as f64) as f32
    }
}

/// How an instance moves from frame to frame (`render --frames`): at frame f its map is
/// its frame-0 map followed by a turn of f·`spin` degrees (about X, then Y, then Z) about
/// `pivot` and a move by f·`velocity`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Motion {
    /// The point it turns about, world space (at frame 0).
    pub pivot: Vec3,
    /// World units a frame.
    pub velocity: Vec3,
    /// Degrees a frame about X, then Y, then Z.
    pub spin: Vec3,
}

impl Motion {
    /// Whether it moves at all.
    pub fn moves(&self) -> bool {
        self.velocity != Vec3::ZERO || self.spin != Vec3::ZERO
    }

    /// `map` (an instance's frame-0 map) at frame `frame`, composed in f64 and rounded once.
    pub fn at(&self, map: &Affine, frame: u32) -> Affine {
        if frame == 0 || !self.moves() {
            return *map;
        }
        let f = frame as f64;
        let [rx, ry, rz] = (self.spin.as_dvec3() * f).to_array().map(f64::to_radians);
        let turn =
            DMat3::from_rotation_z(rz) * DMat3::from_rotation_y(ry) * DMat3::from_rotation_x(rx);
        let pivot = self.pivot.as_dvec3();
        let r = map.rows.map(|r| r.map(f64::from));
        let linear = DMat3::from_cols_array_2d(&[
            [r[0][0], r[1][0], r[2][0]],
            [r[0][1], r[1][1], r[2][1]],
            [r[0][2], r[1][2], r[2][2]],
        ]);
        let offset = DVec3::new(r[0][3], r[1][3], r[2][3]);
        let (l, t) = (
            turn * linear,
            turn * (offset - pivot) + pivot + self.velocity.as_dvec3() * f,
        );
        let row = |i: usize| {
            let c = l.row(i);
            [c.x as f32, c.y as f32, c.z as f32, t[i] as f32]
        };
        Affine {
            rows: [row(0), row(1), row(2)],
        }
    }
}

/// A triangle of the scene as shading sees it: in world space, with where its shading data
/// is.
#[derive(Clone, Copy, Debug)]
pub struct PlacedTriangle {
    /// Vertices in world space (each mapped by its instance's [`Affine::point`]).
    pub v: [Vec3; 3],
    /// Index of its shading data in [`RenderScene::mesh`](super::RenderScene::mesh),
    /// `uvs` and `material_of`.
    pub shade: usize,
    /// The instance that places it (None in a scene without placements).
    pub instance: Option<u32>,
    /// Per coordinate, the largest magnitude of its object-space vertices.
    vmax: Vec3,
}

impl PlacedTriangle {
    /// A triangle of a scene without placements: as it is.
    pub fn unplaced(v: [Vec3; 3], shade: usize) -> Self {
        PlacedTriangle {
            v,
            shade,
            instance: None,
            vmax: Vec3::ZERO,
        }
    }
}

impl Placements {
    /// `set`'s meshes, mesh k's shading triangles starting at `mesh_base[k]`. The set was
    /// checked ([`InstanceSet::new`]): every map has an inverse.
    pub fn new(set: InstanceSet, mesh_base: Vec<u32>) -> Self {
        let first_prims = set.first_prims();
        let to_object = (set.instances.iter())
            .map(|i| i.to_world.inverse().unwrap_or(Affine::IDENTITY))
            .collect();
        Placements {
            set,
            mesh_base,
            first_prims,
            to_object,
            motions: Vec::new(),
            animation: None,
        }
    }

    /// The placements with instances `first..` moved by a glTF file's animation (one
    /// instance for each map it gives), frame f at f ÷ [`DEFAULT_FRAME_RATE`] seconds.
    /// Ignored where those instances do not exist.
    pub fn with_animation(mut self, first: usize, clip: GltfAnimation) -> Self {
        let end = first.checked_add(clip.placements());
        if end.is_some_and(|end| end <= self.set.instances.len()) {
            self.animation = Some(Animated {
                first,
                clip: Arc::new(clip),
                fps: DEFAULT_FRAME_RATE,
                camera: None,
            });
        }
        self
    }

    /// Sets the frames a second at which an animation in seconds is sampled (a glTF
    /// file's); motions given per frame do not change. Refused unless positive and finite.
    pub fn set_frame_rate(&mut self, fps: f32) -> crate::Result<()> {
        Self::check_frame_rate(fps)?;
        if let Some(a) = &mut self.animation {
            a.fps = fps;
        }
        Ok(())
    }

    /// Moves the view with the animation where it moves `camera` (the file's camera the
    /// scene is seen from): [`Placements::camera_at`] then places it.
    pub fn animate_camera(&mut self, camera: &GltfCamera) {
        if let Some(a) = &mut self.animation {
            a.camera = a.clip.moves(camera.node).then(|| camera.clone());
        }
    }

    /// Keeps the view where it is in every frame (a view given on the command line).
    pub fn stop_camera(&mut self) {
        if let Some(a) = &mut self.animation {
            a.camera = None;
        }
    }

    /// The animated camera at frame `frame` (None where the view does not move). Refused
    /// where the animation leaves it no direction.
    pub fn camera_at(&self, frame: u32) -> crate::Result<Option<GltfCamera>> {
        let Some(a) = &self.animation else {
            return Ok(None);
        };
        let Some(camera) = &a.camera else {
            return Ok(None);
        };
        (a.clip.camera_at(camera, a.time(frame)))
            .map(Some)
            .map_err(|e| crate::Error::Usage(format!("frame {frame}: {e}")))
    }

    /// Refuses a frame rate that is not positive and finite.
    pub(super) fn check_frame_rate(fps: f32) -> crate::Result<()> {
        match fps.is_finite() && fps > 0.0 {
            true => Ok(()),
            false => Err(crate::Error::Usage(format!(
                "frames a second (--fps) must be a positive number, not {fps}"
            ))),
        }
    }

    /// The length of its glTF animation in frames (the frame of its last key, rounded up),
    /// where it has one.
    pub fn animation_frames(&self) -> Option<u32> {
        let a = self.animation.as_ref()?;
        Some((a.clip.duration() * a.fps).ceil().min(u32::MAX as f32) as u32)
    }

    /// The placements with each instance moving by `motions[i]` from frame to frame (one
    /// per instance, in order; none moves where all are still).
    pub fn with_motions(mut self, motions: &[Motion]) -> Self {
        if motions.len() == self.set.instances.len() && motions.iter().any(Motion::moves) {
            self.motions = (motions.iter().zip(&self.set.instances))
                .map(|(&m, i)| (m, i.to_world))
                .collect();
        }
        self
    }

    /// Whether an instance moves from frame to frame.
    pub fn moves(&self) -> bool {
        !self.motions.is_empty() || self.animation.is_some()
    }

    /// Each instance's map at frame `frame` (its own where nothing moves). Refused where
    /// an animation's map turns singular or mirrors its mesh otherwise than at rest.
    pub fn maps_at(&self, frame: u32) -> crate::Result<Vec<Affine>> {
        let mut maps: Vec<Affine> = match self.motions.is_empty() {
            true => self.set.instances.iter().map(|i| i.to_world).collect(),
            false => (self.motions.iter())
                .map(|(motion, first)| motion.at(first, frame))
                .collect(),
        };
        if let Some(a) = &self.animation {
            let moved = a
                .clip
                .maps_at(a.time(frame))
                .map_err(|e| crate::Error::Usage(format!("frame {frame}: {e}")))?;
            maps[a.first..a.first + moved.len()].copy_from_slice(&moved);
        }
        Ok(maps)
    }

    /// The same meshes placed as at frame `frame`, the motions kept. Refused where a moved
    /// map is not invertible (a motion that overflows f32, an animation that scales to 0).
    pub fn at_frame(&self, frame: u32) -> crate::Result<Placements> {
        let instances = (self.set.instances.iter().zip(self.maps_at(frame)?))
            .map(|(i, to_world)| Instance {
                mesh: i.mesh,
                to_world,
            })
            .collect();
        let set = InstanceSet::new(self.set.meshes.clone(), instances)?;
        let mut moved = Placements::new(set, self.mesh_base.clone());
        moved.motions = self.motions.clone();
        moved.animation = self.animation.clone();
        Ok(moved)
    }

    /// The meshes and their instances.
    pub fn set(&self) -> &InstanceSet {
        &self.set
    }

    /// Where mesh k's shading triangles start in the scene's mesh.
    pub fn mesh_base(&self) -> &[u32] {
        &self.mesh_base
    }

    /// Each instance's first triangle number.
    pub fn first_prims(&self) -> &[u32] {
        &self.first_prims
    }

    /// Each instance's world-to-object map (the inverse of its placement, in f32).
    pub fn to_object(&self) -> &[Affine] {
        &self.to_object
    }

    /// Bounds of the placed meshes in world space.
    pub fn bounds(&self) -> Aabb {
        self.set.bounds()
    }

    /// The instance triangle number `prim` falls in: the last one whose first triangle is
    /// at most `prim` (instances of empty meshes share their successor's first number and
    /// come before it). WGSL `placement_of` finds the same.
    pub fn locate(&self, prim: u32) -> usize {
        self.first_prims
            .partition_point(|&f| f <= prim)
            .saturating_sub(1)
    }

    /// The index of the shading data of triangle `prim` (in instance `i`, its
    /// [`Self::locate`]).
    fn shade_in(&self, prim: u32, i: usize) -> usize {
        let inst = &self.set.instances[i];
        (self.mesh_base[inst.mesh as usize] + prim - self.first_prims[i]) as usize
    }

    /// The index of triangle `prim`'s shading data (its object-space triangle's).
    pub fn shade_of(&self, prim: u32) -> usize {
        self.shade_in(prim, self.locate(prim))
    }

    /// Triangle `prim` of the scene, whose object-space vertices are `mesh` (the scene's
    /// shading triangles).
    pub fn triangle(&self, prim: u32, mesh: &crate::mesh::Mesh) -> PlacedTriangle {
        let i = self.locate(prim);
        let inst = &self.set.instances[i];
        let shade = self.shade_in(prim, i);
        let v = mesh.triangles[shade].v;
        PlacedTriangle {
            v: v.map(|p| inst.to_world.point(p)),
            shade,
            instance: Some(i as u32),
            vmax: v[0].abs().max(v[1].abs()).max(v[2].abs()),
        }
    }

    /// The rounding the placement of `t` adds to the error bound of a point `p` on it (see
    /// the module comment); zero for an unplaced triangle. WGSL `placed_error` is the same.
    pub fn error(&self, t: &PlacedTriangle, p: Vec3) -> Vec3 {
        let Some(i) = t.instance else {
            return Vec3::ZERO;
        };
        let world = self.set.instances[i as usize].to_world.abs();
        let images = world.point(t.vmax);
        let back = world.vector(self.to_object[i as usize].abs().point(p.abs()));
        (images + back) * TRANSFORM_ERROR
    }
}
