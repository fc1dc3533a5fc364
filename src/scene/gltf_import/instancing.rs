//! `EXT_mesh_gpu_instancing`: a node's mesh drawn once per instance, each instance placed by
//! the node's world transform times its own T·R·S, read from the extension's TRANSLATION,
//! ROTATION and SCALE attributes (each optional; absent ones are the identity). glTF-Transform's
//! `optimize` writes it for meshes reused often, and Blender's exporter can.

use super::attributes;
use super::buffer::Buffer;
use crate::scene::error::LoadErrorKind;
use glam::{Mat4, Quat, Vec3};
use gltf::accessor::{DataType, Dimensions};

/// The extension's name.
pub(super) const EXTENSION: &str = "EXT_mesh_gpu_instancing";

/// The instances' local transforms (T·R·S) of `node`, or `None` without the extension. Each
/// attribute must be the type the extension allows: TRANSLATION and SCALE VEC3 float, ROTATION
/// VEC4 float or normalized byte or short (with `KHR_mesh_quantization` declared,
/// `quantization`, TRANSLATION and SCALE may also be byte or short, normalized or not), and all
/// must have the same count. A transform that is not finite is kept; the walk skips it as it
/// skips a singular node.
pub(super) fn transforms(
    node: &gltf::Node,
    document: &gltf::Document,
    buffers: &[Buffer],
    quantization: bool,
) -> Result<Option<Vec<Mat4>>, LoadErrorKind> {
    let Some(extension) = node.extension_value(EXTENSION) else {
        return Ok(None);
    };
    let fail = |problem: String| LoadErrorKind::Instancing {
        node: node.index(),
        problem,
    };
    let attributes = extension
        .get("attributes")
        .and_then(|a| a.as_object())
        .ok_or_else(|| fail("has no attributes object".to_string()))?;
    let accessor = |name: &str| -> Result<Option<gltf::Accessor>, LoadErrorKind> {
        let Some(value) = attributes.get(name) else {
            return Ok(None);
        };
        let index = value
            .as_u64()
            .and_then(|i| usize::try_from(i).ok())
            .ok_or_else(|| fail(format!("{name} is not an accessor index: {value}")))?;
        document.accessors().nth(index).map(Some).ok_or_else(|| {
            fail(format!(
                "{name} names accessor {index}, which does not exist"
            ))
        })
    };
    let translation = accessor("TRANSLATION")?;
    let rotation = accessor("ROTATION")?;
    let scale = accessor("SCALE")?;
    let counts: Vec<(&str, usize)> = [
        ("TRANSLATION", &translation),
        ("ROTATION", &rotation),
        ("SCALE", &scale),
    ]
    .into_iter()
    .filter_map(|(name, a)| a.as_ref().map(|a| (name, a.count())))
    .collect();
    let Some(&(_, count)) = counts.first() else {
        return Err(fail(
            "names none of TRANSLATION, ROTATION and SCALE".to_string(),
        ));
    };
    if let Some((name, other)) = counts.iter().find(|(_, c)| *c != count) {
        return Err(fail(format!(
            "{name} has {other} instances where {} has {count}",
            counts[0].0
        )));
    }
    let read = |name: &str, a: &gltf::Accessor, dims: Dimensions, rotation: bool| {
        let data_type = a.data_type();
        let allowed = data_type == DataType::F32
            || (matches!(data_type, DataType::I8 | DataType::I16)
                && (a.normalized() || (quantization && !rotation)))
            || (quantization && !rotation && matches!(data_type, DataType::U8 | DataType::U16));
        if a.dimensions() != dims || !allowed {
            return Err(fail(format!(
                "{name} accessor {} is {:?} {}{:?}, which the extension does not allow",
                a.index(),
                a.dimensions(),
                if a.normalized() { "normalized " } else { "" },
                data_type
            )));
        }
        let problem = |p: String| fail(format!("{name} accessor {}: {p}", a.index()));
        match dims {
            Dimensions::Vec4 => attributes::read::<4>(a, buffers, a.normalized()).map_err(problem),
            _ => attributes::read::<3>(a, buffers, a.normalized())
                .map_err(problem)
                .map(|v| v.into_iter().map(|[x, y, z]| [x, y, z, 0.0]).collect()),
        }
    };
    let t = match &translation {
        Some(a) => Some(read("TRANSLATION", a, Dimensions::Vec3, false)?),
        None => None,
    };
    let r = match &rotation {
        Some(a) => Some(read("ROTATION", a, Dimensions::Vec4, true)?),
        None => None,
    };
    let s = match &scale {
        Some(a) => Some(read("SCALE", a, Dimensions::Vec3, false)?),
        None => None,
    };
    let at = |v: &Option<Vec<[f32; 4]>>, i: usize| v.as_ref().and_then(|v| v.get(i)).copied();
    Ok(Some(
        (0..count)
            .map(|i| {
                let translation = at(&t, i).map_or(Vec3::ZERO, |[x, y, z, _]| Vec3::new(x, y, z));
                // A quaternion that is not unit (quantised ones are not, exactly) is normalised,
                // as node rotations are.
                let rotation = at(&r, i).map_or(Quat::IDENTITY, |[x, y, z, w]| {
                    Quat::from_xyzw(x, y, z, w).normalize()
                });
                let scale = at(&s, i).map_or(Vec3::ONE, |[x, y, z, _]| Vec3::new(x, y, z));
                Mat4::from_scale_rotation_translation(scale, rotation, translation)
            })
            .collect(),
    ))
}
