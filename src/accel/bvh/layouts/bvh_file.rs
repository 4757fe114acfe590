//! BVH files: a flattened [`GpuForm`] saved with `lancer build --out` and traced with
//! `--bvh`, so a flattener of one's own can be traced without building a tree here, and
//! checked: `lancer check --bvh` compares its GPU kernel with its CPU twin and judges the
//! file's answers by the f64 oracle (`lancer::trace::check`).
//!
//! # Format (version 1)
//!
//! An 84-byte header, then the layout's node array and its [`LeafTri`] array, exactly the
//! bytes the GPU reads ([`GpuForm::arrays`]). Every number is little-endian.
//!
//! | offset | bytes | field |
//! |---|---|---|
//! | 0 | 8 | magic `LANCRBVH` |
//! | 8 | 4 | format version, u32 = 1 |
//! | 12 | 4 | bytes of one node record, u32 (the layout's: 32, 64, 80 or 128) |
//! | 16 | 16 | layout name ([`LayoutKind::name`]), ASCII, zero-padded |
//! | 32 | 8 | bytes of the node array, u64 (whole records) |
//! | 40 | 8 | leaf triangles, u64 (48 bytes each) |
//! | 48 | 8 | triangles of the mesh it was built from, u64 (every `prim` is below it) |
//! | 56 | 24 | root box: lo xyz, hi xyz, f32 ([`Accel::bounds`](crate::Accel::bounds) of the layout) |
//! | 80 | 4 | CRC-32 (IEEE, as zlib's) of bytes 0..80 and the whole payload |
//! | 84 | | node array, then triangle array |
//!
//! The arrays are all a layout holds: every layout is rebuilt from them
//! ([`layouts::from_arrays`](super::from_arrays)), and the root box is checked against the
//! rebuilt layout's. Reading refuses, naming the file and what to do: a file shorter or
//! longer than its header says (checked against the file's length before anything is
//! allocated, and against the memory available), a wrong magic, an unknown version or
//! layout, a record size that is not the layout's, a bad checksum, a triangle index not
//! below the mesh's count, and arrays that fail the layout's `validate` (indices out of
//! range, a tree deeper than the traversal stack, unreachable nodes; a box that does not
//! hold every triangle vertex below it, exactly in f32 (`cwbvh`: its dequantised boxes); a
//! triangle record in two leaves or in none), so a hostile file cannot make the CPU twin or
//! a GPU kernel read out of bounds or loop, and a checksum recomputed over moved boxes does
//! not make it trace wrong answers. [`BvhFile::check_mesh`] then refuses a mesh the file
//! was not built from (its triangles, each in one leaf or more, vertex for vertex).

use std::io::{Read, Write};
use std::path::Path;
use std::sync::Arc;

use crate::error::{Error, Result};
use crate::mesh::Mesh;

use super::{GpuArrays, GpuForm, LayoutKind, LeafTri};

/// The first 8 bytes of every BVH file.
pub const MAGIC: [u8; 8] = *b"LANCRBVH";

/// The format version this build writes and reads.
pub const VERSION: u32 = 1;

/// Bytes before the node array.
pub const HEADER_BYTES: usize = 84;

/// Where the checksum sits (it covers the bytes before it and the payload).
const CRC_AT: usize = 80;

/// Bytes of the zero-padded layout name.
const NAME_BYTES: usize = 16;

const TRI_BYTES: usize = std::mem::size_of::<LeafTri>();

/// A BVH file's contents: the layout, rebuilt and validated, and what it was built from.
pub struct BvhFile {
    /// Which layout.
    pub kind: LayoutKind,
    /// The layout, ready for [`Tracer::with_layout`](crate::Tracer::with_layout).
    pub layout: Arc<dyn GpuForm>,
    /// Triangles of the mesh it was built from (every leaf triangle's `prim` is below it).
    pub mesh_triangles: u64,
}

/// The header's fields.
struct Header {
    record_bytes: u32,
    name: [u8; NAME_BYTES],
    node_bytes: u64,
    tris: u64,
    mesh_triangles: u64,
    bounds: [f32; 6],
    crc: u32,
}

