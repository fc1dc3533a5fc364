//! `KHR_animation_pointer`: animation channels that target a property by a JSON pointer
//! (`/materials/0/pbrMetallicRoughness/baseColorFactor`, `/extensions/KHR_lights_punctual/lights/1/intensity`)
//! instead of a node's transform.
//!
//! The pointer channels of the animation a render asks for (`--animation`, `--time`) are
//! sampled like the core channels ([`pose::Track`]: STEP, LINEAR, CUBICSPLINE; node rotations
//! by slerp) and their values written into the document's JSON where the pointers point; the
//! document is then read as if the file held those values, so every animated property is drawn
//! exactly as the same value written in a file would be (clamped and warned about the same
//! way). The static pose, and every other animation, leave the JSON alone.
//!
//! What can be animated is what the extension's list of animatable properties names and
//! meshtracer draws: node `translation`, `rotation`, `scale` and `weights`; the material
//! factors (`baseColorFactor`, `metallicFactor`, `roughnessFactor`, `emissiveFactor`,
//! `alphaCutoff`, a normal texture's `scale`, an occlusion texture's `strength`) and those of
//! the `KHR_materials_*` extensions; `KHR_texture_transform`'s `offset`, `rotation` and
//! `scale`; `KHR_lights_punctual`'s `color`, `intensity`, `range` and spot cone angles; and the
//! cameras' `yfov`, `aspectRatio`, `xmag`, `ymag`, `znear` and `zfar`; and
//! `KHR_node_visibility`'s `visible` (0 false, anything else true). Any other pointer is left
//! out with a warning naming the channel and the pointer.

use super::buffer::Buffer;
use super::pose::{self, Track};
use crate::scene::pose::PoseOptions;
use gltf::animation::Interpolation;
use serde_json::{Map, Value};

/// One `KHR_animation_pointer` channel, taken out of the JSON before the `gltf` crate reads it
/// (which knows only node targets).
#[derive(Clone, Debug)]
pub(crate) struct PointerChannel {
    /// Its index among the animation's channels in the file.
    pub channel: usize,
    /// The animation sampler it reads.
    pub sampler: usize,
    /// The JSON pointer it animates (RFC 6901), `None` when the channel has none.
    pub pointer: Option<String>,
}

/// What kind of value an animatable property holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    /// A number or an array of them.
    Number,
    /// A node rotation: a quaternion, slerped.
    Rotation,
    /// A boolean (`KHR_node_visibility`'s `visible`): 0 is false, anything else true (the
    /// extension's STEP keyframes of unsigned bytes).
    Flag,
}

/// The kind of value a pointer animates, `None` for a pointer meshtracer does not animate.
fn animatable(segments: &[String]) -> Option<Kind> {
    let is_index = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    let strs: Vec<&str> = segments.iter().map(String::as_str).collect();
    match strs.as_slice() {
        ["nodes", i, property] if is_index(i) => match *property {
            "rotation" => Some(Kind::Rotation),
            "translation" | "scale" | "weights" => Some(Kind::Number),
            _ => None,
        },
        ["nodes", i, "extensions", "KHR_node_visibility", "visible"] if is_index(i) => {
            Some(Kind::Flag)
        }
        ["materials", i, rest @ ..] if is_index(i) && !rest.is_empty() => {
            material_property(rest).then_some(Kind::Number)
        }
        ["extensions", "KHR_lights_punctual", "lights", i, rest @ ..] if is_index(i) => matches!(
            rest,
            ["color" | "intensity" | "range"] | ["spot", "innerConeAngle" | "outerConeAngle"]
        )
        .then_some(Kind::Number),
        ["cameras", i, kind, property] if is_index(i) => {
            let ok = match *kind {
                "perspective" => matches!(*property, "yfov" | "aspectRatio" | "znear" | "zfar"),
                "orthographic" => matches!(*property, "xmag" | "ymag" | "znear" | "zfar"),
                _ => false,
            };
            ok.then_some(Kind::Number)
        }
        _ => None,
    }
}

