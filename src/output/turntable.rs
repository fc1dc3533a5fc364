//! Turntables (`render MODEL --turntable N --gif FILE`): N views on an orbit around the model,
//! streamed into an animated GIF that loops forever, one frame at a time as the views finish
//! (memory holds one frame, whatever N).
//!
//! GIF stores 256 colours a frame and 1-bit transparency. Colours are chosen per frame by the
//! `gif` crate's NeuQuant at [`gif_speed`]; a pixel is transparent when less than half covered
//! (alpha < 128) and otherwise opaque in its own colour. `--background` composites every frame
//! over a colour instead (no transparency at all). Frames are disposed to the background, so a
//! transparent pixel never shows the previous frame.

use crate::output::{PendingFile, SaveError};
use image::codecs::gif::{GifEncoder, Repeat};
use image::RgbaImage;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::sync::{Arc, Mutex};

/// Most frames `--turntable` accepts: a frame every tenth of a degree. Past that, neighbouring
/// frames differ by less than a pixel at 1024 px, and the GIF runs to gigabytes.
pub const MAX_TURNTABLE_FRAMES: u32 = 3600;

/// How long a full turn takes when `--fps` is not given, seconds.
pub const TURN_SECONDS: f32 = 4.0;

/// Highest `--fps`: GIF delays are whole hundredths of a second, and browsers show delays
/// under 0.02 s as 0.1 s.
pub const MAX_FPS: f32 = 50.0;

/// Shortest frame delay written, hundredths of a second (see [`MAX_FPS`]).
const MIN_DELAY_CENTISECONDS: u16 = 2;

/// NeuQuant's speed for large frames (1 = best and slowest, 30 = fastest; it learns from every
/// `speed`-th pixel), the `gif` crate's suggested balance. Measured on 36 frames of
/// DamagedHelmet at 512x512 (release build, one core): 1.19 s at 10 against 7.9 s at 1 and
/// 1.9 s at 5; the covered pixels differ from the PNG frames by 1.01 levels of 255 in the mean
/// at 10 (1.56 in the worst frame) against 0.69 at 1: not worth 7x the time.
pub const MAX_GIF_SPEED: i32 = 10;

/// Pixels NeuQuant should learn from at least: a small frame gets a slower, finer speed.
/// 4 frames of cornell-box at 64x48 (3072 pixels): worst frame 5.3 levels off at speed 10,
/// 2.1 at speed 1, in well under a millisecond a frame either way.
const MIN_NEUQUANT_SAMPLES: u64 = 25_000;

/// The NeuQuant speed for frames of `pixels` pixels: [`MAX_GIF_SPEED`] from 250,000 pixels
/// (e.g. 512x512) up, slower below so that it learns from at least `MIN_NEUQUANT_SAMPLES`.
pub fn gif_speed(pixels: u64) -> i32 {
    (pixels / MIN_NEUQUANT_SAMPLES).clamp(1, MAX_GIF_SPEED as u64) as i32
}

/// Alpha from which a pixel is drawn opaque in the GIF; below it, transparent.
const OPAQUE_FROM_ALPHA: u8 = 128;

/// Checks an `--fps` value: positive, finite, at most [`MAX_FPS`].
pub fn check_fps(fps: f32) -> Result<(), String> {
    // A GIF frame's delay is a 16-bit count of hundredths: 655.35 s at most.
    let min_fps = 100.0 / f32::from(u16::MAX);
    if fps >= min_fps && fps <= MAX_FPS {
        Ok(())
    } else {
        Err(format!(
            "--fps {fps}: must be between {min_fps:.4} and {MAX_FPS} (a GIF frame lasts a whole number of hundredths of a second, at most 655.35 s)"
        ))
    }
}

/// The delay between frames in hundredths of a second (GIF's unit): `1/fps`, or a full turn
/// of `frames` frames in [`TURN_SECONDS`], rounded, and at least 0.02 s.
pub fn frame_delay_centiseconds(frames: usize, fps: Option<f32>) -> u16 {
    let seconds = match fps {
        Some(fps) => 1.0 / f64::from(fps),
        None => f64::from(TURN_SECONDS) / frames.max(1) as f64,
    };
    (seconds * 100.0)
        .round()
        .clamp(f64::from(MIN_DELAY_CENTISECONDS), f64::from(u16::MAX)) as u16
}

/// Passes writes through to a file and keeps the first error, so that one raised where
/// nobody can return it (the buffer's flush and the trailer the encoder writes when dropped)
/// still fails the output.
struct Tracked {
    file: std::fs::File,
    error: Arc<Mutex<Option<std::io::Error>>>,
}

impl Tracked {
    fn keep<T>(&self, result: std::io::Result<T>) -> std::io::Result<T> {
        if let Err(e) = &result {
            if let Ok(mut slot) = self.error.lock() {
                slot.get_or_insert_with(|| std::io::Error::new(e.kind(), e.to_string()));
            }
        }
        result
    }
}

