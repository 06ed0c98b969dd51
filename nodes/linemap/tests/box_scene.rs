//! The linemap algorithm on a façade with known edges: two strips of cameras in front of a wall with a recessed
//! window and an eave standing off the wall, each image's segments the projections of the true edges with
//! sub-pixel noise, plus a texture line in one image only.
use lineflow_linemap::{map_lines, Guide, MapParams, MapStage, MappedLine, View};
use lineflow_messages::Segment2;
use lineflow_photogrammetry::{rotation_from_opk, Camera, Pose, Vec3};

fn camera() -> Camera {
    Camera::pinhole(2000, 1500, 0.01, 20.0)
}

/// Cameras 12 m in front of the wall y = 0, looking at it, every 0.8 m along x, at the given heights.
fn strips(heights: &[f64]) -> Vec<Pose> {
    heights
        .iter()
        .flat_map(|&z| {
            (0..7).map(move |k| Pose {
                center: Vec3::new(2.0 + 0.8 * k as f64, -12.0, z),
                rotation: rotation_from_opk(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
            })
        })
        .collect()
}

/// The true edges: a window 1.2 × 1.6 m on the wall, its glass 0.15 m deep, and an eave 0.8 m in front of the wall.
fn edges() -> Vec<[Vec3; 2]> {
    let v = Vec3::new;
    let mut out = Vec::new();
    for y in [0.0, 0.15] {
        let (a, b, c, d) = (v(4.0, y, 1.0), v(5.2, y, 1.0), v(5.2, y, 2.6), v(4.0, y, 2.6));
        out.extend([[a, b], [b, c], [c, d], [d, a]]);
    }
    out.push([v(2.0, -0.8, 4.0), v(8.0, -0.8, 4.0)]);
    out.push([v(2.5, 0.0, 0.3), v(2.5, 0.0, 3.5)]);
    out
}

/// Each pose's segments: the true edges it sees, moved across themselves by ±0.15 px.
fn views(cam: &Camera, poses: &[Pose], with_texture: bool) -> Vec<View> {
    poses
        .iter()
        .enumerate()
        .map(|(f, pose)| {
            let mut segs: Vec<Segment2> = edges()
                .iter()
                .enumerate()
                .filter_map(|(k, [a, b])| {
                    let (pa, pb) = (pose.project(cam, a)?, pose.project(cam, b)?);
                    let len = (pb[0] - pa[0]).hypot(pb[1] - pa[1]);
                    let n = if (f + k) % 2 == 0 { 0.15 } else { -0.15 };
                    let off = [-(pb[1] - pa[1]) / len * n, (pb[0] - pa[0]) / len * n];
                    Some(Segment2 {
                        id: k as u32,
                        start_px: [pa[0] + off[0], pa[1] + off[1]],
                        end_px: [pb[0] + off[0], pb[1] + off[1]],
                        ..Default::default()
                    })
                })
                .collect();
            if with_texture && f == 0 {
                segs.push(Segment2 {
                    id: 99,
                    start_px: [300.0, 900.0],
                    end_px: [700.0, 905.0],
                    ..Default::default()
                });
            }
            View::new(cam, f as u64, *pose, &segs, 15.0)
        })
        .collect()
}

fn wall() -> Vec<Vec<Vec3>> {
    vec![vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(10.0, 0.0, 0.0),
        Vec3::new(10.0, 0.0, 5.0),
        Vec3::new(0.0, 0.0, 5.0),
    ]]
}

/// The lines, one per row, endpoints to the centimetre.
fn brief(lines: &[MappedLine]) -> String {
    let p = |v: &Vec3| format!("({:.2} {:.2} {:.2})", v.x, v.y, v.z);
    lines.iter().map(|l| format!("\n{} - {}", p(&l.start), p(&l.end))).collect()
}

fn distance_to_line(p: &Vec3, [a, b]: &[Vec3; 2]) -> f64 {
    let d = (b - a).normalize();
    let v = p - a;
    (v - d * v.dot(&d)).norm()
}