/// Whether `path` (below `/materials/i/`) is an animatable material property: a factor (of the
/// core material or a `KHR_materials_*` extension, any name ending in `Factor`), one of the
/// extensions' other numbers, a texture's scale or strength, or a `KHR_texture_transform`.
fn material_property(path: &[&str]) -> bool {
    const NUMBERS: [&str; 11] = [
        "alphaCutoff",
        "ior",
        "emissiveStrength",
        "dispersion",
        "attenuationDistance",
        "attenuationColor",
        "iridescenceIor",
        "iridescenceThicknessMinimum",
        "iridescenceThicknessMaximum",
        "anisotropyStrength",
        "anisotropyRotation",
    ];
    let Some((last, parents)) = path.split_last() else {
        return false;
    };
    if let Some(at) = parents.iter().position(|s| *s == "extensions") {
        let extension = parents.get(at + 1).copied().unwrap_or(*last);
        if extension == "KHR_texture_transform" {
            return parents.len() == at + 2 && matches!(*last, "offset" | "rotation" | "scale");
        }
        if !extension.starts_with("KHR_materials_") {
            return false;
        }
    }
    last.ends_with("Factor")
        || NUMBERS.contains(last)
        || (*last == "scale" && parents.last().is_some_and(|p| p.ends_with("Texture")))
        || (*last == "strength" && parents.last() == Some(&"occlusionTexture"))
}

/// The segments of a JSON pointer (`/a/b~1c` is `a`, `b/c`), `None` if it is not one.
fn segments(pointer: &str) -> Option<Vec<String>> {
    let rest = pointer.strip_prefix('/')?;
    Some(
        rest.split('/')
            .map(|s| s.replace("~1", "/").replace("~0", "~"))
            .collect(),
    )
}

/// Reads a pointer channel's keyframes. The output may be scalar or a vector of 2 to 4
/// numbers: floats as they are, normalized integers by glTF's dequantisation, other integers
/// as the equal floats (the extension's conversions); a scalar output with several values a
/// keyframe (morph weights) is read as one array a keyframe.
fn read_track(
    sampler: &gltf::animation::Sampler,
    buffers: &[Buffer],
    kind: Kind,
) -> Result<Track, String> {
    let times = pose::read_times(&sampler.input(), buffers)?;
    let output = sampler.output();
    let values = pose::read_output(&output, buffers)?;
    let rotation = kind == Kind::Rotation;
    let interpolation = sampler.interpolation();
    let elements = times.len()
        * if interpolation == Interpolation::CubicSpline {
            3
        } else {
            1
        };
    if elements == 0 || !values.len().is_multiple_of(elements) {
        return Err(format!(
            "output accessor {} holds {} numbers, not a whole number for each of {elements} keyframe elements",
            output.index(),
            values.len()
        ));
    }
    let track = Track {
        width: values.len() / elements,
        times,
        values,
        interpolation,
        rotation,
    };
    if rotation && track.width != 4 {
        return Err(format!(
            "output accessor {}: a rotation needs 4 numbers a keyframe, not {}",
            output.index(),
            track.width
        ));
    }
    track
        .check()
        .map_err(|p| format!("sampler {}: {p}", sampler.index()))?;
    Ok(track)
}

/// What a pointer channel animates.
enum Target {
    /// The property at `path`, of `kind`, with its keyframes.
    Animated {
        path: Vec<String>,
        kind: Kind,
        track: Track,
    },
    /// Nothing meshtracer animates, for this reason.
    Skipped(String),
}

/// What `channel` of `animation` animates; an error when its keyframes cannot be read.
fn channel_track(
    animation: &gltf::Animation,
    channel: &PointerChannel,
    buffers: &[Buffer],
) -> Result<Target, String> {
    let Some(pointer) = &channel.pointer else {
        return Ok(Target::Skipped("it names no pointer".to_string()));
    };
    let Some(path) = segments(pointer) else {
        return Ok(Target::Skipped(format!(
            "'{pointer}' is not a JSON pointer"
        )));
    };
    let Some(kind) = animatable(&path) else {
        return Ok(Target::Skipped(format!(
            "meshtracer does not animate '{pointer}'"
        )));
    };
    let sampler = animation
        .samplers()
        .nth(channel.sampler)
        .ok_or_else(|| format!("sampler {} does not exist", channel.sampler))?;
    let track = read_track(&sampler, buffers, kind)?;
    Ok(Target::Animated { path, kind, track })
}

