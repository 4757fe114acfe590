//! `lancer adapters`: every GPU adapter wgpu finds, and what lancer can use of each.

use clap::Args;
use lancer::gpu::adapters;
use lancer::util::human_bytes;
use lancer::Result;

use super::out::{say, Say};

#[derive(Args)]
pub struct AdaptersCmd {}

impl AdaptersCmd {
    pub fn run(self) -> Result<()> {
        let say = Say::new(false);
        let all = adapters()?;
        if all.is_empty() {
            say!(
                say,
                "no adapter: install a Vulkan driver (Debian/Ubuntu: apt-get install \
                 mesa-vulkan-drivers libvulkan1, which includes lavapipe) or use --device cpu"
            );
            return Ok(());
        }
        for (i, a) in all.iter().enumerate() {
            let yes = |b: bool| if b { "yes" } else { "no" };
            say!(say, "{i}: {} ({}, {})", a.name, a.device_type, a.backend);
            say!(say, "   driver            {}", a.driver);
            say!(
                say,
                "   limits            storage binding {}, 2D texture {} texels, workgroup {} invocations",
                human_bytes(a.max_storage_buffer_binding),
                a.max_texture_dimension_2d,
                a.max_workgroup_invocations
            );
            let subgroups = match a.subgroups {
                Some((lo, hi)) if lo == hi => format!("yes (size {lo})"),
                Some((lo, hi)) => format!("yes (sizes {lo}–{hi})"),
                None => "no".into(),
            };
            say!(
                say,
                "   features          subgroups {subgroups}, timestamps {}, shader f64 {}, \
                 ray queries {}",
                yes(a.timestamps),
                yes(a.shader_f64),
                yes(a.ray_query)
            );
            let arithmetic = match a.exact_arithmetic {
                true => "as the CPU's (lancer's own SPIR-V: nothing fused, f64 division; `lancer check` tests it)",
                false => "may differ from the CPU's by an ulp (wgpu's translation)",
            };
            say!(say, "   arithmetic        {arithmetic}");
            if a.device_type == "Cpu" {
                say!(say, "   (a software driver: it runs on the CPU)");
            }
        }
        say!(
            say,
            "choose one with WGPU_ADAPTER_NAME=<part of its name> (WGPU_BACKEND and \
             WGPU_POWER_PREF=low|high also apply)"
        );
        Ok(())
    }
}
