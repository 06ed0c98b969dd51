//! Procedural textures, box-filtered over the pixel footprint so that fine patterns (mortar joints, tile gaps)
//! fade to their mean instead of aliasing when seen from afar.
use super::geometry::Material;
use super::rng::{hash, mix64, unit};

/// `floor` without a libm call (x86-64 without SSE4.1 has no rounding instruction); exact for |x| < 2⁶³.
#[inline]
fn floor(x: f64) -> f64 {
    let i = x as i64 as f64;
    if i > x {
        i - 1.0
    } else {
        i
    }
}

/// A cheap lattice hash for value noise.
#[inline]
fn lattice(seed: u64, ix: i64, iy: i64) -> f64 {
    unit(mix64(
        seed ^ (ix as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (iy as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F),
    ))
}

/// Linear RGB in [0, 1].
pub type Rgb = [f32; 3];

/// Fraction of `[x − fw/2, x + fw/2]` covered by pulses of `width` repeating every `period` (starting at 0).
fn pulse_coverage(x: f64, period: f64, width: f64, fw: f64) -> f64 {
    let integral = |x: f64| {
        let n = floor(x / period);
        n * width + (x - n * period).min(width)
    };
    if fw > 1e3 * period {
        return width / period;
    }
    if fw < 1e-9 {
        return if (x - floor(x / period) * period) < width { 1.0 } else { 0.0 };
    }
    ((integral(x + fw / 2.0) - integral(x - fw / 2.0)) / fw).clamp(0.0, 1.0)
}

fn smooth(t: f64) -> f64 {
    t * t * (3.0 - 2.0 * t)
}

/// Value noise in [−1, 1] with features of size `scale`, fading to 0 as the footprint `fw` approaches it.
fn noise(s: f64, t: f64, scale: f64, fw: f64, seed: u64) -> f64 {
    let fade = (1.0 - fw / scale).clamp(0.0, 1.0);
    if fade == 0.0 {
        return 0.0;
    }
    let (x, y) = (s / scale, t / scale);
    let (ix, iy) = (floor(x), floor(y));
    let (fx, fy) = (smooth(x - ix), smooth(y - iy));
    let (ix, iy) = (ix as i64, iy as i64);
    let v = |dx: i64, dy: i64| lattice(seed, ix + dx, iy + dy) * 2.0 - 1.0;
    let (v00, v10, v01, v11) = (v(0, 0), v(1, 0), v(0, 1), v(1, 1));
    let top = v00 + (v10 - v00) * fx;
    let bottom = v01 + (v11 - v01) * fx;
    (top + (bottom - top) * fy) * fade
}

fn mix(a: Rgb, b: Rgb, t: f64) -> Rgb {
    let t = t as f32;
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t]
}

fn scale(c: Rgb, k: f64) -> Rgb {
    let k = k as f32;
    [c[0] * k, c[1] * k, c[2] * k]
}

/// Soot and rain streaks over a wall, a factor around 1. Real walls are never periodic at the scale of their window
/// bays; without this, a façade of identical bays can be matched one bay off as consistently as in truth.
fn weathering(s: f64, t: f64, fw: f64, seed: u64) -> f64 {
    1.0 + 0.12 * noise(s, t, 1.3, fw, seed ^ 20) + 0.08 * noise(s, t * 0.25, 0.4, fw, seed ^ 21)
}

