//! One primitive's vertices in world space: every attribute checked first, then read from its
//! accessor or the Draco stream, morphed (§3.7.2.2), and placed by the skin's joints (§3.7.3)
//! or by the node's transform, normals by its inverse transpose (§3.7.2.1).

use super::attributes;
use super::buffer::Buffer;
use super::draco;
use super::pose::{self, skin_vertices, Skinning};
use super::validate::{
    accessor_error, check_accessor, check_accessor_type, Expect, COLOR, JOINTS, MORPH_NORMAL,
    MORPH_POSITION, MORPH_TANGENT, NORMAL, POSITION, TANGENT, TEXCOORD, WEIGHTS,
};
use crate::scene::builder::place_vertices;
use crate::scene::error::{LoadErrorKind, PrimitiveAt};
use glam::{Mat4, Vec2, Vec3, Vec4};
use gltf::accessor::Dimensions;

/// One primitive's vertex data in world space.
pub(super) struct WorldVertices {
    pub(super) positions: Vec<Vec3>,
    pub(super) normals: Option<Vec<Vec3>>,
    pub(super) tangents: Option<Vec<Vec4>>,
    pub(super) uv0: Option<Vec<Vec2>>,
    pub(super) uv1: Option<Vec<Vec2>>,
    pub(super) colors: Option<Vec<Vec4>>,
    /// Placed by a skin's joints rather than by the node's world transform.
    pub(super) skinned: bool,
    /// Problems met while posing, for the scene's warnings.
    pub(super) warnings: Vec<String>,
}

/// How far a NORMAL's length may be from 1 before it is reported: `KHR_mesh_quantization`'s
/// normalized signed bytes put a unit vector within 0.7% of unit length (half of 1/127 on
/// each of three components), float exports within 1e-6; further than 1% the file did not
/// mean a unit vector (glTF 2.0 §3.7.2.1 requires one). The soup normalises every normal.
const NORMAL_LENGTH_TOLERANCE: f32 = 0.01;

/// A warning naming the primitive's NORMAL accessor when some of its normals (read from the
/// file, before morphing and placing) are not unit length.
fn not_unit_length(
    normals: &[Vec3],
    at: PrimitiveAt,
    primitive: &gltf::Primitive,
) -> Option<String> {
    let off = |n: &Vec3| !n.is_finite() || (n.length() - 1.0).abs() > NORMAL_LENGTH_TOLERANCE;
    let first = normals.iter().position(off)?;
    let count = normals.iter().filter(|n| off(n)).count();
    let accessor = primitive
        .get(&gltf::Semantic::Normals)
        .map_or(String::new(), |a| format!("accessor {} ", a.index()));
    Some(format!(
        "{at}: {accessor}(NORMAL): {count} of {} normals are not unit length (vertex {first} has length {}); they are normalised",
        normals.len(),
        normals[first].length()
    ))
}

/// How one mesh instance is deformed: its morph weights, and the skin of its node.
pub(super) struct Deform<'a> {
    /// One weight per morph target (§3.7.2.2), resolved for this node and pose.
    pub(super) weights: &'a [f32],
    /// The node's skin (index, joint matrices), if it has one.
    pub(super) skin: Option<(usize, &'a Skinning)>,
}

/// Reads vertex attributes from the file's buffers, each accessor checked first.
#[derive(Clone, Copy)]
pub(super) struct VertexReader<'a> {
    /// The file's buffers, their views checked against them.
    pub(super) buffers: &'a [Buffer<'a>],
    /// The file declares `KHR_mesh_quantization`: integer attribute types are allowed.
    pub(super) quantization: bool,
}