impl Write for Tracked {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let result = self.file.write(buf);
        self.keep(result)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        let result = self.file.flush();
        self.keep(result)
    }
}

/// An animated GIF being written: frames are encoded as they come into a temporary file beside
/// the destination, renamed into place by [`GifWriter::finish`].
pub struct GifWriter {
    pending: PendingFile,
    /// The file, until the first frame says the speed.
    writer: Option<BufWriter<Tracked>>,
    encoder: Option<GifEncoder<BufWriter<Tracked>>>,
    error: Arc<Mutex<Option<std::io::Error>>>,
    delay: image::Delay,
    size: Option<(u32, u32)>,
    frames: usize,
    encode_time: std::time::Duration,
}

impl GifWriter {
    /// Reserves `path` (failing now if it cannot be written) for a GIF whose frames last
    /// `delay_centiseconds` each and that loops forever.
    pub fn create(
        path: &Path,
        no_clobber: bool,
        delay_centiseconds: u16,
    ) -> Result<GifWriter, SaveError> {
        let pending = PendingFile::reserve(path, no_clobber)?;
        let error = Arc::new(Mutex::new(None));
        let file = pending
            .file()
            .try_clone()
            .map_err(|e| pending.unwritable(e))?;
        let tracked = Tracked {
            file,
            error: Arc::clone(&error),
        };
        Ok(GifWriter {
            pending,
            writer: Some(BufWriter::new(tracked)),
            encoder: None,
            error,
            delay: image::Delay::from_numer_denom_ms(u32::from(delay_centiseconds) * 10, 1),
            size: None,
            frames: 0,
            encode_time: std::time::Duration::ZERO,
        })
    }

    /// Appends a frame: 8-bit sRGB with straight alpha, as a PNG output holds it. Every frame
    /// must have the size of the first, at most 65535 pixels a side (GIF's limit).
    pub fn add(&mut self, mut frame: RgbaImage) -> Result<(), SaveError> {
        let start = std::time::Instant::now();
        let size = frame.dimensions();
        if size.0 > u32::from(u16::MAX) || size.1 > u32::from(u16::MAX) {
            return Err(self.encode_error(format!(
                "{}x{} frames: GIF allows at most 65535 pixels a side",
                size.0, size.1
            )));
        }
        let first = *self.size.get_or_insert(size);
        if first != size {
            return Err(self.encode_error(format!(
                "frame {} is {}x{}, the first was {}x{}",
                self.frames, size.0, size.1, first.0, first.1
            )));
        }
        one_bit_alpha(&mut frame);
        if let Some(writer) = self.writer.take() {
            let speed = gif_speed(u64::from(size.0) * u64::from(size.1));
            let mut encoder = GifEncoder::new_with_speed(writer, speed);
            if let Err(source) = encoder.set_repeat(Repeat::Infinite) {
                return Err(self.failure(source));
            }
            self.encoder = Some(encoder);
        }
        let Some(encoder) = self.encoder.as_mut() else {
            return Err(self.encode_error("frame added after the end".into()));
        };
        let result = encoder.encode_frame(image::Frame::from_parts(frame, 0, 0, self.delay));
        if let Err(source) = result {
            return Err(self.failure(source));
        }
        self.frames += 1;
        self.encode_time += start.elapsed();
        Ok(())
    }

    /// The destination.
    pub fn path(&self) -> &Path {
        self.pending.path()
    }

    /// Frames added so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Time spent quantising and encoding frames so far.
    pub fn encode_time(&self) -> std::time::Duration {
        self.encode_time
    }

    /// Ends the GIF (its trailer), flushes it to disk and renames it into place.
    pub fn finish(mut self) -> Result<(), SaveError> {
        if self.frames == 0 {
            return Err(self.encode_error("no frames".into()));
        }
        // Dropping the encoder writes the trailer and flushes the buffer; any error on the way
        // lands in `error`.
        drop(self.encoder.take());
        let failed = self.error.lock().ok().and_then(|mut slot| slot.take());
        if let Some(e) = failed {
            return Err(self.pending.unwritable(e));
        }
        self.pending.commit()
    }

    fn encode_error(&self, problem: String) -> SaveError {
        SaveError::Encode {
            path: self.pending.path().to_path_buf(),
            error: image::ImageError::Parameter(image::error::ParameterError::from_kind(
                image::error::ParameterErrorKind::Generic(problem),
            )),
        }
    }

    /// An encoder error, or the write error under it when the file refused the bytes.
    fn failure(&self, source: image::ImageError) -> SaveError {
        match self.error.lock().ok().and_then(|mut slot| slot.take()) {
            Some(e) => self.pending.unwritable(e),
            None => SaveError::Encode {
                path: self.pending.path().to_path_buf(),
                error: source,
            },
        }
    }
}

