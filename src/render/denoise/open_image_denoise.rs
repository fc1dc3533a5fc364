//! Intel Open Image Denoise's `RT` filter (cargo feature `denoise`): the film, albedo and
//! normal guides handed to the library's CPU device. Non-finite film values (none are expected)
//! enter the filter as 0, since OIDN would spread one NaN over its whole receptive field; its
//! rare negative outputs are clamped to 0.

use super::{DenoiseError, Denoised, Denoiser, Guides};
use crate::render::Image;
use glam::Vec3;

/// OIDN's `RT` filter over `image` (its size checked against `guides` by the caller).
pub(super) fn filter(image: &mut Image, guides: &Guides) -> Result<Denoised, DenoiseError> {
    let start = std::time::Instant::now();
    let fail = |step: &'static str| {
        move |e: oidn::Error| DenoiseError::Library {
            step,
            message: e.to_string(),
        }
    };
    let flat = |v: &[Vec3]| -> Vec<f32> { v.iter().flat_map(|c| c.to_array()).collect() };
    let color: Vec<f32> = image
        .pixels
        .iter()
        .flat_map(|p| p.truncate().to_array())
        .map(|c| if c.is_finite() { c } else { 0.0 })
        .collect();
    let device = oidn::Device::cpu().map_err(fail("cannot create the CPU device"))?;
    let library_version = library_version(&device);
    let albedo = device
        .create_buffer(&flat(&guides.albedo))
        .map_err(fail("albedo buffer"))?;
    let normal = device
        .create_buffer(&flat(&guides.normal))
        .map_err(fail("normal buffer"))?;
    let mut filter = oidn::RayTracing::try_new(&device).map_err(fail("RT filter"))?;
    filter
        .image_dimensions(image.width as usize, image.height as usize)
        .hdr(true)
        .clean_aux(true)
        .albedo_normal_buffer(albedo, normal)
        .map_err(fail("guide images"))?;
    let mut output = vec![0.0f32; color.len()];
    filter
        .filter(&color, &mut output)
        .map_err(fail("filtering"))?;
    device.get_error().map_err(fail("filtering"))?;
    for (pixel, rgb) in image.pixels.iter_mut().zip(output.chunks_exact(3)) {
        if pixel.w > 0.0 {
            pixel.x = rgb[0].max(0.0);
            pixel.y = rgb[1].max(0.0);
            pixel.z = rgb[2].max(0.0);
        }
    }
    Ok(Denoised {
        denoiser: Denoiser::Oidn,
        version: library_version,
        time: start.elapsed(),
        visibility_guide: false,
        emission_apart: false,
    })
}

/// The library's `version` parameter (major·10000 + minor·100 + patch) as "major.minor.patch":
/// what actually ran, which the view file records.
fn library_version(device: &oidn::Device) -> String {
    // SAFETY: the device handle is valid and committed for as long as `device` lives, and
    // "version" is a NUL-terminated parameter name every OIDN 2.x device reads.
    let version = unsafe { oidn::sys::oidnGetDeviceInt(device.raw(), c"version".as_ptr()) };
    format!(
        "{}.{}.{}",
        version / 10000,
        version / 100 % 100,
        version % 100
    )
}
