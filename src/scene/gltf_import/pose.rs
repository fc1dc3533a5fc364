//! Poses: the node transforms and morph weights a glTF file is drawn with, at rest or at a time
//! of one of its animations, and the skinning and morphing of vertices by them.
//!
//! Conventions (glTF 2.0 specification):
//! - §3.11: an animation's channels target a node's `translation`, `rotation`, `scale` or
//!   `weights`; keyframe times (the sampler `input`) are seconds, strictly increasing. Before
//!   the first keyframe a channel holds its first value, after the last its last value (so a
//!   `--time` past the end shows the last keyframe).
//! - §3.11 / Appendix C: STEP holds a keyframe's value until the next; LINEAR interpolates
//!   linearly, rotations by spherical linear interpolation along the shorter arc; CUBICSPLINE
//!   stores (in-tangent, value, out-tangent) per keyframe and evaluates the cubic Hermite
//!   spline with the tangents scaled by the keyframe interval `t_{k+1} - t_k`. Rotations are
//!   normalised after interpolating.
//! - §3.7.3: a joint matrix is `globalTransform(joint) · inverseBindMatrix(joint)` (identity
//!   without `inverseBindMatrices`); a skinned vertex is `Σ w_i · jointMatrix_i · position` and
//!   is in world space: the transform of the node that instances the skinned mesh is ignored.
//!   Normals use the inverse transpose of each joint matrix.
//! - §3.7.2.2: a morphed attribute is `base + Σ weight_i · delta_i` (POSITION, NORMAL, TANGENT
//!   xyz); the weights are the mesh's `weights`, replaced by the node's `weights`, replaced by
//!   an animation's `weights` channel.

use super::attributes;
use super::buffer::Buffer;
use super::pointer::PointerChannel;
use crate::scene::pose::{choose_animation, AnimationInfo, PoseOptions};
use glam::{Mat3, Mat4, Quat, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};
use gltf::animation::{Interpolation, Property};

/// Keyframes of one animation channel: `values` holds `width` floats per output element (3 for
/// translation and scale, 4 for rotation, one per morph target for weights), three elements per
/// keyframe for CUBICSPLINE.
#[derive(Clone, Debug)]
pub(crate) struct Track {
    pub times: Vec<f32>,
    pub values: Vec<f32>,
    pub width: usize,
    pub interpolation: Interpolation,
    /// Quaternions: slerp for LINEAR, normalised after any interpolation.
    pub rotation: bool,
}

impl Track {
    /// Checks the keyframes: at least one, finite times that never decrease, and as many
    /// values as the interpolation needs. §3.11 asks for strictly increasing times; two equal
    /// neighbours (a jump) are tolerated, since sampling never divides by their zero interval
    /// (it picks the interval with `t_k <= t < t_{k+1}`).
    pub fn check(&self) -> Result<(), String> {
        if self.times.is_empty() {
            return Err("has no keyframes".to_string());
        }
        if let Some(i) = self.times.iter().position(|t| !t.is_finite()) {
            return Err(format!("keyframe time {i} is not finite"));
        }
        if let Some(i) = self.times.windows(2).position(|w| w[1] < w[0]) {
            return Err(format!(
                "keyframe times are not increasing: time {} ({}) comes after {}",
                i + 1,
                self.times[i + 1],
                self.times[i]
            ));
        }
        let per_key = if self.interpolation == Interpolation::CubicSpline {
            3
        } else {
            1
        };
        let expected = self.times.len() * per_key * self.width;
        if self.width == 0 || self.values.len() != expected {
            return Err(format!(
                "{} output values for {} keyframes of {} components ({:?}): expected {expected}",
                self.values.len(),
                self.times.len(),
                self.width,
                self.interpolation
            ));
        }
        Ok(())
    }

    /// What is wrong with keyframe times that [`Track::check`] lets through (§3.11 asks for
    /// times that are not negative and strictly increase): a negative time (the channel holds
    /// its first value until then, as sampling before the first key always does), or two
    /// equal times (a jump at that instant). `None` when the times are as the specification
    /// asks.
    pub fn odd_times(&self) -> Option<String> {
        if let Some(i) = self.times.iter().position(|t| *t < 0.0) {
            return Some(format!(
                "keyframe time {i} is negative ({} s); glTF times start at 0",
                self.times[i]
            ));
        }
        let i = self.times.windows(2).position(|w| w[1] == w[0])?;
        Some(format!(
            "keyframe times {i} and {} are equal ({} s); glTF times strictly increase",
            i + 1,
            self.times[i]
        ))
    }

