//! The linear scan: every triangle, every ray. O(n) per ray, and obviously correct.

use super::{Accel, Accept, Closest};
use crate::geometry::Ray;

#[inline(always)]
pub(super) fn closest(accel: &Accel, ray: &Ray, accept: Option<&Accept>) -> Option<Closest> {
    let mut best = None;
    for slot in 0..accel.triangles.len() {
        let t = accel.test(slot, ray, true, accept);
        if t < f32::INFINITY {
            Closest::offer(&mut best, t, slot, &accel.ids);
        }
    }
    best
}

#[inline(always)]
pub(super) fn occluded(accel: &Accel, ray: &Ray, accept: Option<&Accept>) -> bool {
    (0..accel.triangles.len()).any(|slot| accel.test(slot, ray, false, accept) < f32::INFINITY)
}