impl Header {
    /// The 84 header bytes, with the checksum `crc`.
    fn encode(&self) -> [u8; HEADER_BYTES] {
        let mut h = [0u8; HEADER_BYTES];
        h[0..8].copy_from_slice(&MAGIC);
        h[8..12].copy_from_slice(&VERSION.to_le_bytes());
        h[12..16].copy_from_slice(&self.record_bytes.to_le_bytes());
        h[16..32].copy_from_slice(&self.name);
        h[32..40].copy_from_slice(&self.node_bytes.to_le_bytes());
        h[40..48].copy_from_slice(&self.tris.to_le_bytes());
        h[48..56].copy_from_slice(&self.mesh_triangles.to_le_bytes());
        for (k, x) in self.bounds.iter().enumerate() {
            h[56 + 4 * k..60 + 4 * k].copy_from_slice(&x.to_le_bytes());
        }
        h[CRC_AT..].copy_from_slice(&self.crc.to_le_bytes());
        h
    }

    /// The fields of a header (magic and version checked first).
    fn decode(h: &[u8; HEADER_BYTES]) -> std::result::Result<Header, String> {
        if h[0..8] != MAGIC {
            return Err(format!(
                "not a lancer BVH file (it starts with {:?}, not {:?}): write one with \
                 `lancer build MESH --out FILE`",
                String::from_utf8_lossy(&h[0..8]),
                String::from_utf8_lossy(&MAGIC)
            ));
        }
        let u32_at = |i: usize| u32::from_le_bytes([h[i], h[i + 1], h[i + 2], h[i + 3]]);
        let u64_at = |i: usize| u32_at(i) as u64 | (u32_at(i + 4) as u64) << 32;
        let version = u32_at(8);
        if version != VERSION {
            return Err(format!(
                "BVH file format version {version}, but this lancer reads version {VERSION}: \
                 write it again with this lancer's `build --out`"
            ));
        }
        let mut name = [0u8; NAME_BYTES];
        name.copy_from_slice(&h[16..32]);
        let mut bounds = [0f32; 6];
        for (k, b) in bounds.iter_mut().enumerate() {
            *b = f32::from_bits(u32_at(56 + 4 * k));
        }
        Ok(Header {
            record_bytes: u32_at(12),
            name,
            node_bytes: u64_at(32),
            tris: u64_at(40),
            mesh_triangles: u64_at(48),
            bounds,
            crc: u32_at(CRC_AT),
        })
    }

    /// The layout its name names.
    fn kind(&self) -> std::result::Result<LayoutKind, String> {
        let end = self.name.iter().position(|&b| b == 0).unwrap_or(NAME_BYTES);
        let name = String::from_utf8_lossy(&self.name[..end]);
        LayoutKind::from_name(&name).ok_or_else(|| {
            let names: Vec<&str> = LayoutKind::ALL.iter().map(|k| k.name()).collect();
            format!(
                "unknown layout {name:?} (this lancer has {}): write the file in one of them",
                names.join(", ")
            )
        })
    }

    /// The whole file's length, from the counts; None when it overflows.
    fn file_bytes(&self) -> Option<u64> {
        let tris = self.tris.checked_mul(TRI_BYTES as u64)?;
        (HEADER_BYTES as u64)
            .checked_add(self.node_bytes)?
            .checked_add(tris)
    }
}

/// Refuses a layout that is not one of [`LayoutKind::ALL`] (a kd-tree's or BIH's GPU form).
fn kind_of(layout: &dyn GpuForm) -> Result<LayoutKind> {
    LayoutKind::from_name(layout.name()).ok_or_else(|| {
        Error::Usage(format!(
            "only a flattened BVH can be saved, not the {} structure's arrays",
            layout.name()
        ))
    })
}

/// The bytes of `layout`'s BVH file (built from a mesh of `mesh_triangles` triangles).
pub fn encode(layout: &dyn GpuForm, mesh_triangles: usize) -> Result<Vec<u8>> {
    let header = header_of(layout, mesh_triangles)?;
    let a = layout.arrays();
    Ok([&header.encode()[..], a.nodes, a.tris].concat())
}

/// Writes `layout` (built from a mesh of `mesh_triangles` triangles) to the BVH file
/// `path`, atomically ([`write_atomic`](crate::output::write_atomic)); check the path with
/// [`check_output`](crate::output::check_output) first.
pub fn write(path: &Path, layout: &dyn GpuForm, mesh_triangles: usize) -> Result<()> {
    let header = header_of(layout, mesh_triangles)?;
    let a = layout.arrays();
    crate::output::write_atomic(path, |w| {
        w.write_all(&header.encode())?;
        w.write_all(a.nodes)?;
        w.write_all(a.tris)
    })
}