    /// Element `e` (0..count) of the output, `width` floats.
    fn element(&self, e: usize) -> &[f32] {
        &self.values[e * self.width..(e + 1) * self.width]
    }

    /// The value at keyframe `k` (the middle element for CUBICSPLINE).
    fn key(&self, k: usize) -> &[f32] {
        match self.interpolation {
            Interpolation::CubicSpline => self.element(3 * k + 1),
            _ => self.element(k),
        }
    }

    /// The channel's value at `time` seconds, clamped to the first and last keyframes.
    /// Precondition: [`Track::check`] passed.
    pub fn sample(&self, time: f32) -> Vec<f32> {
        let last = self.times.len() - 1;
        if time <= self.times[0] {
            return self.finish(self.key(0).to_vec());
        }
        if time >= self.times[last] {
            return self.finish(self.key(last).to_vec());
        }
        // times[k] <= time < times[k + 1], so the interval is not empty.
        let k = self.times.partition_point(|&t| t <= time) - 1;
        let interval = self.times[k + 1] - self.times[k];
        let s = (time - self.times[k]) / interval;
        let value = match self.interpolation {
            Interpolation::Step => self.key(k).to_vec(),
            Interpolation::Linear if self.rotation => {
                let q = |v: &[f32]| Quat::from_xyzw(v[0], v[1], v[2], v[3]).normalize();
                q(self.key(k))
                    .slerp(q(self.key(k + 1)), s)
                    .to_array()
                    .to_vec()
            }
            Interpolation::Linear => {
                let (a, b) = (self.key(k), self.key(k + 1));
                a.iter().zip(b).map(|(a, b)| a + (b - a) * s).collect()
            }
            Interpolation::CubicSpline => {
                // Appendix C: p(s) = (2s³-3s²+1)·v_k + (s³-2s²+s)·Δt·b_k
                //                  + (-2s³+3s²)·v_{k+1} + (s³-s²)·Δt·a_{k+1},
                // b_k the out-tangent of key k, a_{k+1} the in-tangent of key k + 1.
                let (s2, s3) = (s * s, s * s * s);
                let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
                let h10 = (s3 - 2.0 * s2 + s) * interval;
                let h01 = -2.0 * s3 + 3.0 * s2;
                let h11 = (s3 - s2) * interval;
                let v0 = self.element(3 * k + 1);
                let b0 = self.element(3 * k + 2);
                let v1 = self.element(3 * (k + 1) + 1);
                let a1 = self.element(3 * (k + 1));
                (0..self.width)
                    .map(|i| h00 * v0[i] + h10 * b0[i] + h01 * v1[i] + h11 * a1[i])
                    .collect()
            }
        };
        self.finish(value)
    }

    /// Rotations come out as unit quaternions.
    fn finish(&self, mut value: Vec<f32>) -> Vec<f32> {
        if self.rotation {
            let q = Quat::from_slice(&value);
            let q = if q.length_squared() > 0.0 && q.is_finite() {
                q.normalize()
            } else {
                Quat::IDENTITY
            };
            value.copy_from_slice(&q.to_array());
        }
        value
    }

    /// The last keyframe time.
    pub fn end(&self) -> f32 {
        self.times.last().copied().unwrap_or(0.0)
    }
}

/// Refuses an accessor that is not of float `dims` (`what` names its use).
fn expect_float(accessor: &gltf::Accessor, dims: Dimensions, what: &str) -> Result<(), String> {
    if accessor.dimensions() == dims && accessor.data_type() == DataType::F32 {
        return Ok(());
    }
    Err(format!(
        "{what} accessor {} must be {dims:?} float, not {:?} {:?}",
        accessor.index(),
        accessor.dimensions(),
        accessor.data_type()
    ))
}

/// An animation sampler's keyframe times (`input`, which must be scalar floats).
pub(super) fn read_times(input: &gltf::Accessor, buffers: &[Buffer]) -> Result<Vec<f32>, String> {
    expect_float(input, Dimensions::Scalar, "input (keyframe times)")?;
    Ok(attributes::read::<1>(input, buffers, false)
        .map_err(|p| format!("input accessor {}: {p}", input.index()))?
        .into_iter()
        .map(|[t]| t)
        .collect())
}

