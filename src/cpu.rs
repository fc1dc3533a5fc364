//! What this CPU can run: the hot ray queries, texture lookups and the render's tile loop (with
//! the integrator's per-vertex shading inlined into it) are compiled twice, once for the
//! baseline x86-64 every build targets and once for x86-64-v3 (AVX2, FMA, BMI, POPCNT,
//! SSE4.1), and the second is taken when the CPU has those instructions.
//!
//! Why: the baseline has no `popcnt` (the wide BVH counts hit bits on every node visited) and
//! no `roundss` (every texture tap floors its coordinates through a libm call). A whole binary
//! built with `-C target-cpu=native` traced 10-35% more rays a second (README, "Benchmarks"),
//! but such a binary dies with an illegal instruction on older CPUs and on virtual machines
//! that hide AVX. Runtime dispatch keeps one binary for every x86-64 machine; the two copies
//! here gave DamagedHelmet about 16% more rays a second on one thread. The shading gains less
//! from any single instruction than from VEX's three-operand forms (SSE's two-operand ones
//! copy a register before most arithmetic): the tile loop's copy made the path tracer on the
//! bundled Cornell box 13-15% faster on one thread.
//!
//! The results are identical bit for bit on either path: Rust never fuses a multiply and an
//! add unless asked (`mul_add`, which is exact either way), and the rounding instructions give
//! the same results as their library calls. `tests` below and the byte-identical renders in
//! `tests/` hold both paths to that.

/// True when the CPU runs x86-64-v3 code (checked once, then a relaxed load).
#[cfg(target_arch = "x86_64")]
#[inline]
pub(crate) fn has_v3() -> bool {
    use std::sync::atomic::{AtomicU8, Ordering};
    // 0: not checked yet, 1: no, 2: yes.
    static STATE: AtomicU8 = AtomicU8::new(0);
    match STATE.load(Ordering::Relaxed) {
        0 => {
            let yes = detect_v3() && !disabled_by_environment();
            STATE.store(if yes { 2 } else { 1 }, Ordering::Relaxed);
            yes
        }
        s => s == 2,
    }
}

/// Every feature the `_v3` functions are compiled with (see [`v3!`]).
#[cfg(target_arch = "x86_64")]
fn detect_v3() -> bool {
    is_x86_feature_detected!("avx2")
        && is_x86_feature_detected!("fma")
        && is_x86_feature_detected!("bmi1")
        && is_x86_feature_detected!("bmi2")
        && is_x86_feature_detected!("lzcnt")
        && is_x86_feature_detected!("popcnt")
        && is_x86_feature_detected!("sse4.1")
        && is_x86_feature_detected!("sse4.2")
        && is_x86_feature_detected!("ssse3")
}

/// `MESHTRACER_BASELINE_CPU=1` keeps the baseline code (to compare the two paths).
#[cfg(target_arch = "x86_64")]
fn disabled_by_environment() -> bool {
    std::env::var_os("MESHTRACER_BASELINE_CPU").is_some_and(|v| !v.is_empty() && v != "0")
}

/// Defines `$name` as a copy of the `#[inline(always)]` function `$body` compiled for
/// x86-64-v3, for [`has_v3`] to choose. The features are the ones [`detect_v3`] checks.
///
/// ```ignore
/// cpu::v3! { fn name_v3(&self, a: A) -> R = name_baseline }
/// ```
macro_rules! v3 {
    ($(#[$meta:meta])* fn $name:ident(&self $(, $arg:ident: $ty:ty)*) -> $ret:ty = $body:ident) => {
        $(#[$meta])*
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,sse4.1,sse4.2,ssse3")]
        fn $name(&self $(, $arg: $ty)*) -> $ret {
            self.$body($($arg),*)
        }
    };
}
pub(crate) use v3;

#[cfg(test)]
mod tests {
    /// The check is stable and the environment switch turns it off.
    #[test]
    #[cfg(target_arch = "x86_64")]
    fn the_check_answers_the_same_every_time() {
        let first = super::has_v3();
        for _ in 0..10 {
            assert_eq!(super::has_v3(), first);
        }
        if first {
            assert!(super::detect_v3());
        }
    }
}
