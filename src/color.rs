//! Colour arithmetic shared by every phase: luminance and the sRGB transfer curves. A leaf:
//! it imports nothing of the crate.

use glam::Vec3;

/// Luminance weights of linear Rec. 709.
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// Linear -> sRGB transfer function (IEC 61966-2-1), for values in [0, 1].
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB -> linear transfer function (IEC 61966-2-1), for values in [0, 1].
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// How linear scene radiance becomes a displayable colour in an 8-bit image (`--tonemap`): the
/// view transform, applied after exposure and before the sRGB encoding. Floating-point outputs
/// (EXR, HDR) stay linear and untouched.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Hash)]
pub enum ViewTransform {
    /// Clip to [0, 1]: radiance above 1 burns out (Blender's "Standard").
    #[default]
    Standard,
    /// Khronos PBR Neutral (Khronos Group, 2024): base colours under a white light of
    /// illuminance π stay as authored up to 0.76, highlights roll off to white with little
    /// hue shift. The glTF Sample Viewer's and model-viewer's default; a Blender view
    /// transform since 4.2.
    KhronosPbrNeutral,
    /// AgX (Troy Sobotka; Eary Chow's formulation that Blender 4.0+ uses by default): a
    /// log-encoded sigmoid in an inset Rec. 2020 space, desaturating highlights toward white.
    Agx,
    /// ACES filmic, Stephen Hill's fit of the ACES 1.0 RRT and sRGB ODT (as in three.js and the
    /// glTF Sample Viewer, without their exposure boost).
    Aces,
}

impl ViewTransform {
    /// Every view transform, in the order `--help` lists them.
    pub const ALL: [ViewTransform; 4] = [
        ViewTransform::Standard,
        ViewTransform::KhronosPbrNeutral,
        ViewTransform::Agx,
        ViewTransform::Aces,
    ];

    /// The name on the command line and in view files.
    pub fn name(self) -> &'static str {
        match self {
            ViewTransform::Standard => "standard",
            ViewTransform::KhronosPbrNeutral => "khronos-pbr-neutral",
            ViewTransform::Agx => "agx",
            ViewTransform::Aces => "aces",
        }
    }

    /// The view transform called `name` ([`ViewTransform::name`]).
    pub fn from_name(name: &str) -> Option<ViewTransform> {
        Self::ALL.into_iter().find(|v| v.name() == name)
    }

    /// Linear Rec. 709 scene radiance (non-negative) to linear Rec. 709 display values in
    /// [0, 1], ready for the sRGB transfer curve.
    pub fn apply(self, c: Vec3) -> Vec3 {
        let c = c.max(Vec3::ZERO);
        let out = match self {
            ViewTransform::Standard => c,
            ViewTransform::KhronosPbrNeutral => pbr_neutral(c),
            ViewTransform::Agx => agx(c),
            ViewTransform::Aces => aces_hill(c),
        };
        out.clamp(Vec3::ZERO, Vec3::ONE)
    }
}

/// Khronos PBR Neutral, from its specification (KhronosGroup/ToneMapping, PBR_Neutral): with
/// F90 = 0.04, K_s = 0.8 - F90 and K_d = 0.15, x = min(R, G, B), the Fresnel offset
/// f = x - x²/(4·F90) for x ≤ 2·F90 and F90 above, the peak p = max(c - f); below K_s the
/// colour is c - f, above it the peak is compressed to p_n = 1 - (1 - K_s)²/(p + 1 - 2·K_s)
/// and the colour mixed toward grey p_n by 1 - g, g = 1/(K_d·(p - p_n) + 1).
fn pbr_neutral(c: Vec3) -> Vec3 {
    const F90: f32 = 0.04;
    const START: f32 = 0.8 - F90;
    const DESATURATION: f32 = 0.15;
    let x = c.min_element();
    let offset = if x <= 2.0 * F90 {
        x - x * x / (4.0 * F90)
    } else {
        F90
    };
    let c = c - Vec3::splat(offset);
    let peak = c.max_element();
    if peak <= START {
        return c;
    }
    let d = 1.0 - START;
    let new_peak = 1.0 - d * d / (peak + d - START);
    let g = 1.0 / (DESATURATION * (peak - new_peak) + 1.0);
    c * (new_peak / peak * g) + Vec3::splat(new_peak * (1.0 - g))
}

