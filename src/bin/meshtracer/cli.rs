//! Command-line definitions (clap). Parsing only: the commands run in [`crate::commands`].

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Args, Parser, Subcommand};
use glam::Vec3;
use meshtracer::accel::{AccelKind, BvhPreset};
use meshtracer::color::ViewTransform;
use meshtracer::integrator::IntegratorKind;
pub use meshtracer::output::preview::PreviewMode;
use meshtracer::shading::ShadingModel;
use meshtracer::tools::bench::RayKind;
use std::path::PathBuf;

/// A library enum as a command-line choice: each variant with its name on the command line and
/// its help line. The library's types know nothing of clap (and a foreign type cannot get clap's
/// `ValueEnum` here), so their fields take [`choice`] as their value parser.
trait Choice: Copy + Send + Sync + 'static {
    /// Every variant, its name and its help line, in the order `--help` lists them.
    const CHOICES: &'static [(Self, &'static str, &'static str)];
}

macro_rules! value_enum {
    ($type:ty { $($variant:ident => $name:literal: $help:literal,)* }) => {
        impl Choice for $type {
            const CHOICES: &'static [(Self, &'static str, &'static str)] =
                &[$((<$type>::$variant, $name, $help)),*];
        }
    };
}

/// The value parser of a [`Choice`]: one of its names, listed with their help in `--help`.
fn choice<T: Choice>() -> impl TypedValueParser<Value = T> {
    let names = T::CHOICES
        .iter()
        .map(|&(_, name, help)| PossibleValue::new(name).help(help));
    PossibleValuesParser::new(names).try_map(|name: String| {
        T::CHOICES
            .iter()
            .find(|&&(_, n, _)| n == name)
            .map(|&(value, _, _)| value)
            .ok_or_else(|| format!("'{name}' is not one of the choices"))
    })
}

value_enum!(AccelKind {
    Bvh => "bvh": "obvhs compressed wide BVH (CWBVH, eight-way)",
    Linear => "linear": "Test every triangle (the reference and benchmark baseline)",
});
value_enum!(PreviewMode {
    Auto => "auto": "Only when standard output is a terminal, in the best protocol it answers for",
    Blocks => "blocks": "Always, as half blocks, with no terminal queries",
});
value_enum!(BvhPreset {
    Auto => "auto": "Chosen by the work at hand: `very-fast` for few rays per triangle, `medium` otherwise",
    // obvhs's `BvhBuildParams::{fastest,very_fast,fast,medium,slow,very_slow}_build`.
    Fastest => "fastest": "Quickest build, one triangle a leaf and no refinement; the slowest to trace",
    VeryFast => "very-fast": "Quick build with a little refinement",
    Fast => "fast": "A wider search for neighbours to pair and more refinement",
    Medium => "medium": "About Embree's build time, with faster tracing",
    Slow => "slow": "Large triangles split spatially and a thorough search: a slower build, faster tracing",
    VerySlow => "very-slow": "Spatial splits and every node refined: the slowest build",
});
value_enum!(ShadingModel {
    Pbr => "pbr": "The glTF 2.0 metallic-roughness BRDF (Appendix B)",
    Phong => "phong": "Blinn-Phong, the classic reference",
});
value_enum!(IntegratorKind {
    Direct => "direct": "Punctual lights through shadow rays, constant ambient, emission as seen; no bounces",
    Path => "path": "Path tracing: area lights, the environment, interreflection, MIS",
});
value_enum!(ViewTransform {
    Standard => "standard": "Clip at 1 (radiance above it burns out)",
    KhronosPbrNeutral => "khronos-pbr-neutral": "Khronos PBR Neutral: base colours kept, highlights rolled off",
    Agx => "agx": "AgX as Blender's default view transform",
    Aces => "aces": "ACES filmic (Hill's fit of the RRT and sRGB ODT)",
});
value_enum!(RayKind {
    Primary => "primary": "Camera rays in scanline order; closest hit",
    Shadow => "shadow": "From primary hits toward a light; any hit",
    Diffuse => "diffuse": "From primary hits in random cosine-weighted directions; closest hit",
});

/// A CPU ray tracer for glTF 2.0 and Wavefront OBJ assets.
#[derive(Debug, Parser)]
#[command(name = "meshtracer", version, about, propagate_version = true)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a model to an image (.png 8-bit sRGB, .exr/.hdr linear float).
    Render(Box<RenderArgs>),
    /// Render every job of a manifest (a folder of models, or a JSONL file of jobs) into
    /// DIR/JOB_ID/, recording each job in DIR/results.jsonl; --resume, --shard I/N.
    Batch(Box<BatchArgs>),
    /// Join the results.I-of-N.jsonl of every shard of a batch into DIR/results.jsonl.
    BatchMerge(BatchMergeArgs),
    /// Show what the importer read from a model: triangles, materials, cameras, lights, bounds.
    Info(InfoArgs),
    /// Measure BVH build time and BVH vs. linear-scan throughput on generated meshes of growing
    /// size and on models; print a table, optionally write a Markdown report and a log-log plot.
    Bench(BenchArgs),
    /// Compare two images (A is the reference): PSNR, SSIM, mean FLIP, RMSE, max error and
    /// coverage IoU; optionally a FLIP heatmap and an A | B | heatmap strip.
    Compare(CompareArgs),
    /// Join tiles rendered with `render --tile I/N` or `--crop` (and, the same way, their
    /// AOVs) into the whole image, identical to a single render's (denoised, from the tiles'
    /// OUT.denoise.exr, when the render is); refuses tiles that are missing, overlap or come
    /// from different renders.
    #[command(visible_alias = "merge-tiles")]
    Merge(MergeArgs),
}

