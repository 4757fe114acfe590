use lancer::accel::bvh::layouts::{try_flatten, LayoutKind};
use lancer::accel::bvh::{build, BuildOptions};
use lancer::{Device, DeviceChoice, GpuForm, Tracer, TracerOptions};
use std::sync::Arc;
use std::time::Instant;
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let kind = match std::env::args().nth(2).as_deref() {
        Some("dfs-sign") => LayoutKind::DfsSign,
        _ => LayoutKind::Cwbvh,
    };
    let mesh = lancer::mesh::load_mesh(path.as_ref()).unwrap();
    let device = Device::open(DeviceChoice::Gpu).unwrap();
    let t = Instant::now();
    let bvh = build(&mesh, &BuildOptions::default());
    println!("build {:.0}", t.elapsed().as_secs_f64() * 1e3);
    let t = Instant::now();
    let layout: Arc<dyn GpuForm> = try_flatten(kind, &bvh, &mesh).unwrap().into();
    println!("flatten {:.0}", t.elapsed().as_secs_f64() * 1e3);
    drop(bvh);
    let a = layout.arrays();
    println!(
        "nodes {} MB tris {} MB",
        a.nodes.len() >> 20,
        a.tris.len() >> 20
    );
    for _ in 0..8 {
        let t = Instant::now();
        layout.validate().unwrap();
        println!("validate {:.0}", t.elapsed().as_secs_f64() * 1e3);
    }
    let t = Instant::now();
    let tr = Tracer::with_layout(&device, layout.clone(), &TracerOptions::default()).unwrap();
    println!(
        "with_layout (validate+upload+kernel) {:.0}",
        t.elapsed().as_secs_f64() * 1e3
    );
    drop(tr);
}
