//! The glTF JSON as the specification reads it, rewritten before gltf-json 1.4 deserializes it:
//! valid forms that crate refuses are turned into ones it accepts, and invalid ones that would
//! change the picture are corrected, each with a warning that names the place.
//!
//! Valid (glTF 2.0 and its JSON schema), refused by gltf-json:
//! - an integer written with a fraction of zero (`1.0`): JSON Schema's `integer` is any number
//!   with no fractional part, so every such number becomes an integer (a float field reads an
//!   integer the same);
//! - a scene without `nodes` (optional in the schema; gltf-json requires it): given an empty
//!   list, so that the node walk says there is nothing to draw;
//! - `extras` of any JSON type (§5.27: "application-specific data"), which gltf-json without
//!   its `extras` feature reads as an object: `extras` that is not an object is dropped
//!   (meshtracer reads no extras);
//! - a `KHR_lights_punctual` light of a type the extension does not define (a later version's):
//!   removed, with a warning, and the nodes' references renumbered;
//! - `KHR_animation_pointer` channels (a target with a `pointer` instead of a node and path):
//!   taken out into [`Rewritten::pointer_channels`], which [`super::pointer`] samples when
//!   their animation is drawn.
//!
//! Invalid, corrected with a warning:
//! - a node `rotation` that is not a unit quaternion (§5.25) is normalised: the `gltf` crate
//!   would build a matrix that also scales, by the squared length ([1, 1, 1, 1] scales by 4);
//! - a node with both `matrix` and `translation`/`rotation`/`scale` (§5.25: not allowed) keeps
//!   its matrix, as the `gltf` crate reads it.

use super::pointer::PointerChannel;
use serde_json::{Map, Value};

/// How far a rotation's length may be from 1 before it is normalised and reported: exporters
/// write f32 quaternions a few ulps from unit length (about 1e-7); a quantized animation or a
/// hand-written file rounded to 4 digits is still within 1e-3, and no visible change in scale.
const UNIT_QUATERNION_TOLERANCE: f64 = 1e-3;

/// Largest magnitude at which every integer is exactly an f64 (2^53).
const MAX_EXACT_INTEGER: f64 = 9_007_199_254_740_992.0;

/// The light types `KHR_lights_punctual` defines.
const LIGHT_TYPES: [&str; 3] = ["directional", "point", "spot"];

/// The JSON rewritten, and what the rewriting reports.
pub(super) struct Rewritten {
    /// The document, deserialized.
    pub root: gltf::json::Root,
    /// One line per correction or omission, naming the place.
    pub warnings: Vec<String>,
    /// For each animation (by index), the `KHR_animation_pointer` channels taken out of it.
    pub pointer_channels: Vec<Vec<PointerChannel>>,
}

/// Deserializes glTF JSON after the rewriting above. A document that still does not
/// deserialize gets the error of a plain parse of `bytes` (which says at which line and column)
/// when that is the same error, else the error of the rewritten document.
pub(super) fn deserialize(bytes: &[u8]) -> Result<Rewritten, gltf::Error> {
    let mut value: Value = match serde_json::from_slice(bytes) {
        Ok(value) => value,
        Err(e) => return Err(gltf::Error::Deserialize(e)),
    };
    let mut warnings = Vec::new();
    integers_and_extras(&mut value);
    let pointer_channels = match value.as_object_mut() {
        Some(top) => {
            for scene in array(top, "scenes").into_iter().flatten() {
                if let Some(scene) = scene.as_object_mut() {
                    scene
                        .entry("nodes")
                        .or_insert_with(|| Value::Array(Vec::new()));
                }
            }
            unknown_lights(top, &mut warnings);
            node_transforms(top, &mut warnings);
            pointer_channels(top)
        }
        None => Vec::new(),
    };
    match serde_json::from_value::<gltf::json::Root>(value) {
        Ok(root) => Ok(Rewritten {
            root,
            warnings,
            pointer_channels,
        }),
        Err(rewritten) => {
            let located = gltf::json::deserialize::from_slice::<gltf::json::Root>(bytes).err();
            Err(gltf::Error::Deserialize(match located {
                Some(e) if e.to_string().starts_with(&rewritten.to_string()) => e,
                _ => rewritten,
            }))
        }
    }
}