/// An animation sampler's output numbers, element after element: scalars or vectors of 2 to
/// 4 (normalized integers mapped to floats); a matrix is refused.
pub(super) fn read_output(output: &gltf::Accessor, buffers: &[Buffer]) -> Result<Vec<f32>, String> {
    let normalized = output.normalized();
    let read_err = |p: String| format!("output accessor {}: {p}", output.index());
    Ok(match output.dimensions() {
        Dimensions::Scalar => attributes::read::<1>(output, buffers, normalized)
            .map_err(read_err)?
            .concat(),
        Dimensions::Vec2 => attributes::read::<2>(output, buffers, normalized)
            .map_err(read_err)?
            .concat(),
        Dimensions::Vec3 => attributes::read::<3>(output, buffers, normalized)
            .map_err(read_err)?
            .concat(),
        Dimensions::Vec4 => attributes::read::<4>(output, buffers, normalized)
            .map_err(read_err)?
            .concat(),
        other => {
            return Err(format!(
                "output accessor {}: {other:?} is no animatable value",
                output.index()
            ))
        }
    })
}

/// Reads one channel's keyframes, checked (`buffers` after the importer's view checks).
pub(crate) fn read_track(
    channel: &gltf::animation::Channel,
    buffers: &[Buffer],
    morph_targets: usize,
) -> Result<Track, String> {
    let sampler = channel.sampler();
    let times = read_times(&sampler.input(), buffers)?;
    let property = channel.target().property();
    let (dims, width, rotation) = match property {
        Property::Translation | Property::Scale => (Dimensions::Vec3, 3, false),
        Property::Rotation => (Dimensions::Vec4, 4, true),
        Property::MorphTargetWeights => (Dimensions::Scalar, morph_targets, false),
    };
    let output = sampler.output();
    // §3.11: translation and scale are float; rotation and weights float or normalized
    // integers (KHR_mesh_quantization widens the same list).
    let integer_allowed = matches!(property, Property::Rotation | Property::MorphTargetWeights);
    let type_ok = output.data_type() == DataType::F32
        || (integer_allowed && output.normalized() && output.data_type() != DataType::U32);
    if output.dimensions() != dims || !type_ok {
        return Err(format!(
            "output accessor {}: {property:?} must be {dims:?} float{}, not {:?} {}{:?}",
            output.index(),
            if integer_allowed {
                " or normalized integer"
            } else {
                ""
            },
            output.dimensions(),
            if output.normalized() {
                "normalized "
            } else {
                ""
            },
            output.data_type()
        ));
    }
    let values = read_output(&output, buffers)?;
    let track = Track {
        times,
        values,
        width,
        interpolation: sampler.interpolation(),
        rotation,
    };
    track
        .check()
        .map_err(|p| format!("sampler {}: {p}", sampler.index()))?;
    Ok(track)
}

/// Every node's local transform and morph weights in the chosen pose.
#[derive(Clone, Debug, Default)]
pub(crate) struct Pose {
    /// Local transform of each node (glTF 2.0 §3.5.3: `matrix` or T·R·S).
    pub local: Vec<Mat4>,
    /// Morph weights set by the node or by the animation; `None`: the mesh's defaults.
    pub weights: Vec<Option<Vec<f32>>>,
    /// The animation sampled and when, for `info` and the render summary
    /// ("animation 1 'Walk' at 0.2 s"); `None` for the static pose.
    pub description: Option<String>,
}

impl Pose {
    /// The static pose: the nodes' own transforms and weights.
    pub fn rest(document: &gltf::Document) -> Pose {
        Pose {
            local: document
                .nodes()
                .map(|n| Mat4::from_cols_array_2d(&n.transform().matrix()))
                .collect(),
            weights: document
                .nodes()
                .map(|n| n.weights().map(<[f32]>::to_vec))
                .collect(),
            description: None,
        }
    }

    /// The morph weights of `node` drawing `mesh` with `targets` morph targets, resolved as
    /// §3.7.2.2 says, padded with zeros or cut to `targets` (a mismatch is reported in
    /// `warnings`, for each instance of the node).
    pub fn morph_weights(
        &self,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
        targets: usize,
        warnings: &mut Vec<String>,
    ) -> Vec<f32> {
        let given = self
            .weights
            .get(node.index())
            .and_then(Option::as_deref)
            .or(mesh.weights())
            .unwrap_or(&[]);
        if !given.is_empty() && given.len() != targets {
            warnings.push(format!(
                "node {} (mesh {}): {} morph weights for {targets} morph targets; missing ones are 0, extra ones ignored",
                node.index(),
                mesh.index(),
                given.len()
            ));
        }
        let mut weights: Vec<f32> = given.iter().take(targets).copied().collect();
        weights.resize(targets, 0.0);
        weights
    }

