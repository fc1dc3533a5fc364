//! `render MODEL --frames N -o DIR`: a glTF animation as N frames, DIR/000.png, 001.png, ...
//! and, with `--gif`, an animated GIF that plays them at the animation's speed.
//!
//! The importer poses a model while it flattens it (node channels, skins, morph targets,
//! `KHR_animation_pointer`), so each frame loads the model in its own pose and renders it as a
//! plain `render --animation A --time T` would: frame k of N is that render at
//! T = k·duration/N, byte for byte. The last frame stops one step short of the end, so a
//! looping GIF does not show the first pose twice.
//!
//! The camera is chosen for each frame as for one image (the file's camera follows its own
//! animation; `--camera` and `--look-from` stand where asked), except the automatic camera:
//! fitted to each pose it would shake, and fitted to the first it cuts off a tail or a leg
//! that swings out later. So the frames share one automatic camera that frames every pose
//! (as the plain render's frames its one pose's vertices), found by loading each pose once
//! before the first frame renders (a load is parse and flatten, a few milliseconds for a
//! character; textures are decoded when the first frame is prepared, and kept for the others
//! while they are the same ([`super::prepare_scene`]).
//! With it, frame k is the plain render of its pose only where that pose is the one that
//! decides the framing.

use super::render::{bar_with_template, render_one, stop_if_cancelled};
use super::views::has_extension;
use super::{image_size, interrupt_flag, load, render_load_options, RenderReport};
use crate::cli::RenderArgs;
use anyhow::{bail, Context, Result};
use meshtracer::camera::{auto_camera, auto_camera_extremes};
use meshtracer::light::environment::Environment;
use meshtracer::output::turntable::{check_fps, frame_delay_centiseconds, GifWriter};
use meshtracer::output::OutputFormat;
use meshtracer::scene::pose::choose_animation;
use meshtracer::scene::{Camera, Projection, Scene};
use std::path::Path;
use std::time::Instant;

/// The animation the frames play, as the first pose's load names it.
struct Clip {
    /// `1 'Walk'`.
    label: String,
    /// Seconds: its last keyframe.
    duration: f32,
}

impl Clip {
    /// Seconds into the animation of frame `k` of `frames`.
    fn time_of(&self, k: u32, frames: u32) -> f32 {
        self.duration * k as f32 / frames as f32
    }
}

/// Renders `frames` frames of the chosen animation into the `-o` folder (and `--gif`),
/// calling `on_view(done, frames)` as each is written.
pub(super) fn render_frames(
    args: &RenderArgs,
    frames: u32,
    env_file: Option<Environment>,
    on_view: &(dyn Fn(usize, usize) + Sync),
) -> Result<RenderReport> {
    let run_start = Instant::now();
    let dir = args.output.as_path();
    check_frames_folder(dir)?;
    if let Some(fps) = args.fps {
        check_fps(fps).map_err(anyhow::Error::msg)?;
    }
    if let Some(path) = args.gif.as_ref().filter(|p| !has_extension(p, "gif")) {
        bail!("--gif {}: the file name must end in .gif", path.display());
    }
    let first = load_pose(args, 0.0).with_context(|| format!("--frames {frames}"))?;
    let clip = chosen_clip(args, &first)?;
    let camera = match uses_automatic_camera(args, &first) {
        true => Some(camera_for_every_pose(args, frames, &clip, &first)?),
        false => None,
    };
    drop(first);
    let mut gif = match &args.gif {
        Some(path) => {
            // Real time: the animation's duration over the frames, unless --fps.
            let fps = args.fps.unwrap_or(frames as f32 / clip.duration);
            let delay = frame_delay_centiseconds(frames as usize, Some(fps));
            Some(GifWriter::create(path, args.no_clobber, delay)?)
        }
        None => None,
    };
    std::fs::create_dir_all(dir)
        .with_context(|| format!("-o {}: cannot create the folder", dir.display()))?;
    let digits = frames.saturating_sub(1).to_string().len().max(3);
    let mut total = RenderReport::default();
    for k in 0..frames {
        let time = clip.time_of(k, frames);
        let mut frame = frame_args(args, time, k > 0);
        frame.output = dir.join(format!("{k:0digits$}.png"));
        // The poses share their images: decoded for the first frame, kept for the others
        // (`prepare_scene`).
        let report = render_one(&frame, None, env_file.clone(), run_start, camera.as_ref())
            .with_context(|| format!("--frames {frames}: frame {k} (at {time} s)"))?;
        if let Some(gif) = &mut gif {
            // The frame as its PNG holds it (8-bit sRGB, straight alpha).
            let rgba = image::open(&frame.output)
                .with_context(|| format!("{}: reading the frame back", frame.output.display()))?
                .to_rgba8();
            gif.add(rgba)?;
        }
        add_frame(&mut total, report, k == 0);
        on_view(k as usize + 1, frames as usize);
    }
    if let Some(gif) = gif {
        total.outputs.push(gif.path().to_path_buf());
        gif.finish()?;
    }
    if !args.quiet {
        note!(
            "{}: {frames} frames of animation {}, {} s, one every {:.4} s{}",
            dir.display(),
            clip.label,
            clip.duration,
            clip.duration / frames as f32,
            match &args.gif {
                Some(path) => format!(", played by {}", path.display()),
                None => String::new(),
            }
        );
    }
    Ok(total)
}

