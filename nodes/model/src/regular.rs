//! Regularity: the directions buildings are made of, imposed where the lines cannot tell them apart.
//!
//! A façade's edges are plumb or level, and most level ones run along one of two perpendicular plan directions.
//! A noisy line within k of its own direction σ of such a direction is turned onto it about its midpoint, and
//! Shape then holds the slopes it fixed (see [`crate::adjust`]). Its across position stays as measured, only its
//! tilt goes: a corner between a plumb and a level line is then known to σ/√2 along both, where two free lines
//! give σ. The dominant plan directions come from the level lines themselves (modes of their azimuth modulo
//! 90°), so a site frame need not be aligned with the building.
use lineflow_linegeom::{azimuth_mod_quarter, signed_quarter};
use lineflow_photogrammetry::Vec3;

use crate::ModelLine;

/// Which of a line's slopes are exact after regularisation.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Regularity {
    /// As measured.
    #[default]
    Free,
    /// Level: its height does not change along it.
    Level,
    /// Its plan direction is one of the building's (a sloped edge such as a rake, mostly horizontal).
    Azimuth,
    /// Plumb, or level along one of the building's plan directions: the whole direction is exact.
    Fixed,
}

impl Regularity {
    /// Whether the slope of object axis `j` against a line's dominant axis is exact.
    pub fn fixes(self, j: usize) -> bool {
        match self {
            Regularity::Free => false,
            Regularity::Level => j == 2,
            Regularity::Azimuth => j != 2,
            Regularity::Fixed => true,
        }
    }
}

/// Gates of the regularisation.
#[derive(Debug, Clone, Copy)]
pub struct RegularParams {
    /// A line is turned onto a direction within this many of its direction σ.
    pub k: f64,
    /// ... and never by more than this, degrees.
    pub max_deg: f64,
    /// A plan direction counts when its level lines hold at least this share of all level lines' length.
    pub min_share: f64,
}

/// How many lines were turned, by the kind of direction they were given.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RegularCounts {
    pub plumb: usize,
    pub level: usize,
    pub level_on_axis: usize,
    pub sloped_on_axis: usize,
    /// How many plan directions of the building were found (each with its perpendicular).
    pub plan_directions: usize,
}

/// The direction σ of a line across object axes `axes` (the largest endpoint σ among them), radians: two endpoints
/// of σ each, `length` apart.
fn direction_sigma(line: &ModelLine, axes: &[usize]) -> f64 {
    let s = axes.iter().map(|&a| line.sigma_along(a)).fold(0.0, f64::max);
    std::f64::consts::SQRT_2 * s / line.length().max(1e-9)
}

fn gate(line: &ModelLine, axes: &[usize], p: &RegularParams) -> f64 {
    (p.k * direction_sigma(line, axes)).min(p.max_deg.to_radians())
}

/// The smallest angle between two azimuths modulo 90°, radians.
fn quarter_gap(a: f64, b: f64) -> f64 {
    signed_quarter(a - b).abs()
}

