//! The project's colour map (Turbo-like), shared by the viewer's panels and
//! 3-D shader and by the benchmark's figures; depends on nothing.

/// Coefficients `c0..c5` (red, green, blue) of the degree-5 polynomial
/// approximation of Google's Turbo colour map (A. Mikhailov, 2019).
/// Keep in sync with `TURBO_C*` in surface.wgsl.
const TURBO: [[f32; 3]; 6] = [
    [0.135_721_38, 0.091_402_61, 0.106_673_3],
    [4.615_392_6, 2.194_188_4, 12.641_946],
    [-42.660_324, 4.842_966_6, -60.582_047],
    [132.131_08, -14.185_033, 110.362_77],
    [-152.942_4, 4.277_298_5, -89.903_11],
    [59.286_38, 2.829_566, 27.348_25],
];

/// The Turbo-like colour map used by the 3-D view, for 2-D panels and scale
/// bars: `t` in 0..1 (clamped; NaN gives 0) to display (sRGB-encoded) RGB.
/// The shader evaluates the same polynomial.
pub fn colour_map(t: f32) -> [u8; 3] {
    let x = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let mut rgb = [0u8; 3];
    for (channel, out) in rgb.iter_mut().enumerate() {
        let value = TURBO
            .iter()
            .rev()
            .fold(0.0f32, |acc, c| acc * x + c[channel]);
        *out = (value.clamp(0.0, 1.0) * 255.0).round() as u8;
    }
    rgb
}

/// The usual normal-map colour of a unit normal in the camera frame (x
/// right, y down, z away from the camera): red = right, green = up, blue =
/// towards the camera, each `(1 + component) / 2` in [0, 1]; black for a
/// normal that is not finite.
pub fn normal_rgb(normal: [f64; 3]) -> [f64; 3] {
    if normal.iter().any(|v| !v.is_finite()) {
        return [0.0; 3];
    }
    [
        (0.5 * (1.0 + normal[0])).clamp(0.0, 1.0),
        (0.5 * (1.0 - normal[1])).clamp(0.0, 1.0),
        (0.5 * (1.0 - normal[2])).clamp(0.0, 1.0),
    ]
}
