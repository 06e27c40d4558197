//! Colour spaces for interpolating between transfer-function control points, as ParaView
//! names them, plus the sRGB transfer curve.

use std::f32::consts::PI;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColorSpace {
    Rgb,
    Hsv,
    /// CIELAB (D65).
    Lab,
    /// Moreland's Msh interpolation: through white between saturated colours of distant hue.
    Diverging,
    /// Constant colour from each point up to the next.
    Step,
}

impl ColorSpace {
    pub const KNOWN: &'static str = "RGB, HSV, Lab, Lab/CIEDE2000, Diverging, Step";

    /// ParaView's `ColorSpace` strings (case-insensitive).
    pub fn from_paraview(s: &str) -> Option<ColorSpace> {
        match s.to_ascii_lowercase().as_str() {
            "rgb" => Some(ColorSpace::Rgb),
            "hsv" => Some(ColorSpace::Hsv),
            // CIEDE2000 only changes how ParaView spaces the points; interpolation is Lab.
            "lab" | "lab/ciede2000" | "cielab" => Some(ColorSpace::Lab),
            "diverging" => Some(ColorSpace::Diverging),
            "step" => Some(ColorSpace::Step),
            _ => None,
        }
    }
}

/// sRGB colour between `a` (f = 0) and `b` (f = 1).
pub fn interpolate(space: ColorSpace, a: [f32; 3], b: [f32; 3], f: f32) -> [f32; 3] {
    let lerp3 = |x: [f32; 3], y: [f32; 3]| -> [f32; 3] { std::array::from_fn(|k| x[k] + (y[k] - x[k]) * f) };
    match space {
        ColorSpace::Rgb => lerp3(a, b),
        ColorSpace::Step => {
            if f < 1.0 {
                a
            } else {
                b
            }
        }
        ColorSpace::Hsv => {
            let (mut ha, hb) = (rgb_to_hsv(a), rgb_to_hsv(b));
            // The shorter way round the hue circle.
            if (hb[0] - ha[0]).abs() > 0.5 {
                ha[0] += if hb[0] > ha[0] { 1.0 } else { -1.0 };
            }
            let mut h = lerp3(ha, hb);
            h[0] = h[0].rem_euclid(1.0);
            hsv_to_rgb(h)
        }
        ColorSpace::Lab => lab_to_rgb(lerp3(rgb_to_lab(a), rgb_to_lab(b))),
        ColorSpace::Diverging => diverging(a, b, f),
    }
}

pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

pub fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

const WHITE: [f32; 3] = [0.950_47, 1.0, 1.088_83];

