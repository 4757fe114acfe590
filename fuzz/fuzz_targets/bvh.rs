#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lancer_fuzz::run("bvh", data));
