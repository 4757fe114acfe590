//! glTF 2.0 loading (`.gltf` with external or embedded buffers, and `.glb`) through the
//! `gltf` crate, which parses and validates the JSON. Buffers and images are read here, each
//! size checked against the file before it is trusted, and every accessor is bounds-checked
//! before the crate's reader touches it. The default scene's node tree is flattened into
//! world-space triangles, in the order the tree is walked (depth first, children in order).

use std::collections::hash_map::{Entry, HashMap};
use std::path::{Path, PathBuf};

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::mesh::{Mode, Semantic};
use ::gltf::{Accessor, Document, Node, Primitive};
use base64::Engine;
use glam::{Mat3, Mat4, Vec2, Vec3};

use super::gltf_animation::GltfAnimation;
use super::{
    classify, pack_corners, placeholder, Instance, InstanceSet, Mesh, TriStatus, BYTES_PER_TRIANGLE,
};
use crate::error::{Error, Result};
use crate::geometry::{cross, dot, pack_tangent, Affine, Triangle, NO_NORMAL, NO_TANGENT};

/// Where a texture's encoded image is: bytes from a buffer or data URI, or a file.
#[derive(Clone, Debug)]
pub enum GltfImage {
    /// The encoded image (PNG, JPEG).
    Bytes(Vec<u8>),
    /// An image file beside the glTF.
    File(PathBuf),
}

/// A texture a glTF material reads.
#[derive(Clone, Debug)]
pub struct GltfTexture {
    /// The index of its image in the file.
    pub image: usize,
    /// Where the image's bytes are.
    pub bytes: GltfImage,
    /// Where it reads the coordinates lancer interpolates for the material
    /// ([`GltfScene::uvs`], v up): rows of the 2 × 3 map that moves them, from the
    /// textures' `KHR_texture_transform`s; None where it reads them as they are.
    pub uv_transform: Option<[[f32; 3]; 2]>,
}

/// A glTF material's parameters that lancer maps onto its own materials.
#[derive(Clone, Debug)]
pub struct GltfMaterial {
    /// The material's name, or its index.
    pub name: String,
    /// Base colour factor, linear RGBA.
    pub base_color: [f32; 4],
    /// Base colour texture (sRGB).
    pub base_color_texture: Option<GltfTexture>,
    /// Emissive factor × KHR_materials_emissive_strength, linear RGB.
    pub emissive: [f32; 3],
    /// Emissive texture (sRGB), which multiplies the factor.
    pub emissive_texture: Option<GltfTexture>,
    /// Metallic-roughness texture (linear; green: roughness, blue: metalness), which
    /// multiplies the factors.
    pub metallic_roughness_texture: Option<GltfTexture>,
    /// Normal map (linear, tangent space) and its scale of red and green.
    pub normal_texture: Option<(GltfTexture, f32)>,
    /// Occlusion texture (linear, red channel) and its strength.
    pub occlusion_texture: Option<(GltfTexture, f32)>,
    /// The textures of this material that read another set of texture coordinates than
    /// the one lancer interpolates (the first of base colour, emissive,
    /// metallic-roughness's), by name: read at the interpolated set's.
    pub other_coordinates: Vec<&'static str>,
    /// KHR_materials_transmission factor (0 when absent).
    pub transmission: f32,
    /// KHR_materials_ior (1.5, glTF's default, when absent).
    pub ior: f32,
    /// Metallic factor.
    pub metallic: f32,
    /// Roughness factor.
    pub roughness: f32,
    /// Seen from both sides.
    pub double_sided: bool,
    /// Alpha mode `MASK`: the cutoff below which the surface is cut away (alpha is the base
    /// colour factor's times its texture's where the texture is read); None for `OPAQUE`
    /// and `BLEND`.
    pub alpha_cutoff: Option<f32>,
    /// Alpha mode `BLEND`: rendered by stochastic transparency (the surface there with
    /// probability alpha at each hit).
    pub alpha_blend: bool,
}

/// A glTF scene flattened: world-space triangles with texture coordinates and materials.
#[derive(Clone, Debug, Default)]
pub struct GltfScene {
    /// The triangles, node tree walked depth first, each classified.
    pub mesh: Mesh,
    /// Texture coordinates of each triangle's corners, of the set its material's base
    /// colour texture uses, with v pointing up as in OBJ (zero where the file gives none).
    pub uvs: Vec<[Vec2; 3]>,
    /// Each triangle's corner normals (`NORMAL`, moved as the positions are), packed
    /// ([`pack_corners`]); empty where no primitive has normals.
    pub normals: Vec<[u32; 3]>,
    /// Each triangle's corner tangents (`TANGENT`, of a primitive that also has `NORMAL`;
    /// moved as the positions are), packed ([`pack_tangent`]) with the handedness relative
    /// to the triangle's winding; [`NO_TANGENT`] where its primitive has none, empty where
    /// none has any.
    pub tangents: Vec<[u32; 3]>,
    /// Per triangle: index into `materials`, or None (a primitive with no material).
    pub material_ids: Vec<Option<usize>>,
    /// The file's materials, by glTF material index.
    pub materials: Vec<GltfMaterial>,
    /// The perspective cameras its nodes place, in the order the nodes are walked.
    pub cameras: Vec<GltfCamera>,
    /// The lights its nodes place (`KHR_lights_punctual`), in the order the nodes are
    /// walked.
    pub lights: Vec<GltfLight>,
}

/// What kind of light a [`GltfLight`] is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GltfLightKind {
    /// From a point, in every direction.
    Point,
    /// From a point into a cone along `direction`: full within `inner` radians of it,
    /// none beyond `outer`.
    Spot {
        /// The half-angle of full intensity, radians.
        inner: f32,
        /// The half-angle beyond which no light goes, radians.
        outer: f32,
    },
    /// From infinitely far away, along `direction`.
    Directional,
}

/// A punctual light a glTF node places (`KHR_lights_punctual`), in world space.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfLight {
    /// The light's name, else its node's.
    pub name: Option<String>,
    /// Point, spot or directional.
    pub kind: GltfLightKind,
    /// Where it is (point, spot).
    pub position: Vec3,
    /// The unit direction it shines along: its node's −Z (spot, directional).
    pub direction: Vec3,
    /// Linear RGB colour times intensity, as the file gives them: candela (point, spot)
    /// or lux (directional).
    pub photometric: Vec3,
}

