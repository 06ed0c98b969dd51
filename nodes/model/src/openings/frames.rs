//! The frame behind an opening, for its reveals. An opening found from its frame (a recessed face, a rectangle of
//! recessed edges) knows its depth; one whose outline closed on the wall, or which its row and column predicted,
//! does not, though the 3-D lines often hold pieces of its frame's standing sides behind it: too few to close a
//! rectangle, enough to tell the depth. Each frame is built on its opening's outline moved straight back, with its
//! four reveals as completed edges ([`add_frames`], [`add_frame`]).
use super::*;

/// Panes cover at least this share of their opening's area (one pane of four will do: frames and mullions take
/// their share, and panes often fail to close).
const MIN_PANES_SHARE: f64 = 0.2;
/// A frame side's edges cover at least this share of the opening's height.
const MIN_FRAME_COVER: f64 = 0.3;
/// How far outside the opening's side a frame side may lie, metres (the opening's own edge is a noisy line too).
const OUTSIDE_M: f64 = 0.03;

/// The depth of the frame behind the opening `[x0, x1, z0, z1]` of `view`'s wall, from the standing sides behind
/// the wall at its two sides: on each side, the front-most one within the frame's width inside it (the glazing lies
/// further back) covering [`MIN_FRAME_COVER`] of its height. Where both sides show one, they must agree
/// ([`DEPTH_TOLERANCE_M`]) and their mean is the depth; one side alone will do, since a deep reveal hides the
/// frame's side nearer the cameras from most of them (a strip sees the left sides of the windows at its left end,
/// the right sides at its right end).
pub(super) fn frame_depth(view: &WallView, [x0, x1, z0, z1]: [f64; 4]) -> Option<f64> {
    let reach = view.sizes.frame_m.1;
    let front_most = |lo: f64, hi: f64| {
        view.standing
            .iter()
            .filter(|s| (lo..=hi).contains(&s.at) && s.cover(z0, z1) >= MIN_FRAME_COVER)
            .map(|s| s.depth)
            .min_by(f64::total_cmp)
    };
    agreed(front_most(x0 - OUTSIDE_M, x0 + reach), front_most(x1 - reach, x1 + OUTSIDE_M))
}

/// The depth two sides of an opening give its frame: their mean where they agree ([`DEPTH_TOLERANCE_M`]), none
/// where they do not, the one where only one shows it.
fn agreed(left: Option<f64>, right: Option<f64>) -> Option<f64> {
    match (left, right) {
        (Some(left), Some(right)) => ((left - right).abs() <= DEPTH_TOLERANCE_M).then_some((left + right) / 2.0),
        (one, other) => one.or(other),
    }
}

/// Standing edges this far from an opening's side, metres, are its reveal's corners.
const AT_SIDE_M: f64 = 2.0 * SIDE_TOLERANCE_M;
/// A nearly flush frame lies at least this far behind the wall's face, metres, and this many σ of its edges…
pub(super) const FLUSH_MIN_M: f64 = 0.015;
const FLUSH_MIN_SIGMAS: f64 = 3.0;

/// The depth of a nearly flush frame (less than `recess_min_m` back, among the wall's own edges) behind the opening
/// `[x0, x1, z0, z1]`: at each side of the opening the standing edges on the wall at its position fall at two
/// depths, the reveal's outer corner on the wall's face and its inner corner on the frame. The frame's depth is the
/// length-weighted mean of those behind the face by [`FLUSH_MIN_M`] and [`FLUSH_MIN_SIGMAS`] of their σ, where
/// they cover [`MIN_FRAME_COVER`] of the height; both sides must agree ([`DEPTH_TOLERANCE_M`]) where both show
/// one.
pub(super) fn flush_frame_depth(view: &WallView, [x0, x1, z0, z1]: [f64; 4]) -> Option<f64> {
    let behind_at = |x: f64| {
        let back: Vec<&Piece> = view
            .standing_pieces_on_wall
            .iter()
            .filter(|p| (p.0 - x).abs() <= AT_SIDE_M && p.3 > z0 && p.2 < z1)
            .filter(|p| p.1 >= FLUSH_MIN_M.max(FLUSH_MIN_SIGMAS * p.4.map_or(0.0, |s| s.norm())))
            .collect();
        let spans: Vec<(f64, f64)> = back.iter().map(|p| (p.2, p.3)).collect();
        let length: f64 = back.iter().map(|p| p.3 - p.2).sum();
        (covered_share(&spans, z0, z1) >= MIN_FRAME_COVER).then(|| back.iter().map(|p| p.1 * (p.3 - p.2)).sum::<f64>() / length)
    };
    agreed(behind_at(x0), behind_at(x1))
}

/// The faces of the model behind an opening: a frame that closed, or its panes.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct FaceBehind {
    /// The front-most one's depth behind the wall, metres.
    pub(super) depth: f64,
    /// Whether one spans the opening, side to side and foot to top (within a frame's width): the frame itself,
    /// not its panes.
    pub(super) spans: bool,
    /// The share of the opening's area they cover at the front-most one's depth.
    pub(super) share: f64,
    /// The bounds of those at that depth that do not span it: its panes.
    pub(super) panes: Vec<[f64; 4]>,
}

