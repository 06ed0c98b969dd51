//! Line tracing on edge maps whose lines are known.
use lineflow_lines2d::{trace, TraceParams};

fn identity(px: &[[u16; 2]]) -> Vec<[f64; 2]> {
    px.iter().map(|p| [p[0] as f64, p[1] as f64]).collect()
}

fn raster(mut px: Vec<[u16; 2]>) -> Vec<[u16; 2]> {
    px.sort_by_key(|p| (p[1], p[0]));
    px.dedup();
    px
}

#[test]
fn a_digital_line_is_one_segment_from_end_to_end_whatever_the_seed() {
    // A line of slope 0.3 from (5, 10) to (85, 34), rasterised.
    let px = raster((0..=80).map(|k| [5 + k as u16, (10.0 + 0.3 * k as f64).round() as u16]).collect());
    let lines = trace(100, 50, &px, &identity(&px), &TraceParams::default());
    assert_eq!(lines.len(), 1, "{lines:?}");
    let l = &lines[0];
    assert_eq!(l.chain.len(), px.len());
    let (a, b) = if l.start[0] < l.end[0] {
        (l.start, l.end)
    } else {
        (l.end, l.start)
    };
    assert!((a[0] - 5.0).abs() < 0.6 && (b[0] - 85.0).abs() < 0.6, "{a:?} {b:?}");
    // Ordered: consecutive chain pixels are 8-neighbours.
    assert!(l
        .chain
        .windows(2)
        .all(|w| (w[0][0] as i32 - w[1][0] as i32).abs() <= 1 && (w[0][1] as i32 - w[1][1] as i32).abs() <= 1));
}

#[test]
fn a_corner_splits_into_two_segments_and_short_bits_are_dropped() {
    let mut v: Vec<[u16; 2]> = (10..60).map(|c| [c, 20]).collect();
    v.extend((21..70).map(|r| [59, r]));
    v.extend([[2, 2], [3, 3]]);
    let px = raster(v);
    let lines = trace(100, 100, &px, &identity(&px), &TraceParams::default());
    assert_eq!(lines.len(), 2, "{:?}", lines.iter().map(|l| (l.start, l.end)).collect::<Vec<_>>());
}

#[test]
fn lines_are_straight_in_the_corrected_coordinates_given() {
    // Pixels on a parabola in the image that is a straight line in "corrected" coordinates.
    let px: Vec<[u16; 2]> = (0..60)
        .map(|c| [c + 10, 30 + ((c as f64 - 30.0).powi(2) / 300.0).round() as u16])
        .collect();
    let px = raster(px);
    let corrected: Vec<[f64; 2]> = px.iter().map(|p| [p[0] as f64, 30.0]).collect();
    let lines = trace(100, 100, &px, &corrected, &TraceParams::default());
    assert_eq!(lines.len(), 1);
}

#[test]
fn nothing_in_nothing_out() {
    assert!(trace(0, 0, &[], &[], &TraceParams::default()).is_empty());
    assert!(trace(1, 1, &[[0, 0]], &[[0.0, 0.0]], &TraceParams::default()).is_empty());
}

#[test]
fn collinear_fragments_are_joined_across_a_small_gap_only() {
    let mut v: Vec<[u16; 2]> = (10..40).map(|c| [c, 20]).collect();
    v.extend((43..80).map(|c| [c, 20]));
    v.extend((86..99).map(|c| [c, 20]));
    let px = raster(v);
    let joined = trace(
        120,
        40,
        &px,
        &identity(&px),
        &TraceParams {
            min_length_px: 5.0,
            max_gap_px: 4.0,
            max_jump_px: 0.0,
            ..TraceParams::default()
        },
    );
    let mut lengths: Vec<f64> = joined.iter().map(|l| (l.end[0] - l.start[0]).abs()).collect();
    lengths.sort_by(f64::total_cmp);
    assert_eq!(lengths.len(), 2, "{lengths:?}");
    assert!((lengths[1] - 69.0).abs() < 0.5, "3 px gap joined: {lengths:?}");
    let thesis = trace(
        120,
        40,
        &px,
        &identity(&px),
        &TraceParams {
            min_length_px: 5.0,
            max_gap_px: 0.0,
            max_jump_px: 0.0,
            ..TraceParams::default()
        },
    );
    assert_eq!(thesis.len(), 3);
}

