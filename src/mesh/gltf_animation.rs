//! glTF node animations: the keyframes of a file's first animation that move nodes
//! (translation, rotation, scale), sampled at any time as the world maps of the nodes that
//! draw meshes and of the cameras. Interpolation follows glTF 2.0 §3.11: `STEP` holds a key, `LINEAR` lerps
//! translations and scales and slerps rotations, `CUBICSPLINE` is a cubic Hermite spline
//! over (in-tangent, value, out-tangent) triples. Before the first key a channel holds its
//! first value, after the last its last. Morph-target weights (and skins) are not played.

use std::path::Path;

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::animation::util::ReadOutputs;
use ::gltf::animation::{Interpolation, Property};
use ::gltf::Document;
use glam::{Mat4, Quat, Vec3, Vec4};

use super::gltf::{camera_frame, check_accessor, GltfCamera};
use crate::error::{Error, Result};
use crate::geometry::Affine;

/// What a channel moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Part {
    Translation,
    Rotation,
    Scale,
}

/// One animated property of one node: key times (seconds, non-decreasing) and values
/// (xyz, or a quaternion's xyzw); three values a key for a cubic spline.
#[derive(Clone, Debug)]
struct Channel {
    node: usize,
    part: Part,
    interpolation: Interpolation,
    times: Vec<f32>,
    values: Vec<Vec4>,
}