/// Albedo of `material` at texture coordinates (s, t) in metres, filtered over a footprint `fw` metres wide.
pub fn albedo(material: Material, s: f64, t: f64, fw: f64, seed: u64) -> Rgb {
    match material {
        Material::Brick => {
            const ROW: f64 = 0.075;
            const LEN: f64 = 0.25;
            const JOINT: f64 = 0.01;
            let row = floor(t / ROW);
            let shift = if row as i64 % 2 == 0 { 0.0 } else { LEN / 2.0 };
            let col = floor((s + shift) / LEN);
            let mortar_h = pulse_coverage(t, ROW, JOINT, fw);
            let mortar_v = pulse_coverage(s + shift, LEN, JOINT, fw);
            let mortar = 1.0 - (1.0 - mortar_h) * (1.0 - mortar_v);
            let tint = (unit(hash(&[seed, 11, row as i64 as u64, col as i64 as u64])) - 0.5) * 0.25 * (1.0 - fw / LEN).clamp(0.0, 1.0);
            let brick = scale([0.56, 0.28, 0.19], 1.0 + tint + 0.06 * noise(s, t, 0.02, fw, seed ^ 1));
            scale(mix(brick, [0.74, 0.71, 0.66], mortar), weathering(s, t, fw, seed))
        }
        Material::Plaster => scale(
            [0.80, 0.78, 0.72],
            (1.0 + 0.05 * noise(s, t, 0.04, fw, seed ^ 2) + 0.04 * noise(s, t, 0.6, fw, seed ^ 3)) * weathering(s, t, fw, seed),
        ),
        Material::Tiles => {
            let gap = 1.0 - (1.0 - pulse_coverage(t, 0.33, 0.03, fw)) * (1.0 - pulse_coverage(s, 0.25, 0.015, fw));
            let row = floor(t / 0.33);
            let tint =
                (unit(hash(&[seed, 13, row as i64 as u64, floor(s / 0.25) as i64 as u64])) - 0.5) * 0.2 * (1.0 - fw / 0.25).clamp(0.0, 1.0);
            mix(scale([0.47, 0.23, 0.15], 1.0 + tint), [0.18, 0.12, 0.10], gap)
        }
        // Near-uniform on purpose: the thesis's hard case, a region that matches at every depth.
        Material::Glass => scale([0.24, 0.29, 0.34], 1.0 + 0.01 * noise(s, t, 1.5, fw, seed ^ 4)),
        Material::Frame => scale([0.90, 0.90, 0.88], 1.0 + 0.01 * noise(s, t, 0.3, fw, seed ^ 5)),
        Material::Stone => scale([0.70, 0.69, 0.66], 1.0 + 0.06 * noise(s, t, 0.03, fw, seed ^ 6)),
        Material::Wood => scale([0.42, 0.28, 0.17], 1.0 + 0.10 * noise(s * 8.0, t, 0.4, fw * 8.0, seed ^ 7)),
        Material::Asphalt => scale(
            [0.33, 0.33, 0.34],
            1.0 + 0.10 * noise(s, t, 0.03, fw, seed ^ 8) + 0.05 * noise(s, t, 1.0, fw, seed ^ 9),
        ),
    }
}

/// Share of a survey target's white centre and of its black ring at distance `r` from its centre.
pub fn target_pattern(r: f64, radius: f64, fw: f64) -> (f64, f64) {
    let cover = |edge: f64| ((edge - r) / fw.max(1e-6) + 0.5).clamp(0.0, 1.0);
    let white = cover(radius);
    let disk = cover(2.0 * radius);
    (white, disk - white)
}

/// Colour of a target over an albedo.
pub fn paint_target(base: Rgb, white: f64, black: f64) -> Rgb {
    let c = mix(base, [0.95, 0.95, 0.95], white);
    mix(c, [0.04, 0.04, 0.04], black / (1.0 - white).max(1e-9))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filtered_pulses_average_to_the_duty_cycle() {
        assert!((pulse_coverage(0.3, 1.0, 0.1, 10.0) - 0.1).abs() < 1e-9);
        assert_eq!(pulse_coverage(0.05, 1.0, 0.1, 0.0), 1.0);
        assert_eq!(pulse_coverage(0.5, 1.0, 0.1, 0.0), 0.0);
        assert!((pulse_coverage(0.1, 1.0, 0.1, 0.1) - 0.5).abs() < 1e-9);
    }

    #[test]
    fn target_edges_are_antialiased() {
        let (w, b) = target_pattern(0.05, 0.05, 0.01);
        assert!((w - 0.5).abs() < 1e-9 && (b - 0.5).abs() < 1e-9);
        assert_eq!(target_pattern(0.0, 0.05, 0.01), (1.0, 0.0));
    }
}