/// A perspective camera a glTF node places, in world space.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfCamera {
    /// The camera's name, else its node's (None where neither has one).
    pub name: Option<String>,
    /// Eye position.
    pub eye: Vec3,
    /// A point straight ahead (along the node's −Z).
    pub look_at: Vec3,
    /// The node's +Y.
    pub up: Vec3,
    /// The index of the node that places it (a file's animation may move it).
    pub node: usize,
    /// Vertical field of view, degrees.
    pub yfov_deg: f32,
    /// The width over the height of its view (`aspectRatio`; None where the file gives
    /// none, or one that is not finite and positive): `lancer render` sizes a mesh's image
    /// by it where the command line gives no more than one side.
    pub aspect_ratio: Option<f32>,
}

impl GltfCamera {
    /// The image size `width` pixels wide at its aspect ratio (None where it gives none).
    pub fn shaped(&self, width: u32) -> Option<(u32, u32)> {
        let aspect = self.aspect_ratio?;
        let tall = (width as f32 / aspect)
            .round()
            .clamp(1.0, 64.0 * width.max(1) as f32);
        Some((width, tall as u32))
    }
}

/// The perspective cameras of the nodes `walked` (each with its world map), in that order;
/// orthographic ones are left out with a warning (lancer's camera is a pinhole), as are
/// cameras whose map has no direction left.
fn cameras_of(path: &Path, walked: &[(Node, Mat4)]) -> Vec<GltfCamera> {
    let mut out = Vec::new();
    for (node, world) in walked {
        let Some(camera) = node.camera() else {
            continue;
        };
        let name = (camera.name().or(node.name())).map(str::to_string);
        // Named in warnings as materials are: by name, else by index.
        let label = name
            .clone()
            .unwrap_or_else(|| format!("#{}", camera.index()));
        let ::gltf::camera::Projection::Perspective(p) = camera.projection() else {
            log::warn!(
                "{}: orthographic camera {label:?} not used (lancer's camera is a pinhole)",
                path.display()
            );
            continue;
        };
        let yfov_deg = p.yfov().to_degrees();
        let frame = camera_frame(world).filter(|_| yfov_deg > 0.0 && yfov_deg < 180.0);
        let Some((eye, look_at, up)) = frame else {
            log::warn!(
                "{}: camera {label:?} not used: its node's map or field of view is degenerate",
                path.display()
            );
            continue;
        };
        out.push(GltfCamera {
            name,
            eye,
            look_at,
            up,
            node: node.index(),
            yfov_deg,
            aspect_ratio: p.aspect_ratio().filter(|a| a.is_finite() && *a > 0.0),
        });
    }
    out
}

/// Where a camera placed by the world map `world` looks: its eye, a point straight ahead
/// (along −Z) and its up (+Y); None where the map leaves it no position or direction.
pub(super) fn camera_frame(world: &Mat4) -> Option<(Vec3, Vec3, Vec3)> {
    let eye = world.transform_point3(Vec3::ZERO);
    let ahead = world.transform_vector3(-Vec3::Z);
    let up = world.transform_vector3(Vec3::Y);
    let usable = eye.is_finite()
        && ahead.length() > 0.0
        && ahead.is_finite()
        && up.cross(ahead).length() > 0.0;
    usable.then(|| (eye, eye + ahead.normalize(), up.normalize()))
}

/// A `KHR_texture_transform`: glTF texture coordinates scaled, turned, then offset, as
/// CesiumJS and three.js read the specification (u' = u·cos r + v·sin r, v' = v·cos r −
/// u·sin r, after the scale).
#[derive(Clone, Copy, Debug, PartialEq)]
struct UvTransform {
    /// Rows of the 2 × 3 matrix T·R·S of the specification.
    rows: [[f32; 3]; 2],
}

impl UvTransform {
    const IDENTITY: UvTransform = UvTransform {
        rows: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
    };

    /// The transform `t` gives (None: the identity).
    fn of(t: Option<&::gltf::texture::TextureTransform>) -> UvTransform {
        let Some(t) = t else {
            return UvTransform::IDENTITY;
        };
        UvTransform::from_parts(t.offset(), t.scale(), t.rotation())
    }

    /// The transform of `offset`, `scale` and `rotation` (radians).
    fn from_parts([ox, oy]: [f32; 2], [sx, sy]: [f32; 2], r: f32) -> UvTransform {
        let (s, c) = r.sin_cos();
        UvTransform {
            rows: [[c * sx, s * sy, ox], [-s * sx, c * sy, oy]],
        }
    }

    /// The map from coordinates moved by `base` to coordinates moved by `self`, both with
    /// v up as lancer keeps them (v' = 1 − v): `flip ∘ self ∘ base⁻¹ ∘ flip`; None where
    /// it is the identity, or `base` cannot be undone (it collapses the coordinates).
    fn relative_to(&self, base: &UvTransform) -> Option<[[f32; 3]; 2]> {
        if self == base {
            return None;
        }
        let m = |t: &UvTransform| {
            let [a, b] = t.rows.map(|r| r.map(f64::from));
            glam::DMat3::from_cols_array_2d(&[
                [a[0], b[0], 0.0],
                [a[1], b[1], 0.0],
                [a[2], b[2], 1.0],
            ])
        };
        let flip =
            glam::DMat3::from_cols_array_2d(&[[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 1.0, 1.0]]);
        let base = m(base);
        if base.determinant().abs() < 1e-12 {
            return None;
        }
        let r = flip * m(self) * base.inverse() * flip;
        let rows = [0, 1].map(|i| [r.x_axis[i], r.y_axis[i], r.z_axis[i]].map(|x| x as f32));
        let finite = rows.iter().flatten().all(|x| x.is_finite());
        (finite && rows != UvTransform::IDENTITY.rows).then_some(rows)
    }

    /// Gltf coordinates (v down) moved.
    fn apply(&self, [u, v]: [f32; 2]) -> [f32; 2] {
        let [a, b] = &self.rows;
        [a[0] * u + a[1] * v + a[2], b[0] * u + b[1] * v + b[2]]
    }
}