impl VertexReader<'_> {
    /// Reads (and transforms to world space) the attributes the soup uses. With `draco`, the
    /// attributes its extension maps come from the decoded stream, the others from their
    /// accessors.
    pub(super) fn read_vertices(
        &self,
        primitive: &gltf::Primitive,
        at: PrimitiveAt,
        world: Mat4,
        draco: Option<&draco::Decoded>,
        deform: &Deform,
    ) -> Result<WorldVertices, LoadErrorKind> {
        use gltf::Semantic;
        let (count, influence_sets) = self.check_attributes(primitive, at, draco, deform)?;

        // Each attribute is read straight into the type the soup keeps (the vectors of
        // [f32; N] become Vec3 and Vec2 in place); three-component colours get alpha 1.
        let read =
            |semantic: Semantic, expect: &Expect| -> Result<Option<Vec<Vec4>>, LoadErrorKind> {
                let three = primitive
                    .get(&semantic)
                    .is_some_and(|a| a.dimensions() == Dimensions::Vec3);
                Ok(if three {
                    self.read_attribute::<3>(primitive, at, draco, semantic, expect, count)?
                        .map(|v| {
                            v.into_iter()
                                .map(|[x, y, z]| Vec4::new(x, y, z, 1.0))
                                .collect()
                        })
                } else {
                    self.read_attribute::<4>(primitive, at, draco, semantic, expect, count)?
                        .map(|v| v.into_iter().map(Vec4::from).collect())
                })
            };
        let read3 =
            |semantic: Semantic, expect: &Expect| -> Result<Option<Vec<Vec3>>, LoadErrorKind> {
                Ok(self
                    .read_attribute::<3>(primitive, at, draco, semantic, expect, count)?
                    .map(|v| v.into_iter().map(Vec3::from).collect()))
            };
        let mut positions = read3(Semantic::Positions, &POSITION)?.unwrap_or_default();
        let mut normals = read3(Semantic::Normals, &NORMAL)?;
        let not_unit = normals
            .as_deref()
            .and_then(|n| not_unit_length(n, at, primitive));
        let mut tangents = read(Semantic::Tangents, &TANGENT)?;
        self.morph(
            primitive,
            at,
            deform.weights,
            &mut positions,
            normals.as_deref_mut(),
            tangents.as_deref_mut(),
        )?;
        let mut influences = Vec::with_capacity(influence_sets as usize);
        for set in 0..influence_sets {
            let joints = read(Semantic::Joints(set), &JOINTS)?.unwrap_or_default();
            let weights = read(Semantic::Weights(set), &WEIGHTS)?.unwrap_or_default();
            influences.push((joints, weights));
        }
        let (skinned, mut warnings) = place(
            world,
            deform.skin,
            &influences,
            at,
            &mut positions,
            normals.as_deref_mut(),
            tangents.as_deref_mut(),
        )?;
        let uv = |set: u32| -> Result<Option<Vec<Vec2>>, LoadErrorKind> {
            Ok(self
                .read_attribute::<2>(
                    primitive,
                    at,
                    draco,
                    Semantic::TexCoords(set),
                    &TEXCOORD,
                    count,
                )?
                .map(|v| v.into_iter().map(Vec2::from).collect()))
        };
        let uv0 = uv(0)?;
        let uv1 = uv(1)?;
        let colors = read(Semantic::Colors(0), &COLOR)?;
        warnings.extend(not_unit);
        Ok(WorldVertices {
            positions,
            normals,
            tangents,
            uv0,
            uv1,
            colors,
            skinned,
            warnings,
        })
    }

    /// Checks every attribute the soup uses before any is read: POSITION, then the optional
    /// ones (each against POSITION's count) and, with a skin, as many JOINTS_n/WEIGHTS_n sets
    /// as the file gives. Returns POSITION's count and the number of influence sets.
    fn check_attributes(
        &self,
        primitive: &gltf::Primitive,
        at: PrimitiveAt,
        draco: Option<&draco::Decoded>,
        deform: &Deform,
    ) -> Result<(usize, u32), LoadErrorKind> {
        use gltf::Semantic;
        let decoded = |semantic: &Semantic| draco.filter(|d| d.has(&semantic.to_string()));
        let check = |accessor: &gltf::Accessor,
                     semantic: &Semantic,
                     expect: &Expect|
         -> Result<(), LoadErrorKind> {
            match decoded(semantic) {
                // draco::decode checked count, type and componentType against the stream.
                Some(_) => check_accessor_type(accessor, at, expect, self.quantization),
                None => check_accessor(accessor, at, expect, self.quantization),
            }
        };
        let position_accessor = primitive
            .get(&Semantic::Positions)
            .ok_or(LoadErrorKind::MissingPositions { at })?;
        check(&position_accessor, &Semantic::Positions, &POSITION)?;
        let count = position_accessor.count();
        let optional = |semantic: Semantic, expect: &Expect| -> Result<(), LoadErrorKind> {
            match primitive.get(&semantic) {
                None => Ok(()),
                Some(accessor) => {
                    check(&accessor, &semantic, expect)?;
                    if accessor.count() != count {
                        return Err(LoadErrorKind::Accessor {
                            at,
                            accessor: accessor.index(),
                            semantic: expect.semantic.to_string(),
                            problem: format!(
                                "count {} differs from POSITION's {count}",
                                accessor.count()
                            ),
                        });
                    }
                    Ok(())
                }
            }
        };
        // Every attribute is checked before any is read.
        optional(Semantic::Normals, &NORMAL)?;
        optional(Semantic::Tangents, &TANGENT)?;
        optional(Semantic::TexCoords(0), &TEXCOORD)?;
        optional(Semantic::TexCoords(1), &TEXCOORD)?;
        optional(Semantic::Colors(0), &COLOR)?;
        // Skinning influences, as many sets as the file gives (JOINTS_0/WEIGHTS_0, _1...).
        let mut influence_sets = 0;
        if deform.skin.is_some() {
            while primitive.get(&Semantic::Joints(influence_sets)).is_some()
                && primitive.get(&Semantic::Weights(influence_sets)).is_some()
            {
                optional(Semantic::Joints(influence_sets), &JOINTS)?;
                optional(Semantic::Weights(influence_sets), &WEIGHTS)?;
                influence_sets += 1;
            }
        }
        Ok((count, influence_sets))
    }

    /// Attribute `semantic` of `primitive` as `count` elements of `N` components (its
    /// accessor already checked against `expect`), from the Draco stream where the extension
    /// maps it; `None` when the primitive does not have it.
    fn read_attribute<const N: usize>(
        &self,
        primitive: &gltf::Primitive,
        at: PrimitiveAt,
        draco: Option<&draco::Decoded>,
        semantic: gltf::Semantic,
        expect: &Expect,
        count: usize,
    ) -> Result<Option<Vec<[f32; N]>>, LoadErrorKind> {
        let Some(accessor) = primitive.get(&semantic) else {
            return Ok(None);
        };
        let normalized = expect.reads_normalized(accessor.normalized(), self.quantization);
        let fail = accessor_error(at, &accessor, expect);
        let name = semantic.to_string();
        let values = match draco.filter(|d| d.has(&name)) {
            Some(d) => d.read::<N>(&name, normalized),
            None => attributes::read::<N>(&accessor, self.buffers, normalized),
        }
        .map_err(&fail)?;
        if values.len() != count {
            return Err(fail(format!("read {} of {count} elements", values.len())));
        }
        Ok(Some(values))
    }

    /// Adds each morph target's deltas, times its weight, to the primitive's positions,
    /// normals and tangents in place (§3.7.2.2); targets of weight 0 are not read.
    fn morph(
        &self,
        primitive: &gltf::Primitive,
        at: PrimitiveAt,
        weights: &[f32],
        positions: &mut [Vec3],
        mut normals: Option<&mut [Vec3]>,
        mut tangents: Option<&mut [Vec4]>,
    ) -> Result<(), LoadErrorKind> {
        let count = positions.len();
        for (i, target) in primitive.morph_targets().enumerate() {
            let weight = weights.get(i).copied().unwrap_or(0.0);
            if weight == 0.0 || !weight.is_finite() {
                continue;
            }
            let read = |accessor: Option<gltf::Accessor>,
                        expect: &Expect|
             -> Result<Option<Vec<Vec3>>, LoadErrorKind> {
                let Some(accessor) = accessor else {
                    return Ok(None);
                };
                let fail = |problem: String| LoadErrorKind::Accessor {
                    at,
                    accessor: accessor.index(),
                    semantic: format!("targets[{i}].{}", expect.semantic),
                    problem,
                };
                check_accessor(&accessor, at, expect, self.quantization).map_err(|e| match e {
                    LoadErrorKind::Accessor { problem, .. } => fail(problem),
                    other => other,
                })?;
                if accessor.count() != count {
                    return Err(fail(format!(
                        "count {} differs from POSITION's {count}",
                        accessor.count()
                    )));
                }
                let values = attributes::read::<3>(&accessor, self.buffers, accessor.normalized())
                    .map_err(fail)?;
                Ok(Some(values.into_iter().map(Vec3::from).collect()))
            };
            if let Some(delta) = read(target.positions(), &MORPH_POSITION)? {
                pose::morph(positions, &delta, weight);
            }
            if let (Some(delta), Some(normals)) = (
                read(target.normals(), &MORPH_NORMAL)?,
                normals.as_deref_mut(),
            ) {
                pose::morph(normals, &delta, weight);
            }
            if let (Some(delta), Some(tangents)) = (
                read(target.tangents(), &MORPH_TANGENT)?,
                tangents.as_deref_mut(),
            ) {
                pose::morph_tangents(tangents, &delta, weight);
            }
        }
        Ok(())
    }
}