/// The last keyframe time of the animatable pointer channels of `animation` (0 without),
/// with a warning for each channel that cannot be read.
pub(crate) fn duration(
    animation: &gltf::Animation,
    channels: &[PointerChannel],
    buffers: &[Buffer],
    warnings: &mut Vec<String>,
) -> f32 {
    let mut end = 0.0f32;
    for channel in channels {
        match channel_track(animation, channel, buffers) {
            Ok(Target::Animated { track, .. }) => end = end.max(track.end()),
            Ok(Target::Skipped(_)) => {}
            Err(problem) => warnings.push(format!(
                "animation {} channel {}: {problem}",
                animation.index(),
                channel.channel
            )),
        }
    }
    end
}

/// The document's JSON with the pointer channels of the animation `options` ask for written at
/// its time, or `None` when the render draws the static pose or that animation has no pointer
/// channels. A channel that cannot be read stops the load (as a core channel's does); one
/// whose pointer meshtracer does not animate, or that points at nothing, is left out with a
/// warning.
pub(crate) fn animate(
    document: &gltf::Document,
    buffers: &[Buffer],
    index: Option<usize>,
    channels: &[Vec<PointerChannel>],
    options: &PoseOptions,
    warnings: &mut Vec<String>,
) -> Result<Option<gltf::json::Root>, String> {
    let Some(index) = index.filter(|_| options.animates()) else {
        return Ok(None);
    };
    let list = channels.get(index).map_or(&[][..], Vec::as_slice);
    let Some(animation) = document.animations().nth(index) else {
        return Ok(None);
    };
    if list.is_empty() {
        return Ok(None);
    }
    let time = options.time.unwrap_or(0.0);
    let mut json = serde_json::to_value(document.as_json())
        .map_err(|e| format!("the document as JSON: {e}"))?;
    for channel in list {
        let at =
            |problem: String| format!("animation {index} channel {}: {problem}", channel.channel);
        match channel_track(&animation, channel, buffers).map_err(at)? {
            Target::Animated { path, kind, track } => {
                let value = track.sample(time);
                if let Err(problem) = write(&mut json, &path, &value, kind) {
                    warnings.push(at(format!("KHR_animation_pointer {problem}; left out")));
                }
            }
            Target::Skipped(problem) => {
                warnings.push(at(format!("KHR_animation_pointer: {problem}; left out")))
            }
        }
    }
    readable_again(&mut json);
    serde_json::from_value(json)
        .map(Some)
        .map_err(|e| format!("animation {index}: the animated document does not read back: {e}"))
}

/// Makes gltf-json's own JSON of a document readable by gltf-json again: puts back the lists
/// it leaves out when empty but needs to read (an animation's `channels`, empty once its
/// pointer channels are taken out, its `samplers`, and a scene's `nodes`), and drops the
/// members it writes as `null`, which are defaults it holds as non-finite numbers
/// (`KHR_materials_volume`'s infinite `attenuationDistance`) and reads back the same when
/// absent.
fn readable_again(json: &mut Value) {
    drop_nulls(json);
    for (list, field) in [
        ("animations", "channels"),
        ("animations", "samplers"),
        ("scenes", "nodes"),
    ] {
        if let Some(items) = json.get_mut(list).and_then(Value::as_array_mut) {
            for item in items.iter_mut().filter_map(Value::as_object_mut) {
                item.entry(field)
                    .or_insert_with(|| Value::Array(Vec::new()));
            }
        }
    }
}

/// Removes every object member whose value is `null`, at any depth (see
/// [`readable_again`]); glTF's schema allows `null` nowhere.
fn drop_nulls(json: &mut Value) {
    // An explicit stack: a hostile document nested a million levels deep must not overflow.
    let mut stack = vec![json];
    while let Some(value) = stack.pop() {
        match value {
            Value::Object(map) => {
                map.retain(|_, v| !v.is_null());
                stack.extend(map.values_mut());
            }
            Value::Array(list) => stack.extend(list.iter_mut()),
            _ => {}
        }
    }
}