/// The header of `layout`'s file, checksum included.
fn header_of(layout: &dyn GpuForm, mesh_triangles: usize) -> Result<Header> {
    refuse_big_endian()?;
    let kind = kind_of(layout)?;
    let a = layout.arrays();
    let mut name = [0u8; NAME_BYTES];
    // Every name fits (the round-trip test reads each back).
    for (d, c) in name.iter_mut().zip(kind.name().bytes()) {
        *d = c;
    }
    let b = layout.bounds();
    let mut header = Header {
        record_bytes: layout.node_bytes() as u32,
        name,
        node_bytes: a.nodes.len() as u64,
        tris: (a.tris.len() / TRI_BYTES) as u64,
        mesh_triangles: mesh_triangles as u64,
        bounds: [b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z],
        crc: 0,
    };
    header.crc = checksum(&header.encode(), a);
    Ok(header)
}

/// CRC-32 of the header before the checksum and the payload.
fn checksum(header: &[u8; HEADER_BYTES], a: GpuArrays<'_>) -> u32 {
    let mut h = crc32fast::Hasher::new();
    h.update(&header[..CRC_AT]);
    h.update(a.nodes);
    h.update(a.tris);
    h.finalize()
}

/// The arrays are the host's memory, which the file stores little-endian.
fn refuse_big_endian() -> Result<()> {
    if cfg!(target_endian = "big") {
        return Err(Error::Usage(
            "BVH files hold little-endian arrays and this host is big-endian".into(),
        ));
    }
    Ok(())
}

/// Reads the BVH file `path`: its length is checked against the header (and the memory
/// available) before the payload is read, then everything [`decode`] checks.
pub fn read(path: &Path) -> Result<BvhFile> {
    let bad = |msg: String| Error::input(path, None, msg);
    let (mut file, len) = crate::input::open(path)?;
    let mut head = [0u8; HEADER_BYTES];
    if len < HEADER_BYTES as u64 {
        return Err(bad(truncated(len, HEADER_BYTES as u64)));
    }
    file.read_exact(&mut head)
        .map_err(|e| Error::read(path, e))?;
    let header = Header::decode(&head).map_err(bad)?;
    check_length(&header, len).map_err(bad)?;
    // The bytes, then the records copied out of them.
    crate::limits::check_memory(
        &format!("reading {}", path.display()),
        2 * len as u128,
        "use a machine with more memory",
    )?;
    let mut bytes = Vec::with_capacity(len as usize);
    bytes.extend_from_slice(&head);
    (file.take(len - HEADER_BYTES as u64))
        .read_to_end(&mut bytes)
        .map_err(|e| Error::read(path, e))?;
    decode(path, &bytes)
}

/// "truncated" or "too long", by how the length differs from what the header says.
fn truncated(len: u64, want: u64) -> String {
    if len < want {
        format!(
            "truncated: {len} bytes, but its header says {want}: the file is incomplete; \
             write it again"
        )
    } else {
        format!(
            "{len} bytes, but its header says {want}: {} bytes follow the triangle array; \
             write it again",
            len - want
        )
    }
}

/// Refuses a length that is not the one the header's counts give.
fn check_length(h: &Header, len: u64) -> std::result::Result<(), String> {
    let Some(want) = h.file_bytes() else {
        return Err(format!(
            "its header counts ({} node bytes, {} triangles) overflow: the file is corrupt",
            h.node_bytes, h.tris
        ));
    };
    if len != want {
        return Err(truncated(len, want));
    }
    Ok(())
}

