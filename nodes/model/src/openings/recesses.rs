//! Rule one: a closed recessed face makes the opening in the wall in front of it.
use super::*;

/// A vertical wall-kind face at least the smallest opening across, nearly a rectangle, parallel to a wall and
/// a recess behind it ([`OpeningSizes`]), is what one sees through an opening: its bounding rectangle, widened to the frame
/// ([`widened_to_frame`]). Largest first, so that a frame comes before its panes.
pub(super) fn from_recesses(
    vertices: &[Vertex],
    faces: &[Face],
    outlines: &[Outline],
    walls: &[WallView],
    cos_par: f64,
    centres: &[Vec3],
    sizes: OpeningSizes,
) -> Vec<Proposal> {
    let mut order: Vec<usize> = (0..faces.len()).collect();
    order.sort_by(|&a, &b| outlines[b].area.total_cmp(&outlines[a].area).then(a.cmp(&b)));
    order
        .into_iter()
        .filter(|&i| {
            let f = &faces[i];
            f.kind == SurfaceKind::Wall && f.normal.z.abs() < 0.2 && smaller_side(vertices, &f.ring, f.normal) >= sizes.opening_m.0
        })
        .filter_map(|i| {
            let (f, c) = (&faces[i], outlines[i].centroid);
            let k = walls
                .iter()
                .position(|w| w.wall.out.dot(&f.normal) > cos_par && (sizes.recess_m.0..=sizes.recess_m.1).contains(&w.wall.depth(&c)))?;
            let wall = &walls[k].wall;
            let (xs, zs): (Vec<f64>, Vec<f64>) = f
                .ring
                .iter()
                .map(|&w| (vertices[w].point.dot(&wall.across), vertices[w].point.z))
                .unzip();
            let rect = Rect::behind([min(&xs), max(&xs), min(&zs), max(&zs)]);
            let [x0, x1, z0, z1] = rect.bounds;
            // Only a rectangle is carried over as its box.
            if outlines[i].area < 0.8 * (x1 - x0) * (z1 - z0) {
                return None;
            }
            let depth = wall.depth(&c);
            Some(Proposal {
                wall: k,
                rect: widened_to_frame(rect, depth, &walls[k], centres).unwrap_or(rect),
                depth,
                sigma: f.ring.iter().find_map(|&w| vertices[w].sigma),
            })
        })
        .collect()
}