/// Writes `value` (one number, or an array of them; a [`Kind::Flag`] as a boolean) where
/// `path` points in `json`, creating the objects on the way that the file left out (a default
/// factor, an extension's object); an array index must exist. The value takes the property's
/// [`shape`]: a keyframe of another size is an error (the channel is then left out), and
/// morph target weights keep the length the file gives them.
fn write(json: &mut Value, path: &[String], value: &[f32], kind: Kind) -> Result<(), String> {
    let pointer = || format!("'/{}'", path.join("/"));
    if let Some((i, bad)) = value.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(format!("{}: value {i} is {bad}", pointer()));
    }
    let Some((last, parents)) = path.split_last() else {
        return Err("an empty pointer".to_string());
    };
    let mut at = json;
    for segment in parents {
        at = match at {
            Value::Object(map) => map
                .entry(segment.as_str())
                .or_insert_with(|| Value::Object(Map::new())),
            Value::Array(list) => segment
                .parse::<usize>()
                .ok()
                .and_then(|i| list.get_mut(i))
                .ok_or_else(|| format!("{} points at nothing", pointer()))?,
            _ => return Err(format!("{} points into a number", pointer())),
        };
    }
    let Value::Object(map) = at else {
        return Err(format!("{} points at nothing", pointer()));
    };
    if parents.first().map(String::as_str) == Some("nodes")
        && last != "weights"
        && map.contains_key("matrix")
    {
        return Err(format!(
            "{}: the node has a matrix, which its translation, rotation and scale may not replace",
            pointer()
        ));
    }
    let number = |v: f32| Value::from(f64::from(v));
    let count = |n: usize| match n {
        1 => "1 number".to_string(),
        n => format!("{n} numbers"),
    };
    let new = match (shape(path), map.get(last.as_str())) {
        (Some(n), _) if value.len() != n => {
            return Err(format!(
                "{}: {} a keyframe, where the property takes {}",
                pointer(),
                count(value.len()),
                count(n)
            ))
        }
        (None, Some(Value::Array(old))) if old.len() != value.len() => {
            return Err(format!(
                "{}: {} a keyframe, where the file has {}",
                pointer(),
                count(value.len()),
                count(old.len())
            ))
        }
        (Some(1), _) if kind == Kind::Flag => Value::Bool(value[0] != 0.0),
        (Some(1), _) => number(value[0]),
        _ => Value::Array(value.iter().map(|v| number(*v)).collect()),
    };
    map.insert(last.clone(), new);
    Ok(())
}

/// How many numbers a keyframe of the animatable property at `path` holds, as glTF's schema
/// types it: `Some(1)` a number (or a boolean), `Some(n)` an array of n, `None` an array of
/// any length (a node's morph target `weights`, as many as its mesh has targets). A value the
/// file leaves out is written in this shape, so one of the wrong shape is left out here
/// rather than refused by the schema when the document is read again.
fn shape(path: &[String]) -> Option<usize> {
    let strs: Vec<&str> = path.iter().map(String::as_str).collect();
    let last = strs.last().copied().unwrap_or_default();
    let extension = strs
        .iter()
        .rposition(|s| *s == "extensions")
        .and_then(|at| strs.get(at + 1).copied());
    match (strs.first().copied(), extension, last) {
        (Some("nodes"), None, "translation" | "scale") => Some(3),
        (Some("nodes"), None, "rotation") => Some(4),
        (Some("nodes"), None, "weights") => None,
        (_, Some("KHR_texture_transform"), "offset" | "scale") => Some(2),
        (Some("materials"), _, "baseColorFactor") => Some(4),
        (Some("materials"), Some("KHR_materials_pbrSpecularGlossiness"), "diffuseFactor") => {
            Some(4)
        }
        (Some("materials"), Some("KHR_materials_pbrSpecularGlossiness"), "specularFactor") => {
            Some(3)
        }
        (
            Some("materials"),
            _,
            "emissiveFactor"
            | "sheenColorFactor"
            | "specularColorFactor"
            | "attenuationColor"
            | "diffuseTransmissionColorFactor",
        ) => Some(3),
        (Some("extensions"), _, "color") => Some(3),
        _ => Some(1),
    }
}