/// Options shared by every command that loads a model.
#[derive(Debug, Args, Clone)]
pub struct LoadArgs {
    /// Allow URIs that are absolute or point outside the model's folder (off by default: a
    /// downloaded model must not read your files).
    #[arg(long)]
    pub allow_external_files: bool,
    /// Refuse scenes with more triangles than this, after instancing.
    #[arg(long, default_value_t = meshtracer::defaults::MAX_TRIANGLES, value_name = "N", allow_negative_numbers = true)]
    pub max_triangles: u64,
    /// Pose the model by this glTF animation, by name or index (`info` lists them) [default
    /// with --time: animation 0]: its node channels, and its KHR_animation_pointer channels
    /// (material, texture-transform, light, camera and visibility properties). Without
    /// --animation and --time the file's static pose is drawn: the nodes' own transforms,
    /// default morph weights, skins through their joints.
    #[arg(long, value_name = "NAME|INDEX")]
    pub animation: Option<String>,
    /// Seconds into the animation [default with --animation: 0]; past the animation's end the
    /// last keyframes hold, before a channel's first keyframe its first.
    #[arg(long, value_name = "SECONDS", value_parser = parse_time, allow_hyphen_values = true)]
    pub time: Option<f32>,
}

/// The most worker threads `--threads` takes: more than the largest machines' cores. Past a
/// few thousand, starting the threads exhausts memory (each has its own stack) and the
/// process fails inside the thread library instead of with a message.
pub const MAX_THREADS: usize = 1024;

/// A `--threads`: 0 (one per core) to [`MAX_THREADS`].
fn parse_threads(text: &str) -> Result<usize, String> {
    let threads: usize = text
        .trim()
        .parse()
        .map_err(|_| format!("'{text}' is not a whole number of threads"))?;
    if threads > MAX_THREADS {
        return Err(format!(
            "{threads} threads: at most {MAX_THREADS} (0 = one per core)"
        ));
    }
    Ok(threads)
}

/// A `--time`: a finite number of seconds, 0 or more.
fn parse_time(text: &str) -> Result<f32, String> {
    let time: f32 = text
        .trim()
        .parse()
        .map_err(|_| format!("'{text}' is not a number of seconds"))?;
    meshtracer::scene::PoseOptions {
        animation: None,
        time: Some(time),
    }
    .check()?;
    Ok(time)
}

/// `meshtracer info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The model: .gltf, .glb or .obj, or a .zip download (or the folder it unzips to) holding
    /// one with its files.
    pub model: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Loading options.
    #[command(flatten)]
    pub load: LoadArgs,
}