/// The punctual lights of the nodes `walked` (each with its world map), in that order; a
/// light's `range` is not honoured (lancer's lights fall off with 1/d² without end), and a
/// light whose map has no direction left is left out, each with a warning.
fn lights_of(path: &Path, walked: &[(Node, Mat4)]) -> Vec<GltfLight> {
    use ::gltf::khr_lights_punctual::Kind;
    let mut out = Vec::new();
    for (node, world) in walked {
        let Some(light) = node.light() else {
            continue;
        };
        let name = (light.name().or(node.name())).map(str::to_string);
        let label = name
            .clone()
            .unwrap_or_else(|| format!("#{}", light.index()));
        let kind = match light.kind() {
            Kind::Point => GltfLightKind::Point,
            Kind::Directional => GltfLightKind::Directional,
            Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => GltfLightKind::Spot {
                inner: inner_cone_angle,
                outer: outer_cone_angle,
            },
        };
        let position = world.transform_point3(Vec3::ZERO);
        let direction = world.transform_vector3(-Vec3::Z);
        let photometric = Vec3::from(light.color()) * light.intensity();
        let angles_ok = match kind {
            GltfLightKind::Spot { inner, outer } => {
                (0.0..outer).contains(&inner) && outer <= std::f32::consts::FRAC_PI_2
            }
            _ => true,
        };
        let usable = position.is_finite()
            && direction.is_finite()
            && direction.length() > 0.0
            && photometric.is_finite()
            && photometric.min_element() >= 0.0
            && angles_ok;
        if !usable {
            log::warn!(
                "{}: light {label:?} not used: its node's map, its intensity or its cone is \
                 degenerate",
                path.display()
            );
            continue;
        }
        if light.range().is_some() {
            log::warn!(
                "{}: light {label:?}: its range is not honoured (it lights beyond it, falling \
                 off with the square of the distance)",
                path.display()
            );
        }
        out.push(GltfLight {
            name,
            kind,
            position,
            direction: direction.normalize(),
            photometric,
        });
    }
    out
}

/// Loads a glTF 2.0 file's default scene (or its first; or every root node when it has no
/// scene) as world-space triangles, without materials' textures decoded.
pub fn load_gltf(path: &Path) -> Result<GltfScene> {
    flatten_opened(path, open(path)?)
}

/// [`load_gltf`] of a file opened.
fn flatten_opened(path: &Path, opened: Opened) -> Result<GltfScene> {
    let Opened {
        document,
        buffers,
        dir,
        mut sources,
    } = opened;
    let bad = |msg: String| Error::input(path, None, msg);
    let materials = document
        .materials()
        .map(|m| material(path, &dir, &buffers, &m, &mut sources))
        .collect::<Result<Vec<_>>>()?;
    let instances = instances(path, &document)?;

    // Count first, so a file that instances a mesh too often is refused before allocating.
    let mut total: u128 = 0;
    for (node, _) in &instances {
        for p in node.mesh().iter().flat_map(|m| m.primitives()) {
            total += triangle_count(path, &p)? as u128;
        }
    }
    if total >= u32::MAX as u128 / 2 {
        return Err(bad(format!(
            "{total} triangles after instancing, more than lancer indexes: split the scene"
        )));
    }
    crate::limits::check_memory(
        &format!("{} ({total} triangles)", path.display()),
        total * BYTES_PER_TRIANGLE,
        "use a smaller scene",
    )?;

    let mut out = GltfScene {
        materials,
        cameras: cameras_of(path, &instances),
        lights: lights_of(path, &instances),
        ..GltfScene::default()
    };
    // Each mesh is read once, however many nodes instance it.
    let mut surfaces: HashMap<usize, Vec<Option<Surface>>> = HashMap::new();
    let mut skipped = 0usize;
    for (node, world) in &instances {
        let Some(mesh) = node.mesh() else { continue };
        let read = match surfaces.entry(mesh.index()) {
            Entry::Occupied(e) => e.into_mut(),
            Entry::Vacant(e) => e.insert(
                mesh.primitives()
                    .map(|p| read_surface(path, &p, &buffers))
                    .collect::<Result<Vec<_>>>()?,
            ),
        };
        for s in read.iter() {
            match s {
                Some(s) => add_surface(s, world, world.determinant() < 0.0, &mut out),
                None => skipped += 1,
            }
        }
    }
    if skipped > 0 {
        log::warn!(
            "{}: {skipped} primitives of points or lines left out (no surface to hit)",
            path.display()
        );
    }
    out.mesh.sources = sources;
    Ok(out)
}

/// A glTF file read and checked: its document, its buffers' bytes, its folder, and the
/// files read (the file and its external buffers).
struct Opened {
    document: Document,
    buffers: Vec<Vec<u8>>,
    dir: PathBuf,
    sources: Vec<PathBuf>,
}

/// Reads and checks a glTF file and its buffers.
fn open(path: &Path) -> Result<Opened> {
    let bytes = crate::input::read(path)?;
    let bad = |msg: String| Error::input(path, None, msg);
    // Checked first: the crate panics on some references out of range.
    let json = super::gltf_check::json_of(&bytes).map_err(bad)?;
    super::gltf_check::check(json).map_err(|e| bad(format!("not a valid glTF 2.0 file: {e}")))?;
    let unsupported = super::gltf_check::unsupported_required(json);
    if !unsupported.is_empty() {
        return Err(bad(format!(
            "a glTF 2.0 file that requires an extension lancer does not support: {}",
            unsupported.join(", ")
        )));
    }
    let ::gltf::Gltf { document, mut blob } = ::gltf::Gltf::from_slice(&bytes)
        .map_err(|e| bad(format!("not a valid glTF 2.0 file: {e}")))?;
    drop(bytes);
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut sources = vec![path.to_path_buf()];
    let buffers = read_buffers(path, &dir, &document, &mut blob, &mut sources)?;
    Ok(Opened {
        document,
        buffers,
        dir,
        sources,
    })
}

/// A glTF scene whose meshes are drawn by several nodes: each mesh once, in its own space,
/// with its texture coordinates and materials, and the nodes that draw it as instances.
#[derive(Clone, Debug, Default)]
pub struct GltfPlaced {
    /// The meshes, each as [`GltfScene`] holds a flattened scene (the first also names
    /// every file read; `materials` empty: they are [`GltfPlaced::materials`]).
    pub meshes: Vec<GltfScene>,
    /// The file's materials, by glTF material index.
    pub materials: Vec<GltfMaterial>,
    /// The meshes placed (index into `meshes`), in the order [`load_gltf`] walks the nodes.
    pub instances: Vec<Instance>,
    /// The perspective cameras its nodes place ([`GltfScene::cameras`]).
    pub cameras: Vec<GltfCamera>,
    /// The lights its nodes place ([`GltfScene::lights`]).
    pub lights: Vec<GltfLight>,
    /// The file's first animation, where it moves its meshes or its cameras: the
    /// instances' maps at any time (one per instance, in order).
    pub animation: Option<GltfAnimation>,
    /// Whether a mesh is drawn by several nodes; else the file is placed only for its
    /// animation, and a still use of it ([`load_gltf_instances`]) takes it flattened.
    pub shares_meshes: bool,
}