/// The faces of the model (a frame that closed but made no rectangle, or its panes) behind the opening
/// `[x0, x1, z0, z1]` of `wall`, from [`FLUSH_MIN_M`] (a nearly flush frame) to the deepest recess `sizes`
/// allow: they give the reveal already.
pub(super) fn face_behind(
    outlines: &[Outline],
    wall: &Wall,
    [x0, x1, z0, z1]: [f64; 4],
    sizes: OpeningSizes,
    cos_par: f64,
) -> Option<FaceBehind> {
    let reach = sizes.frame_m.1.max(OUTSIDE_M);
    let behind: Vec<([f64; 4], f64, f64)> = outlines
        .iter()
        .filter_map(|o| {
            let [a0, a1, b0, b1] = o.bounds_in(wall);
            let depth = wall.depth(&o.centroid);
            (o.normal.dot(&wall.out).abs() > cos_par
                && (FLUSH_MIN_M..=sizes.recess_m.1).contains(&depth)
                && (x0..=x1).contains(&((a0 + a1) / 2.0))
                && (z0..=z1).contains(&((b0 + b1) / 2.0)))
            .then_some(([a0, a1, b0, b1], depth, o.area))
        })
        .collect();
    let depth = behind.iter().map(|b| b.1).min_by(f64::total_cmp)?;
    let front: Vec<&([f64; 4], f64, f64)> = behind.iter().filter(|b| b.1 - depth <= DEPTH_TOLERANCE_M).collect();
    let spanning = |[a0, a1, b0, b1]: &[f64; 4]| [a0 - x0, x1 - a1, b0 - z0, z1 - b1].iter().all(|gap| gap.abs() <= reach);
    Some(FaceBehind {
        depth,
        spans: front.iter().any(|b| spanning(&b.0)),
        share: front.iter().map(|b| b.2).sum::<f64>() / ((x1 - x0) * (z1 - z0)).max(1e-9),
        panes: front.iter().filter(|b| !spanning(&b.0)).map(|b| b.0).collect(),
    })
}

/// Gives every window and door of the model in a wall's plane with no frame face behind it (its outline closed on
/// the wall, or its row and column predicted it) the frame its 3-D lines show: at its panes' depth where the model
/// has them ([`face_behind`]), else where the frame's sides are ([`frame_depth`]); with its reveals.
/// After the openings are nested, so that the frame takes its opening's kind.
pub(crate) fn add_frames(
    walls: &[WallView],
    params: &ModelParams,
    vertices: &mut Vec<Vertex>,
    edges: &mut Vec<Edge>,
    faces: &mut Vec<Face>,
) {
    let cos_par = params.plane_angle_deg.to_radians().cos();
    let sizes = params.opening_sizes();
    let outlines = Outline::of_faces(faces, vertices);
    let mut frames = Vec::new();
    for (j, (f, o)) in faces.iter().zip(&outlines).enumerate() {
        if !matches!(f.kind, SurfaceKind::Window | SurfaceKind::Door) {
            continue;
        }
        // In the wall's plane: a nearly flush frame's own face, FLUSH_MIN_M or more behind, is no opening of it.
        let on_its_wall = |v: &&WallView| o.normal.dot(&v.wall.out) > cos_par && v.wall.depth(&o.centroid).abs() < FLUSH_MIN_M;
        let Some(view) = walls.iter().find(on_its_wall) else {
            continue;
        };
        let bounds = o.bounds_in(&view.wall);
        let depth = match face_behind(&outlines, &view.wall, bounds, sizes, cos_par) {
            // Panes: they sit in the frame's face, which the opening's reveals reach. A face that spans the opening
            // is its frame already; one that covers little of it is something else behind it.
            Some(FaceBehind {
                depth,
                spans: false,
                share,
                ..
            }) if share >= MIN_PANES_SHARE => Some(depth),
            Some(_) => continue,
            // The standing sides behind the wall start at `recess_min_m`; nearer frames are among the wall's own
            // edges.
            None => frame_depth(view, bounds).or_else(|| flush_frame_depth(view, bounds)),
        };
        if let Some(depth) = depth {
            frames.push((j, depth));
        }
    }
    for (j, depth) in frames {
        let (ring, normal, kind) = (faces[j].ring.clone(), faces[j].normal, faces[j].kind);
        add_frame(&ring, normal, depth, kind, vertices, edges, faces);
    }
}

/// The frame face `depth` behind the opening `outline` (its corners moved back along `normal`) and its reveals,
/// square to the wall, from the outline's corners to the frame's, as completed edges: an LOD-3 opening has its
/// depth.
pub(super) fn add_frame(
    outline: &[usize],
    normal: Vec3,
    depth: f64,
    kind: SurfaceKind,
    vertices: &mut Vec<Vertex>,
    edges: &mut Vec<Edge>,
    faces: &mut Vec<Face>,
) {
    let frame = outline
        .iter()
        .map(|&k| Vertex {
            point: vertices[k].point - depth * normal,
            sigma: vertices[k].sigma,
        })
        .collect();
    let back = add_face(frame, normal, kind, vertices, edges, faces);
    edges.extend(outline.iter().zip(&back).map(|(&a, &b)| Edge {
        a,
        b,
        line: usize::MAX,
        origin: EdgeOrigin::Inferred,
    }));
}