/// `meshtracer render`.
#[derive(Debug, Args, Clone)]
#[command(group(clap::ArgGroup::new("many_views").args(["views", "turntable"])))]
#[command(group(clap::ArgGroup::new("animated").args(["views", "turntable", "frames"])))]
pub struct RenderArgs {
    /// The model: .gltf, .glb or .obj, or a .zip download (or the folder it unzips to) holding
    /// one with its files.
    pub model: PathBuf,
    /// Output image: .png (8-bit sRGB with alpha), .jpg (8-bit sRGB over --background or
    /// black), .exr or .hdr (linear float); with --views or --turntable, the folder the views
    /// are written to.
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Image width in pixels [default: 1024].
    #[arg(long, allow_negative_numbers = true)]
    pub width: Option<u32>,
    /// Image height in pixels [default: from the camera's aspectRatio, else 768].
    #[arg(long, allow_negative_numbers = true)]
    pub height: Option<u32>,
    /// Samples per pixel, exactly: 1 shoots through pixel centres; N > 1 takes
    /// Owen-scrambled Sobol samples (powers of two stratify best) [default: the path tracer samples each
    /// pixel adaptively, up to 32, until its noise is under --noise (1.0 when denoised, as the
    /// default render is, else 0.1); the direct integrator takes 4].
    // Read it through `RenderArgs::spp`, which applies the default.
    #[arg(long = "spp", value_name = "N", allow_negative_numbers = true)]
    pub spp_given: Option<u32>,
    /// Adaptive sampling: each pixel stops once the standard error of its luminance is at most
    /// this fraction of it (of 0.05 in dark pixels), checked every 4 samples (every 2 when
    /// the image is denoised, as the default render is); --spp is then
    /// the cap (e.g. --noise 0.02 --spp 1024).
    // Read it through `RenderArgs::noise`, which applies the default.
    #[arg(long = "noise", value_name = "FRACTION", value_parser = parse_noise)]
    pub noise_given: Option<f32>,
    /// Render for about this many seconds instead of a fixed --spp: one sample per pixel is
    /// timed, then the image is rendered at the largest spp that fits the rest of the budget
    /// (at most --max-spp); the summary says which. The result is exactly the --spp render of
    /// that count, so the same spp reached gives the same image.
    #[arg(long, value_name = "SECS")]
    pub time_limit: Option<f64>,
    /// Denoise the linear HDR image, guided by the albedo, normals and depth of the first
    /// surfaces (and, in the path tracer, by where its punctual lights' hard shadows fall),
    /// with either integrator: the built-in edge-avoiding à-trous filter, or Intel
    /// Open Image Denoise's RT filter in builds made with `--features denoise`
    /// (docs/denoising.md); the view file, --stats and the summary say which. With --views
    /// or --turntable each view is denoised as a single image; a --tile or --crop keeps the
    /// film and guides beside its image (OUT.denoise.exr) and `merge` denoises the whole.
    /// [default: on for the default render (the path tracer without --spp, --noise or
    /// --time-limit, one image or its tiles), whose noise target is then 1.0; off otherwise].
    // Read it through `RenderArgs::denoises`, which applies the default.
    #[arg(long, conflicts_with = "no_denoise")]
    pub denoise: bool,
    /// Do not denoise the default render: it then samples to --noise 0.1 instead of 1.0.
    #[arg(long)]
    pub no_denoise: bool,
    /// Seed of the sample pattern (the output is identical for the same seed).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub seed: u64,
    /// Use the file's camera with this index (in node order) instead of the first.
    #[arg(long, value_name = "INDEX", allow_negative_numbers = true)]
    pub camera: Option<usize>,
    /// Place the camera here instead (X,Y,Z); with --look-at, --up and --yfov.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub look_from: Option<Vec3>,
    /// Point the camera (with --views: every generated view) at this point (X,Y,Z)
    /// [default: the scene's centre].
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub look_at: Option<Vec3>,
    /// Camera up vector (X,Y,Z) [default: 0,1,0].
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub up: Option<Vec3>,
    /// Vertical field of view in degrees [default: 45, or the file camera's].
    // A negative value is taken as the value, so that its range check names it.
    #[arg(long, value_name = "DEG", allow_hyphen_values = true)]
    pub yfov: Option<f32>,
    /// Depth of field: the radius of a thin lens's aperture, in scene units (metres for glTF);
    /// the plane at --focus-distance stays sharp and the rest blurs. Lens points are sampled
    /// with the pixel's samples (one sample a pixel goes through the lens centre). With
    /// --views each view file and transforms.json frame records the lens [default: 0, a
    /// pinhole, as glTF cameras are].
    #[arg(long, value_name = "R", allow_hyphen_values = true)]
    pub aperture_radius: Option<f32>,
    /// With --aperture-radius: the distance of the plane in focus in front of the camera,
    /// along its view axis [default: that of --look-at, else of the scene's centre; for
    /// --views, each view's distance to the point it looks at].
    #[arg(
        long,
        value_name = "D",
        allow_hyphen_values = true,
        requires = "aperture_radius"
    )]
    pub focus_distance: Option<f32>,
    /// Render many views after one load and one BVH build, into the folder -o names:
    /// orbit:N (a circle around the model), sphere:N (spread evenly over a sphere), random:N
    /// (random directions from --seed), cameras (every camera of the file), or a JSON file of
    /// views (format in docs/views-and-datasets.md). Each view writes its image, the AOVs asked for and its
    /// view file; the folder gets a transforms.json (nerfstudio, instant-ngp).
    #[arg(
        long,
        value_name = "SPEC",
        conflicts_with_all = ["view", "camera", "look_from", "up", "time_limit", "stats"]
    )]
    pub views: Option<String>,
    /// Render N views on a circle around the model for --gif: `--views orbit:N` starting where
    /// the plain render's camera stands (its azimuth and elevation; frame 0 is `render MODEL`
    /// when the automatic camera frames it). The frames go into the -o folder as with --views.
    #[arg(
        long,
        value_name = "N",
        value_parser = clap::value_parser!(u32).range(1..=i64::from(meshtracer::output::turntable::MAX_TURNTABLE_FRAMES)),
        conflicts_with_all = ["views", "view", "camera", "look_from", "up", "time_limit", "stats"],
        allow_negative_numbers = true
    )]
    pub turntable: Option<u32>,
    /// Render a glTF animation (--animation, default animation 0) as N frames into the -o
    /// folder (000.png, 001.png, ...): frame k poses the model at k/N of the animation's
    /// duration, so that the frames loop. The camera is the file's (an animated camera moves),
    /// --camera or --look-from as asked, else the automatic camera of the first frame, kept
    /// for all. --gif plays them at the animation's speed.
    #[arg(
        long,
        value_name = "N",
        value_parser = clap::value_parser!(u32).range(1..=i64::from(meshtracer::output::turntable::MAX_TURNTABLE_FRAMES)),
        conflicts_with_all = [
            "views", "turntable", "time", "view", "tile", "crop", "resume", "shard",
            "contact_sheet", "preview", "stats", "view_out", "env_out", "depth_out",
            "normal_out", "mask_out", "segmentation_out",
        ],
        allow_negative_numbers = true
    )]
    pub frames: Option<u32>,
    /// With --turntable or --frames (or --views: the views in order): also write the frames as
    /// an animated GIF that loops forever (256 colours a frame; transparent where less than
    /// half covered, unless --background).
    #[arg(long, value_name = "FILE.gif", requires = "animated")]
    pub gif: Option<PathBuf>,
    /// With --gif: frames per second, 0.0015 to 50 (GIF delays are whole hundredths of a
    /// second, at most 655.35 s) [default: a full turn in 4 s, e.g. 9 fps for 36 frames; with
    /// --frames, the animation's own speed, at most 50 fps].
    #[arg(long, value_name = "FPS", requires = "gif")]
    pub fps: Option<f32>,
    /// With --views orbit:N or --turntable: elevation of the circle above the target, in
    /// degrees [default: 20 for --views; for --turntable, the plain render's camera's].
    #[arg(
        long,
        value_name = "DEG",
        allow_hyphen_values = true,
        requires = "many_views"
    )]
    pub orbit_elevation: Option<f32>,
    /// With --views orbit:N or --turntable: azimuth of view 0 in degrees, counter-clockwise
    /// seen from above from +Z (the front) [default: 0 for --views; for --turntable, the plain
    /// render's camera's].
    #[arg(
        long,
        value_name = "DEG",
        allow_hyphen_values = true,
        requires = "many_views"
    )]
    pub orbit_azimuth: Option<f32>,
    /// With --views orbit:N, sphere:N, random:N or --turntable: distance of the views from the
    /// target [default: the automatic camera's, which frames the whole model].
    #[arg(
        long,
        value_name = "X",
        requires = "many_views",
        allow_hyphen_values = true
    )]
    pub orbit_radius: Option<f32>,
    /// With --views or --turntable (or in batch, one cell per job): write a labelled grid of
    /// the views as a PNG, each cell a thumbnail with its view number (or job id) under it.
    #[arg(long, value_name = "FILE.png")]
    pub contact_sheet: Option<PathBuf>,
    /// With --contact-sheet: cells per row [default: about the square root of the count].
    #[arg(
        long,
        value_name = "N",
        requires = "contact_sheet",
        allow_negative_numbers = true
    )]
    pub sheet_columns: Option<u32>,
    /// With --contact-sheet: width of a cell's thumbnail in pixels; its height follows the
    /// images' aspect.
    #[arg(
        long,
        value_name = "PX",
        default_value_t = meshtracer::output::sheet::DEFAULT_CELL_WIDTH,
        requires = "contact_sheet",
        allow_negative_numbers = true
    )]
    pub sheet_cell_width: u32,
    /// With --views: each view's image, relative to the -o folder; {view} is the view number,
    /// {view:03} the number padded to 3 digits [default: {view:03}.png, wider past 1000
    /// views]. With --views, --depth-out, --normal-out, --mask-out, --segmentation-out and
    /// --view-out take such patterns too (--view-out default: {view:03}.view.json).
    #[arg(long, value_name = "PATTERN", requires = "many_views")]
    pub view_name: Option<String>,
    /// Render only tile I of N (counted from 0): the image cut into N bands of whole rows.
    /// The outputs (image and AOVs) hold the tile alone, with a sidecar OUT.tile.json saying
    /// where it belongs; `meshtracer merge` joins the tiles into the single render's image.
    /// A denoised render's tile (the default render's) keeps its film and guides in
    /// OUT.denoise.exr, and its image is not denoised: merge denoises the whole.
    #[arg(
        long,
        value_name = "I/N",
        value_parser = parse_tile,
        conflicts_with_all = ["views", "turntable", "time_limit", "crop"]
    )]
    pub tile: Option<meshtracer::jobs::tiles::TileIndex>,
    /// Render only the rectangle of W x H pixels whose top-left pixel is X,Y (from the
    /// image's top-left corner); written like a --tile, with its sidecar.
    #[arg(
        long,
        value_name = "X,Y,W,H",
        value_parser = parse_crop,
        conflicts_with_all = ["views", "turntable", "time_limit"]
    )]
    pub crop: Option<meshtracer::render::Region>,
    /// Show the finished image in the terminal, sized to it: as sixel, iTerm2 or kitty
    /// graphics when the terminal speaks one, else as Unicode half blocks (24-bit colour when
    /// COLORTERM says so, 256 colours otherwise). `--preview` (auto) prints only when standard
    /// output is a terminal; `--preview=blocks` prints half blocks in any case without asking
    /// the terminal anything (80x24 when its size cannot be asked). With --views, --turntable
    /// or batch: the views or jobs once at the end, as a contact sheet.
    #[arg(
        long,
        value_parser = choice::<PreviewMode>(),
        value_name = "MODE",
        num_args = 0..=1,
        require_equals = true,
        default_missing_value = "auto"
    )]
    pub preview: Option<PreviewMode>,
    /// Acceleration structure: the BVH, or a linear scan of every triangle (the baseline).
    #[arg(long, value_parser = choice::<AccelKind>(), default_value = "bvh")]
    pub accel: AccelKind,
    /// obvhs build preset for the BVH; `auto` picks `very-fast` when the render traces fewer
    /// than 32 rays a triangle (a big model, a small image), `medium` otherwise.
    #[arg(long, value_parser = choice::<BvhPreset>(), default_value = "auto")]
    pub bvh_preset: BvhPreset,
    /// Worker threads (0 = one per core; at most 1024).
    #[arg(long, default_value_t = 0, value_parser = parse_threads, allow_negative_numbers = true)]
    pub threads: usize,
    /// Exposure in stops: linear radiance is multiplied by 2^EV before encoding.
    #[arg(
        long,
        default_value_t = 0.0,
        value_name = "EV",
        allow_hyphen_values = true
    )]
    pub exposure: f32,
    /// View transform from linear radiance to the 8-bit image (PNG, preview; EXR and HDR stay
    /// linear), after the exposure.
    /// [default: khronos-pbr-neutral, which keeps authored base colours as they are below its
    /// knee and rolls highlights off; standard clips as sRGB does].
    #[arg(long, value_parser = choice::<ViewTransform>(), default_value = "khronos-pbr-neutral")]
    pub tonemap: ViewTransform,
    /// Fill pixels where nothing was hit with this linear colour (R,G,B) instead of leaving
    /// them transparent.
    #[arg(long, value_name = "R,G,B", value_parser = parse_vec3)]
    pub background: Option<Vec3>,
    /// Ambient radiance factor (R,G,B or one value) [default: 0.08 with the default rig,
    /// 0.03 with the file's lights].
    #[arg(
        long,
        value_name = "R,G,B",
        value_parser = parse_vec3_or_scalar,
        allow_hyphen_values = true
    )]
    pub ambient: Option<Vec3>,
    /// Shading model: the glTF metallic-roughness BRDF, or classic Blinn-Phong.
    #[arg(long, value_parser = choice::<ShadingModel>(), default_value = "pbr")]
    pub shading: meshtracer::shading::ShadingModel,
    /// Decoded texture memory budget in MiB; larger images are halved until they fit, with a
    /// warning.
    #[arg(long, default_value_t = meshtracer::defaults::MAX_TEXTURE_MIB, value_name = "MIB", allow_negative_numbers = true)]
    pub max_texture_memory: usize,
    /// Do not add the default key and fill lights (direct) or the built-in studio environment
    /// (path) when the file has no lights.
    #[arg(long)]
    pub no_default_lights: bool,
    /// Light transport: `direct` (punctual lights through shadow rays, constant ambient) or
    /// `path` (path tracing: emissive surfaces as area lights, the environment,
    /// interreflection, multiple importance sampling) [default: path, lit by the file's lights,
    /// else by a neutral studio environment].
    #[arg(long, value_parser = choice::<IntegratorKind>(), default_value = "path")]
    pub integrator: meshtracer::integrator::IntegratorKind,
    /// Path tracer: most bounces after the first hit (0 = direct light only).
    #[arg(long, default_value_t = meshtracer::defaults::DEFAULT_BOUNCES, value_name = "N", allow_negative_numbers = true)]
    pub bounces: u32,
    /// Path tracer: the most a sample's indirect light may bring (its largest channel, after
    /// the first surface's direct light), against fireflies; biased, as Cycles' Clamp
    /// Indirect [default: no clamp].
    #[arg(long, value_name = "RADIANCE", value_parser = parse_clamp)]
    pub clamp_indirect: Option<f32>,
    /// Path tracer: light the scene with this equirectangular panorama (.hdr, or .exr with
    /// any compression but HTJ2K; an 8-bit .png or .jpg is read as sRGB) [default: the
    /// built-in neutral studio when the file has no lights].
    #[arg(long, value_name = "FILE")]
    pub env: Option<PathBuf>,
    /// Path tracer: turn the environment about +Y by this many degrees.
    #[arg(
        long,
        default_value_t = 0.0,
        value_name = "DEG",
        allow_hyphen_values = true
    )]
    pub env_rotation: f32,
    /// Path tracer: multiply the environment's radiance by this.
    #[arg(long, default_value_t = 1.0, value_name = "X")]
    pub env_intensity: f32,
    /// Path tracer: camera rays that miss show the environment (else they stay transparent,
    /// or take --background).
    #[arg(long)]
    pub env_visible: bool,
    /// Path tracer: write the environment actually used (built-in included, rotation and
    /// intensity applied) as a Radiance .hdr panorama, to light another renderer the same way.
    #[arg(long, value_name = "FILE.hdr")]
    pub env_out: Option<PathBuf>,
    /// Write camera-space depth (distance along the view axis, 0 = no hit): .exr, .npy, or
    /// 16-bit .png in units of --depth-scale.
    #[arg(long, value_name = "FILE")]
    pub depth_out: Option<PathBuf>,
    /// Metres per unit of a 16-bit PNG depth map (default 0.001: millimetres).
    #[arg(long, default_value_t = 0.001)]
    pub depth_scale: f32,
    /// Write world-space shading normals: .exr, .npy or .png.
    #[arg(long, value_name = "FILE")]
    pub normal_out: Option<PathBuf>,
    /// Write coverage (the image's alpha): .png or .npy.
    #[arg(long, value_name = "FILE")]
    pub mask_out: Option<PathBuf>,
    /// Write mesh-instance ids (0 = background, no blending across edges): 16-bit .png or
    /// .npy; the id table is in the --view-out JSON.
    #[arg(long, value_name = "FILE")]
    pub segmentation_out: Option<PathBuf>,
    /// Write where the time and memory went as JSON: each phase (parse and flatten, tangents,
    /// textures, BVH build, prepare, render, write) with its wall time and the peak memory
    /// after it, and the steps of the load (read, parse, flatten, materials and images) and
    /// of the BVH build.
    #[arg(long, value_name = "FILE.json")]
    pub stats: Option<PathBuf>,
    /// Write the camera and lights actually used as JSON (the schema is in docs/view-file.md).
    #[arg(long, value_name = "FILE")]
    pub view_out: Option<PathBuf>,
    /// Render with exactly the camera, lights, ambient and image size of a view file written
    /// by --view-out (overrides --camera, --look-from and the file's lights).
    #[arg(long, value_name = "FILE")]
    pub view: Option<PathBuf>,
    /// Refuse images with more pixels than this.
    #[arg(long, default_value_t = meshtracer::defaults::MAX_RENDER_PIXELS, value_name = "N", allow_negative_numbers = true)]
    pub max_pixels: u64,
    /// Refuse more samples per pixel than this.
    #[arg(long, default_value_t = meshtracer::defaults::MAX_SPP, value_name = "N", allow_negative_numbers = true)]
    pub max_spp: u32,
    /// Refuse to overwrite an existing output file.
    #[arg(long)]
    pub no_clobber: bool,
    /// With --views or --turntable: keep the views that an earlier run of the same command
    /// finished in the -o folder (DIR/rendered.jsonl records each, with its files' SHA-256)
    /// and render the rest; the folder ends as an uninterrupted run leaves it.
    #[arg(long)]
    pub resume: bool,
    /// With --views: render only shard I of N (0-based, I < N), the views k with k mod N = I,
    /// into the -o folder, recording them in DIR/rendered.I-of-N.jsonl (no transforms.json);
    /// then the same command without --shard and with --resume keeps every shard's views and
    /// writes transforms.json (and the GIF or the sheet).
    #[arg(long, value_name = "I/N", value_parser = meshtracer::jobs::batch::Shard::parse)]
    pub shard: Option<meshtracer::jobs::batch::Shard>,
    /// No progress bar and no summary. Warnings about the picture (a texture drawn without,
    /// a value corrected) are still printed: --no-warnings silences them.
    #[arg(short, long)]
    pub quiet: bool,
    /// Print no warnings about the model or the picture (a batch still records each job's
    /// in its results).
    #[arg(long)]
    pub no_warnings: bool,
    /// Refuse the model when a texture image or an OBJ's .mtl is missing or cannot be read,
    /// instead of drawing its materials with their factors (a missing .mtl's faces grey) and
    /// a warning; and refuse a --view file with keys no view file has (a warning otherwise).
    #[arg(long)]
    pub strict: bool,
    /// Draw this KHR_materials_variants variant (by name; `info` lists them).
    #[arg(long, value_name = "NAME")]
    pub variant: Option<String>,
    /// Loading options.
    #[command(flatten)]
    pub load: LoadArgs,
}