/// The BVH file in `bytes` (read from `name`, which errors name): header, length,
/// checksum, counts and the layout's own validation all checked.
pub fn decode(name: &Path, bytes: &[u8]) -> Result<BvhFile> {
    refuse_big_endian()?;
    let bad = |msg: String| Error::input(name, None, msg);
    let Some(head) = bytes.first_chunk::<HEADER_BYTES>() else {
        return Err(bad(truncated(bytes.len() as u64, HEADER_BYTES as u64)));
    };
    let h = Header::decode(head).map_err(bad)?;
    check_length(&h, bytes.len() as u64).map_err(bad)?;
    // The length matched counts that fit in the file, so these fit in usize.
    let (nodes, tris) = bytes[HEADER_BYTES..].split_at(h.node_bytes as usize);
    let arrays = GpuArrays::new(nodes, tris);
    let crc = checksum(head, arrays);
    if crc != h.crc {
        return Err(bad(format!(
            "checksum {crc:#010x} differs from the header's {:#010x}: the file is corrupt; \
             write it again",
            h.crc
        )));
    }
    let kind = h.kind().map_err(bad)?;
    if h.tris > u32::MAX as u64 || h.mesh_triangles > u32::MAX as u64 {
        return Err(bad(format!(
            "{} leaf triangles of a {}-triangle mesh: triangle indices are u32",
            h.tris, h.mesh_triangles
        )));
    }
    if let Some(t) = leaf_tris(tris).find(|t| t.prim as u64 >= h.mesh_triangles) {
        return Err(bad(format!(
            "a leaf triangle has index {}, but the mesh has {} triangles: the file is corrupt",
            t.prim, h.mesh_triangles
        )));
    }
    let layout =
        super::from_arrays(kind, arrays).map_err(|e| bad(format!("invalid {kind} arrays: {e}")))?;
    if layout.node_bytes() != h.record_bytes as usize {
        return Err(bad(format!(
            "{kind} nodes are {} bytes, but the header says {}: the file is corrupt",
            layout.node_bytes(),
            h.record_bytes
        )));
    }
    let b = layout.bounds();
    let root = [b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z];
    if root.map(f32::to_bits) != h.bounds.map(f32::to_bits) {
        return Err(bad(format!(
            "the header's root box {:?} is not the arrays' {:?}: the file is corrupt",
            h.bounds, root
        )));
    }
    Ok(BvhFile {
        kind,
        layout: layout.into(),
        mesh_triangles: h.mesh_triangles,
    })
}

/// The triangles of a triangle array's bytes (any alignment; a partial record is left out).
fn leaf_tris(bytes: &[u8]) -> impl Iterator<Item = LeafTri> + '_ {
    bytes
        .chunks_exact(TRI_BYTES)
        .map(bytemuck::pod_read_unaligned::<LeafTri>)
}

impl BvhFile {
    /// Refuses a mesh the file was not built from: another triangle count, a leaf triangle
    /// whose vertices are not those of the mesh's triangle of the same index, or a triangle
    /// the mesh's BVH would hold ([`Mesh::included`]) in no leaf (so answers judged against `mesh` are about the structure traced). `file` names
    /// the BVH file in the error.
    pub fn check_mesh(&self, file: &Path, mesh: &Mesh) -> Result<()> {
        let bad = |msg: String| {
            Error::input(
                file,
                None,
                format!("{msg}: build it again from this mesh with `lancer build MESH --out`"),
            )
        };
        if self.mesh_triangles != mesh.triangles.len() as u64 {
            return Err(bad(format!(
                "built from a mesh of {} triangles, but the mesh has {}",
                self.mesh_triangles,
                mesh.triangles.len()
            )));
        }
        let mut held = vec![false; mesh.triangles.len()];
        for t in leaf_tris(self.layout.arrays().tris) {
            let same = mesh.triangles.get(t.prim as usize).is_some_and(|m| {
                let v: [[f32; 3]; 3] = [t.v0, t.v1, t.v2];
                let w = m.v.map(|p| p.to_array());
                bytemuck::cast::<_, [u32; 9]>(v) == bytemuck::cast::<_, [u32; 9]>(w)
            });
            if !same {
                return Err(bad(format!(
                    "its triangle {} is not the mesh's triangle {}",
                    t.prim, t.prim
                )));
            }
            // Several leaves may hold one triangle (spatial splits: the layout's validation
            // checked that their boxes cover it).
            held[t.prim as usize] = true;
        }
        let left_out = (held.iter().zip(&mesh.status))
            .position(|(&h, &s)| !h && s == crate::mesh::TriStatus::Ok);
        if let Some(p) = left_out {
            return Err(bad(format!(
                "the mesh's triangle {p} is in none of its leaves"
            )));
        }
        Ok(())
    }
}