/// The model posed at `time`, loaded as a frame's render loads it (silently: the frame's own
/// load reports its warnings).
fn load_pose(args: &RenderArgs, time: f32) -> Result<Scene> {
    load(
        &args.model,
        &render_load_options(&frame_args(args, time, true)),
    )
}

/// The automatic camera for every frame's pose: fitted to the bounds of them all, `first`'s
/// grown by each later pose's, and to the points of each pose that decide the fit
/// ([`auto_camera_extremes`]), which frames them as all their vertices would; `--yfov` as a
/// plain render applies it.
fn camera_for_every_pose(
    args: &RenderArgs,
    frames: u32,
    clip: &Clip,
    first: &Scene,
) -> Result<Camera> {
    let (width, height) = image_size(args, None);
    let aspect = width as f32 / height as f32;
    let mut bounds = first.bounds;
    let mut extremes = auto_camera_extremes(&first.soup.positions, aspect);
    let cancel = interrupt_flag();
    // A big model's poses take a while before the first frame renders.
    let bar = bar_with_template(
        args.quiet,
        "{spinner} framing every pose [{bar:40}] {pos}/{len} eta {eta}",
    );
    bar.set_length(u64::from(frames.saturating_sub(1)));
    for k in 1..frames {
        stop_if_cancelled(&cancel)?;
        bar.inc(1);
        let time = clip.time_of(k, frames);
        let pose = load_pose(args, time)
            .with_context(|| format!("--frames {frames}: frame {k} (at {time} s)"))?;
        if !pose.bounds.is_empty() {
            bounds.grow(pose.bounds.min);
            bounds.grow(pose.bounds.max);
        }
        extremes.extend(auto_camera_extremes(&pose.soup.positions, aspect));
    }
    bar.finish_and_clear();
    let mut camera = auto_camera(&bounds, &extremes, aspect);
    if let (Some(deg), Projection::Perspective { yfov, .. }) = (args.yfov, &mut camera.projection) {
        *yfov = deg.to_radians();
    }
    Ok(camera)
}

/// Refuses an `-o` that names a file or (not existing yet) an image or a GIF: with `--frames`,
/// `-o` is the folder the frames are written to.
fn check_frames_folder(dir: &Path) -> Result<()> {
    let looks_like_a_file =
        !dir.exists() && (has_extension(dir, "gif") || OutputFormat::from_path(dir).is_ok());
    if dir.is_file() || looks_like_a_file {
        bail!(
            "-o {}: with --frames, -o names the folder the frames are written to (000.png, 001.png, ...), not an image; write a GIF with --gif FILE.gif",
            dir.display()
        );
    }
    Ok(())
}

/// One frame's options: the plain render of the pose at `time` (its `output` is set by the
/// caller). Later frames do not print the model's warnings again (the first did).
fn frame_args(args: &RenderArgs, time: f32, later: bool) -> RenderArgs {
    let mut frame = args.clone();
    frame.load.time = Some(time);
    frame.frames = None;
    frame.gif = None;
    frame.fps = None;
    frame.no_warnings |= later;
    frame
}

/// The animation `--animation` names (default animation 0) in the loaded `scene`, refused when
/// it does not last: its frames would all be one pose.
fn chosen_clip(args: &RenderArgs, scene: &Scene) -> Result<Clip> {
    let model = args.model.display();
    let index = choose_animation(&scene.animations, args.load.animation.as_deref())
        .map_err(|e| anyhow::anyhow!("{model}: {e}"))?;
    let Some(animation) = scene.animations.get(index) else {
        bail!("{model}: no animation {index}");
    };
    let duration = animation.duration;
    if !(duration > 0.0 && duration.is_finite()) {
        bail!(
            "{model}: animation {} lasts {duration} s: every frame would be the same pose (render one image with --animation and --time)",
            animation.label()
        );
    }
    Ok(Clip {
        label: animation.label(),
        duration,
    })
}

/// Whether the frame's camera is the automatic one (no `--camera`, `--look-from` or file
/// camera), which the frames keep from the first.
fn uses_automatic_camera(args: &RenderArgs, scene: &Scene) -> bool {
    args.camera.is_none() && args.look_from.is_none() && scene.cameras.is_empty()
}

/// Adds one frame's report to the run's: the times add up and the outputs follow each other;
/// the first frame's warnings and inputs stand for the run.
fn add_frame(total: &mut RenderReport, frame: RenderReport, first: bool) {
    total.triangles = total.triangles.max(frame.triangles);
    total.load += frame.load;
    total.bvh += frame.bvh;
    total.render += frame.render;
    total.outputs.extend(frame.outputs);
    if first {
        total.warnings = frame.warnings;
        total.inputs = frame.inputs;
    }
}