impl RenderArgs {
    /// Samples per pixel: `--spp`, else the integrator's default
    /// ([`meshtracer::defaults::DEFAULT_PATH_SPP`] for the path tracer, which then samples
    /// adaptively, [`meshtracer::defaults::DEFAULT_SPP`] for the direct integrator).
    pub fn spp(&self) -> u32 {
        self.sampling().0
    }

    /// The adaptive sampler's noise target: `--noise`, else, for the path tracer without
    /// `--spp` or `--time-limit`, [`meshtracer::defaults::DEFAULT_NOISE`]; `--spp N` alone asks
    /// for exactly N samples.
    pub fn noise(&self) -> Option<f32> {
        self.sampling().1
    }

    /// [`meshtracer::setup::sampling`] of these options.
    fn sampling(&self) -> (u32, Option<f32>) {
        meshtracer::setup::sampling(
            self.integrator,
            self.spp_given,
            self.noise_given,
            self.time_limit.is_some(),
            self.denoises(),
        )
    }

    /// Whether the image is denoised: `--denoise`, else unless `--no-denoise` for the default
    /// render ([`meshtracer::setup::denoises_by_default`]).
    pub fn denoises(&self) -> bool {
        self.denoise
            || (!self.no_denoise
                && meshtracer::setup::denoises_by_default(
                    self.integrator,
                    self.spp_given,
                    self.noise_given,
                    self.time_limit.is_some(),
                    // Views are denoised when asked: a denoiser's residual blotches differ
                    // from view to view, which multi-view reconstruction does not average out
                    // as it does zero-mean noise. A tile is part of one image: `merge`
                    // denoises the whole, as the single render is.
                    self.views.is_none() && self.turntable.is_none(),
                ))
    }

