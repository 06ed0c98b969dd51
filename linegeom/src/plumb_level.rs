//! Plumb and level: the directions a façade's edges follow, imposed on the 3-D lines that nearly follow them.
//!
//! A horizontal edge seen from a strip of images lies along their epipolar lines: the images fix its height and
//! its distance across well, the depth of its two ends hardly, and the fitted line comes out turned in plan by a
//! few degrees (on the tuning façades, the bars and heads inside the windows by 6–12°). The building's level edges
//! run along two plan directions a right angle apart, and its standing edges are plumb; a line within
//! `max_deg` of one of them is turned onto it about its midpoint, keeping its length. The plan direction is the
//! lines' own (the length-weighted mode of the level lines' azimuths modulo 90°), so a façade need not be aligned
//! with the axes of the frame. Lines further off (rakes, a curved wall's chords, a third wall direction) stay.
use lineflow_photogrammetry::Vec3;

/// The plan direction of the level lines among `lines`: the azimuth (radians, modulo 90°, in [0, π/2)) most level
/// line length runs along, in 1° bins refined by the length-weighted mean within the bin's neighbours; none
/// without a line within `max_deg` of level.
pub fn plan_azimuth(lines: &[[Vec3; 2]], max_deg: f64) -> Option<f64> {
    let quarter = std::f64::consts::FRAC_PI_2;
    let level: Vec<(f64, f64)> = lines
        .iter()
        .filter_map(|[a, b]| {
            let d = b - a;
            let (h, len) = (d.x.hypot(d.y), d.norm());
            (len > 1e-9 && d.z.abs().atan2(h) < max_deg.to_radians()).then(|| (azimuth_mod_quarter(&d), len))
        })
        .collect();
    let mut bins = [0.0f64; 90];
    for &(az, len) in &level {
        bins[(az.to_degrees() as usize).min(89)] += len;
    }
    let (best, &weight) = bins.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0)))?;
    if weight <= 0.0 {
        return None;
    }
    // The mean of the azimuths within 1.5° of the bin's centre, taken as offsets from it (the bins wrap at 90°).
    let centre = (best as f64 + 0.5).to_radians();
    let (sum, total) = level.iter().fold((0.0, 0.0), |(s, t), &(az, len)| {
        let off = signed_quarter(az - centre);
        if off.abs() <= 1.5f64.to_radians() {
            (s + off * len, t + len)
        } else {
            (s, t)
        }
    });
    Some((centre + sum / total).rem_euclid(quarter))
}

/// Plan azimuth of a direction modulo 90°, radians in [0, π/2).
pub fn azimuth_mod_quarter(d: &Vec3) -> f64 {
    d.y.atan2(d.x).rem_euclid(std::f64::consts::FRAC_PI_2)
}

/// An azimuth difference folded into (−45°, 45°], radians.
pub fn signed_quarter(d: f64) -> f64 {
    let q = std::f64::consts::FRAC_PI_2;
    let r = d.rem_euclid(q);
    if r > q / 2.0 {
        r - q
    } else {
        r
    }
}

/// Turns each line within `max_deg` of plumb, or of level along the plan direction ([`plan_azimuth`]) or square
/// to it, onto that direction about its midpoint, keeping its length. Returns how many lines turned.
pub fn snap_plumb_and_level(lines: &mut [[Vec3; 2]], max_deg: f64) -> usize {
    if max_deg <= 0.0 {
        return 0;
    }
    let plan = plan_azimuth(lines, max_deg);
    let limit = max_deg.to_radians();
    let mut turned = 0;
    for line in lines.iter_mut() {
        let [a, b] = *line;
        let d = b - a;
        let len = d.norm();
        if len <= 1e-9 {
            continue;
        }
        let slope = d.z.abs().atan2(d.x.hypot(d.y));
        let direction = if slope > std::f64::consts::FRAC_PI_2 - limit {
            Some(Vec3::z() * d.z.signum())
        } else if slope < limit {
            plan.and_then(|plan| {
                let azimuth = d.y.atan2(d.x);
                let off = signed_quarter(azimuth - plan);
                (off.abs() < limit).then(|| Vec3::new((azimuth - off).cos(), (azimuth - off).sin(), 0.0))
            })
        } else {
            None
        };
        if let Some(u) = direction {
            let mid = (a + b) / 2.0;
            *line = [mid - u * (len / 2.0), mid + u * (len / 2.0)];
            turned += 1;
        }
    }
    turned
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_nearly_plumb_or_level_along_the_facade_are_turned_and_others_stay() {
        // A façade 30° off the x axis, 4,000 m from the origin.
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let along = Vec3::new(c, s, 0.0);
        let across = Vec3::new(-s, c, 0.0);
        let o = Vec3::new(4000.0, -2500.0, 10.0);
        let turn = |u: Vec3, deg: f64| {
            let (c, s) = (deg.to_radians().cos(), deg.to_radians().sin());
            Vec3::new(u.x * c - u.y * s, u.x * s + u.y * c, u.z)
        };
        let mut lines = vec![
            [o, o + along * 10.0],                                 // the façade's direction itself
            [o, o + along * 8.0],                                  // again, to make it the mode
            [o, o + turn(along, 6.0) * 2.0],                       // a head turned 6° in plan
            [o, o + turn(across, -5.0) * 0.3],                     // a reveal 5° off square
            [o, o + (Vec3::z() + along * 0.05).normalize() * 3.0], // a jamb 2.9° off plumb
            [o, o + (along + Vec3::z() * 0.7).normalize() * 4.0],  // a rake at 35°
            [o, o + turn(along, 20.0) * 3.0],                      // a wall's chord 20° off
        ];
        let before = lines.clone();
        let turned = snap_plumb_and_level(&mut lines, 8.0);
        assert_eq!(turned, 5);
        let dir = |l: &[Vec3; 2]| (l[1] - l[0]).normalize();
        assert!(dir(&lines[2]).dot(&along) > 1.0 - 1e-12);
        assert!(dir(&lines[3]).dot(&across).abs() > 1.0 - 1e-12);
        assert!(dir(&lines[4]).dot(&Vec3::z()) > 1.0 - 1e-12);
        assert_eq!(lines[5], before[5]);
        assert_eq!(lines[6], before[6]);
        for (l, b) in lines.iter().zip(&before) {
            assert!(((l[0] + l[1]) / 2.0 - (b[0] + b[1]) / 2.0).norm() < 1e-9, "midpoints stay");
            assert!(((l[1] - l[0]).norm() - (b[1] - b[0]).norm()).abs() < 1e-9, "lengths stay");
        }
        assert_eq!(snap_plumb_and_level(&mut lines.clone(), 0.0), 0);
    }

    #[test]
    fn the_plan_direction_wraps_at_a_right_angle() {
        // Level lines at 89.6° and 0.2°: one direction, 0.3° on average (modulo 90°).
        let at = |deg: f64| [Vec3::zeros(), Vec3::new(deg.to_radians().cos(), deg.to_radians().sin(), 0.0)];
        let az = plan_azimuth(&[at(89.6), at(0.2), at(0.2), at(90.2)], 8.0).expect("a direction");
        let off = signed_quarter(az).to_degrees();
        assert!((off - 0.05).abs() < 0.01, "{off}");
        assert!(plan_azimuth(&[[Vec3::zeros(), Vec3::z()]], 8.0).is_none());
    }
}