impl GltfPlaced {
    /// The geometry alone, for tracing.
    pub fn instance_set(&self) -> Result<InstanceSet> {
        let meshes = (self.meshes.iter())
            .map(|m| std::sync::Arc::new(m.mesh.clone()))
            .collect();
        InstanceSet::new(meshes, self.instances.clone())
    }
}

/// A glTF file read once: its meshes placed by instances where a mesh is drawn by several
/// nodes, else its scene flattened.
#[derive(Clone, Debug)]
pub enum GltfLoaded {
    /// Each mesh drawn once: [`load_gltf`]'s flattened scene.
    Flat(GltfScene),
    /// A mesh drawn by several nodes: [`load_gltf_placed`]'s meshes and instances.
    Placed(GltfPlaced),
}

/// The default scene's meshes placed by instances ([`load_gltf_placed`]) where a mesh is
/// drawn by several nodes, geometry alone (None also where the file is placed only for its
/// animation: a still use takes it flattened).
pub fn load_gltf_instances(path: &Path) -> Result<Option<InstanceSet>> {
    match read_gltf(path)? {
        GltfLoaded::Flat(_) => Ok(None),
        GltfLoaded::Placed(p) if !p.shares_meshes => Ok(None),
        GltfLoaded::Placed(p) => (p.instance_set())
            .map(Some)
            .map_err(|e| Error::input(path, None, e.to_string())),
    }
}

/// The default scene's meshes placed by instances, when a mesh is drawn by several nodes
/// or an animation moves the file (as [`read_gltf`] reads it; None otherwise).
pub fn load_gltf_placed(path: &Path) -> Result<Option<GltfPlaced>> {
    Ok(match read_gltf(path)? {
        GltfLoaded::Flat(_) => None,
        GltfLoaded::Placed(p) => Some(p),
    })
}

/// Reads a glTF file once: the default scene's meshes placed by instances, when a mesh is
/// drawn by several nodes or its first animation moves a mesh ([`GltfPlaced::animation`]);
/// else (the flattened scene is then no bigger) [`load_gltf`]'s
/// flattened scene. One mesh per glTF mesh (its primitives' triangles in order, in its own space), one
/// instance per node that draws it, in the order [`load_gltf`] walks them, so triangles are
/// numbered alike. A mirroring node draws a copy of its mesh with two corners swapped (as
/// [`load_gltf`] swaps them); a node whose map is singular draws a copy whose triangles are
/// all left out (they have no area), at the identity.
pub fn read_gltf(path: &Path) -> Result<GltfLoaded> {
    let opened = open(path)?;
    let bad = |msg: String| Error::input(path, None, msg);
    let placed = instances(path, &opened.document)?;
    /// How a node draws its glTF mesh: as it is, mirrored, or with no area.
    #[derive(Clone, Copy, PartialEq, Eq, Hash)]
    enum Drawn {
        Plain,
        Mirrored,
        Flat,
    }
    let mut unique: HashMap<(usize, Drawn), u32> = HashMap::new();
    let mut order: Vec<(usize, Drawn)> = Vec::new();
    let mut placements = Vec::new();
    for (node, world) in &placed {
        let Some(mesh) = node.mesh() else { continue };
        let to_world = Affine::from_mat4(world);
        let drawn = match to_world.inverse() {
            None => Drawn::Flat,
            Some(_) if world.determinant() < 0.0 => Drawn::Mirrored,
            Some(_) => Drawn::Plain,
        };
        let next = order.len() as u32;
        let id = *unique.entry((mesh.index(), drawn)).or_insert(next);
        if id == next {
            order.push((mesh.index(), drawn));
        }
        let to_world = if drawn == Drawn::Flat {
            Affine::IDENTITY
        } else {
            to_world
        };
        placements.push(Instance { mesh: id, to_world });
    }
    let drawn_meshes: std::collections::HashSet<usize> = order.iter().map(|k| k.0).collect();
    // An animation that moves meshes places them (each then moves with its node).
    let nodes_with = |has: fn(&Node) -> bool| -> Vec<usize> {
        placed
            .iter()
            .filter(|(n, _)| has(n))
            .map(|(n, _)| n.index())
            .collect()
    };
    let mesh_nodes = (placed.iter())
        .filter(|(n, _)| n.mesh().is_some())
        .map(|(n, w)| (n.index(), *w))
        .collect();
    let (camera_nodes, light_nodes) = (
        nodes_with(|n| n.camera().is_some()),
        nodes_with(|n| n.light().is_some()),
    );
    let read = GltfAnimation::read(
        path,
        &opened.document,
        &opened.buffers,
        mesh_nodes,
        (&camera_nodes, &light_nodes),
    );
    // An animation that cannot be played does not keep the file from being drawn still.
    let animation = read.unwrap_or_else(|e| {
        log::warn!("{e}: the animation is not played");
        None
    });
    let shares_meshes = placements.len() > drawn_meshes.len();
    if !shares_meshes && animation.is_none() {
        return flatten_opened(path, opened).map(GltfLoaded::Flat);
    }
    let cameras = cameras_of(path, &placed);
    let lights = lights_of(path, &placed);
    let Opened {
        document,
        buffers,
        dir,
        mut sources,
    } = opened;
    let materials = (document.materials())
        .map(|m| material(path, &dir, &buffers, &m, &mut sources))
        .collect::<Result<Vec<_>>>()?;
    let mut total: u128 = 0;
    for &(m, _) in &order {
        for p in document.meshes().nth(m).iter().flat_map(|m| m.primitives()) {
            total += triangle_count(path, &p)? as u128;
        }
    }
    crate::limits::check_memory(
        &format!("{} ({total} triangles in its meshes)", path.display()),
        total * BYTES_PER_TRIANGLE,
        "use a smaller scene",
    )?;
    let mut surfaces: HashMap<usize, Vec<Option<Surface>>> = HashMap::new();
    let mut meshes = Vec::with_capacity(order.len());
    let mut skipped = 0usize;
    for &(m, drawn) in &order {
        let Some(mesh) = document.meshes().nth(m) else {
            continue;
        };
        let read = match surfaces.entry(m) {
            Entry::Occupied(e) => e.into_mut(),
            Entry::Vacant(e) => e.insert(
                mesh.primitives()
                    .map(|p| read_surface(path, &p, &buffers))
                    .collect::<Result<Vec<_>>>()?,
            ),
        };
        let mut out = GltfScene::default();
        for s in read.iter() {
            match s {
                Some(s) => add_surface(s, &Mat4::IDENTITY, drawn == Drawn::Mirrored, &mut out),
                None => skipped += 1,
            }
        }
        if drawn == Drawn::Flat {
            out.mesh.status.iter_mut().for_each(|s| {
                if *s == TriStatus::Ok {
                    *s = TriStatus::Degenerate;
                }
            });
        }
        meshes.push(out);
    }
    if skipped > 0 {
        log::warn!(
            "{}: {skipped} primitives of points or lines left out (no surface to hit)",
            path.display()
        );
    }
    if let Some(first) = meshes.first_mut() {
        first.mesh.sources = sources;
    }
    let placed = GltfPlaced {
        meshes,
        materials,
        instances: placements,
        cameras,
        lights,
        animation,
        shares_meshes,
    };
    // The maps were checked above (a singular one placed at the identity); the count is
    // what InstanceSet::new would refuse.
    let placed_triangles: u64 = (placed.instances.iter())
        .map(|i| placed.meshes[i.mesh as usize].mesh.len() as u64)
        .sum();
    if placed_triangles > super::MAX_INSTANCED_TRIANGLES {
        return Err(bad(format!(
            "{placed_triangles} triangles after instancing, more than lancer numbers: split \
             the scene"
        )));
    }
    Ok(GltfLoaded::Placed(placed))
}