#[test]
fn a_chain_jumps_gaps_along_its_line_up_to_the_set_length() {
    // A line of slope 0.1 with gaps of 3 missing pixels every 12 (a weak edge, or one cut by crossing joints),
    // then a gap of 6, in one band of the parallel tracing.
    let on_line = |c: u16| [c, (200.0 + 0.1 * c as f64).round() as u16];
    let mut v: Vec<[u16; 2]> = (15..130).filter(|c| c % 15 < 12).map(on_line).collect();
    v.extend((136..180).map(on_line));
    // An unrelated pixel beside the line within reach of a jump but off the line: not taken.
    v.push([131, 207]);
    let px = raster(v);
    let run = |max_jump_px: f64| {
        let p = TraceParams {
            max_jump_px,
            ..TraceParams::default()
        };
        let mut lengths: Vec<f64> = trace(200, 400, &px, &identity(&px), &p)
            .iter()
            .map(|l| (l.end[0] - l.start[0]).hypot(l.end[1] - l.start[1]))
            .collect();
        lengths.sort_by(f64::total_cmp);
        lengths
    };
    // No jumps: pieces of 12 px are too short to keep; only the last stretch is left.
    assert_eq!(run(0.0).len(), 1, "{:?}", run(0.0));
    // 4 px: the 3-pixel gaps are crossed, the 6-pixel one is not.
    let four = run(4.0);
    assert_eq!(four.len(), 2, "{four:?}");
    assert!((four[1] - 114.6).abs() < 1.5, "{four:?}");
    // 8 px: one segment from end to end.
    let eight = run(8.0);
    assert_eq!(eight.len(), 1, "{eight:?}");
    assert!((eight[0] - 164.8).abs() < 1.5, "{eight:?}");
}

/// A blurred step edge between columns: `x` is where the intensity crosses half-way.
fn vertical_step(width: usize, height: usize, x: f64) -> Vec<u8> {
    let mut g = vec![0u8; width * height];
    for r in 0..height {
        for c in 0..width {
            // A linear ramp two pixels wide, centred on x (pixel centres at integers).
            let t = ((c as f64 - x) / 2.0 + 0.5).clamp(0.0, 1.0);
            g[r * width + c] = (40.0 + 160.0 * t).round() as u8;
        }
    }
    g
}

#[test]
fn sub_pixel_positions_put_an_axis_aligned_line_where_the_edge_is() {
    let (w, h) = (80usize, 60usize);
    let camera = lineflow_photogrammetry::Camera::pinhole(w as u32, h as u32, 0.01, 10.0);
    for x in [30.0, 30.25, 30.5, 30.75] {
        let gray = vertical_step(w, h, x);
        let found = lineflow_edges::pixels(&gray, w, h, &lineflow_edges::canny(&gray, w, h, 20.0, 50.0));
        let pixels: Vec<[u16; 2]> = found.iter().map(|e| [e.col, e.row]).collect();
        let positions = lineflow_imaging::subpixel_positions(&gray, w, h, &found);
        let at = lineflow_lines2d::trace_measured_at(&camera, &pixels, &positions, &TraceParams::default());
        let whole = lineflow_lines2d::trace_measured(&camera, &pixels, &TraceParams::default());
        let col = |s: &[lineflow_lines2d::MeasuredSegment]| {
            let l = s.iter().max_by_key(|l| l.2.len()).expect("one line");
            (l.0[0] + l.1[0]) / 2.0
        };
        assert!((col(&at) - x).abs() < 0.1, "edge at {x}: sub-pixel line at {}", col(&at));
        // The pixel grid alone cannot tell 30.25 from 30.
        assert!((col(&whole) - col(&whole).round()).abs() < 1e-9);
    }
}

#[test]
fn steep_lines_cross_every_band_of_the_parallel_tracing_whole_and_apart() {
    // Two nearly vertical lines 3 px apart through all rows: the tracing works in bands of rows and must join each
    // line's pieces across the band boundaries without joining the two lines.
    let line = |x0: f64| (0..100u16).map(move |r| [(x0 + 0.02 * r as f64).round() as u16, r]);
    let px = raster(line(20.0).chain(line(23.0)).collect());
    let lines = trace(40, 100, &px, &identity(&px), &TraceParams::default());
    assert_eq!(lines.len(), 2, "{lines:?}");
    for l in &lines {
        assert_eq!(l.chain.len(), 100, "{l:?}");
        assert!((l.end[1] - l.start[1]).abs() > 98.0, "{l:?}");
    }
    assert_eq!(lines, trace(40, 100, &px, &identity(&px), &TraceParams::default()), "deterministic");
}

#[test]
fn short_chains_that_cross_a_long_edge_first_do_not_cut_it_into_pieces() {
    // A horizontal edge on row 240 with a short vertical joint touching it from above every 10 columns, as brick
    // mortar meets a window lintel: in raster order every joint is seeded before the edge and, tracing down, takes
    // the edge pixel it meets; a joint is too short to keep, so the edge must be able to pass through. (All in one
    // band of the parallel tracing: rows 200 to 249.)
    let mut v: Vec<[u16; 2]> = (10..190).map(|c| [c, 240]).collect();
    for c in (15..190).step_by(10) {
        v.extend((233..240).map(|r| [c, r]));
    }
    let px = raster(v);
    let lines = trace(200, 400, &px, &identity(&px), &TraceParams::default());
    let horizontal: Vec<_> = lines.iter().filter(|l| (l.end[1] - l.start[1]).abs() < 1.0).collect();
    assert_eq!(
        horizontal.len(),
        1,
        "{:?}",
        lines.iter().map(|l| (l.start, l.end)).collect::<Vec<_>>()
    );
    assert!((horizontal[0].end[0] - horizontal[0].start[0]).abs() > 175.0);
}
