//! Wall surfaces from the lines. Two strips 3 m apart at 25 m fix a horizontal line's depth only to about
//! σ_px · D / B = 2.5 pixels of the wall, yet most lines on a façade lie in the wall's surface: mortar, tile and
//! panel joints, and the outlines of its openings. Hundreds of them fix that surface far better than any one does.
//! Each wall's surface is the mode of the depths of the lines lying along it, sought near the site model's wall
//! (which is only a few centimetres right); a line whose own segments leave its depth open within `k` of its σ
//! of that surface is moved onto it. A line its segments place clearly off the surface (a frame in a reveal, a
//! sill proud of the wall) stays where they put it, and so does a line made from a corner with a vertical, whose
//! depth comes from that vertical.
use lineflow_photogrammetry::Vec3;

use crate::guide::Guide;
use crate::line::MappedLine;

/// Settings of the surfaces.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceParams {
    /// A line within this many of its own depth σ of a wall's surface is moved onto it; 0 turns this off.
    pub k: f64,
    /// Lines lying along a wall within this distance of the site model's wall are its surface's candidates,
    /// metres.
    pub search_m: f64,
    /// Fewest lines near the mode that make a surface.
    pub min_lines: usize,
}

/// A line lies along a wall when its direction is within this angle of the wall's plane (the preferred
/// directions make most exact).
const IN_PLANE_SIN: f64 = 0.1;

/// Moves the lines whose depth is open within `k` σ onto their wall's surface, wall by wall; returns how many
/// lines were moved.
pub fn settle_on_walls(lines: &mut [MappedLine], guide: &Guide, p: &SurfaceParams) -> usize {
    if p.k <= 0.0 {
        return 0;
    }
    let normals: Vec<Vec3> = guide.wall_normals().collect();
    let mut moved = vec![false; lines.len()];
    for (w, normal) in normals.iter().enumerate() {
        let depth = |q: &Vec3| guide.in_front_of_wall(w, q, p.search_m);
        let members: Vec<Member> = lines
            .iter()
            .enumerate()
            .filter(|(_, l)| !l.from_corner)
            .filter_map(|(line, l)| {
                let dir = (l.end - l.start).try_normalize(1e-12)?;
                if dir.dot(normal).abs() > IN_PLANE_SIN {
                    return None;
                }
                let ends = [depth(&l.start)?, depth(&l.end)?];
                ends.iter().all(|d| d.abs() <= p.search_m).then(|| Member {
                    line,
                    ends,
                    sigma: l.sigma_along(normal),
                    length: (l.end - l.start).norm(),
                })
            })
            .collect();
        let Some(surface) = surface_depth(&members, p.min_lines) else {
            continue;
        };
        for m in &members {
            if (m.depth() - surface).abs() > p.k * m.sigma {
                continue;
            }
            let l = &mut lines[m.line];
            l.start += normal * (surface - m.ends[0]);
            l.end += normal * (surface - m.ends[1]);
            moved[m.line] = true;
        }
    }
    moved.iter().filter(|&&m| m).count()
}

/// A line lying along a wall: its index, its endpoints' depths in front of the wall, its σ along the wall's
/// normal, and its length.
struct Member {
    line: usize,
    ends: [f64; 2],
    sigma: f64,
    length: f64,
}

impl Member {
    /// Depth of its midpoint.
    fn depth(&self) -> f64 {
        0.5 * (self.ends[0] + self.ends[1])
    }
}

