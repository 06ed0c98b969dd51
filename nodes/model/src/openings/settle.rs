//! Openings settled in the images. An opening proposed from one imprecise find, or predicted by its row and column,
//! takes the sides of the edges it was built from or of the cells it copies: on the full-size presets whole rows and
//! columns came out 4–17 cm off, beyond what an opening may be off and still be that opening. Each new opening's
//! sides are measured again in the images' 2-D lines.
//!
//! - **Standing sides** (jambs) by their position. A strip of cameras looks at a jamb from left and right, so an
//!   edge on the wall lies at one position on the wall plane in every image, and an edge behind it (a frame, a
//!   pane) at positions that differ with the viewpoint ([`Evidence::positions`]). Of the positions the images
//!   show, the outermost is the opening's edge: the frame and the glazing lie inside it.
//! - **Foot and top** by where the jambs end ([`Evidence::extents`]). The strip has no parallax across a lying side:
//!   the images alone cannot tell the opening's foot on the wall from a sill's edges in front of it or a frame's
//!   rail behind it (moving the foot to the outermost lying edge the images show lost as many openings as it
//!   found). A jamb lies on the wall and ends at the opening's foot and head, where the wall plane turns into the
//!   reveal, so its lines' ends place them on the wall plane.
use super::evidence::MIN_IMAGES;
use super::*;

/// How far from where it was put a side is looked for, and moved at most, metres: a column or row copied from one
/// imprecise find is a few centimetres off, a frame's width inside at most; beyond, a jamb's lines that end at a
/// transom would move the top onto it.
const SETTLE_REACH_M: f64 = 0.2;
/// The two jambs' ends place the foot (or the top) where they agree within this, metres; where they do not, a
/// line of one ends early (at a transom, a shadow) and the side stays.
const JAMB_AGREEMENT_M: f64 = 0.03;

/// `rect` settled in the images: each standing side moved to the outermost position within [`SETTLE_REACH_M`] where
/// the images show it, then the foot and the top to where both jambs end ([`jamb_ends`]); a side the images do not
/// place stays.
pub(super) fn settle(wall: &Wall, rect: Rect, near: &Vec3, evidence: &Evidence) -> Rect {
    let mut out = rect;
    let [x0, x1, z0, z1] = rect.bounds;
    for (k, x, outward) in [(0, x0, -1.0), (1, x1, 1.0)] {
        let (a, b) = (wall.point(x, z0, near), wall.point(x, z1, near));
        let outermost = evidence
            .positions(&a, &b, &wall.across, SETTLE_REACH_M)
            .into_iter()
            .map(|p| p.offset_m)
            .max_by(|p, q| (p * outward).total_cmp(&(q * outward)));
        if let Some(offset) = outermost {
            out.bounds[k] = x + offset;
        }
    }
    let [x0, x1, z0, z1] = out.bounds;
    let (Some(left), Some(right)) = (
        jamb_ends(wall, x0, (z0, z1), near, evidence),
        jamb_ends(wall, x1, (z0, z1), near, evidence),
    ) else {
        return out;
    };
    for (k, ends, was) in [(2, (left.0, right.0), z0), (3, (left.1, right.1), z1)] {
        let at = (ends.0 + ends.1) / 2.0;
        if (ends.0 - ends.1).abs() <= JAMB_AGREEMENT_M && (at - was).abs() <= SETTLE_REACH_M {
            out.bounds[k] = at;
            // Measured on the wall plane: no line of sight to correct it along.
            out.on_wall[k] = true;
        }
    }
    out
}