pub fn rgb_to_lab(c: [f32; 3]) -> [f32; 3] {
    let [r, g, b] = c.map(srgb_to_linear);
    let xyz = [
        0.412_456_4 * r + 0.357_576_1 * g + 0.180_437_5 * b,
        0.212_672_9 * r + 0.715_152_2 * g + 0.072_175 * b,
        0.019_333_9 * r + 0.119_192 * g + 0.950_304_1 * b,
    ];
    let f = |t: f32| if t > 0.008_856 { t.cbrt() } else { 7.787 * t + 16.0 / 116.0 };
    let [fx, fy, fz] = std::array::from_fn(|k| f(xyz[k] / WHITE[k]));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

pub fn lab_to_rgb(lab: [f32; 3]) -> [f32; 3] {
    let fy = (lab[0] + 16.0) / 116.0;
    let (fx, fz) = (lab[1] / 500.0 + fy, fy - lab[2] / 200.0);
    let inv = |f: f32| if f * f * f > 0.008_856 { f * f * f } else { (f - 16.0 / 116.0) / 7.787 };
    let [x, y, z] = [inv(fx) * WHITE[0], inv(fy) * WHITE[1], inv(fz) * WHITE[2]];
    let lin = [
        3.240_454_2 * x - 1.537_138_5 * y - 0.498_531_4 * z,
        -0.969_266 * x + 1.876_010_8 * y + 0.041_556 * z,
        0.055_643_4 * x - 0.204_025_9 * y + 1.057_225_2 * z,
    ];
    lin.map(linear_to_srgb)
}

fn rgb_to_hsv([r, g, b]: [f32; 3]) -> [f32; 3] {
    let (max, min) = (r.max(g).max(b), r.min(g).min(b));
    let d = max - min;
    let h = if d == 0.0 {
        0.0
    } else if max == r {
        ((g - b) / d).rem_euclid(6.0) / 6.0
    } else if max == g {
        ((b - r) / d + 2.0) / 6.0
    } else {
        ((r - g) / d + 4.0) / 6.0
    };
    [h, if max > 0.0 { d / max } else { 0.0 }, max]
}

fn hsv_to_rgb([h, s, v]: [f32; 3]) -> [f32; 3] {
    let h6 = (h * 6.0).rem_euclid(6.0);
    let i = h6.floor();
    let f = h6 - i;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    match i as u32 {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    }
}

fn lab_to_msh([l, a, b]: [f32; 3]) -> [f32; 3] {
    let m = (l * l + a * a + b * b).sqrt();
    let s = if m > 0.0 { (l / m).clamp(-1.0, 1.0).acos() } else { 0.0 };
    [m, s, b.atan2(a)]
}

fn msh_to_lab([m, s, h]: [f32; 3]) -> [f32; 3] {
    [m * s.cos(), m * s.sin() * h.cos(), m * s.sin() * h.sin()]
}

/// Moreland (2009), "Diverging Color Maps for Scientific Visualization": the hue of an
/// unsaturated colour is spun so the map stays perceptually smooth next to it.
fn adjust_hue([m, s, h]: [f32; 3], m_unsat: f32) -> f32 {
    if m >= m_unsat {
        return h;
    }
    let spin = s * (m_unsat * m_unsat - m * m).sqrt() / (m * s.sin());
    if h > -PI / 3.0 {
        h + spin
    } else {
        h - spin
    }
}

fn diverging(a: [f32; 3], b: [f32; 3], mut f: f32) -> [f32; 3] {
    let (mut p, mut q) = (lab_to_msh(rgb_to_lab(a)), lab_to_msh(rgb_to_lab(b)));
    let mut dh = (p[2] - q[2]).abs();
    if dh > PI {
        dh = 2.0 * PI - dh;
    }
    // Two saturated, distinct hues: pass through an unsaturated white in the middle.
    if p[1] > 0.05 && q[1] > 0.05 && dh > PI / 3.0 {
        let m_mid = p[0].max(q[0]).max(88.0);
        if f < 0.5 {
            q = [m_mid, 0.0, 0.0];
            f *= 2.0;
        } else {
            p = [m_mid, 0.0, 0.0];
            f = 2.0 * f - 1.0;
        }
    }
    if p[1] < 0.05 && q[1] > 0.05 {
        p[2] = adjust_hue(q, p[0]);
    } else if q[1] < 0.05 && p[1] > 0.05 {
        q[2] = adjust_hue(p, q[0]);
    }
    let msh: [f32; 3] = std::array::from_fn(|k| p[k] + (q[k] - p[k]) * f);
    lab_to_rgb(msh_to_lab(msh))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f32; 3], b: [f32; 3], tol: f32) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() <= tol)
    }

    #[test]
    fn conversions_round_trip() {
        for c in [[0.1, 0.5, 0.9], [1.0, 0.0, 0.0], [0.3, 0.3, 0.3], [0.95, 0.7, 0.05]] {
            assert!(close(lab_to_rgb(rgb_to_lab(c)), c, 1e-3), "{c:?}");
            assert!(close(hsv_to_rgb(rgb_to_hsv(c)), c, 1e-5), "{c:?}");
        }
        for x in [0.0, 0.01, 0.5, 1.0] {
            assert!((linear_to_srgb(srgb_to_linear(x)) - x).abs() < 1e-5);
        }
    }

    #[test]
    fn endpoints_are_kept_in_every_space() {
        let (a, b) = ([0.230, 0.299, 0.754], [0.706, 0.016, 0.150]);
        for space in [ColorSpace::Rgb, ColorSpace::Hsv, ColorSpace::Lab, ColorSpace::Diverging] {
            assert!(close(interpolate(space, a, b, 0.0), a, 2e-3), "{space:?}");
            assert!(close(interpolate(space, a, b, 1.0), b, 2e-3), "{space:?}");
        }
    }

    #[test]
    fn hsv_takes_the_short_way_round() {
        // Red to magenta-red: the middle is a red-magenta, not a trip through green.
        let mid = interpolate(ColorSpace::Hsv, [1.0, 0.0, 0.1], [1.0, 0.0, 0.5], 0.5);
        assert!(mid[1] < 0.01 && mid[0] > 0.99, "{mid:?}");
        let wrap = interpolate(ColorSpace::Hsv, [1.0, 0.0, 0.2], [1.0, 0.2, 0.0], 0.5);
        assert!(wrap[1] < 0.05 && wrap[2] < 0.05, "{wrap:?}");
    }
}