/// Integral floats to integers and non-object `extras` dropped, at every depth.
pub(super) fn integers_and_extras(value: &mut Value) {
    match value {
        Value::Number(n) => {
            if let Some(f) = n.as_f64().filter(|_| n.is_f64()) {
                if f.fract() == 0.0 && f.abs() <= MAX_EXACT_INTEGER {
                    *value = if f < 0.0 {
                        Value::from(f as i64)
                    } else {
                        Value::from(f as u64)
                    };
                }
            }
        }
        Value::Array(items) => items.iter_mut().for_each(integers_and_extras),
        Value::Object(map) => {
            if map.get("extras").is_some_and(|e| !e.is_object()) {
                map.remove("extras");
            }
            map.values_mut().for_each(integers_and_extras);
        }
        _ => {}
    }
}

/// The array `top[key]`, if it is one.
fn array<'a>(top: &'a mut Map<String, Value>, key: &str) -> Option<&'a mut Vec<Value>> {
    top.get_mut(key).and_then(Value::as_array_mut)
}

/// Removes `KHR_lights_punctual` lights of an unknown type and renumbers the nodes' references
/// (a node that referred to a removed light loses its reference).
fn unknown_lights(top: &mut Map<String, Value>, warnings: &mut Vec<String>) {
    let Some(lights) = top
        .get_mut("extensions")
        .and_then(|e| e.get_mut("KHR_lights_punctual"))
        .and_then(|e| e.get_mut("lights"))
        .and_then(Value::as_array_mut)
    else {
        return;
    };
    // New index of each old light, `None` where it is removed.
    let mut renumbered = Vec::with_capacity(lights.len());
    let mut kept = 0u64;
    for (i, light) in lights.iter().enumerate() {
        match light.get("type") {
            Some(Value::String(t)) if !LIGHT_TYPES.contains(&t.as_str()) => {
                warnings.push(format!(
                    "KHR_lights_punctual light {i}: type '{t}' is not one of {}; the light is skipped",
                    LIGHT_TYPES.join(", ")
                ));
                renumbered.push(None);
            }
            _ => {
                renumbered.push(Some(kept));
                kept += 1;
            }
        }
    }
    if renumbered.iter().all(Option::is_some) {
        return;
    }
    let mut keep = renumbered.iter().map(Option::is_some);
    lights.retain(|_| keep.next().unwrap_or(true));
    for node in array(top, "nodes").into_iter().flatten() {
        let Some(extensions) = node.get_mut("extensions").and_then(Value::as_object_mut) else {
            continue;
        };
        let Some(old) = extensions
            .get("KHR_lights_punctual")
            .and_then(|e| e.get("light"))
            .and_then(Value::as_u64)
        else {
            continue;
        };
        match usize::try_from(old).ok().and_then(|i| renumbered.get(i)) {
            Some(Some(new)) => extensions["KHR_lights_punctual"]["light"] = Value::from(*new),
            Some(None) => {
                extensions.remove("KHR_lights_punctual");
            }
            // Out of range: left for the validation to name.
            None => {}
        }
    }
}

/// Normalises node rotations that are not unit quaternions and reports nodes with both a
/// matrix and TRS.
fn node_transforms(top: &mut Map<String, Value>, warnings: &mut Vec<String>) {
    for (i, node) in array(top, "nodes").into_iter().flatten().enumerate() {
        let Some(node) = node.as_object_mut() else {
            continue;
        };
        let trs: Vec<&str> = ["translation", "rotation", "scale"]
            .into_iter()
            .filter(|k| node.contains_key(*k))
            .collect();
        if node.contains_key("matrix") && !trs.is_empty() {
            warnings.push(format!(
                "node {i}{}: has both matrix and {} (glTF allows one or the other); the matrix is used",
                name_of(node),
                trs.join(", ")
            ));
        }
        let Some(q) = node.get("rotation").and_then(Value::as_array) else {
            continue;
        };
        let Some(q) = q.iter().map(Value::as_f64).collect::<Option<Vec<f64>>>() else {
            continue;
        };
        let length = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        if q.len() != 4 || (length - 1.0).abs() <= UNIT_QUATERNION_TOLERANCE {
            continue;
        }
        if !(length.is_finite() && length > 0.0) {
            // No rotation to recover: the validation or the node walk reports it.
            continue;
        }
        let unit: Vec<f64> = q.iter().map(|c| c / length).collect();
        warnings.push(format!(
            "node {i}{}: rotation {q:?} is not a unit quaternion (length {length}); normalised to {unit:.6?}",
            name_of(node)
        ));
        node.insert("rotation".to_string(), Value::from(unit));
    }
}

/// ` ('name')` for an object with a name, else nothing.
fn name_of(object: &Map<String, Value>) -> String {
    object
        .get("name")
        .and_then(Value::as_str)
        .map_or(String::new(), |n| format!(" ('{n}')"))
}