/// Where the jamb at `x` on the wall, put from `z0` to `z1`, starts and ends in the images: the lowest start and
/// the highest end of its lines over the images that show it (a line ends early, broken by noise or a shadow, far
/// more often than it runs on, and none runs on past [`MAX_SIDE_GAP_M`]); none where fewer than [`MIN_IMAGES`]
/// show it.
fn jamb_ends(wall: &Wall, x: f64, (z0, z1): (f64, f64), near: &Vec3, evidence: &Evidence) -> Option<(f64, f64)> {
    let extents = evidence.extents(&wall.point(x, z0, near), &wall.point(x, z1, near), &wall.across);
    if extents.len() < MIN_IMAGES {
        return None;
    }
    let lowest = extents.iter().map(|e| e.0).fold(f64::INFINITY, f64::min);
    let highest = extents.iter().map(|e| e.1).fold(f64::NEG_INFINITY, f64::max);
    Some((z0 + lowest * (z1 - z0), z0 + highest * (z1 - z0)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::ImageLines;
    use crate::test_views::{cameras, image_lines};

    const NEAR: Vec3 = Vec3::new(0.0, -5.0, 0.5);

    fn wall() -> Wall {
        let plane = Plane {
            normal: Vec3::y(),
            offset: 0.0,
        };
        Wall::facing(plane, &NEAR).unwrap()
    }

    fn standing(x: f64, y: f64, z: (f64, f64)) -> (Vec3, Vec3) {
        (Vec3::new(x, y, z.0), Vec3::new(x, y, z.1))
    }

    /// The jambs of an opening from x = 0 to 1 and z = 0 to 1.2 on the wall y = 0, the left one's lines the
    /// pieces `left` of it, and a frame's sides 6 cm inside them and 15 cm behind the wall.
    fn settled(rect: [f64; 4], left: &[(f64, f64)]) -> Rect {
        let (camera, poses) = cameras(&[-1.0, -0.5, 0.0, 0.5, 1.0]);
        let mut edges = vec![
            standing(1.0, 0.0, (0.0, 1.2)),
            standing(0.06, 0.15, (0.0, 1.2)),
            standing(0.94, 0.15, (0.0, 1.2)),
        ];
        edges.extend(left.iter().map(|&z| standing(0.0, 0.0, z)));
        let images: Vec<ImageLines> = poses.iter().map(|p| image_lines(&camera, p, &edges, 0.0)).collect();
        let evidence = Evidence {
            camera: &camera,
            images: &images,
        };
        settle(&wall(), Rect::behind(rect), &NEAR, &evidence)
    }

    fn near(a: f64, b: f64) -> bool {
        (a - b).abs() < 0.005
    }

    #[test]
    fn jambs_move_to_the_outermost_edge_the_images_show_and_foot_and_top_to_where_they_end() {
        // Copied from a column 5 cm to the right (the left side a frame's width inside), from a row 8 cm up.
        let s = settled([0.05, 1.05, 0.08, 1.28], &[(0.0, 1.2)]);
        assert!(near(s.bounds[0], 0.0) && near(s.bounds[1], 1.0), "{s:?}");
        assert!(near(s.bounds[2], 0.0) && near(s.bounds[3], 1.2), "{s:?}");
        assert_eq!(s.on_wall, [false, false, true, true], "foot and top measured on the wall");
    }

    #[test]
    fn a_jamb_broken_at_a_transom_leaves_the_top_where_it_was_put() {
        // The left jamb's lines broken at a transom 0.5 m below the top: its highest line still ends at the top.
        let s = settled([0.05, 1.05, 0.08, 1.28], &[(0.0, 0.7), (0.75, 1.2)]);
        assert!(near(s.bounds[3], 1.2), "{s:?}");
        // Seen only up to 10 cm below the top (a shadow): the two jambs disagree on the top, which stays; they
        // agree on the foot.
        let s = settled([0.0, 1.0, 0.08, 1.25], &[(0.0, 1.1)]);
        assert!(near(s.bounds[3], 1.25) && !s.on_wall[3], "{s:?}");
        assert!(near(s.bounds[2], 0.0) && s.on_wall[2], "{s:?}");
        // Both jambs end farther below the top than a side is looked for: a transom, not the head.
        let s = settled([0.0, 1.0, 0.0, 1.45], &[(0.0, 1.2)]);
        assert!(near(s.bounds[3], 1.45) && !s.on_wall[3], "{s:?}");
    }

    #[test]
    fn sides_the_images_do_not_show_stay_where_they_were_put() {
        let (camera, poses) = cameras(&[-1.0, 0.0, 1.0]);
        let images: Vec<ImageLines> = poses.iter().map(|p| image_lines(&camera, p, &[], 0.0)).collect();
        let evidence = Evidence {
            camera: &camera,
            images: &images,
        };
        let rect = Rect::behind([0.05, 1.05, 0.0, 1.2]);
        assert_eq!(settle(&wall(), rect, &NEAR, &evidence), rect);
    }
}