    /// World transform of every node (parent · child), following the node hierarchy from
    /// each node up (a node with several parents, which glTF forbids, takes its first).
    pub fn world(&self, document: &gltf::Document) -> Result<Vec<Mat4>, usize> {
        let count = self.local.len();
        let mut parent = vec![None; count];
        for node in document.nodes() {
            for child in node.children() {
                if let Some(slot) = parent.get_mut(child.index()) {
                    slot.get_or_insert(node.index());
                }
            }
        }
        let mut world: Vec<Option<Mat4>> = vec![None; count];
        for start in 0..count {
            // The chain from `start` up to the first node whose world is known (or a root).
            let mut chain = vec![start];
            while let Some(p) = parent[*chain.last().unwrap_or(&start)] {
                if world[p].is_some() {
                    break;
                }
                if chain.len() > count {
                    return Err(start);
                }
                chain.push(p);
            }
            for &n in chain.iter().rev() {
                if world[n].is_some() {
                    continue;
                }
                let above = parent[n].and_then(|p| world[p]).unwrap_or(Mat4::IDENTITY);
                world[n] = Some(above * self.local[n]);
            }
        }
        Ok(world
            .into_iter()
            .map(|m| m.unwrap_or(Mat4::IDENTITY))
            .collect())
    }
}

/// What the `gltf` crate indexes without checking (gltf-json 1.4 validates an animation's
/// samplers but not its channels' targets): each channel's node must exist and its `path`
/// be one of the four properties. Checked on the JSON before the crate sees it.
pub(crate) fn check_channel_targets(root: &gltf::json::Root) -> Result<(), String> {
    use gltf::json::validation::Checked;
    let nodes = root.nodes.len();
    for (a, animation) in root.animations.iter().enumerate() {
        for (c, channel) in animation.channels.iter().enumerate() {
            let node = channel.target.node.value();
            if node >= nodes {
                return Err(format!(
                    "animations[{a}].channels[{c}] targets node {node}, but the file has {nodes}"
                ));
            }
            if matches!(channel.target.path, Checked::Invalid) {
                return Err(format!(
                    "animations[{a}].channels[{c}]: target path is not translation, rotation, scale or weights"
                ));
            }
        }
    }
    Ok(())
}

/// Lists the file's animations; broken ones are listed with the problem in `warnings` (they
/// stop the load only when chosen).
pub(crate) fn list_animations(
    document: &gltf::Document,
    buffers: &[Buffer],
    pointer_channels: &[Vec<PointerChannel>],
    warnings: &mut Vec<String>,
) -> Vec<AnimationInfo> {
    document
        .animations()
        .map(|animation| {
            let pointers = pointer_channels
                .get(animation.index())
                .map_or(&[][..], Vec::as_slice);
            let mut duration = super::pointer::duration(&animation, pointers, buffers, warnings);
            for channel in animation.channels() {
                match read_track(&channel, buffers, targets_of(&channel.target().node())) {
                    Ok(track) => {
                        duration = duration.max(track.end());
                        if let Some(problem) = track.odd_times() {
                            warnings.push(format!(
                                "animation {} channel {}: {problem}",
                                animation.index(),
                                channel.index()
                            ));
                        }
                    }
                    Err(problem) => {
                        warnings.push(format!(
                            "animation {} channel {}: {problem}",
                            animation.index(),
                            channel.index()
                        ));
                        break;
                    }
                }
            }
            AnimationInfo {
                index: animation.index(),
                name: animation.name().map(str::to_string),
                duration,
                channels: animation.channels().count() + pointers.len(),
            }
        })
        .collect()
}

/// Morph targets of the node's mesh (its first primitive's; §3.7.2.2 requires all primitives
/// of a mesh to have the same number).
fn targets_of(node: &gltf::Node) -> usize {
    node.mesh()
        .and_then(|m| m.primitives().next())
        .map_or(0, |p| p.morph_targets().len())
}