    /// The files a render writes beside its image, each with the option that names it, in
    /// the order a single-view render writes them: the AOVs, the panorama, the view file and
    /// the statistics. The one list that render and batch both read.
    pub fn side_outputs(&self) -> [(&'static str, Option<&PathBuf>); 7] {
        [
            ("--depth-out", self.depth_out.as_ref()),
            ("--normal-out", self.normal_out.as_ref()),
            ("--segmentation-out", self.segmentation_out.as_ref()),
            ("--mask-out", self.mask_out.as_ref()),
            ("--env-out", self.env_out.as_ref()),
            ("--view-out", self.view_out.as_ref()),
            ("--stats", self.stats.as_ref()),
        ]
    }
}

/// `meshtracer batch`: the render options are the defaults of every job, with the model
/// argument naming the manifest and `-o` the output folder. Output options (`--depth-out`...)
/// name files inside each job's folder.
#[derive(Debug, Args)]
#[command(
    mut_arg("model", |a| a
        .value_name("MANIFEST")
        .help("A folder of models (every .gltf, .glb and .obj below it, and every .zip holding one that is not unzipped beside it, sorted) or a JSONL file of jobs, one a line: {\"id\", \"model\", \"views\", \"width\", \"height\", \"spp\", \"seed\", \"animation\", \"time\", \"outputs\"}; relative model paths resolve against the manifest's folder")),
    mut_arg("output", |a| a
        .value_name("DIR")
        .help("The output folder: each job writes into DIR/<job id>/, the batch records every job in DIR/results.jsonl (results.I-of-N.jsonl for a shard)")),
    mut_arg("shard", |a| a
        .help("Render only shard I of N (0-based, I < N): the jobs whose id hashes (FNV-1a 64 of its UTF-8 bytes) to I modulo N [default: from SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT, or JOB_COMPLETION_INDEX and --shard-count; 0/1 for all jobs]")),
    mut_arg("resume", |a| a
        .help("Skip the jobs whose job.json says they finished with these options and whose outputs still have the recorded SHA-256 hashes; redo the others (a job with views keeps the views it finished)")),
)]
pub struct BatchArgs {
    /// The manifest, the output folder and the render options every job starts from.
    #[command(flatten)]
    pub render: RenderArgs,
    /// Each job's image, relative to its folder [default: image.png; for a job with views,
    /// --view-name, else {view:03}.png]. For a job with views, this name and the other output
    /// names of the command line (--depth-out...) are numbered per view when they have no
    /// {view}: depth.exr becomes {view:03}.depth.exr.
    #[arg(long, value_name = "NAME")]
    pub image_name: Option<String>,
    /// The number of shards when JOB_COMPLETION_INDEX (a Kubernetes Indexed Job) gives the
    /// index [default: MESHTRACER_SHARD_COUNT].
    #[arg(
        long,
        value_name = "N",
        conflicts_with = "shard",
        allow_negative_numbers = true
    )]
    pub shard_count: Option<usize>,
}