/// GIF transparency is on or off: a pixel less than half covered becomes transparent, any
/// other opaque in its own (straight) colour.
fn one_bit_alpha(frame: &mut RgbaImage) {
    for p in frame.pixels_mut() {
        p.0 = if p.0[3] < OPAQUE_FROM_ALPHA {
            [0, 0, 0, 0]
        } else {
            [p.0[0], p.0[1], p.0[2], 255]
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::AnimationDecoder;

    #[test]
    fn small_frames_quantise_finer() {
        assert_eq!(gif_speed(512 * 512), 10);
        assert_eq!(gif_speed(4096 * 4096), 10);
        assert_eq!(gif_speed(256 * 256), 2);
        assert_eq!(gif_speed(64 * 48), 1);
        assert_eq!(gif_speed(0), 1);
    }

    #[test]
    fn delays_follow_fps_or_a_four_second_turn() {
        assert_eq!(frame_delay_centiseconds(36, None), 11, "4 s / 36 = 0.111 s");
        assert_eq!(frame_delay_centiseconds(100, None), 4);
        assert_eq!(
            frame_delay_centiseconds(1000, None),
            2,
            "never under 0.02 s"
        );
        assert_eq!(frame_delay_centiseconds(1, None), 400);
        assert_eq!(frame_delay_centiseconds(36, Some(25.0)), 4);
        assert_eq!(
            frame_delay_centiseconds(36, Some(24.0)),
            4,
            "0.0417 s rounds"
        );
        assert_eq!(frame_delay_centiseconds(36, Some(50.0)), 2);
        assert_eq!(frame_delay_centiseconds(36, Some(0.001)), u16::MAX);
        assert!(check_fps(24.0).is_ok() && check_fps(50.0).is_ok());
        assert!(check_fps(0.0016).is_ok());
        for bad in [0.0, 0.001, -1.0, 51.0, f32::NAN, f32::INFINITY] {
            assert!(check_fps(bad).unwrap_err().contains("--fps"), "{bad}");
        }
    }

    /// Frames go in, the decoder gives them back: count, size, delay, looping, colours within
    /// quantisation, transparency where coverage was under half.
    #[test]
    fn frames_round_trip_through_the_gif_decoder() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("spin.gif");
        let mut gif = GifWriter::create(&path, false, 7).unwrap();
        for k in 0..3u8 {
            let frame = RgbaImage::from_fn(20, 10, |x, _| {
                let alpha = if x < 5 {
                    0
                } else if x < 8 {
                    100
                } else {
                    255
                };
                image::Rgba([60 * k + 10, 200 - 3 * x as u8, 128, alpha])
            });
            gif.add(frame).unwrap();
        }
        assert!(
            gif.add(RgbaImage::new(4, 4)).is_err(),
            "a frame of another size"
        );
        assert_eq!(gif.frames(), 3);
        gif.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let decoder = image::codecs::gif::GifDecoder::new(std::io::Cursor::new(&bytes)).unwrap();
        let frames = decoder.into_frames().collect_frames().unwrap();
        assert_eq!(frames.len(), 3);
        for (k, f) in frames.iter().enumerate() {
            assert_eq!(f.delay().numer_denom_ms(), (70, 1));
            let buffer = f.buffer();
            assert_eq!(buffer.dimensions(), (20, 10));
            assert_eq!(buffer.get_pixel(2, 3).0[3], 0, "uncovered: transparent");
            assert_eq!(
                buffer.get_pixel(6, 3).0[3],
                0,
                "under half covered: transparent"
            );
            let p = buffer.get_pixel(12, 3).0;
            assert_eq!(p[3], 255);
            let expected = [60 * k as u8 + 10, 200 - 36, 128];
            for c in 0..3 {
                assert!(p[c].abs_diff(expected[c]) <= 2, "frame {k}: {p:?}");
            }
        }
        // NETSCAPE2.0 application extension with loop count 0 = forever.
        let netscape = bytes
            .windows(11)
            .position(|w| w == b"NETSCAPE2.0")
            .expect("a looping extension");
        assert_eq!(&bytes[netscape + 11..netscape + 15], &[3, 1, 0, 0]);
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "no leftovers"
        );
    }

    #[test]
    fn unwritable_destinations_fail_before_any_frame() {
        let dir = tempfile::tempdir().unwrap();
        assert!(GifWriter::create(&dir.path().join("missing/spin.gif"), false, 4).is_err());
        assert!(GifWriter::create(dir.path(), false, 4).is_err(), "a folder");
        // Dropped without finishing: nothing is left.
        let gif = GifWriter::create(&dir.path().join("spin.gif"), false, 4).unwrap();
        drop(gif);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