/// Each buffer's bytes, checked to hold at least its declared byteLength, and every buffer
/// view checked to lie inside its buffer.
fn read_buffers(
    path: &Path,
    dir: &Path,
    doc: &Document,
    blob: &mut Option<Vec<u8>>,
    sources: &mut Vec<PathBuf>,
) -> Result<Vec<Vec<u8>>> {
    let mut buffers = Vec::new();
    for b in doc.buffers() {
        let bad = |msg: String| Error::input(path, None, format!("buffer {}: {msg}", b.index()));
        let data = match b.source() {
            ::gltf::buffer::Source::Bin => blob
                .take()
                .ok_or_else(|| bad("refers to a GLB binary chunk the file does not have".into()))?,
            ::gltf::buffer::Source::Uri(uri) => {
                read_uri(path, dir, uri, b.length(), sources).map_err(&bad)?
            }
        };
        if data.len() < b.length() {
            return Err(bad(format!(
                "holds {} bytes but declares byteLength {}: the file is truncated",
                data.len(),
                b.length()
            )));
        }
        buffers.push(data);
    }
    for v in doc.views() {
        let len = buffers[v.buffer().index()].len();
        let end = v.offset().checked_add(v.length());
        if end.is_none_or(|e| e > len) {
            return Err(Error::input(
                path,
                None,
                format!(
                    "bufferView {} reaches past the end of buffer {} ({len} bytes)",
                    v.index(),
                    v.buffer().index()
                ),
            ));
        }
    }
    Ok(buffers)
}

/// The bytes of a URI: a base64 data URI, or a file relative to the glTF; `expect` bytes
/// are declared (a file shorter than that is refused before it is read).
fn read_uri(
    path: &Path,
    dir: &Path,
    uri: &str,
    expect: usize,
    sources: &mut Vec<PathBuf>,
) -> std::result::Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, data) = rest
            .split_once(";base64,")
            .ok_or("a data URI that is not base64")?;
        return base64::engine::general_purpose::STANDARD
            .decode(data)
            .map_err(|e| format!("its data URI is not valid base64 ({e})"));
    }
    let file = dir.join(percent_decode(uri));
    let len = crate::input::regular_file(&file).map_err(|e| e.to_string())?;
    if len < expect as u64 {
        return Err(format!(
            "{} is {len} bytes, shorter than the {expect} declared",
            file.display()
        ));
    }
    crate::limits::check_memory(
        &file.display().to_string(),
        len as u128,
        "use smaller files",
    )
    .map_err(|e| e.to_string())?;
    if file == path {
        return Err("names the glTF file itself as its buffer".into());
    }
    sources.push(file.clone());
    crate::input::read(&file).map_err(|e| e.to_string())
}