/// The building's plan directions modulo 90°: the modes of the level lines' azimuths, each weighed by length,
/// found one after another among the lines no earlier mode took (each within its own gate). Deterministic: a 0.05°
/// grid.
fn plan_directions(levels: &[(f64, f64, f64)], p: &RegularParams) -> Vec<f64> {
    let total: f64 = levels.iter().map(|l| l.1).sum();
    let mut left: Vec<(f64, f64, f64)> = levels.to_vec();
    let mut modes = Vec::new();
    while modes.len() < 4 && !left.is_empty() {
        // Kernel density on a circle of period 90°, each line spread over its own gate.
        let steps = 1800;
        let score = |theta: f64| -> f64 {
            left.iter()
                .map(|&(az, w, g)| {
                    let d = quarter_gap(az, theta);
                    if d < g {
                        w * (1.0 - d / g)
                    } else {
                        0.0
                    }
                })
                .sum()
        };
        let (best, _) = (0..steps)
            .map(|s| s as f64 * std::f64::consts::FRAC_PI_2 / steps as f64)
            .map(|t| (t, score(t)))
            .fold((0.0, f64::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
        // The mode's own estimate: the weighted mean of the azimuths it gathers.
        let near: Vec<&(f64, f64, f64)> = left.iter().filter(|l| quarter_gap(l.0, best) < l.2).collect();
        let w: f64 = near.iter().map(|l| l.1).sum();
        // A direction of one or two lines is theirs, not the building's.
        if near.len() < 3 || w < p.min_share * total {
            break;
        }
        let mean = best + near.iter().map(|l| signed_quarter(l.0 - best) * l.1).sum::<f64>() / w;
        modes.push(mean.rem_euclid(std::f64::consts::FRAC_PI_2));
        left.retain(|l| quarter_gap(l.0, best) >= l.2);
    }
    modes
}

/// The line turned onto direction `dir` about its midpoint.
fn turned(line: &ModelLine, dir: Vec3, regular: Regularity) -> ModelLine {
    let m = line.midpoint();
    let dir = dir.normalize();
    let t0 = (line.start - m).dot(&dir);
    let t1 = (line.end - m).dot(&dir);
    ModelLine {
        start: m + dir * t0,
        end: m + dir * t1,
        regular,
        ..line.clone()
    }
}

/// Turns every line that lies within its gate of plumb, level or one of the building's plan directions onto it.
/// Returns what it did and the plan directions (azimuths modulo 90°, radians).
pub fn regularise(lines: &mut [ModelLine], p: &RegularParams) -> (RegularCounts, Vec<f64>) {
    let mut counts = RegularCounts::default();
    let up = Vec3::z();
    // Plumb and level first; the plan directions come from the level lines.
    let mut levels = Vec::new();
    for line in lines.iter_mut() {
        let d = line.direction();
        let tilt_from_plumb = d.z.abs().min(1.0).acos();
        let slope = d.z.abs().min(1.0).asin();
        if tilt_from_plumb <= gate(line, &[0, 1], p) {
            *line = turned(line, up * d.z.signum(), Regularity::Fixed);
            counts.plumb += 1;
        } else if slope <= gate(line, &[2], p) {
            *line = turned(line, Vec3::new(d.x, d.y, 0.0), Regularity::Level);
            counts.level += 1;
            levels.push((azimuth_mod_quarter(&d), line.length(), gate(line, &[0, 1], p)));
        }
    }
    let modes = plan_directions(&levels, p);
    counts.plan_directions = modes.len();
    for line in lines.iter_mut().filter(|l| l.regular != Regularity::Fixed) {
        let d = line.direction();
        let plan = (d.x * d.x + d.y * d.y).sqrt();
        // A steep line's plan direction is poorly known and its slopes against Z do not separate azimuth from
        // slope: left as is.
        if plan < d.z.abs() {
            continue;
        }
        let az = azimuth_mod_quarter(&d);
        let g = gate(line, &[0, 1], p) / plan;
        let Some(&mode) = modes
            .iter()
            .filter(|&&m| quarter_gap(az, m) <= g)
            .min_by(|a, b| quarter_gap(az, **a).total_cmp(&quarter_gap(az, **b)))
        else {
            continue;
        };
        let target = d.y.atan2(d.x) - signed_quarter(az - mode);
        let dir = Vec3::new(target.cos() * plan, target.sin() * plan, d.z);
        if line.regular == Regularity::Level {
            *line = turned(line, dir, Regularity::Fixed);
            counts.level -= 1;
            counts.level_on_axis += 1;
        } else {
            *line = turned(line, dir, Regularity::Azimuth);
            counts.sloped_on_axis += 1;
        }
    }
    (counts, modes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> RegularParams {
        RegularParams {
            k: 3.0,
            max_deg: 6.0,
            min_share: 0.1,
        }
    }

    #[test]
    fn near_plumb_and_level_lines_are_turned_about_their_midpoints_and_a_rake_keeps_its_slope() {
        let rot = 20f64.to_radians();
        let along = Vec3::new(rot.cos(), rot.sin(), 0.0);
        let across = Vec3::new(-rot.sin(), rot.cos(), 0.0);
        let mut lines = vec![
            // Plumb, 4 mm off at the top of 2 m.
            ModelLine::new(Vec3::new(1.0, 2.0, 0.0), Vec3::new(1.004, 2.0, 2.0), 0.005),
            // Level along the building's direction (20°), a little off in slope and azimuth.
            ModelLine::new(Vec3::zeros(), along * 3.0 + Vec3::new(0.0, 0.0, 0.006) + across * 0.006, 0.005),
            ModelLine::new(Vec3::new(0.0, 0.0, 1.0), along * 2.0 + Vec3::new(0.0, 0.0, 1.0), 0.005),
            ModelLine::new(Vec3::new(0.0, 0.0, 2.0), across * 2.5 + Vec3::new(0.0, 0.0, 2.0), 0.005),
            // A rake: along `across`, rising 35°, 5 mm off its plan direction.
            ModelLine::new(
                Vec3::zeros(),
                across * 2.0 + Vec3::new(0.0, 0.0, 2.0 * 35f64.to_radians().tan()) + along * 0.005,
                0.005,
            ),
            // A diagonal brace at 45° in plan, level: no plan direction of the building.
            ModelLine::new(Vec3::zeros(), Vec3::new(0.0, 0.0, 0.0) + (along + across) * 2.0, 0.005),
        ];
        let before: Vec<Vec3> = lines.iter().map(|l| l.midpoint()).collect();
        let (c, _) = regularise(&mut lines, &params());
        assert_eq!((c.plumb, c.level_on_axis, c.sloped_on_axis, c.level), (1, 3, 1, 1), "{c:?}");
        for (l, m) in lines.iter().zip(&before) {
            assert!((l.midpoint() - m).norm() < 1e-12, "a line moved: {l:?}");
        }
        assert!(lines[0].direction().x.abs() < 1e-12 && lines[0].regular == Regularity::Fixed);
        // The three level lines share one plan direction (their weighted mean, 20° to within the one's offset),
        // and the third is square to it.
        let d = lines[1].direction();
        assert!(d.dot(&along) > 1.0 - 1e-6, "{d:?}");
        assert!((lines[2].direction().dot(&d) - 1.0).abs() < 1e-12);
        assert!(lines[3].direction().dot(&d).abs() < 1e-12);
        let rake = lines[4].direction();
        assert!(rake.dot(&d).abs() < 1e-12 && (rake.z.asin().to_degrees() - 35.0).abs() < 0.2);
        assert_eq!(lines[4].regular, Regularity::Azimuth);
        assert_eq!(lines[5].regular, Regularity::Level);
    }

    #[test]
    fn a_tilt_beyond_the_lines_own_noise_stays() {
        // 1 cm lean over 3 m of a line known to 1 mm: real, not noise.
        let mut lines = vec![ModelLine::new(Vec3::zeros(), Vec3::new(0.01, 0.0, 3.0), 0.001)];
        let (c, _) = regularise(&mut lines, &params());
        assert_eq!(c, RegularCounts::default());
        assert_eq!(lines[0].end, Vec3::new(0.01, 0.0, 3.0));
    }
}
