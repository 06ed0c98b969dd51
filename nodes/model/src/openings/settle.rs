//! Openings' standing sides settled in the images. An opening proposed from one imprecise find, or predicted by its
//! row and column, takes the sides of the edges it was built from or of the cells it copies: on the full-size
//! presets 4–7 cm off for whole columns, beyond what an opening may be off and still be that opening. The images
//! place a standing side better than the 3-D lines do: a strip of cameras looks at it from left and right, so an
//! edge on the wall lies at one position on the wall plane in every image, and an edge behind it (a frame, a pane)
//! at positions that differ with the viewpoint ([`Evidence::positions`]). Of the positions the images show, the
//! outermost is the opening's edge: the frame and the glazing lie inside it.
//!
//! The foot and the top stay where they were put: the strip's cameras stand side by side, so the images have no
//! parallax across a lying side to tell the opening's edge on the wall from a sill's edges in front of it or a
//! frame's behind it, and the one they show best is often not the opening's (on the tuning buildings, moving them
//! too lost as many openings as it found).
use super::*;

/// How far from where it was put a standing side is looked for in the images, metres: a column copied from one
/// imprecise find is a few centimetres off, a frame's width inside at most.
const SETTLE_REACH_M: f64 = 0.2;

/// `rect` with each standing side moved to the outermost position within [`SETTLE_REACH_M`] where the images show
/// it; a side they show nowhere stays.
pub(super) fn settle_standing_sides(wall: &Wall, rect: Rect, near: &Vec3, evidence: &Evidence) -> Rect {
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
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::ImageLines;
    use crate::test_views::{cameras, image_lines};

    fn wall() -> Wall {
        let plane = Plane {
            normal: Vec3::y(),
            offset: 0.0,
        };
        Wall::facing(plane, &Vec3::new(0.0, -5.0, 0.5)).unwrap()
    }

    /// The jambs of an opening from x = 0 to 1 on the wall y = 0, and a frame's sides 6 cm inside them and 15 cm
    /// behind the wall.
    fn opening_and_frame() -> Vec<(Vec3, Vec3)> {
        let standing = |x: f64, y: f64| (Vec3::new(x, y, 0.0), Vec3::new(x, y, 1.2));
        vec![standing(0.0, 0.0), standing(1.0, 0.0), standing(0.06, 0.15), standing(0.94, 0.15)]
    }

    #[test]
    fn standing_sides_move_to_the_outermost_edge_the_images_show() {
        let (camera, poses) = cameras(&[-1.0, -0.5, 0.0, 0.5, 1.0]);
        let edges = opening_and_frame();
        let images: Vec<ImageLines> = poses.iter().map(|p| image_lines(&camera, p, &edges, 0.0)).collect();
        let evidence = Evidence {
            camera: &camera,
            images: &images,
        };
        // Copied from a column 5 cm to the right, and put a frame's width inside on the left.
        let rect = Rect::behind([0.05, 1.05, 0.0, 1.2]);
        let settled = settle_standing_sides(&wall(), rect, &Vec3::new(0.0, -5.0, 0.5), &evidence);
        assert!(settled.bounds[0].abs() < 0.005, "{settled:?}");
        assert!((settled.bounds[1] - 1.0).abs() < 0.005, "{settled:?}");
        assert_eq!(settled.bounds[2..], rect.bounds[2..], "foot and top stay");
    }

    #[test]
    fn a_side_the_images_do_not_show_stays_where_it_was_put() {
        let (camera, poses) = cameras(&[-1.0, 0.0, 1.0]);
        let images: Vec<ImageLines> = poses.iter().map(|p| image_lines(&camera, p, &[], 0.0)).collect();
        let evidence = Evidence {
            camera: &camera,
            images: &images,
        };
        let rect = Rect::behind([0.05, 1.05, 0.0, 1.2]);
        assert_eq!(settle_standing_sides(&wall(), rect, &Vec3::new(0.0, -5.0, 0.5), &evidence), rect);
    }
}