/// AgX as Blender's "AgX Base sRGB" LUT is generated (Eary Chow's AgX_LUT_Gen), without its
/// chroma-angle mixing and low-side compensation: linear sRGB into Rec. 2020 and AgX's inset
/// primaries (one matrix), log2 encoding over [-12.47, 4.03] stops around middle grey 0.18
/// (-10 to +6.5 EV), Eary Chow's piecewise sigmoid through the pivot (0.606, 0.18^(1/2.4)),
/// the 2.4 power back to linear, and the outset and Rec. 2020 to sRGB matrices (one matrix).
/// Middle grey maps to itself.
fn agx(c: Vec3) -> Vec3 {
    use glam::Mat3;
    // Column-major, each the product of two published matrices.
    const INSET: Mat3 = Mat3::from_cols_array(&[
        0.544_908_14,
        0.140_440_06,
        0.088_827_41,
        0.373_779_46,
        0.754_109_6,
        0.178_877_12,
        0.081_384_98,
        0.105_433_58,
        0.732_25,
    ]);
    const OUTSET: Mat3 = Mat3::from_cols_array(&[
        1.964_551,
        -0.299_322_43,
        -0.164_368_34,
        -0.855_858_45,
        1.326_451_1,
        -0.238_224_64,
        -0.108_867_11,
        -0.027_084_02,
        1.402_665_3,
    ]);
    const MIN_EV: f32 = -12.473_931;
    const MAX_EV: f32 = 4.026_069;
    const X_PIVOT: f32 = 0.606_060_6;
    const Y_PIVOT: f32 = 0.489_437_1;
    let encoded = INSET * c.max(Vec3::splat(2e-10));
    let curve = |v: f32| {
        let x = ((v.log2() - MIN_EV) / (MAX_EV - MIN_EV)).max(0.0);
        let (a, b) = if x < X_PIVOT {
            (-58.337_322, 35.355_953)
        } else {
            (46.141_05, -27.964_273)
        };
        let y = Y_PIVOT
            + 2.4 * (x - X_PIVOT)
                / (1.0 + 0.019_613_087 * (b + a * x).abs().powf(1.5)).powf(1.0 / 1.5);
        y.max(0.0).powf(2.4)
    };
    OUTSET * Vec3::new(curve(encoded.x), curve(encoded.y), curve(encoded.z))
}

