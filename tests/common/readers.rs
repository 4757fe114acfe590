//! Every reader, by fuzz-target name, fed bytes: the entry points of the coverage-guided fuzz
//! targets (fuzz/, scripts/fuzz.sh) and of the regression cases they found
//! (tests/fuzz-regressions/, run by tests/fuzz_readers.rs). The readers take paths, so each
//! input is written to a file in a folder of this process's own (the name gives the reader
//! its format); a reader must return — `Ok` or an error — without a panic, an abort or a
//! hang.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// This process's folder for inputs.
fn dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("lancer-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("a scratch folder");
        d
    })
}

/// Writes `data` as `name` in this process's folder and returns the path.
pub fn file(name: &str, data: &[u8]) -> PathBuf {
    let p = dir().join(name);
    std::fs::write(&p, data).expect("a scratch file");
    p
}

/// The readers by target name, each fed `data` as its format; the result is dropped (an
/// error is a fine answer).
pub fn run(target: &str, data: &[u8]) {
    match target {
        "obj" => drop(lancer::mesh::load_obj(&file("case.obj", data))),
        // The MTL beside an OBJ that names it, read as `lancer render` reads it.
        "mtl" => {
            file("case.mtl", data);
            let obj = file(
                "mtl.obj",
                b"mtllib case.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            );
            drop(lancer::RenderScene::from_mesh(&obj, 4, 4));
        }
        "ply" => drop(lancer::mesh::load_mesh(&file("case.ply", data))),
        "gltf" => drop(lancer::RenderScene::from_mesh(
            &file("case.gltf", data),
            4,
            4,
        )),
        "glb" => drop(lancer::RenderScene::from_mesh(
            &file("case.glb", data),
            4,
            4,
        )),
        "scene" => drop(lancer::RenderScene::from_file(&file("case.toml", data))),
        "exr" => drop(lancer::render::ExrImage::read(&file("case.exr", data))),
        "bvh" => drop(lancer::accel::bvh::layouts::bvh_file::read(&file(
            "case.bvh", data,
        ))),
        "rays" => drop(lancer::trace::files::decode_rays(
            Path::new("case.rays"),
            data,
        )),
        "hits" => drop(lancer::trace::files::read_hits(&file("case.hits", data))),
        other => panic!("no fuzz target {other}"),
    }
}

/// Every target's name.
pub const TARGETS: [&str; 10] = [
    "obj", "mtl", "ply", "gltf", "glb", "scene", "exr", "bvh", "rays", "hits",
];