/// `%20` and the like in relative URIs (glTF URIs are percent-encoded).
fn percent_decode(uri: &str) -> String {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        if b[i] == b'%' && i + 2 < b.len() {
            if let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn material(
    path: &Path,
    dir: &Path,
    buffers: &[Vec<u8>],
    m: &::gltf::Material,
    sources: &mut Vec<PathBuf>,
) -> Result<GltfMaterial> {
    let name = m
        .name()
        .map(str::to_string)
        .unwrap_or_else(|| format!("#{}", m.index().unwrap_or(0)));
    let bad = |msg: String| Error::input(path, None, format!("material {name:?}: {msg}"));
    let alpha_cutoff = match m.alpha_mode() {
        ::gltf::material::AlphaMode::Mask => Some(m.alpha_cutoff().unwrap_or(0.5)),
        _ => None,
    };
    let alpha_blend = m.alpha_mode() == ::gltf::material::AlphaMode::Blend;
    if alpha_cutoff.is_some_and(|c| !c.is_finite() || c < 0.0) {
        return Err(bad("alphaCutoff must be finite and non-negative".into()));
    }
    let pbr = m.pbr_metallic_roughness();
    let strength = m.emissive_strength().unwrap_or(1.0);
    let emissive = m.emissive_factor().map(|x| x * strength);
    let base_color = pbr.base_color_factor();
    let ior = m.ior().unwrap_or(1.5);
    let transmission = m.transmission().map_or(0.0, |t| t.transmission_factor());
    let (metallic, roughness) = (pbr.metallic_factor(), pbr.roughness_factor());
    let finite = base_color
        .iter()
        .chain(&emissive)
        .chain(&[ior, transmission, metallic, roughness])
        .all(|x| x.is_finite());
    if !finite || base_color.iter().chain(&emissive).any(|&x| x < 0.0) {
        return Err(bad(
            "colours and factors must be finite, colours non-negative".into(),
        ));
    }
    let used = texture_coordinates(m);
    let (used_set, used_map) = used.unwrap_or((0, UvTransform::IDENTITY));
    let mut other_coordinates: Vec<&'static str> = Vec::new();
    let mut texture_of = |what: &'static str,
                          texture: Option<(::gltf::Texture, (u32, UvTransform))>,
                          sources: &mut Vec<PathBuf>|
     -> Result<Option<GltfTexture>> {
        let Some((texture, (set, map))) = texture else {
            return Ok(None);
        };
        if set != used_set {
            other_coordinates.push(what);
        }
        let image = texture.source();
        let bytes = match image.source() {
            ::gltf::image::Source::View { view, .. } => GltfImage::Bytes(
                buffers[view.buffer().index()][view.offset()..view.offset() + view.length()]
                    .to_vec(),
            ),
            ::gltf::image::Source::Uri { uri, .. } if uri.starts_with("data:") => GltfImage::Bytes(
                read_uri(path, dir, uri, 0, sources)
                    .map_err(|e| bad(format!("image {}: {e}", image.index())))?,
            ),
            ::gltf::image::Source::Uri { uri, .. } => {
                let file = dir.join(percent_decode(uri));
                if !sources.contains(&file) {
                    sources.push(file.clone());
                }
                GltfImage::File(file)
            }
        };
        Ok(Some(GltfTexture {
            image: image.index(),
            bytes,
            uv_transform: (set == used_set)
                .then(|| map.relative_to(&used_map))
                .flatten(),
        }))
    };

    let base_color_texture = texture_of(
        "base colour",
        pbr.base_color_texture()
            .map(|i| (i.texture(), coordinates_of(&i))),
        sources,
    )?;
    let emissive_texture = texture_of(
        "emissive",
        m.emissive_texture()
            .map(|i| (i.texture(), coordinates_of(&i))),
        sources,
    )?;
    let metallic_roughness_texture = texture_of(
        "metallic-roughness",
        (pbr.metallic_roughness_texture()).map(|i| (i.texture(), coordinates_of(&i))),
        sources,
    )?;
    // A normal or occlusion texture's KHR_texture_transform is read from its JSON (the
    // gltf crate parses it for the others only).
    let normal = m.normal_texture();
    let normal_coordinates = (normal.as_ref()).map(|n| {
        (
            n.texture(),
            json_coordinates(n.tex_coord(), n.extension_value(TRANSFORM)),
        )
    });
    let normal_texture = texture_of("normal", normal_coordinates, sources)?
        .map(|t| (t, normal.as_ref().map_or(1.0, |n| n.scale())));
    let occlusion = m.occlusion_texture();
    let occlusion_coordinates = (occlusion.as_ref()).map(|o| {
        (
            o.texture(),
            json_coordinates(o.tex_coord(), o.extension_value(TRANSFORM)),
        )
    });
    let occlusion_texture = texture_of("occlusion", occlusion_coordinates, sources)?
        .map(|t| (t, occlusion.as_ref().map_or(1.0, |o| o.strength())));
    Ok(GltfMaterial {
        name,
        base_color,
        base_color_texture,
        emissive,
        emissive_texture,
        metallic_roughness_texture,
        normal_texture,
        occlusion_texture,
        other_coordinates,
        transmission,
        ior,
        metallic,
        roughness,
        double_sided: m.double_sided(),
        alpha_cutoff,
        alpha_blend,
    })
}

/// The name of the texture transform extension.
const TRANSFORM: &str = "KHR_texture_transform";

/// A normal or occlusion texture's coordinate set (`tex_coord`), moved by its
/// KHR_texture_transform read from the extension's JSON `ext` (which may name another
/// set); members that are missing or malformed take the extension's defaults.
fn json_coordinates(tex_coord: u32, ext: Option<&serde_json::Value>) -> (u32, UvTransform) {
    let Some(ext) = ext else {
        return (tex_coord, UvTransform::IDENTITY);
    };
    let pair = |key: &str, default: [f32; 2]| {
        let v = ext.get(key).and_then(|v| v.as_array());
        let at = |i: usize| v.and_then(|v| v.get(i)).and_then(|x| x.as_f64());
        match (at(0), at(1)) {
            (Some(a), Some(b)) if v.is_some_and(|v| v.len() == 2) => [a as f32, b as f32],
            _ => default,
        }
    };
    let rotation = ext.get("rotation").and_then(|r| r.as_f64()).unwrap_or(0.0) as f32;
    let set = (ext.get("texCoord").and_then(|t| t.as_u64()))
        .and_then(|t| u32::try_from(t).ok())
        .unwrap_or(tex_coord);
    (
        set,
        UvTransform::from_parts(
            pair("offset", [0.0, 0.0]),
            pair("scale", [1.0, 1.0]),
            rotation,
        ),
    )
}

/// A texture's coordinate set, moved by its KHR_texture_transform (which may name another
/// set).
fn coordinates_of(info: &::gltf::texture::Info) -> (u32, UvTransform) {
    let transform = info.texture_transform();
    let set = (transform.as_ref().and_then(|x| x.tex_coord())).unwrap_or(info.tex_coord());
    (set, UvTransform::of(transform.as_ref()))
}

/// The texture coordinates lancer interpolates for a material: those of its base colour
/// texture, else its emissive, else its metallic-roughness texture (None: it has none).
fn texture_coordinates(m: &::gltf::Material) -> Option<(u32, UvTransform)> {
    let pbr = m.pbr_metallic_roughness();
    (pbr.base_color_texture())
        .or(m.emissive_texture())
        .or(pbr.metallic_roughness_texture())
        .map(|i| coordinates_of(&i))
}

/// The nodes of the scene with a mesh, a camera or a light, each with its world transform, in the order the
/// tree is walked. glTF nodes form trees: a node with two parents or on a cycle is refused
/// (it would be instanced without end).
fn instances<'a>(path: &Path, doc: &'a Document) -> Result<Vec<(Node<'a>, Mat4)>> {
    let n = doc.nodes().len();
    let mut parent = vec![None; n];
    for p in doc.nodes() {
        for c in p.children() {
            if let Some(q) = parent[c.index()].replace(p.index()) {
                return Err(Error::input(
                    path,
                    None,
                    format!(
                        "node {} is a child of nodes {q} and {}: glTF nodes must form trees",
                        c.index(),
                        p.index()
                    ),
                ));
            }
        }
    }
    let roots: Vec<Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(s) => s.nodes().collect(),
        None => doc
            .nodes()
            .filter(|x| parent[x.index()].is_none())
            .collect(),
    };
    let mut seen = vec![false; n];
    let mut out = Vec::new();
    let mut stack: Vec<(Node, Mat4)> = roots
        .into_iter()
        .rev()
        .map(|r| (r, Mat4::IDENTITY))
        .collect();
    while let Some((node, up)) = stack.pop() {
        if std::mem::replace(&mut seen[node.index()], true) {
            return Err(Error::input(
                path,
                None,
                format!(
                    "node {} is reached twice from the scene (a cycle, or listed twice): glTF \
                     nodes must form trees",
                    node.index()
                ),
            ));
        }
        let world = up * Mat4::from_cols_array_2d(&node.transform().matrix());
        let children: Vec<Node> = node.children().collect();
        for c in children.into_iter().rev() {
            stack.push((c, world));
        }
        if node.mesh().is_some() || node.camera().is_some() || node.light().is_some() {
            out.push((node, world));
        }
    }
    Ok(out)
}