/// Stephen Hill's fit of ACES (BakingLab, ACES.hlsl): the sRGB-to-ACES-AP1-with-RRT-saturation
/// matrix, the rational fit (v(v + 0.0245786) - 0.000090537) / (v(0.983729v + 0.4329510) +
/// 0.238081) of the RRT and ODT curves, and the ODT-saturation-to-sRGB matrix.
fn aces_hill(c: Vec3) -> Vec3 {
    use glam::Mat3;
    const INPUT: Mat3 = Mat3::from_cols_array(&[
        0.597_19, 0.076, 0.028_4, 0.354_58, 0.908_34, 0.133_83, 0.048_23, 0.015_66, 0.837_77,
    ]);
    const OUTPUT: Mat3 = Mat3::from_cols_array(&[
        1.604_75, -0.102_08, -0.003_27, -0.531_08, 1.108_13, -0.072_76, -0.073_67, -0.006_05,
        1.076_02,
    ]);
    let v = INPUT * c;
    let fit =
        (v * (v + 0.024_578_6) - 0.000_090_537) / (v * (0.983_729 * v + 0.432_951) + 0.238_081);
    OUTPUT * fit
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each view transform against its published definition at reference points, evaluated
    /// here in f64 from the published formulas (not the code under test): grey ramps and a
    /// saturated colour through Khronos PBR Neutral's specification and Hill's ACES fit; AgX
    /// at its anchor (middle grey 0.18 is its pivot and maps to itself), its black and white
    /// ends and its monotonic grey ramp. Standard is the clip.
    #[test]
    fn each_view_transform_matches_its_published_curve() {
        // Khronos PBR Neutral, from the specification's equations.
        let neutral = |c: [f64; 3]| -> [f64; 3] {
            let (f90, ks, kd) = (0.04, 0.8 - 0.04, 0.15);
            let x = c[0].min(c[1]).min(c[2]);
            let f = if x <= 2.0 * f90 {
                x - x * x / (4.0 * f90)
            } else {
                f90
            };
            let p = (c[0] - f).max(c[1] - f).max(c[2] - f);
            if p <= ks {
                return c.map(|v| v - f);
            }
            let pn = 1.0 - (1.0 - ks) * (1.0 - ks) / (p + 1.0 - 2.0 * ks);
            let g = 1.0 / (kd * (p - pn) + 1.0);
            c.map(|v| (v - f) * pn / p * g + pn * (1.0 - g))
        };
        // Hill's ACES fit, rows of the published row-major matrices.
        let aces = |c: [f64; 3]| -> [f64; 3] {
            let input = [
                [0.59719, 0.35458, 0.04823],
                [0.07600, 0.90834, 0.01566],
                [0.02840, 0.13383, 0.83777],
            ];
            let output = [
                [1.60475, -0.53108, -0.07367],
                [-0.10208, 1.10813, -0.00605],
                [-0.00327, -0.07276, 1.07602],
            ];
            let mul = |m: [[f64; 3]; 3], v: [f64; 3]| {
                m.map(|row| row[0] * v[0] + row[1] * v[1] + row[2] * v[2])
            };
            let v = mul(input, c);
            let fit = v.map(|v| {
                (v * (v + 0.0245786) - 0.000090537) / (v * (0.983729 * v + 0.4329510) + 0.238081)
            });
            mul(output, fit).map(|v| v.clamp(0.0, 1.0))
        };
        let samples = [
            [0.0, 0.0, 0.0],
            [0.03, 0.03, 0.03],
            [0.18, 0.18, 0.18],
            [0.5, 0.5, 0.5],
            [0.76, 0.76, 0.76],
            [1.0, 1.0, 1.0],
            [4.0, 4.0, 4.0],
            [1.0, 0.5, 0.25],
            [3.0, 0.2, 0.05],
        ];
        for c in samples {
            let input = Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32);
            for (view, expected) in [
                (
                    ViewTransform::KhronosPbrNeutral,
                    neutral(c).map(|v| v.clamp(0.0, 1.0)),
                ),
                (ViewTransform::Aces, aces(c)),
                (ViewTransform::Standard, c.map(|v| v.clamp(0.0, 1.0))),
            ] {
                let got = view.apply(input).to_array();
                for k in 0..3 {
                    assert!(
                        (f64::from(got[k]) - expected[k]).abs() < 2e-5,
                        "{view:?} {c:?}: {got:?} vs {expected:?}"
                    );
                }
            }
        }
        // Reference values: PBR Neutral keeps 0.5 grey at 0.46 (the 4% Fresnel offset) and
        // compresses 1.0 to 1 - 0.24²/0.44; Hill's ACES maps 0.18 to 0.1056.
        let grey = |view: ViewTransform, v: f32| view.apply(Vec3::splat(v)).x;
        assert!((grey(ViewTransform::KhronosPbrNeutral, 0.5) - 0.46).abs() < 1e-6);
        let peak = 1.0 - 0.24 * 0.24 / 0.44;
        assert!((grey(ViewTransform::KhronosPbrNeutral, 1.0) - peak).abs() < 1e-5);
        assert!((grey(ViewTransform::Aces, 0.18) - 0.10559).abs() < 1e-4);
        // AgX: middle grey is the sigmoid's pivot and comes out as itself; black stays black,
        // a bright grey approaches white, and the ramp rises.
        assert!(
            (grey(ViewTransform::Agx, 0.18) - 0.18).abs() < 2e-3,
            "{}",
            grey(ViewTransform::Agx, 0.18)
        );
        assert!(grey(ViewTransform::Agx, 0.0) < 1e-3);
        assert!(grey(ViewTransform::Agx, 64.0) > 0.95);
        let mut last = -1.0;
        for k in 0..200 {
            let v = grey(ViewTransform::Agx, 2f32.powf(k as f32 * 0.1 - 12.0));
            assert!(v >= last, "AgX falls at step {k}");
            last = v;
        }
        for view in ViewTransform::ALL {
            assert_eq!(ViewTransform::from_name(view.name()), Some(view));
        }
    }
}