/// `meshtracer batch-merge`.
#[derive(Debug, Args)]
pub struct BatchMergeArgs {
    /// The output folder of a sharded batch, holding results.I-of-N.jsonl for every I < N.
    pub dir: PathBuf,
    /// No summary line.
    #[arg(short, long)]
    pub quiet: bool,
}

/// `meshtracer merge`.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// The tiles: their images (the sidecar IMAGE.tile.json beside each is read) or their
    /// sidecars.
    #[arg(required = true, value_name = "TILE")]
    pub tiles: Vec<PathBuf>,
    /// The whole image; the same format as the tiles' images.
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Join the tiles' depth maps into this file (the tiles' format).
    #[arg(long, value_name = "FILE")]
    pub depth_out: Option<PathBuf>,
    /// Join the tiles' normal maps into this file (the tiles' format).
    #[arg(long, value_name = "FILE")]
    pub normal_out: Option<PathBuf>,
    /// Join the tiles' masks into this file (the tiles' format).
    #[arg(long, value_name = "FILE")]
    pub mask_out: Option<PathBuf>,
    /// Join the tiles' segmentation maps into this file (the tiles' format).
    #[arg(long, value_name = "FILE")]
    pub segmentation_out: Option<PathBuf>,
    /// Refuse to overwrite an existing output file.
    #[arg(long)]
    pub no_clobber: bool,
    /// No summary line.
    #[arg(short, long)]
    pub quiet: bool,
}