impl Channel {
    /// The value at time `t`.
    fn at(&self, t: f32) -> Vec4 {
        let (times, n) = (&self.times, self.times.len());
        let cubic = self.interpolation == Interpolation::CubicSpline;
        // The value of key k (the middle of its triple for a spline).
        let key = |k: usize| {
            if cubic {
                self.values[3 * k + 1]
            } else {
                self.values[k]
            }
        };
        // Times are finite and non-decreasing (checked when read); NaN t reads the first.
        let next = times.partition_point(|&x| x <= t);
        if next == 0 {
            return key(0);
        }
        if next == n {
            return key(n - 1);
        }
        let (k, span) = (next - 1, times[next] - times[next - 1]);
        let s = if span > 0.0 {
            ((t - times[k]) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        match self.interpolation {
            Interpolation::Step => key(k),
            Interpolation::Linear if self.part == Part::Rotation => {
                let (a, b) = (Quat::from_vec4(key(k)), Quat::from_vec4(key(k + 1)));
                Vec4::from(a.normalize().slerp(b.normalize(), s))
            }
            Interpolation::Linear => key(k).lerp(key(k + 1), s),
            Interpolation::CubicSpline => {
                let (p0, m0) = (key(k), self.values[3 * k + 2] * span);
                let (p1, m1) = (key(k + 1), self.values[3 * (k + 1)] * span);
                let (s2, s3) = (s * s, s * s * s);
                p0 * (2.0 * s3 - 3.0 * s2 + 1.0)
                    + m0 * (s3 - 2.0 * s2 + s)
                    + p1 * (-2.0 * s3 + 3.0 * s2)
                    + m1 * (s3 - s2)
            }
        }
    }
}

/// A glTF file's first animation, as far as it moves the nodes that draw meshes or place
/// cameras.
#[derive(Clone, Debug)]
pub struct GltfAnimation {
    /// Its name, or its index, and its file, for messages.
    name: String,
    file: std::path::PathBuf,
    /// Each node's parent.
    parents: Vec<Option<usize>>,
    /// Each node's map at rest (as the file gives it).
    rest: Vec<Mat4>,
    /// Each node's translation, rotation and scale at rest.
    trs: Vec<(Vec3, Quat, Vec3)>,
    /// Which nodes a channel moves.
    animated: Vec<bool>,
    channels: Vec<Channel>,
    /// The nodes that draw meshes, in the order they are placed, with their world maps at
    /// rest.
    placed: Vec<(usize, Mat4)>,
    /// The time of the last key, seconds.
    duration: f32,
}

impl GltfAnimation {
    /// The file's first animation, where it moves one of `placed` (the nodes that draw
    /// meshes, in placement order, with their world maps at rest) or of `cameras` (the
    /// nodes that place cameras); None where it has none or moves only other nodes. Lights
    /// among `lights` that it moves are warned about: they stay where they are at rest.
    /// Accessors are checked before they are read; times must be finite and non-decreasing,
    /// values finite.
    pub(super) fn read(
        path: &Path,
        doc: &Document,
        buffers: &[Vec<u8>],
        placed: Vec<(usize, Mat4)>,
        (cameras, lights): (&[usize], &[usize]),
    ) -> Result<Option<GltfAnimation>> {
        let Some(anim) = doc.animations().next() else {
            return Ok(None);
        };
        let name = match anim.name() {
            Some(n) => format!("animation {:?}", n),
            None => format!("animation {}", anim.index()),
        };
        let bad = |msg: String| Error::input(path, None, format!("{name}: {msg}"));
        let count = doc.animations().count();
        if count > 1 {
            log::warn!(
                "{}: plays its first animation ({name}) of {count}",
                path.display()
            );
        }
        let n = doc.nodes().len();
        let mut parents = vec![None; n];
        for p in doc.nodes() {
            for c in p.children() {
                parents[c.index()] = Some(p.index());
            }
        }
        let rest = (doc.nodes())
            .map(|x| Mat4::from_cols_array_2d(&x.transform().matrix()))
            .collect();
        let trs = (doc.nodes())
            .map(|x| {
                let (t, r, s) = x.transform().decomposed();
                (Vec3::from(t), Quat::from_array(r), Vec3::from(s))
            })
            .collect();
        let mut channels = Vec::new();
        let mut weights = 0;
        for c in anim.channels() {
            let part = match c.target().property() {
                Property::Translation => Part::Translation,
                Property::Rotation => Part::Rotation,
                Property::Scale => Part::Scale,
                Property::MorphTargetWeights => {
                    weights += 1;
                    continue;
                }
            };
            let sampler = c.sampler();
            let what = format!("channel {} input", c.index());
            let keys = check_accessor(
                path,
                &sampler.input(),
                &what,
                Dimensions::Scalar,
                &[DataType::F32],
            )?;
            let (dims, types): (_, &[DataType]) = match part {
                Part::Rotation => (
                    Dimensions::Vec4,
                    &[
                        DataType::F32,
                        DataType::I8,
                        DataType::U8,
                        DataType::I16,
                        DataType::U16,
                    ],
                ),
                _ => (Dimensions::Vec3, &[DataType::F32]),
            };
            let what = format!("channel {} output", c.index());
            let outputs = check_accessor(path, &sampler.output(), &what, dims, types)?;
            let interpolation = sampler.interpolation();
            let per_key = if interpolation == Interpolation::CubicSpline {
                3
            } else {
                1
            };
            if keys == 0 || outputs != keys * per_key {
                return Err(bad(format!(
                    "channel {} has {keys} key times and {outputs} values; {interpolation:?} \
                     needs {per_key} value(s) a key and at least one key",
                    c.index()
                )));
            }
            let reader = c.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
            let times: Vec<f32> = reader
                .read_inputs()
                .map(Iterator::collect)
                .unwrap_or_default();
            let values: Vec<Vec4> = match reader.read_outputs() {
                Some(ReadOutputs::Translations(v)) | Some(ReadOutputs::Scales(v)) => {
                    v.map(|x| Vec3::from(x).extend(0.0)).collect()
                }
                Some(ReadOutputs::Rotations(r)) => r.into_f32().map(Vec4::from).collect(),
                _ => Vec::new(),
            };
            if times.len() != keys || values.len() != outputs {
                return Err(bad(format!(
                    "channel {}'s keys could not be read from its accessors",
                    c.index()
                )));
            }
            if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[1] < w[0]) {
                return Err(bad(format!(
                    "channel {}'s key times must be finite and increasing",
                    c.index()
                )));
            }
            if values.iter().any(|v| !v.is_finite()) {
                return Err(bad(format!(
                    "channel {} has values that are not finite",
                    c.index()
                )));
            }
            // A spline's tangents may be zero; its values and other keys are turns.
            let turns = values
                .iter()
                .enumerate()
                .filter(|(i, _)| per_key == 1 || i % 3 == 1);
            if part == Part::Rotation && turns.clone().any(|(_, q)| q.length() == 0.0) {
                return Err(bad(format!(
                    "channel {} has a rotation of length 0 (no turn)",
                    c.index()
                )));
            }
            channels.push(Channel {
                node: c.target().node().index(),
                part,
                interpolation,
                times,
                values,
            });
        }
        if weights > 0 {
            log::warn!(
                "{}: {name}: {weights} channel(s) of morph-target weights not played",
                path.display()
            );
        }
        let mut animated = vec![false; n];
        for c in &channels {
            animated[c.node] = true;
        }
        let duration = (channels.iter())
            .filter_map(|c| c.times.last().copied())
            .fold(0.0, f32::max);
        let clip = GltfAnimation {
            name,
            file: path.to_path_buf(),
            parents,
            rest,
            trs,
            animated,
            channels,
            placed,
            duration,
        };
        let moved_lights = lights.iter().filter(|&&x| clip.moves(x)).count();
        if moved_lights > 0 {
            log::warn!(
                "{}: {} moves {moved_lights} light node(s): they stay where they are at rest",
                path.display(),
                clip.name
            );
        }
        let hidden = (clip.placed.iter())
            .filter(|&&(x, rest)| clip.moves(x) && Affine::from_mat4(&rest).inverse().is_none())
            .count();
        if hidden > 0 {
            log::warn!(
                "{}: {} moves {hidden} mesh node(s) whose map at rest is singular (a scale of \
                 0): they stay hidden in every frame",
                path.display(),
                clip.name
            );
        }
        let moves_any = clip.placed.iter().any(|&(x, _)| clip.moves(x))
            || cameras.iter().any(|&x| clip.moves(x));
        Ok(moves_any.then_some(clip))
    }

    /// Whether node `x` or one of its ancestors moves (parents form trees: checked when the
    /// scene was walked, so the climb ends).
    pub fn moves(&self, mut x: usize) -> bool {
        loop {
            if self.animated.get(x).copied().unwrap_or(false) {
                return true;
            }
            match self.parents.get(x).copied().flatten() {
                Some(p) => x = p,
                None => return false,
            }
        }
    }

    /// Camera `camera` (placed by a node of this file) at time `t`, seconds: where its
    /// node's animated world map puts it (as it if does not move). Refused where that map
    /// leaves it no direction.
    pub fn camera_at(
        &self,
        camera: &GltfCamera,
        t: f32,
    ) -> std::result::Result<GltfCamera, String> {
        if !self.moves(camera.node) || camera.node >= self.rest.len() {
            return Ok(camera.clone());
        }
        let locals = self.locals_at(t);
        let mut world = vec![None; locals.len()];
        let map = self.world_of(camera.node, &locals, &mut world);
        let (eye, look_at, up) = camera_frame(&map).ok_or_else(|| {
            format!(
                "{}: {} at {t} s: camera {:?}'s map leaves it no direction; end --frames \
                 before this frame",
                self.file.display(),
                self.name,
                camera.name.as_deref().unwrap_or("")
            )
        })?;
        Ok(GltfCamera {
            eye,
            look_at,
            up,
            ..camera.clone()
        })
    }

    /// The world map of node `x` at the time `locals` were taken, composing (and keeping in
    /// `world`) those of its ancestors not composed yet, as the scene's walk composes them.
    fn world_of(&self, x: usize, locals: &[Mat4], world: &mut [Option<Mat4>]) -> Mat4 {
        let mut chain = Vec::new();
        let mut y = Some(x);
        while let Some(z) = y.filter(|&z| world[z].is_none()) {
            chain.push(z);
            y = self.parents[z];
        }
        let mut up = y.and_then(|z| world[z]).unwrap_or(Mat4::IDENTITY);
        for &z in chain.iter().rev() {
            up *= locals[z];
            world[z] = Some(up);
        }
        world[x].unwrap_or(Mat4::IDENTITY)
    }

    /// The time of its last key, seconds (after it every node holds its last pose).
    pub fn duration(&self) -> f32 {
        self.duration
    }

    /// How many placements it moves (the nodes that draw meshes, animated or not).
    pub fn placements(&self) -> usize {
        self.placed.len()
    }

    /// Each node's map at time `t` (seconds): the rest map where no channel moves it.
    fn locals_at(&self, t: f32) -> Vec<Mat4> {
        let mut trs = self.trs.clone();
        for c in &self.channels {
            let v = c.at(t);
            let node = &mut trs[c.node];
            match c.part {
                Part::Translation => node.0 = v.truncate(),
                Part::Rotation => node.1 = Quat::from_vec4(v).normalize(),
                Part::Scale => node.2 = v.truncate(),
            }
        }
        (0..self.rest.len())
            .map(|x| match self.animated[x] {
                true => Mat4::from_scale_rotation_translation(trs[x].2, trs[x].1, trs[x].0),
                false => self.rest[x],
            })
            .collect()
    }

    /// The world map of each node that draws a mesh, in placement order, at time `t`
    /// (seconds), composed as the scene's walk composes them at rest. Refused where a map
    /// turns singular or mirrors where it did not at rest (or the reverse): the mesh was
    /// placed as its rest map draws it. A node singular at rest stays at the identity (its
    /// copy has no area).
    pub fn maps_at(&self, t: f32) -> std::result::Result<Vec<Affine>, String> {
        let locals = self.locals_at(t);
        let mut world: Vec<Option<Mat4>> = vec![None; locals.len()];
        let mut maps = Vec::with_capacity(self.placed.len());
        for &(x, at_rest) in &self.placed {
            let map = self.world_of(x, &locals, &mut world);
            if Affine::from_mat4(&at_rest).inverse().is_none() {
                maps.push(Affine::IDENTITY);
                continue;
            }
            let affine = Affine::from_mat4(&map);
            if affine.inverse().is_none() {
                return Err(format!(
                    "{}: {} at {t} s: node {x}'s map is singular (a scale of 0): lancer places \
                     only invertible maps; end --frames before this frame",
                    self.file.display(),
                    self.name
                ));
            }
            if (map.determinant() < 0.0) != (at_rest.determinant() < 0.0) {
                return Err(format!(
                    "{}: {} at {t} s: node {x} mirrors its mesh where it did not at rest (or \
                     the reverse), which lancer does not support; end --frames before this frame",
                    self.file.display(),
                    self.name
                ));
            }
            maps.push(affine);
        }
        Ok(maps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn channel(
        part: Part,
        interpolation: Interpolation,
        times: &[f32],
        values: &[Vec4],
    ) -> Channel {
        Channel {
            node: 0,
            part,
            interpolation,
            times: times.to_vec(),
            values: values.to_vec(),
        }
    }

    #[test]
    fn keys_hold_outside_and_interpolate_inside() {
        let v = [
            Vec4::new(0.0, 0.0, 0.0, 0.0),
            Vec4::new(2.0, 4.0, -2.0, 0.0),
        ];
        let lin = channel(Part::Translation, Interpolation::Linear, &[1.0, 3.0], &v);
        assert_eq!(lin.at(0.0), v[0]);
        assert_eq!(lin.at(2.0), Vec4::new(1.0, 2.0, -1.0, 0.0));
        assert_eq!(lin.at(9.0), v[1]);
        let step = channel(Part::Translation, Interpolation::Step, &[1.0, 3.0], &v);
        assert_eq!(step.at(2.9), v[0]);
        assert_eq!(step.at(3.0), v[1]);
    }

    #[test]
    fn rotations_slerp_and_splines_pass_their_keys_with_their_tangents() {
        let a = Quat::IDENTITY;
        let b = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        let rot = channel(
            Part::Rotation,
            Interpolation::Linear,
            &[0.0, 1.0],
            &[Vec4::from(a), Vec4::from(b)],
        );
        let half = Quat::from_vec4(rot.at(0.5));
        assert!(half.angle_between(Quat::from_rotation_y(std::f32::consts::FRAC_PI_4)) < 1e-6);
        // A spline from 0 to 1 over 2 s with zero tangents: 0.5 at the middle.
        let z = Vec4::ZERO;
        let one = Vec4::new(1.0, 0.0, 0.0, 0.0);
        let flat = channel(
            Part::Scale,
            Interpolation::CubicSpline,
            &[0.0, 2.0],
            &[z, z, z, z, one, z],
        );
        assert_eq!(flat.at(1.0).x, 0.5);
        assert_eq!(flat.at(2.0).x, 1.0);
        // With an out-tangent of 1 per second the curve leaves the first key at that slope.
        let sloped = channel(
            Part::Scale,
            Interpolation::CubicSpline,
            &[0.0, 2.0],
            &[z, z, one, z, z, z],
        );
        let h = 1e-3;
        assert!((sloped.at(h).x / h - 1.0).abs() < 1e-2);
    }
}
