#![no_main]
//! Fuzzes the panorama loader (`--env FILE`, `render(env=...)`): Radiance `.hdr` and OpenEXR
//! through `Environment::load`, which reads a file; each input is written to one and loaded as
//! `.exr` when it starts with OpenEXR's magic number, else as `.hdr`.

use libfuzzer_sys::fuzz_target;
use meshtracer::light::environment::Environment;
use std::io::Write;

fuzz_target!(|data: &[u8]| {
    let exr = data.starts_with(&[0x76, 0x2f, 0x31, 0x01]);
    let suffix = if exr { ".exr" } else { ".hdr" };
    let Ok(mut file) = tempfile::Builder::new().suffix(suffix).tempfile() else {
        return;
    };
    if file.write_all(data).is_err() {
        return;
    }
    // An error is the expected answer to most inputs; a panic or an abort is the finding.
    let _ = Environment::load(file.path());
});
