//! Nearly flush openings (rule two on the wall's own edges) and the openings their rows and columns predict (rule
//! three), on a brick wall whose courses stop at the openings.
#![cfg(test)]
use super::tests::{edge, vertex};
use super::*;
use crate::faces::find;

/// Four windows 1.2 × 1.5 m in a row (x from 1 + 3k, z 1–2.5) in a wall y = 0 facing −y, each side its own line
/// a centimetre past the corners (no junction, no face), a transom 2 cm behind the wall inside each; brick courses
/// every 10 cm, across the whole wall below and above the windows and between them beside them. The sides listed
/// in `missing` ([window, side], sides left, right, foot, top) are not seen.
fn row_of_flush_windows(missing: &[[usize; 2]]) -> (Vec<Vertex>, Vec<Edge>, Vec3) {
    let viewpoint = Vec3::new(6.0, -19.0, 1.6);
    let mut points: Vec<[f64; 3]> = vec![[-1.0, 0.0, 0.0], [13.0, 0.0, 0.0], [13.0, 0.0, 6.0], [-1.0, 0.0, 6.0]];
    let mut edges: Vec<Edge> = (0..4).map(|k| edge(k, (k + 1) % 4)).collect();
    let mut line = |points: &mut Vec<[f64; 3]>, a: [f64; 3], b: [f64; 3]| {
        points.extend([a, b]);
        edges.push(edge(points.len() - 2, points.len() - 1));
    };
    let o = 0.01;
    for k in 0..4 {
        let (x0, x1) = (1.0 + 3.0 * k as f64, 2.2 + 3.0 * k as f64);
        let sides = [
            ([x0, 0.0, 1.0 - o], [x0, 0.0, 2.5 + o]),
            ([x1, 0.0, 1.0 - o], [x1, 0.0, 2.5 + o]),
            ([x0 - o, 0.0, 1.0], [x1 + o, 0.0, 1.0]),
            ([x0 - o, 0.0, 2.5], [x1 + o, 0.0, 2.5]),
        ];
        for (s, (a, b)) in sides.into_iter().enumerate() {
            if !missing.contains(&[k, s]) {
                line(&mut points, a, b);
            }
        }
        line(&mut points, [x0 + 0.05, 0.02, 1.8], [x1 - 0.05, 0.02, 1.8]);
    }
    for c in 0..58 {
        let z = 0.15 + 0.1 * c as f64;
        if (1.0..=2.5).contains(&z) {
            for k in 0..3 {
                line(&mut points, [2.2 + 3.0 * k as f64, 0.0, z], [4.0 + 3.0 * k as f64, 0.0, z]);
            }
        } else {
            line(&mut points, [-1.0, 0.0, z], [13.0, 0.0, z]);
        }
    }
    (points.into_iter().map(vertex).collect(), edges, viewpoint)
}

/// The window faces' bounds [x0, x1, z0, z1] among the vertices from `first` on, in order along the wall.
fn openings(vertices: &[Vertex], faces: &[Face], first: usize) -> Vec<[f64; 4]> {
    let mut found: Vec<[f64; 4]> = faces
        .iter()
        .filter(|f| f.kind == SurfaceKind::Window && f.ring.iter().all(|&k| k >= first))
        .map(|f| {
            let xs: Vec<f64> = f.ring.iter().map(|&k| vertices[k].point.x).collect();
            let zs: Vec<f64> = f.ring.iter().map(|&k| vertices[k].point.z).collect();
            [min(&xs), max(&xs), min(&zs), max(&zs)]
        })
        .collect();
    found.sort_by(|a, b| a[0].total_cmp(&b[0]));
    found
}

/// Finds the faces of [`row_of_flush_windows`] with `missing` sides and checks that the window faces are those of
/// the windows `expected`, within 2 cm.
fn assert_windows_found(missing: &[[usize; 2]], expected: &[usize]) {
    let (mut vertices, mut edges, viewpoint) = row_of_flush_windows(missing);
    let first = vertices.len();
    let faces = find(&mut vertices, &mut edges, &ModelParams::default(), &viewpoint.into());
    let found = openings(&vertices, &faces, first);
    assert_eq!(found.len(), expected.len(), "{found:?}");
    for (f, &k) in found.iter().zip(expected) {
        let truth = [1.0 + 3.0 * k as f64, 2.2 + 3.0 * k as f64, 1.0, 2.5];
        for (a, b) in f.iter().zip(truth) {
            assert!((a - b).abs() < 0.02, "window {k}: {f:?} against {truth:?}");
        }
    }
}

#[test]
fn nearly_flush_windows_on_a_brick_wall_are_found_and_the_piers_between_them_are_not() {
    assert_windows_found(&[], &[0, 1, 2, 3]);
}

#[test]
fn a_flush_window_whose_foot_is_hidden_ends_where_both_its_sides_end() {
    assert_windows_found(&[[1, 2]], &[0, 1, 2, 3]);
}

#[test]
fn a_window_missing_a_side_is_predicted_by_its_row_and_the_bays_spacing_and_one_missing_two_is_not() {
    // Window 2 lacks its left side: no rectangle of its own, but its row and the bays' spacing place it, and three
    // of its sides are seen.
    assert_windows_found(&[[2, 0]], &[0, 1, 2, 3]);
    // Lacking its top too, too little of it is seen.
    assert_windows_found(&[[2, 0], [2, 3]], &[0, 1, 3]);
}