/// `meshtracer bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Models to measure besides the generated meshes.
    pub models: Vec<PathBuf>,
    /// Triangle counts of the generated meshes (seeded bumpy spheres), comma-separated;
    /// empty (`--sizes=`) for none.
    #[arg(long, default_value = "1000,10000,100000,1000000")]
    pub sizes: SizeList,
    /// Ray coherence: camera rays, shadow rays toward a light, or random diffuse bounces;
    /// several, comma-separated, measure each in turn on the same BVH build.
    #[arg(long, value_parser = choice::<RayKind>(), value_delimiter = ',', default_value = "primary")]
    pub rays: Vec<meshtracer::tools::bench::RayKind>,
    /// Camera rays per image side (side² primary rays per run).
    #[arg(long, default_value_t = 512, allow_negative_numbers = true)]
    pub side: u32,
    /// Timed runs per measurement, 1 or more (the median is reported).
    #[arg(long, default_value_t = 3, allow_negative_numbers = true)]
    pub runs: usize,
    /// Triangle tests the linear scan may spend per measurement (it traces a subset of the rays
    /// so that it finishes); 0 skips the linear scan.
    #[arg(long, default_value_t = 2_000_000_000, allow_negative_numbers = true)]
    pub linear_budget: u64,
    /// obvhs build preset.
    #[arg(long, value_parser = choice::<BvhPreset>(), default_value = "medium")]
    pub bvh_preset: BvhPreset,
    /// Trace the rays eight consecutive ones at a time through the BVH's packet queries
    /// (one walk of the tree for eight rays) instead of one at a time; the answers are checked
    /// to be the same.
    #[arg(long)]
    pub packets: bool,
    /// Worker threads (0 = one per core; at most 1024).
    #[arg(long, default_value_t = 0, value_parser = parse_threads, allow_negative_numbers = true)]
    pub threads: usize,
    /// Write the table and the settings as Markdown here.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Draw time per ray against triangle count (log-log) to this SVG file: the generated
    /// meshes as lines, the models as markers.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    /// Also measure the path tracer on every scene: render its default view at this many
    /// samples per pixel with `--integrator path` (lit as `render` lights it: the file's
    /// lights, else the built-in studio), alternating `--runs` times with the BVH alone on
    /// diffuse rays in the same tree, and report both throughputs and their ratio (the rest
    /// of the path tracer's time is shading). 0 = off.
    #[arg(
        long,
        default_value_t = 0,
        value_name = "SPP",
        allow_negative_numbers = true
    )]
    pub path_spp: u32,
    /// The path tracer's image size for --path-spp.
    #[arg(long, default_value = "512x384", value_name = "WIDTHxHEIGHT", value_parser = parse_size)]
    pub path_size: (u32, u32),
    /// Print one JSON object (settings, a row per scene and ray kind with each run's
    /// throughput, the path tracer's rows) instead of the Markdown tables.
    #[arg(long)]
    pub json: bool,
    /// Trace every triangle from both sides (no back-face culling of single-sided materials),
    /// as Intel Embree does by default: the work `scripts/bench/peers.py` compares.
    #[arg(long)]
    pub double_sided: bool,
    /// Write the triangles, the rays of each `--rays` kind and the BVH's hits as NumPy arrays
    /// into this folder (one model and `--sizes=`); see `scripts/bench/peers.py`.
    #[arg(long, value_name = "DIR")]
    pub export_rays: Option<PathBuf>,
    /// No progress lines.
    #[arg(short, long)]
    pub quiet: bool,
    /// Loading options.
    #[command(flatten)]
    pub load: LoadArgs,
}

/// An image size `WIDTHxHEIGHT`, each side 1 to 8192 (at most the 8192² pixels `render`
/// accepts by default).
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("{s:?}: expected WIDTHxHEIGHT, e.g. 512x384, each side 1 to 8192");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let side = |t: &str| {
        t.trim()
            .parse::<u32>()
            .ok()
            .filter(|v| (1..=8192).contains(v))
    };
    match (side(w), side(h)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(bad()),
    }
}

/// `meshtracer compare`.
#[derive(Debug, Args)]
pub struct CompareArgs {
    /// The reference image.
    pub a: PathBuf,
    /// The image under test.
    pub b: PathBuf,
    /// Print the metrics as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write the per-pixel FLIP error as a heatmap PNG.
    #[arg(long, value_name = "FILE")]
    pub diff_out: Option<PathBuf>,
    /// Write A | B | heatmap side by side, labelled, as a PNG.
    #[arg(long, value_name = "FILE")]
    pub side_by_side: Option<PathBuf>,
    /// Composite both over this sRGB colour (0-255 or 0-1 components, R,G,B) before comparing;
    /// in an image without alpha (a JPEG) the pixels of exactly this colour are the uncovered
    /// ones for coverage IoU [default: black, the same as giving 0,0,0].
    #[arg(long, value_name = "R,G,B", value_parser = parse_vec3)]
    pub background: Option<Vec3>,
    /// View transform for EXR and HDR inputs (linear radiance), as `render --tonemap` encodes
    /// a PNG; 8-bit inputs are compared as they are [default: khronos-pbr-neutral, render's
    /// default, so an EXR and a PNG of one default render compare as the same picture].
    #[arg(long, value_parser = choice::<ViewTransform>(), default_value = "khronos-pbr-neutral")]
    pub tonemap: ViewTransform,
    /// Exit with status 1 when an error metric exceeds a value: flip, rmse or max_abs
    /// (e.g. --fail-above flip=0.1); may be repeated.
    #[arg(long, value_name = "METRIC=VALUE", value_parser = parse_threshold)]
    pub fail_above: Vec<(String, f64)>,
    /// Exit with status 1 when a quality metric falls below a value: psnr, ssim or
    /// coverage_iou (e.g. --fail-below psnr=30); may be repeated.
    #[arg(long, value_name = "METRIC=VALUE", value_parser = parse_threshold)]
    pub fail_below: Vec<(String, f64)>,
}

/// Parses `--noise`: a finite fraction above 0.
fn parse_noise(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a fraction above 0 (e.g. 0.02)")),
    }
}

/// Parses `--clamp-indirect`: a finite radiance above 0.
fn parse_clamp(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a radiance above 0 (e.g. 10)")),
    }
}

/// Parses `METRIC=VALUE`: a finite value the metric can take on one side (0 or more, SSIM -1 or
/// more). NaN compares false with everything, so a NaN bound would never fail the gate; an
/// infinite one or one below the metric's range never fails or always does.
pub fn parse_threshold(s: &str) -> Result<(String, f64), String> {
    let (metric, value) = s
        .split_once('=')
        .ok_or_else(|| format!("expected METRIC=VALUE, got '{s}'"))?;
    let metric = metric.trim().to_ascii_lowercase();
    if !["psnr", "ssim", "flip", "rmse", "max_abs", "coverage_iou"].contains(&metric.as_str()) {
        return Err(format!(
            "unknown metric '{metric}' (psnr, ssim, flip, rmse, max_abs, coverage_iou)"
        ));
    }
    let text = value.trim();
    let value: f64 = text
        .parse()
        .map_err(|_| format!("'{text}' is not a number"))?;
    if !value.is_finite() {
        return Err(format!("'{text}' is not a finite number"));
    }
    let least = if metric == "ssim" { -1.0 } else { 0.0 };
    if value < least {
        return Err(format!("'{text}': {metric} is never below {least}"));
    }
    Ok((metric, value))
}