/// The pose `options` ask for: the rest pose, or animation `options.animation` sampled at
/// `options.time` (missing parts default to animation 0 and time 0). Its
/// `KHR_animation_pointer` channels are in `document` already ([`super::pointer::animate`]).
pub(crate) fn pose(
    document: &gltf::Document,
    buffers: &[Buffer],
    animations: &[AnimationInfo],
    options: &PoseOptions,
) -> Result<Pose, String> {
    let mut pose = Pose::rest(document);
    if !options.animates() {
        return Ok(pose);
    }
    options.check()?;
    let index = choose_animation(animations, options.animation.as_deref())?;
    let Some(animation) = document.animations().nth(index) else {
        return Err(format!("no animation {index}"));
    };
    let time = options.time.unwrap_or(0.0);
    let mut trs: Vec<Option<(Vec3, Quat, Vec3)>> = vec![None; pose.local.len()];
    for channel in animation.channels() {
        let node = channel.target().node();
        let targets = targets_of(&node);
        if channel.target().property() == Property::MorphTargetWeights && targets == 0 {
            return Err(format!(
                "animation {index} channel {}: animates the weights of node {}, which has no morph targets",
                channel.index(),
                node.index()
            ));
        }
        let track = read_track(&channel, buffers, targets)
            .map_err(|p| format!("animation {index} channel {}: {p}", channel.index()))?;
        let value = track.sample(time);
        let n = node.index();
        let (t, r, s) = trs[n].get_or_insert_with(|| {
            let (t, r, s) = node.transform().decomposed();
            (Vec3::from(t), Quat::from_array(r), Vec3::from(s))
        });
        match channel.target().property() {
            Property::Translation => *t = Vec3::from_slice(&value),
            Property::Rotation => *r = Quat::from_slice(&value),
            Property::Scale => *s = Vec3::from_slice(&value),
            Property::MorphTargetWeights => pose.weights[n] = Some(value),
        }
    }
    for (n, trs) in trs.into_iter().enumerate() {
        if let Some((t, r, s)) = trs {
            pose.local[n] = Mat4::from_scale_rotation_translation(s, r, t);
        }
    }
    let label = animations
        .get(index)
        .map_or_else(|| index.to_string(), AnimationInfo::label);
    let end = animations.get(index).map_or(0.0, |a| a.duration);
    let description = if time > end {
        format!("animation {label} at {time} s (past its end at {end} s: its last keyframes)")
    } else {
        format!("animation {label} at {time} s")
    };
    pose.description = Some(description);
    Ok(pose)
}

/// Inverse bind matrices of a skin, one per joint (identity without the accessor, §3.7.3).
pub(crate) fn inverse_bind_matrices(
    skin: &gltf::Skin,
    buffers: &[Buffer],
) -> Result<Vec<Mat4>, String> {
    let joints = skin.joints().count();
    let Some(accessor) = skin.inverse_bind_matrices() else {
        return Ok(vec![Mat4::IDENTITY; joints]);
    };
    expect_float(&accessor, Dimensions::Mat4, "inverseBindMatrices")?;
    if accessor.count() < joints {
        return Err(format!(
            "inverseBindMatrices accessor {} has {} matrices for {joints} joints",
            accessor.index(),
            accessor.count()
        ));
    }
    let matrices = attributes::read::<16>(&accessor, buffers, false)
        .map_err(|p| format!("inverseBindMatrices accessor {}: {p}", accessor.index()))?;
    Ok(matrices
        .iter()
        .take(joints)
        .map(Mat4::from_cols_array)
        .collect())
}

/// The joint matrices of one skin in one pose, with their normal matrices.
#[derive(Clone, Debug)]
pub(crate) struct Skinning {
    /// `globalTransform(joint) · inverseBindMatrix(joint)` per joint.
    pub joints: Vec<Mat4>,
    /// Inverse transpose of each joint matrix's upper 3×3, for normals.
    pub normals: Vec<Mat3>,
}

/// Below this weight sum a vertex has no influence to normalise (weights are stored in as
/// few as 8 bits: 1/255 ≈ 0.004 is the smallest non-zero one).
const MIN_WEIGHT_SUM: f32 = 1e-6;

impl Skinning {
    /// Joint matrices from the joints' world transforms and their inverse bind matrices.
    pub fn new(world_of_joints: &[Mat4], inverse_bind: &[Mat4]) -> Skinning {
        let joints: Vec<Mat4> = world_of_joints
            .iter()
            .zip(inverse_bind)
            .map(|(world, inverse)| *world * *inverse)
            .collect();
        let normals = joints
            .iter()
            .map(|m| {
                let linear = Mat3::from_mat4(*m);
                if linear.determinant() == 0.0 {
                    linear
                } else {
                    linear.inverse().transpose()
                }
            })
            .collect();
        Skinning { joints, normals }
    }

    /// The blended matrix of one vertex from its influences (joint, weight), the weights
    /// normalised to sum to 1. `None` when the weights sum to nothing; `Err(joint)` when a
    /// joint with a non-zero weight is out of range.
    pub fn blend(&self, influences: &[(f32, f32)]) -> Result<Option<(Mat4, Mat3)>, f32> {
        let sum: f32 = influences.iter().map(|&(_, w)| w).sum();
        if !(sum.is_finite() && sum > MIN_WEIGHT_SUM) {
            return Ok(None);
        }
        let mut position = Mat4::ZERO;
        let mut normal = Mat3::ZERO;
        for &(joint, weight) in influences {
            if weight == 0.0 {
                continue;
            }
            let j = joint as usize;
            let (Some(m), Some(n)) = (self.joints.get(j), self.normals.get(j)) else {
                return Err(joint);
            };
            let w = weight / sum;
            position += *m * w;
            normal += *n * w;
        }
        Ok(Some((position, normal)))
    }
}