#[test]
fn the_lattice_of_bays_is_found_from_the_centres_found_and_none_without_two() {
    let l = grid::lattice(&[5.03, 11.0, 17.04, 27.03], 0.8).expect("a lattice");
    assert!((l.period - 2.0).abs() < 0.01, "{l:?}");
    assert!(
        ((l.phase - 5.03) / l.period - ((l.phase - 5.03) / l.period).round()).abs() < 0.01,
        "{l:?}"
    );
    assert_eq!(grid::lattice(&[5.0], 0.8), None);
    assert_eq!(grid::lattice(&[], 0.8), None);
    // Gaps of 2.0 and 3.45 m share no period of at least the smallest opening.
    assert_eq!(grid::lattice(&[0.0, 2.0, 5.45], 0.8), None);
    // One opening found 30 cm off among five on bays of 2.5 m: the lattice is the others'.
    let l = grid::lattice(&[0.88, 3.7, 11.2, 13.72, 16.24, 18.77], 0.8).expect("a lattice");
    assert!((l.period - 2.52).abs() < 0.01, "{l:?}");
    // Two of five off is too many.
    assert_eq!(grid::lattice(&[0.88, 3.7, 11.2, 13.72, 17.0], 0.8), None);
}

#[test]
fn a_window_whose_sides_only_the_images_show_is_confirmed_there() {
    // Window 2 lacks its left side and its top in the 3-D lines: the grid predicts it, but two sides are too few.
    let missing = [[2, 0], [2, 3]];
    let (camera, poses) = crate::test_views::cameras(&[6.8, 7.6, 8.4]);
    let centres = crate::Cameras::new(poses.iter().map(|p| p.center).collect());
    let find_with = |images: Option<&[crate::refine::ImageLines]>| {
        let (mut vertices, mut edges, _) = row_of_flush_windows(&missing);
        let first = vertices.len();
        let evidence = images.map(|images| Evidence { camera: &camera, images });
        let (faces, _) =
            crate::faces::find_with_walls(&mut vertices, &mut edges, &ModelParams::default(), &centres, &[], evidence.as_ref());
        openings(&vertices, &faces, first).len()
    };
    assert_eq!(find_with(None), 3);
    // The images see window 2's outline (and a course beside it, which they take for no side of it).
    let (x0, x1) = (7.0, 8.2);
    let outline = [
        (Vec3::new(x0, 0.0, 1.0), Vec3::new(x0, 0.0, 2.5)),
        (Vec3::new(x1, 0.0, 1.0), Vec3::new(x1, 0.0, 2.5)),
        (Vec3::new(x0, 0.0, 1.0), Vec3::new(x1, 0.0, 1.0)),
        (Vec3::new(x0, 0.0, 2.5), Vec3::new(x1, 0.0, 2.5)),
    ];
    let images: Vec<_> = poses
        .iter()
        .map(|p| crate::test_views::image_lines(&camera, p, &outline, 0.0))
        .collect();
    assert_eq!(find_with(Some(&images)), 4);
    // Lines that only run along the wall past the window (courses at its head and foot, no jambs) confirm nothing.
    let courses = [
        (Vec3::new(5.0, 0.0, 1.0), Vec3::new(10.0, 0.0, 1.0)),
        (Vec3::new(5.0, 0.0, 2.5), Vec3::new(10.0, 0.0, 2.5)),
    ];
    let images: Vec<_> = poses
        .iter()
        .map(|p| crate::test_views::image_lines(&camera, p, &courses, 0.0))
        .collect();
    assert_eq!(find_with(Some(&images)), 3);
}

#[test]
fn courses_left_out_of_the_model_as_surface_lines_still_keep_the_piers_from_passing_for_windows() {
    // The line stage classes most of a brick wall's courses texture, and the model leaves them out of its edges;
    // they come to the openings' rules as surface lines. The courses beside the windows' heads and feet stay
    // edges (aligned with the heads and feet, they pass for structure): between two windows they close a
    // rectangle of the pier's width.
    let (vertices, edges, viewpoint) = row_of_flush_windows(&[]);
    let is_course = |e: &Edge| {
        let (p, q) = (vertices[e.a].point, vertices[e.b].point);
        let on_course = ((p.z - 0.15) / 0.1 - ((p.z - 0.15) / 0.1).round()).abs() < 1e-6;
        let beside_window = (p.z - 1.05).abs() < 1e-6 || (p.z - 2.45).abs() < 1e-6;
        p.z == q.z && p.y == 0.0 && q.y == 0.0 && on_course && !beside_window
    };
    let surface: Vec<[Vec3; 2]> = edges
        .iter()
        .filter(|e| is_course(e))
        .map(|e| [vertices[e.a].point, vertices[e.b].point])
        .collect();
    assert!(surface.len() > 50, "{}", surface.len());
    let kept: Vec<Edge> = edges.iter().filter(|e| !is_course(e)).cloned().collect();
    let windows = |surface: &[[Vec3; 2]]| {
        let (mut vertices, mut edges) = (vertices.clone(), kept.clone());
        let first = vertices.len();
        let (faces, _) =
            crate::faces::find_with_walls(&mut vertices, &mut edges, &ModelParams::default(), &viewpoint.into(), surface, None);
        openings(&vertices, &faces, first)
    };
    let found = windows(&surface);
    assert_eq!(found.len(), 4, "{found:?}");
    // Without them the piers between the windows are bare and pass for windows.
    assert!(windows(&[]).len() > 4);
}