/// Checks an accessor before the gltf crate reads it (its reader panics on some bad
/// layouts): type, no sparse storage, stride, and bounds within its buffer view. Returns
/// the element count.
pub(super) fn check_accessor(
    path: &Path,
    acc: &Accessor,
    what: &str,
    dims: Dimensions,
    types: &[DataType],
) -> Result<usize> {
    let bad = |msg: String| {
        Error::input(
            path,
            None,
            format!("accessor {} ({what}): {msg}", acc.index()),
        )
    };
    if acc.dimensions() != dims || !types.contains(&acc.data_type()) {
        return Err(bad(format!(
            "is {:?} of {:?}; lancer reads {dims:?} of {types:?}",
            acc.dimensions(),
            acc.data_type()
        )));
    }
    if acc.sparse().is_some() {
        return Err(bad(
            "sparse accessors are not supported: export the mesh without sparse storage".into(),
        ));
    }
    let view = acc
        .view()
        .ok_or_else(|| bad("has no bufferView (no data)".into()))?;
    let count = acc.count();
    if count == 0 {
        return Ok(0);
    }
    let elem = acc.size();
    let stride = view.stride().unwrap_or(elem);
    if stride < elem {
        return Err(bad(format!(
            "byteStride {stride} is less than the {elem} bytes of an element"
        )));
    }
    let end = stride
        .checked_mul(count - 1)
        .and_then(|x| x.checked_add(elem))
        .and_then(|x| x.checked_add(acc.offset()));
    if end.is_none_or(|e| e > view.length()) {
        return Err(bad(format!(
            "{count} elements reach past the end of bufferView {} ({} bytes)",
            view.index(),
            view.length()
        )));
    }
    Ok(count)
}

/// Triangles a primitive makes (0 for points and lines), its accessors checked.
fn triangle_count(path: &Path, p: &Primitive) -> Result<usize> {
    let positions = p.get(&Semantic::Positions).ok_or_else(|| {
        Error::input(
            path,
            None,
            "a mesh primitive has no POSITION attribute".to_string(),
        )
    })?;
    let nv = check_accessor(
        path,
        &positions,
        "POSITION",
        Dimensions::Vec3,
        &[DataType::F32],
    )?;
    let n = match p.indices() {
        Some(i) => check_accessor(
            path,
            &i,
            "indices",
            Dimensions::Scalar,
            &[DataType::U8, DataType::U16, DataType::U32],
        )?,
        None => nv,
    };
    Ok(match p.mode() {
        Mode::Triangles => n / 3,
        Mode::TriangleStrip | Mode::TriangleFan => n.saturating_sub(2),
        _ => 0,
    })
}

/// A primitive's triangles in its mesh's space, read once for every node that draws it.
struct Surface {
    positions: Vec<Vec3>,
    /// Each triangle's corners (indices into `positions`, possibly out of range).
    corners: Vec<[usize; 3]>,
    /// Texture coordinates by vertex, v pointing up.
    uvs: Vec<Vec2>,
    /// Normals by vertex (empty where the primitive has none).
    normals: Vec<Vec3>,
    /// Tangents by vertex, w the bitangent's sign (empty where the primitive has none, or
    /// no normals: glTF then ignores them).
    tangents: Vec<glam::Vec4>,
    material: Option<usize>,
    /// Indices left over after the last whole triangle (a short face).
    short: bool,
}

/// Reads a primitive's triangles; None for points and lines (no surface).
fn read_surface(path: &Path, p: &Primitive, buffers: &[Vec<u8>]) -> Result<Option<Surface>> {
    let mode = p.mode();
    if !matches!(
        mode,
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        return Ok(None);
    }
    let reader = p.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    // Accessors were checked by triangle_count; count 0 means no data to read.
    let positions: Vec<Vec3> = if p.get(&Semantic::Positions).is_some_and(|a| a.count() > 0) {
        reader
            .read_positions()
            .map(|it| it.map(Vec3::from).collect())
            .unwrap_or_default()
    } else {
        Vec::new()
    };
    let indices: Vec<u32> = match p.indices() {
        Some(a) if a.count() == 0 => Vec::new(),
        Some(_) => reader
            .read_indices()
            .map(|i| i.into_u32().collect())
            .unwrap_or_default(),
        None => (0..positions.len() as u32).collect(),
    };
    let (set, uv_map) = texture_coordinates(&p.material()).unwrap_or((0, UvTransform::IDENTITY));
    let uvs: Vec<Vec2> = match p.get(&Semantic::TexCoords(set)) {
        Some(a) => {
            let n = check_accessor(
                path,
                &a,
                &format!("TEXCOORD_{set}"),
                Dimensions::Vec2,
                &[DataType::F32, DataType::U8, DataType::U16],
            )?;
            if n == 0 {
                Vec::new()
            } else {
                reader
                    .read_tex_coords(set)
                    .map(|t| {
                        (t.into_f32())
                            .map(|uv| uv_map.apply(uv))
                            .map(|[u, v]| Vec2::new(u, 1.0 - v))
                            .collect()
                    })
                    .unwrap_or_default()
            }
        }
        None => Vec::new(),
    };
    let normals: Vec<Vec3> = match p.get(&Semantic::Normals) {
        Some(a) => {
            let n = check_accessor(path, &a, "NORMAL", Dimensions::Vec3, &[DataType::F32])?;
            match n {
                0 => Vec::new(),
                _ => (reader.read_normals())
                    .map(|it| it.map(Vec3::from).collect())
                    .unwrap_or_default(),
            }
        }
        None => Vec::new(),
    };
    let tangents: Vec<glam::Vec4> = match p.get(&Semantic::Tangents) {
        Some(a) if !normals.is_empty() => {
            let n = check_accessor(path, &a, "TANGENT", Dimensions::Vec4, &[DataType::F32])?;
            match n {
                0 => Vec::new(),
                _ => (reader.read_tangents())
                    .map(|it| it.map(glam::Vec4::from).collect())
                    .unwrap_or_default(),
            }
        }
        _ => Vec::new(),
    };
    let corners: Vec<[usize; 3]> = match mode {
        Mode::Triangles => indices
            .chunks_exact(3)
            .map(|c| [c[0] as usize, c[1] as usize, c[2] as usize])
            .collect(),
        // glTF 2.0 §3.7.2.1: strip triangle i is (v_i, v_{i+1+i%2}, v_{i+2-i%2}); fan
        // triangle i is (v_{i+1}, v_{i+2}, v_0).
        Mode::TriangleStrip => (0..indices.len().saturating_sub(2))
            .map(|i| [i, i + 1 + i % 2, i + 2 - i % 2].map(|k| indices[k] as usize))
            .collect(),
        _ => (0..indices.len().saturating_sub(2))
            .map(|i| [indices[i + 1], indices[i + 2], indices[0]].map(|k| k as usize))
            .collect(),
    };
    Ok(Some(Surface {
        positions,
        corners,
        uvs,
        normals,
        tangents,
        material: p.material().index(),
        short: mode == Mode::Triangles && !indices.len().is_multiple_of(3),
    }))
}