/// Adds `weight · delta` to each value (§3.7.2.2).
pub(crate) fn morph(values: &mut [Vec3], delta: &[Vec3], weight: f32) {
    for (v, d) in values.iter_mut().zip(delta) {
        *v += *d * weight;
    }
}

/// Adds `weight · delta` to the xyz of each tangent (morph targets leave handedness alone).
pub(crate) fn morph_tangents(values: &mut [Vec4], delta: &[Vec3], weight: f32) {
    for (v, d) in values.iter_mut().zip(delta) {
        *v += (*d * weight).extend(0.0);
    }
}

/// Skins vertices in place to world space (§3.7.3): each position by the weighted sum of its
/// joints' matrices, each normal by the weighted sum of their inverse transposes, each
/// tangent's xyz by the matrices' linear part. `influences` holds each JOINTS_n/WEIGHTS_n set
/// as read (joint indices as floats). A vertex whose weights sum to nothing is placed by
/// `world` instead; returns how many were.
pub(super) fn skin_vertices(
    skinning: &Skinning,
    influences: &[(Vec<Vec4>, Vec<Vec4>)],
    world: Mat4,
    positions: &mut [Vec3],
    mut normals: Option<&mut [Vec3]>,
    mut tangents: Option<&mut [Vec4]>,
) -> Result<usize, String> {
    let mut unweighted = 0;
    let mut pairs = Vec::with_capacity(4 * influences.len());
    for (v, position) in positions.iter_mut().enumerate() {
        pairs.clear();
        for (joints, weights) in influences {
            if let (Some(j), Some(w)) = (joints.get(v), weights.get(v)) {
                pairs.extend(j.to_array().into_iter().zip(w.to_array()));
            }
        }
        let (matrix, normal_matrix) = match skinning.blend(&pairs) {
            Ok(Some(blend)) => blend,
            Ok(None) => {
                unweighted += 1;
                (world, Mat3::from_mat4(world).inverse().transpose())
            }
            Err(joint) => {
                return Err(format!(
                    "vertex {v} has weight on joint {joint}, but the skin has {} joints",
                    skinning.joints.len()
                ))
            }
        };
        *position = matrix.transform_point3(*position);
        if let Some(n) = normals.as_deref_mut().and_then(|n| n.get_mut(v)) {
            *n = normal_matrix * *n;
        }
        if let Some(t) = tangents.as_deref_mut().and_then(|t| t.get_mut(v)) {
            let xyz = (Mat3::from_mat4(matrix) * t.truncate()).normalize_or_zero();
            *t = xyz.extend(t.w);
        }
    }
    Ok(unweighted)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::FRAC_PI_2;

    fn track(times: &[f32], values: &[f32], width: usize, interpolation: Interpolation) -> Track {
        let t = Track {
            times: times.to_vec(),
            values: values.to_vec(),
            width,
            interpolation,
            rotation: false,
        };
        t.check().expect("a valid track");
        t
    }

    fn close(a: &[f32], b: &[f32]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-5)
    }

    #[test]
    fn step_holds_each_key_until_the_next() {
        let t = track(
            &[0.0, 1.0, 2.0],
            &[10.0, 20.0, 30.0],
            1,
            Interpolation::Step,
        );
        assert_eq!(t.sample(0.0), [10.0]);
        assert_eq!(t.sample(0.999), [10.0]);
        assert_eq!(t.sample(1.0), [20.0]);
        assert_eq!(t.sample(1.5), [20.0]);
        assert_eq!(t.sample(2.0), [30.0]);
    }

    #[test]
    fn linear_interpolates_and_clamps_before_and_after() {
        let t = track(
            &[1.0, 3.0],
            &[0.0, 0.0, 0.0, 4.0, -2.0, 8.0],
            3,
            Interpolation::Linear,
        );
        assert_eq!(t.sample(1.0), [0.0, 0.0, 0.0]);
        assert!(close(&t.sample(2.0), &[2.0, -1.0, 4.0]));
        assert!(close(&t.sample(2.5), &[3.0, -1.5, 6.0]));
        // Before the first keyframe: the first value; after the last: the last.
        assert_eq!(t.sample(0.0), [0.0, 0.0, 0.0]);
        assert_eq!(t.sample(3.0), [4.0, -2.0, 8.0]);
        assert_eq!(t.sample(100.0), [4.0, -2.0, 8.0]);
        // Two keys at the same time make a jump, without a zero-length interval to divide by.
        let jump = track(
            &[0.0, 1.0, 1.0, 2.0],
            &[0.0, 0.0, 5.0, 5.0],
            1,
            Interpolation::Linear,
        );
        assert_eq!(jump.sample(0.5), [0.0]);
        assert_eq!(jump.sample(1.0), [5.0]);
        assert_eq!(jump.sample(1.5), [5.0]);
    }

    #[test]
    fn cubic_spline_hits_the_keys_and_scales_tangents_by_the_interval() {
        // Keys (t, value): (0, 0) and (2, 1), out-tangent of key 0 = in-tangent of key 1 = 0.5
        // per second. The interval is 2 s, so the Hermite tangents are 1: the curve is the
        // straight line p(s) = s (h10 + h11 + h01 = s³-2s²+s + s³-s² - 2s³+3s² = s).
        let values = [9.0, 0.0, 0.5, 0.5, 1.0, 9.0];
        let t = track(&[0.0, 2.0], &values, 1, Interpolation::CubicSpline);
        assert_eq!(t.sample(0.0), [0.0]);
        assert_eq!(t.sample(2.0), [1.0]);
        assert!(close(&t.sample(0.5), &[0.25]));
        assert!(close(&t.sample(1.0), &[0.5]));
        // The in-tangent of the first key and the out-tangent of the last are never used.
        assert_eq!(t.sample(-1.0), [0.0]);
        assert_eq!(t.sample(5.0), [1.0]);
        // Zero tangents: the smoothstep 3s² - 2s³, at s = 0.25: 0.15625.
        let flat = track(
            &[0.0, 2.0],
            &[0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
            1,
            Interpolation::CubicSpline,
        );
        assert!(close(&flat.sample(0.5), &[0.15625]));
    }

    #[test]
    fn rotations_slerp_along_the_short_arc_and_come_out_unit() {
        let a = Quat::IDENTITY;
        // -q is the same rotation as q: +90° about Y stored with a negative w.
        let b = -Quat::from_rotation_y(FRAC_PI_2);
        let mut values = a.to_array().to_vec();
        values.extend(b.to_array());
        let mut t = track(&[0.0, 1.0], &values, 4, Interpolation::Linear);
        t.rotation = true;
        let half = Quat::from_slice(&t.sample(0.5));
        // The short way is +45° about Y, not -135°.
        let expected = Quat::from_rotation_y(FRAC_PI_2 / 2.0);
        assert!(
            half.dot(expected).abs() > 1.0 - 1e-5,
            "{half:?} vs {expected:?}"
        );
        assert!((half.length() - 1.0).abs() < 1e-6);
        // A cubic spline through unnormalised keys is normalised.
        let mut c = track(
            &[0.0, 1.0],
            &[
                0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0,
            ],
            4,
            Interpolation::CubicSpline,
        );
        c.rotation = true;
        assert!(close(&c.sample(0.3), &[0.0, 0.0, 0.0, 1.0]));
    }

    #[test]
    fn bad_keyframes_are_refused() {
        let bad = |times: &[f32], values: &[f32], i| {
            Track {
                times: times.to_vec(),
                values: values.to_vec(),
                width: 1,
                interpolation: i,
                rotation: false,
            }
            .check()
            .unwrap_err()
        };
        assert!(bad(&[0.0, 2.0, 1.0], &[0.0; 3], Interpolation::Linear).contains("not increasing"));
        assert!(bad(&[0.0, f32::NAN], &[0.0; 2], Interpolation::Linear).contains("not finite"));
        assert!(bad(&[], &[], Interpolation::Step).contains("no keyframes"));
        // CUBICSPLINE needs three values per keyframe.
        assert!(bad(&[0.0, 1.0], &[0.0; 2], Interpolation::CubicSpline).contains("expected 6"));
    }

    #[test]
    fn skinning_blends_joint_matrices_with_normalised_weights() {
        // Joint 0 at rest; joint 1 rotated +90° about Z around the point (1, 0, 0).
        let pivot = Mat4::from_translation(Vec3::X);
        let rotated = pivot * Mat4::from_rotation_z(FRAC_PI_2);
        let skinning = Skinning::new(
            &[Mat4::IDENTITY, rotated],
            &[Mat4::IDENTITY, pivot.inverse()],
        );
        // A vertex at (2, 0, 0) bound fully to joint 1 swings to (1, 1, 0).
        let (m, n) = skinning.blend(&[(1.0, 1.0), (0.0, 0.0)]).unwrap().unwrap();
        let p = m.transform_point3(Vec3::new(2.0, 0.0, 0.0));
        assert!((p - Vec3::new(1.0, 1.0, 0.0)).length() < 1e-5, "{p}");
        // Its normal +X turns to +Y.
        assert!((n * Vec3::X - Vec3::Y).length() < 1e-5);
        // Weights 2 and 2 count as 0.5 and 0.5: halfway between (2,0,0) and (1,1,0).
        let (m, _) = skinning.blend(&[(0.0, 2.0), (1.0, 2.0)]).unwrap().unwrap();
        let p = m.transform_point3(Vec3::new(2.0, 0.0, 0.0));
        assert!((p - Vec3::new(1.5, 0.5, 0.0)).length() < 1e-5, "{p}");
        // No weight: nothing to blend; a weighted joint past the skin's list is reported.
        assert!(skinning.blend(&[(0.0, 0.0)]).unwrap().is_none());
        assert_eq!(skinning.blend(&[(5.0, 1.0)]).unwrap_err(), 5.0);
        // A joint past the list with weight 0 is harmless padding.
        assert!(skinning.blend(&[(0.0, 1.0), (9.0, 0.0)]).is_ok());
    }

    #[test]
    fn animations_are_chosen_by_name_then_index_with_a_listing_error() {
        let list = vec![
            AnimationInfo {
                index: 0,
                name: Some("Survey".into()),
                duration: 3.4,
                channels: 24,
            },
            AnimationInfo {
                index: 1,
                name: Some("Walk".into()),
                duration: 0.7,
                channels: 24,
            },
        ];
        assert_eq!(choose_animation(&list, Some("Walk")), Ok(1));
        assert_eq!(choose_animation(&list, Some("1")), Ok(1));
        assert_eq!(choose_animation(&list, None), Ok(0));
        let e = choose_animation(&list, Some("Run")).unwrap_err();
        assert!(
            e.contains("'Run'") && e.contains("0 'Survey'") && e.contains("1 'Walk'"),
            "{e}"
        );
        assert!(choose_animation(&list, Some("2")).is_err());
        assert!(choose_animation(&[], None)
            .unwrap_err()
            .contains("no animations"));
    }

    #[test]
    fn morph_adds_weighted_deltas() {
        let mut p = vec![Vec3::ZERO, Vec3::ONE];
        morph(&mut p, &[Vec3::Y, Vec3::X], 0.5);
        assert_eq!(p, vec![Vec3::new(0.0, 0.5, 0.0), Vec3::new(1.5, 1.0, 1.0)]);
        let mut t = vec![Vec4::new(1.0, 0.0, 0.0, -1.0)];
        morph_tangents(&mut t, &[Vec3::Y], 2.0);
        assert_eq!(t, vec![Vec4::new(1.0, 2.0, 0.0, -1.0)]);
    }

    /// Influences come from every JOINTS_n/WEIGHTS_n set: here set 1 carries the weight of
    /// vertex 0, and vertex 1 has none at all and is placed by the node's transform.
    #[test]
    fn skinning_reads_every_influence_set_and_places_unweighted_vertices_by_the_node() {
        let lift = Mat4::from_translation(Vec3::Y);
        let skinning = Skinning::new(&[Mat4::IDENTITY, lift], &[Mat4::IDENTITY; 2]);
        let set0 = (vec![Vec4::ZERO; 2], vec![Vec4::ZERO; 2]);
        let set1 = (
            vec![Vec4::new(1.0, 0.0, 0.0, 0.0), Vec4::ZERO],
            vec![Vec4::new(1.0, 0.0, 0.0, 0.0), Vec4::ZERO],
        );
        let node = Mat4::from_translation(Vec3::new(0.0, 0.0, 5.0));
        let mut positions = vec![Vec3::X, Vec3::X];
        let mut normals = vec![Vec3::Z, Vec3::Z];
        let unweighted = skin_vertices(
            &skinning,
            &[set0, set1],
            node,
            &mut positions,
            Some(&mut normals),
            None,
        )
        .unwrap();
        assert_eq!(unweighted, 1);
        assert_eq!(
            positions,
            vec![Vec3::new(1.0, 1.0, 0.0), Vec3::new(1.0, 0.0, 5.0)]
        );
        assert_eq!(normals, vec![Vec3::Z, Vec3::Z]);
        // A weighted joint past the skin's two is refused, naming the vertex and the joint.
        let bad = (vec![Vec4::splat(2.0)], vec![Vec4::new(1.0, 0.0, 0.0, 0.0)]);
        let mut one = vec![Vec3::ZERO];
        let message = skin_vertices(&skinning, &[bad], node, &mut one, None, None).unwrap_err();
        assert!(
            message.contains("vertex 0") && message.contains("joint 2"),
            "{message}"
        );
    }
}