/// The animation `options` choose, when the render animates (for [`animate`]).
pub(crate) fn chosen(
    animations: &[crate::scene::pose::AnimationInfo],
    options: &PoseOptions,
) -> Option<usize> {
    if !options.animates() {
        return None;
    }
    crate::scene::pose::choose_animation(animations, options.animation.as_deref()).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn path(p: &str) -> Vec<String> {
        segments(p).unwrap()
    }

    #[test]
    fn the_animatable_properties_are_recognised() {
        for (p, expected) in [
            ("/nodes/0/rotation", Some(Kind::Rotation)),
            ("/nodes/3/translation", Some(Kind::Number)),
            ("/nodes/3/weights", Some(Kind::Number)),
            ("/nodes/x/scale", None),
            ("/nodes/0/mesh", None),
            ("/materials/1/pbrMetallicRoughness/baseColorFactor", Some(Kind::Number)),
            ("/materials/1/emissiveFactor", Some(Kind::Number)),
            ("/materials/1/alphaCutoff", Some(Kind::Number)),
            ("/materials/1/normalTexture/scale", Some(Kind::Number)),
            ("/materials/1/occlusionTexture/strength", Some(Kind::Number)),
            ("/materials/1/normalTexture/index", None),
            ("/materials/0/extensions/KHR_materials_emissive_strength/emissiveStrength", Some(Kind::Number)),
            ("/materials/0/extensions/KHR_materials_transmission/transmissionFactor", Some(Kind::Number)),
            ("/materials/0/extensions/KHR_materials_volume/attenuationColor", Some(Kind::Number)),
            ("/materials/0/pbrMetallicRoughness/baseColorTexture/extensions/KHR_texture_transform/offset", Some(Kind::Number)),
            ("/materials/0/pbrMetallicRoughness/baseColorTexture/extensions/KHR_texture_transform/texCoord", None),
            ("/materials/0/extensions/EXT_made_up/someFactor", None),
            ("/extensions/KHR_lights_punctual/lights/2/intensity", Some(Kind::Number)),
            ("/extensions/KHR_lights_punctual/lights/2/spot/outerConeAngle", Some(Kind::Number)),
            ("/extensions/KHR_lights_punctual/lights/2/type", None),
            ("/nodes/1/extensions/KHR_node_visibility/visible", Some(Kind::Flag)),
            ("/cameras/0/perspective/yfov", Some(Kind::Number)),
            ("/cameras/0/orthographic/xmag", Some(Kind::Number)),
            ("/cameras/0/perspective/xmag", None),
            ("/accessors/0/count", None),
        ] {
            assert_eq!(animatable(&path(p)), expected, "{p}");
        }
        assert_eq!(path("/a~1b/c~0d"), ["a/b", "c~d"]);
        assert!(segments("nodes/0").is_none());
    }

    /// gltf-json writes an absent `attenuationDistance` (infinite) as `null` and leaves out an
    /// animation's emptied channel list, and reads neither back; the document it writes must
    /// read back as it was.
    #[test]
    fn a_document_reads_back_after_its_round_trip() {
        let root: gltf::json::Root = serde_json::from_value(json!({
            "asset": {"version": "2.0"},
            "extensionsUsed": ["KHR_materials_volume", "KHR_materials_transmission"],
            "materials": [{"extensions": {
                "KHR_materials_transmission": {"transmissionFactor": 1.0},
                "KHR_materials_volume": {"thicknessFactor": 1.0}
            }}],
            "scenes": [{"nodes": []}],
            "animations": [{"channels": [], "samplers": []}]
        }))
        .unwrap();
        let mut json = serde_json::to_value(&root).unwrap();
        assert!(serde_json::from_value::<gltf::json::Root>(json.clone()).is_err());
        readable_again(&mut json);
        let back: gltf::json::Root = serde_json::from_value(json).unwrap();
        assert_eq!(
            serde_json::to_string(&back).unwrap(),
            serde_json::to_string(&root).unwrap()
        );
    }

    #[test]
    fn values_are_written_where_the_pointer_points() {
        let mut doc = json!({
            "nodes": [{"translation": [0.0, 0.0, 0.0]}, {"matrix": [1.0]}],
            "materials": [{"pbrMetallicRoughness": {"metallicFactor": 1.0}}]
        });
        write(
            &mut doc,
            &path("/nodes/0/translation"),
            &[1.0, 2.0, 3.0],
            Kind::Number,
        )
        .unwrap();
        write(
            &mut doc,
            &path("/materials/0/pbrMetallicRoughness/metallicFactor"),
            &[0.5],
            Kind::Number,
        )
        .unwrap();
        // A default the file left out, and an extension object it did not have.
        write(
            &mut doc,
            &path("/materials/0/emissiveFactor"),
            &[1.0, 0.5, 0.0],
            Kind::Number,
        )
        .unwrap();
        write(
            &mut doc,
            &path("/materials/0/extensions/KHR_materials_emissive_strength/emissiveStrength"),
            &[4.0],
            Kind::Number,
        )
        .unwrap();
        write(
            &mut doc,
            &path("/nodes/0/extensions/KHR_node_visibility/visible"),
            &[0.0],
            Kind::Flag,
        )
        .unwrap();
        // One morph target's weight, which the file leaves out: an array of one.
        write(&mut doc, &path("/nodes/0/weights"), &[0.5], Kind::Number).unwrap();
        // A texture transform inside an extension's texture: two numbers, not one.
        let offset = "/materials/0/extensions/KHR_materials_clearcoat/clearcoatTexture/extensions/KHR_texture_transform/offset";
        write(&mut doc, &path(offset), &[0.25, 0.5], Kind::Number).unwrap();
        assert_eq!(doc["nodes"][0]["weights"], json!([0.5]));
        assert_eq!(
            doc["materials"][0]["extensions"]["KHR_materials_clearcoat"]["clearcoatTexture"]
                ["extensions"]["KHR_texture_transform"]["offset"],
            json!([0.25, 0.5])
        );
        assert_eq!(
            doc["nodes"][0]["extensions"]["KHR_node_visibility"]["visible"],
            json!(false)
        );
        assert_eq!(doc["nodes"][0]["translation"], json!([1.0, 2.0, 3.0]));
        assert_eq!(
            doc["materials"][0]["pbrMetallicRoughness"]["metallicFactor"],
            json!(0.5)
        );
        assert_eq!(
            doc["materials"][0]["emissiveFactor"],
            json!([1.0, 0.5, 0.0])
        );
        assert_eq!(
            doc["materials"][0]["extensions"]["KHR_materials_emissive_strength"]
                ["emissiveStrength"],
            json!(4.0)
        );
        for (p, value, problem) in [
            (
                "/nodes/5/translation",
                &[1.0f32, 2.0, 3.0][..],
                "points at nothing",
            ),
            (
                "/nodes/0/translation",
                &[1.0, 2.0][..],
                "2 numbers a keyframe, where the property takes 3 numbers",
            ),
            (
                "/nodes/1/translation",
                &[1.0, 2.0, 3.0][..],
                "the node has a matrix",
            ),
            (
                "/materials/0/alphaCutoff",
                &[f32::NAN][..],
                "value 0 is NaN",
            ),
            // Properties the file leaves out take the schema's shape, not the channel's.
            (
                "/materials/0/extensions/KHR_materials_sheen/sheenColorFactor",
                &[1.0][..],
                "1 number a keyframe, where the property takes 3 numbers",
            ),
            (
                "/materials/0/occlusionTexture/strength",
                &[1.0, 2.0][..],
                "2 numbers a keyframe, where the property takes 1 number",
            ),
        ] {
            let err = write(&mut doc, &path(p), value, Kind::Number).unwrap_err();
            assert!(err.contains(problem), "{p}: {err}");
        }
    }
}