/// The packed tangents of world-space triangle `t`'s corners `c` (vertex numbers): each
/// vertex's tangent and bitangent (n × t, times w) moved by `linear`, the handedness read
/// against `t`'s winding; [`NO_TANGENT`] three times where a corner has none or it is
/// degenerate.
fn corner_tangents(
    t: &Triangle,
    c: [usize; 3],
    normals: &[Vec3],
    tangents: &[glam::Vec4],
    linear: &Mat3,
) -> [u32; 3] {
    let wn = cross(t.v[1] - t.v[0], t.v[2] - t.v[0]);
    let corner = |k: usize| {
        let (n, tw) = (normals.get(k)?, tangents.get(k)?);
        let tangent = linear.mul_vec3(tw.truncate());
        let bitangent = linear.mul_vec3(cross(*n, tw.truncate()) * tw.w);
        pack_tangent(tangent, dot(cross(wn, tangent), bitangent) < 0.0)
    };
    match c.map(corner) {
        [Some(a), Some(b), Some(d)] => [a, b, d],
        _ => [NO_TANGENT; 3],
    }
}

/// Adds a surface's triangles, moved into world space by `world`, two corners swapped when
/// `flip` (a mirroring map turns faces inside out: the swap keeps the front).
fn add_surface(s: &Surface, world: &Mat4, flip: bool, out: &mut GltfScene) {
    let Surface {
        positions,
        corners,
        uvs,
        normals,
        tangents,
        material,
        short,
    } = s;
    out.mesh.short_faces += usize::from(*short);
    // Normals move by the inverse transpose of the map's linear part.
    let normal_map = Mat3::from_mat4(*world).inverse().transpose();
    let with_normals = !normals.is_empty() || !out.normals.is_empty();
    if with_normals {
        out.normals.resize(out.mesh.triangles.len(), [NO_NORMAL; 3]);
    }
    let with_tangents = !tangents.is_empty() || !out.tangents.is_empty();
    if with_tangents {
        out.tangents
            .resize(out.mesh.triangles.len(), [NO_TANGENT; 3]);
    }
    let linear = Mat3::from_mat4(*world);
    for &c in corners {
        let c = if flip { [c[0], c[2], c[1]] } else { c };
        let (t, s, uv) = match c.map(|k| positions.get(k)) {
            [Some(a), Some(b), Some(d)] => {
                let t = Triangle::new(
                    world.transform_point3(*a),
                    world.transform_point3(*b),
                    world.transform_point3(*d),
                );
                let uv = c.map(|k| uvs.get(k).copied().unwrap_or(Vec2::ZERO));
                (t, classify(&t), uv)
            }
            _ => (placeholder(), TriStatus::OutOfRange, [Vec2::ZERO; 3]),
        };
        if with_normals {
            let n = c.map(|k| normals.get(k).map_or(Vec3::ZERO, |&n| normal_map * n));
            out.normals.push(pack_corners(n));
        }
        if with_tangents {
            out.tangents
                .push(corner_tangents(&t, c, normals, tangents, &linear));
        }
        out.mesh.triangles.push(t);
        out.mesh.status.push(s);
        out.uvs.push(uv);
        out.material_ids.push(*material);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Any width gives a size, 0 included (an API caller's), within 1 and 64 × the width.
    #[test]
    fn a_camera_shapes_every_width() {
        let camera = GltfCamera {
            name: None,
            eye: Vec3::ZERO,
            look_at: Vec3::NEG_Z,
            up: Vec3::Y,
            node: 0,
            yfov_deg: 40.0,
            aspect_ratio: Some(2.0),
        };
        assert_eq!(camera.shaped(640), Some((640, 320)));
        assert_eq!(camera.shaped(1), Some((1, 1)));
        assert_eq!(camera.shaped(0), Some((0, 1)));
    }

    fn close(a: Option<[[f32; 3]; 2]>, b: [[f32; 3]; 2]) -> bool {
        a.is_some_and(|a| {
            (a.iter().flatten())
                .zip(b.iter().flatten())
                .all(|(x, y)| (x - y).abs() < 1e-6)
        })
    }

    /// A texture's transform relative to the interpolated set's, in lancer's coordinates
    /// (v up): an offset along glTF's v (down) moves lancer's v the other way; a quarter
    /// turn maps (u, v) to (1 − v, 1 + u); against a moved base, the base is undone first.
    #[test]
    fn relative_transforms_are_in_lancers_coordinates() {
        let id = UvTransform::IDENTITY;
        let shifted = UvTransform::from_parts([0.5, 0.25], [1.0, 1.0], 0.0);
        assert!(close(
            shifted.relative_to(&id),
            [[1.0, 0.0, 0.5], [0.0, 1.0, -0.25]]
        ));
        let turned = UvTransform::from_parts([0.0, 0.0], [1.0, 1.0], std::f32::consts::FRAC_PI_2);
        assert!(close(
            turned.relative_to(&id),
            [[0.0, -1.0, 1.0], [1.0, 0.0, 1.0]]
        ));
        assert!(close(
            id.relative_to(&shifted),
            [[1.0, 0.0, -0.5], [0.0, 1.0, 0.25]]
        ));
        assert_eq!(shifted.relative_to(&shifted), None);
        let collapsed = UvTransform::from_parts([0.0, 0.0], [0.0, 1.0], 0.0);
        assert_eq!(shifted.relative_to(&collapsed), None);
    }

    /// A normal or occlusion texture's transform is read from its JSON, defaults filling
    /// what is missing or malformed.
    #[test]
    fn json_transforms_take_the_extensions_defaults() {
        let ext = serde_json::json!({ "offset": [0.5, 0.25], "scale": "big", "texCoord": 1 });
        let (set, t) = json_coordinates(0, Some(&ext));
        assert_eq!(set, 1);
        assert_eq!(t, UvTransform::from_parts([0.5, 0.25], [1.0, 1.0], 0.0));
        assert_eq!(json_coordinates(2, None), (2, UvTransform::IDENTITY));
    }
}