/// Parses `--tile I/N`.
pub fn parse_tile(s: &str) -> Result<meshtracer::jobs::tiles::TileIndex, String> {
    meshtracer::jobs::tiles::TileIndex::parse(s).map_err(|e| e.to_string())
}

/// Parses `--crop X,Y,W,H`.
pub fn parse_crop(s: &str) -> Result<meshtracer::render::Region, String> {
    meshtracer::jobs::tiles::parse_crop(s).map_err(|e| e.to_string())
}

/// Parses `X,Y,Z` into a vector of three finite numbers.
pub fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected three numbers X,Y,Z, got '{s}'"));
    }
    let mut v = [0.0f32; 3];
    for (slot, part) in v.iter_mut().zip(&parts) {
        *slot = part
            .parse::<f32>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("'{part}' is not a finite number"))?;
    }
    Ok(Vec3::from(v))
}

/// Parses `X,Y,Z` or a single number `A` (meaning A,A,A).
pub fn parse_vec3_or_scalar(s: &str) -> Result<Vec3, String> {
    match s.trim().parse::<f32>() {
        Ok(a) if a.is_finite() => Ok(Vec3::splat(a)),
        _ => parse_vec3(s),
    }
}

/// A comma-separated list of counts, where the empty string is the empty list (`--sizes=`:
/// clap would parse it as one empty value and refuse it).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SizeList(pub Vec<usize>);

impl std::str::FromStr for SizeList {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, String> {
        if text.trim().is_empty() {
            return Ok(SizeList(Vec::new()));
        }
        text.split(',')
            .map(|part| {
                part.trim()
                    .parse()
                    .map_err(|e| format!("'{part}' is not a count: {e}"))
            })
            .collect::<Result<_, _>>()
            .map(SizeList)
    }
}

impl std::ops::Deref for SizeList {
    type Target = [usize];
    fn deref(&self) -> &[usize] {
        &self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vectors_parse_strictly() {
        assert_eq!(parse_vec3("1, -2,3.5"), Ok(Vec3::new(1.0, -2.0, 3.5)));
        assert!(parse_vec3("1,2").is_err());
        assert!(parse_vec3("1,2,nan").is_err());
        assert!(parse_vec3("1,2,inf").is_err());
        assert_eq!(parse_vec3_or_scalar("0.5"), Ok(Vec3::splat(0.5)));
    }

    #[test]
    fn cli_definition_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }

    /// A bound the gate could never cross (NaN, infinite, below the metric's range) is refused.
    #[test]
    fn thresholds_are_finite_and_in_range() {
        assert_eq!(parse_threshold("flip=0.1"), Ok(("flip".into(), 0.1)));
        assert_eq!(parse_threshold("ssim=-0.5"), Ok(("ssim".into(), -0.5)));
        assert_eq!(parse_threshold("PSNR = 30"), Ok(("psnr".into(), 30.0)));
        for bad in [
            "flip=nan",
            "rmse=NaN",
            "psnr=inf",
            "max_abs=-inf",
            "flip=-0.1",
            "ssim=-2",
        ] {
            assert!(parse_threshold(bad).is_err(), "{bad}");
        }
    }

    /// Thousands of threads would fail inside the thread library (each needs its stack).
    #[test]
    fn threads_are_bounded() {
        assert_eq!(parse_threads("0"), Ok(0));
        assert_eq!(parse_threads("1024"), Ok(MAX_THREADS));
        for bad in ["1025", "100000", "-1", "two", ""] {
            assert!(parse_threads(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn sizes_parse_as_width_by_height() {
        assert_eq!(parse_size("512x384"), Ok((512, 384)));
        assert_eq!(parse_size("64X48"), Ok((64, 48)));
        for bad in ["512", "0x10", "10x0", "x", "8193x10", "-1x5", "axb"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }
}

#[cfg(test)]
mod help_tests {
    use super::Cli;
    use clap::CommandFactory;
    use meshtracer::defaults;

    /// `--help` is for users: no doc comment written for rustdoc (an intra-doc link, a path
    /// into the code) leaks into any command's help.
    #[test]
    fn no_help_shows_rustdoc_links_or_code_paths() {
        let mut cli = Cli::command();
        let mut helps = vec![("meshtracer".to_string(), cli.render_long_help().to_string())];
        for sub in cli.get_subcommands_mut() {
            helps.push((
                sub.get_name().to_string(),
                sub.render_long_help().to_string(),
            ));
        }
        assert!(helps.len() > 5, "every subcommand");
        for (name, help) in helps {
            for leak in ["[`", "Self::", "Args::", "::"] {
                assert!(
                    !help.contains(leak),
                    "{name} --help shows {leak:?}:\n{help}"
                );
            }
        }
    }

    /// The defaults `--help` states in prose are the ones [`meshtracer::defaults`] names.
    #[test]
    fn render_help_states_the_library_defaults() {
        let mut cli = Cli::command();
        let help = cli
            .find_subcommand_mut("render")
            .expect("render subcommand")
            .render_long_help()
            .to_string();
        // Each phrase as the help text words it, with the value taken from `defaults`.
        for phrase in [
            format!("default: {}", defaults::DEFAULT_WIDTH),
            format!("else {}", defaults::DEFAULT_HEIGHT),
            format!(
                "default: {}, or the file camera's",
                defaults::DEFAULT_YFOV_DEGREES
            ),
            format!(
                "{} with the default rig",
                defaults::AMBIENT_WITH_DEFAULT_RIG
            ),
            format!(
                "{} with the file's lights",
                defaults::AMBIENT_WITH_FILE_LIGHTS
            ),
            format!("default: {}", defaults::DEFAULT_SPP),
            format!("default: {}", defaults::MAX_TEXTURE_MIB),
        ] {
            let flat = help.split_whitespace().collect::<Vec<_>>().join(" ");
            assert!(flat.contains(&phrase), "--help does not say \"{phrase}\"");
        }
    }
}