/// The true edge a line lies on (both endpoints within `tol` metres of its line, and within 5 cm of its extent),
/// if any. A recessed edge's extent can reach a few centimetres past its end where the front edge beside it lines
/// up with it in one image.
fn edge_of(l: &MappedLine, tol: f64) -> Option<usize> {
    edges().iter().position(|e| {
        let length = (e[1] - e[0]).norm();
        let within = |p: &Vec3| {
            let t = (p - e[0]).dot(&(e[1] - e[0])) / length;
            (-0.05..=length + 0.05).contains(&t)
        };
        distance_to_line(&l.start, e) < tol && distance_to_line(&l.end, e) < tol && within(&l.start) && within(&l.end)
    })
}

#[test]
fn every_edge_of_two_strips_is_found_once_and_nothing_else() {
    let cam = camera();
    let views = views(&cam, &strips(&[1.5, 4.5]), true);
    let guide = Guide::from_walls(&wall(), 3.0);
    let lines = map_lines(&cam, &views, &guide, &MapParams::default());
    for l in &lines {
        assert!(edge_of(l, 0.01).is_some(), "a line on no true edge: {l:?}");
    }
    for (k, e) in edges().iter().enumerate() {
        let on: Vec<&MappedLine> = lines.iter().filter(|l| edge_of(l, 0.01) == Some(k)).collect();
        let covered: f64 = on.iter().map(|l| (l.end - l.start).norm()).sum();
        assert!(
            covered >= 0.9 * (e[1] - e[0]).norm(),
            "edge {k} {e:?}: {covered:.2} m of it found in {on:?}"
        );
        assert!(on.len() <= 2, "edge {k} found {} times", on.len());
    }
}

#[test]
fn a_single_strip_places_its_horizontals_at_the_corners_of_its_verticals() {
    // One strip: every horizontal edge's planes are one plane; only the corners with the verticals place them.
    let cam = camera();
    let views = views(&cam, &strips(&[1.5]), false);
    let guide = Guide::from_walls(&wall(), 3.0);
    let lines = map_lines(&cam, &views, &guide, &MapParams::default());
    let horizontal_found = |k: usize| lines.iter().any(|l| edge_of(l, 0.02) == Some(k));
    // The window's sill and head on the wall, and its head in the recess. The recessed sill, half a metre below
    // the cameras, lies within a pixel of the front sill in every image of the strip, and goes with it.
    for k in [0, 2, 6] {
        assert!(
            horizontal_found(k),
            "horizontal edge {k} {:?} not found in {}",
            edges()[k],
            brief(&lines)
        );
    }
    let without = map_lines(
        &cam,
        &views,
        &guide,
        &MapParams {
            junctions: false,
            ..MapParams::default()
        },
    );
    assert!(
        without.iter().all(|l| (l.end - l.start).normalize().z.abs() > 0.99),
        "without junctions a single strip gives verticals only"
    );
}

#[test]
fn the_map_is_the_same_every_time_and_the_stage_maps_once_frames_are_in() {
    let cam = camera();
    let poses = strips(&[1.5, 4.5]);
    let views = views(&cam, &poses, true);
    let guide = Guide::from_walls(&wall(), 3.0);
    let a = map_lines(&cam, &views, &guide, &MapParams::default());
    let b = map_lines(&cam, &views, &guide, &MapParams::default());
    assert_eq!(a, b);

    let mut stage = MapStage::new(MapParams {
        remap_growth: 2.0,
        ..MapParams::default()
    });
    assert!(!stage.update(), "nothing to map");
    stage.set_walls(&wall());
    for (f, v) in views.iter().enumerate() {
        let segs: Vec<Segment2> = v
            .segments
            .ends
            .iter()
            .map(|e| Segment2 {
                start_px: cam.ideal_to_pixel(e[0]).unwrap(),
                end_px: cam.ideal_to_pixel(e[1]).unwrap(),
                ..Default::default()
            })
            .collect();
        stage.add_segments(f as u64, segs);
    }
    let posed = |n: usize| poses.iter().enumerate().take(n).map(|(f, p)| (f as u64, *p)).collect();
    stage.set_poses(posed(3));
    assert!(!stage.update(), "no camera yet");
    stage.set_camera(cam);
    assert!(stage.update(), "3 frames ready");
    stage.set_poses(posed(5));
    assert!(!stage.update(), "5 frames ready, 6 due");
    stage.set_poses(posed(poses.len()));
    assert!(stage.update());
    assert_eq!(stage.ready_frames(), poses.len());
    let all = stage.finish().to_vec();
    assert_eq!(all.len(), a.len());
}