/// Places a primitive's vertices in world space: by the joints of the node's skin (§3.7.3) when
/// the primitive has influences for it, else by the node's transform `world`. Returns whether
/// they were skinned, and the problems met (a skin without influences, unweighted vertices).
fn place(
    world: Mat4,
    skin: Option<(usize, &Skinning)>,
    influences: &[(Vec<Vec4>, Vec<Vec4>)],
    at: PrimitiveAt,
    positions: &mut [Vec3],
    mut normals: Option<&mut [Vec3]>,
    mut tangents: Option<&mut [Vec4]>,
) -> Result<(bool, Vec<String>), LoadErrorKind> {
    let mut warnings = Vec::new();
    let skinned = match skin {
        Some((skin, skinning)) if !influences.is_empty() => {
            let unweighted = skin_vertices(
                skinning,
                influences,
                world,
                positions,
                normals.as_deref_mut(),
                tangents.as_deref_mut(),
            )
            .map_err(|problem| LoadErrorKind::Skin {
                skin,
                problem: format!("{at}: {problem}"),
            })?;
            if unweighted > 0 {
                warnings.push(format!(
                    "{at}: {unweighted} skinned vertices have no joint weight; they are placed by their node's transform"
                ));
            }
            true
        }
        Some((skin, _)) => {
            warnings.push(format!(
                "{at}: the node's skin {skin} has no JOINTS_0/WEIGHTS_0 to apply; drawn by the node's transform"
            ));
            false
        }
        None => false,
    };
    if !skinned {
        place_vertices(world, positions, normals, tangents);
    }
    Ok((skinned, warnings))
}