/// The mode of the members' depths nearest the site model's wall (depth 0): a mean shift weighted by length, with
/// the members' median σ as its bandwidth; none unless `min_lines` lie within two bandwidths of it.
fn surface_depth(members: &[Member], min_lines: usize) -> Option<f64> {
    if members.len() < min_lines.max(1) {
        return None;
    }
    let mut sigmas: Vec<f64> = members.iter().map(|m| m.sigma).collect();
    sigmas.sort_by(f64::total_cmp);
    let h = sigmas[sigmas.len() / 2].max(1e-3);
    let mut x = 0.0;
    for _ in 0..100 {
        let (mut sw, mut swd) = (0.0, 0.0);
        for m in members {
            let w = m.length * (-0.5 * ((m.depth() - x) / h).powi(2)).exp();
            sw += w;
            swd += w * m.depth();
        }
        if sw <= 0.0 {
            return None;
        }
        let next = swd / sw;
        let done = (next - x).abs() < 1e-6 * h;
        x = next;
        if done {
            break;
        }
    }
    let near = members.iter().filter(|m| (m.depth() - x).abs() <= 2.0 * h).count();
    (near >= min_lines).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_photogrammetry::Mat3;

    use crate::guide::one_wall as guide;

    /// A horizontal line at height `z`, `y` from the wall, with depth σ `sigma` (across it in z: 1 mm).
    fn line(z: f64, y: f64, sigma: f64) -> MappedLine {
        MappedLine {
            start: Vec3::new(2.0, y, z),
            end: Vec3::new(4.0, y, z),
            n_segments: 4,
            n_images: 4,
            rms_m: 0.001,
            across_cov: Mat3::from_diagonal(&Vec3::new(0.0, sigma * sigma, 1e-6)),
            from_corner: false,
        }
    }

    fn params() -> SurfaceParams {
        SurfaceParams {
            k: 3.0,
            search_m: 0.3,
            min_lines: 10,
        }
    }

    #[test]
    fn lines_whose_depth_is_open_settle_on_the_surface_their_neighbours_share() {
        // Twenty courses of a wall 2 cm behind the site model's plane (y = +0.02), up to 4 cm off in depth with a
        // depth σ of 5 cm; a window head 20 cm behind the wall with σ 2 cm; a sill 6 cm in front with σ 5 mm; a
        // line 10 cm in front with σ 5 cm, but made from a corner with a vertical.
        let error = [-0.04, -0.02, 0.0, 0.02, 0.04];
        let mut lines: Vec<MappedLine> = (0..20).map(|k| line(0.5 + 0.3 * k as f64, 0.02 + error[k % 5], 0.05)).collect();
        lines.push(line(3.0, 0.22, 0.02));
        lines.push(line(1.0, -0.06, 0.005));
        let mut corner = line(2.0, -0.10, 0.05);
        corner.from_corner = true;
        lines.push(corner);
        let moved = settle_on_walls(&mut lines, &guide(), &params());
        assert_eq!(moved, 20);
        let surface = lines[0].start.y;
        assert!((surface - 0.02).abs() < 0.005, "the surface is the courses' mode: {surface}");
        for l in &lines[..20] {
            assert!((l.start.y - surface).abs() < 1e-9 && (l.end.y - surface).abs() < 1e-9, "{l:?}");
        }
        assert_eq!(lines[20].start.y, 0.22, "the recessed head keeps its depth");
        assert_eq!(lines[21].start.y, -0.06, "the sill its segments place in front keeps its depth");
        assert_eq!(lines[22].start.y, -0.10, "a corner's line keeps the vertical's depth");
    }

    #[test]
    fn too_few_lines_make_no_surface_and_k_0_moves_nothing() {
        let mut few: Vec<MappedLine> = (0..5).map(|k| line(1.0 + k as f64, 0.03, 0.05)).collect();
        assert_eq!(settle_on_walls(&mut few, &guide(), &params()), 0);
        let mut many: Vec<MappedLine> = (0..20).map(|k| line(0.5 + 0.3 * k as f64, 0.03, 0.05)).collect();
        let off = SurfaceParams { k: 0.0, ..params() };
        assert_eq!(settle_on_walls(&mut many, &guide(), &off), 0);
        assert_eq!(
            settle_on_walls(&mut many, &Guide::default(), &params()),
            0,
            "no site model, no walls"
        );
    }
}