/// Takes the `KHR_animation_pointer` channels out of each animation.
fn pointer_channels(top: &mut Map<String, Value>) -> Vec<Vec<PointerChannel>> {
    let mut taken = Vec::new();
    for animation in array(top, "animations").into_iter().flatten() {
        let mut out = Vec::new();
        if let Some(channels) = animation.get_mut("channels").and_then(Value::as_array_mut) {
            let mut index = 0;
            channels.retain(|channel| {
                let keep = !is_pointer_channel(channel);
                if !keep {
                    out.push(PointerChannel {
                        channel: index,
                        // An index that is not one points at no sampler: refused when sampled.
                        sampler: channel
                            .get("sampler")
                            .and_then(Value::as_u64)
                            .map_or(usize::MAX, |s| usize::try_from(s).unwrap_or(usize::MAX)),
                        pointer: channel
                            .pointer("/target/extensions/KHR_animation_pointer/pointer")
                            .and_then(Value::as_str)
                            .map(str::to_string),
                    });
                }
                index += 1;
                keep
            });
        }
        taken.push(out);
    }
    taken
}

/// A channel whose target is a `KHR_animation_pointer` pointer (path `pointer`, no node).
fn is_pointer_channel(channel: &Value) -> bool {
    let Some(target) = channel.get("target") else {
        return false;
    };
    let pointer = target
        .get("extensions")
        .and_then(|e| e.get("KHR_animation_pointer"))
        .is_some();
    target.get("path").and_then(Value::as_str) == Some("pointer")
        || (pointer && target.get("node").is_none())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn integral_floats_become_integers_and_other_numbers_stay() {
        let mut v = json!({"mesh": 1.0, "x": 1.5, "big": 1e300, "neg": -2.0,
            "extras": 5, "inner": {"extras": {"kept": 1}, "list": [3.0, "a"]}});
        integers_and_extras(&mut v);
        assert_eq!(
            v,
            json!({"mesh": 1, "x": 1.5, "big": 1e300, "neg": -2,
                "inner": {"extras": {"kept": 1}, "list": [3, "a"]}})
        );
    }

    #[test]
    fn unknown_lights_are_removed_and_references_renumbered() {
        let mut v = json!({
            "extensions": {"KHR_lights_punctual": {"lights": [
                {"type": "area"}, {"type": "point"}, {"type": "quantum"}, {"type": "spot"}]}},
            "nodes": [
                {"extensions": {"KHR_lights_punctual": {"light": 0}}},
                {"extensions": {"KHR_lights_punctual": {"light": 1}}},
                {"extensions": {"KHR_lights_punctual": {"light": 3}}}
            ]
        });
        let mut warnings = Vec::new();
        unknown_lights(v.as_object_mut().unwrap(), &mut warnings);
        assert_eq!(
            v["extensions"]["KHR_lights_punctual"]["lights"],
            json!([{"type": "point"}, {"type": "spot"}])
        );
        assert_eq!(v["nodes"][0], json!({"extensions": {}}));
        assert_eq!(
            v["nodes"][1]["extensions"]["KHR_lights_punctual"]["light"],
            0
        );
        assert_eq!(
            v["nodes"][2]["extensions"]["KHR_lights_punctual"]["light"],
            1
        );
        assert_eq!(warnings.len(), 2);
        assert!(warnings[0].starts_with("KHR_lights_punctual light 0: type 'area'"));
    }

    #[test]
    fn rotations_are_normalised_only_when_far_from_unit() {
        let mut v = json!({"nodes": [
            {"rotation": [1.0, 1.0, 1.0, 1.0], "name": "quad"},
            {"rotation": [0.0, 0.0, 0.0, 1.0000001]},
            {"matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1], "scale": [2, 2, 2]}
        ]});
        let mut warnings = Vec::new();
        node_transforms(v.as_object_mut().unwrap(), &mut warnings);
        assert_eq!(v["nodes"][0]["rotation"], json!([0.5, 0.5, 0.5, 0.5]));
        assert_eq!(v["nodes"][1]["rotation"], json!([0.0, 0.0, 0.0, 1.0000001]));
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(warnings[0].starts_with("node 0 ('quad'): rotation [1.0, 1.0, 1.0, 1.0] is not a unit quaternion (length 2)"), "{}", warnings[0]);
        assert!(
            warnings[1].starts_with("node 2: has both matrix and scale"),
            "{}",
            warnings[1]
        );
    }
}
