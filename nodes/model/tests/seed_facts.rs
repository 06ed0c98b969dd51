//! Seed 003's acceptance facts B2–B4 and B6 (seed 003 §5, `docs/sources.md`) on noise-free roof lines.
use lineflow_model::{build, Model, ModelLine, ModelParams, SurfaceKind};
use lineflow_photogrammetry::Vec3;

fn lines(segments: &[([f64; 3], [f64; 3])]) -> Vec<ModelLine> {
    segments
        .iter()
        .map(|&(a, b)| ModelLine::new(Vec3::from(a), Vec3::from(b), 0.01))
        .collect()
}

/// A flat roof outline at height `z` over the rectangle [x0, x1] × [0, 6].
fn flat_roof(x0: f64, x1: f64, z: f64) -> Vec<([f64; 3], [f64; 3])> {
    roof_outline([x0, x1], [0.0, 6.0], z)
}

/// A flat roof outline at height `z` over the rectangle `x` × `y`.
fn roof_outline(x: [f64; 2], y: [f64; 2], z: f64) -> Vec<([f64; 3], [f64; 3])> {
    let c = [[x[0], y[0], z], [x[1], y[0], z], [x[1], y[1], z], [x[0], y[1], z]];
    (0..4).map(|k| (c[k], c[(k + 1) % 4])).collect()
}

/// The adjusted corners (vertices with σ).
fn corners(m: &Model) -> Vec<Vec3> {
    m.vertices.iter().filter(|v| v.sigma.is_some()).map(|v| v.point).collect()
}

fn has(points: &[Vec3], p: [f64; 3]) -> bool {
    points.iter().any(|q| (q - Vec3::from(p)).norm() < 1e-6)
}

/// B2: a gable roof (two eaves at 5 m, the ridge at 8 m, four rakes). The rakes join the eaves and the ridge into
/// one object; each ridge end is one corner of three lines (the two rakes of a gable end are collinear in plan, so
/// the seed's plan reasoning must not intersect them; in 3-D they meet at 90° here), and the two slopes are roof
/// faces.
#[test]
fn b2_a_gable_roof_is_one_object_with_three_line_ridge_corners() {
    let (e0, e1, r) = ([0.0, 0.0, 5.0], [0.0, 6.0, 5.0], [0.0, 3.0, 8.0]);
    let at = |p: [f64; 3], x: f64| [x, p[1], p[2]];
    let segs = vec![
        (e0, at(e0, 10.0)),
        (e1, at(e1, 10.0)),
        (r, at(r, 10.0)),
        (e0, r),
        (e1, r),
        (at(e0, 10.0), at(r, 10.0)),
        (at(e1, 10.0), at(r, 10.0)),
    ];
    let m = build(&lines(&segs), &ModelParams::default(), &Vec3::new(5.0, -20.0, 40.0).into());
    assert_eq!(m.diagnostics.objects, 1, "{}", m.summary());
    let c = corners(&m);
    assert_eq!(c.len(), 6, "{c:?}");
    for p in [e0, e1, r, at(e0, 10.0), at(e1, 10.0), at(r, 10.0)] {
        assert!(has(&c, p), "{p:?} in {c:?}");
    }
    let ridge_end = m.vertices.iter().position(|v| (v.point - Vec3::from(r)).norm() < 1e-6).unwrap();
    assert_eq!(m.edges.iter().filter(|e| e.a == ridge_end || e.b == ridge_end).count(), 3);
    let roofs: Vec<_> = m.faces.iter().filter(|f| f.kind == SurfaceKind::Roof).collect();
    assert_eq!(roofs.len(), 2);
    assert!(roofs.iter().all(|f| f.ring.len() == 4 && f.normal.z > 0.5), "the slopes, facing up");
}

/// Two flat roofs, [0, 10] at 5 m and [x0, 20] at `z`: built as two objects, each a closed face of four corners;
/// their corners.
fn two_buildings(x0: f64, z: f64) -> Vec<Vec3> {
    let mut segs = flat_roof(0.0, 10.0, 5.0);
    segs.extend(flat_roof(x0, 20.0, z));
    let m = build(&lines(&segs), &ModelParams::default(), &Vec3::new(10.0, 3.0, 100.0).into());
    assert_eq!(m.diagnostics.objects, 2, "{}", m.summary());
    assert!(m.inside.is_empty(), "neighbours, not one inside the other: {:?}", m.inside);
    assert_eq!(m.faces.len(), 2);
    let c = corners(&m);
    assert_eq!(c.len(), 8, "{c:?}");
    c
}

/// B3: two buildings whose footprints touch (x = 10) at different heights are two objects with no corner across.
#[test]
fn b3_touching_buildings_of_different_heights_stay_apart() {
    let c = two_buildings(10.0, 8.0);
    assert!(c.iter().all(|p| p.z == 5.0 || p.z == 8.0));
}

/// B4: two buildings of one height 30 cm apart (a fire lane): no junction across the gap.
#[test]
fn b4_a_narrow_gap_keeps_two_buildings_apart() {
    let c = two_buildings(10.3, 5.0);
    for x in [0.0, 10.0, 10.3, 20.0] {
        assert_eq!(c.iter().filter(|p| (p.x - x).abs() < 1e-6).count(), 2, "two corners at x = {x}");
    }
}

/// B6: a penthouse's roof (3 × 3 m at 12.5 m) on a flat roof (20 × 12 m at 10 m) is its own object, flagged inside
/// the roof around it (every edge, extended, runs into that roof's outline), and not the other way round.
#[test]
fn b6_a_roof_structure_inside_a_larger_roof_is_flagged_inside() {
    let mut segs = roof_outline([0.0, 20.0], [0.0, 12.0], 10.0);
    segs.extend(roof_outline([8.0, 11.0], [4.0, 7.0], 12.5));
    let m = build(&lines(&segs), &ModelParams::default(), &Vec3::new(10.0, 6.0, 100.0).into());
    assert_eq!(m.diagnostics.objects, 2, "{}", m.summary());
    assert_eq!(m.inside.len(), 1, "{:?}", m.inside);
    let heights = |object: usize| m.objects[object].iter().map(|&v| m.vertices[v].point.z).collect::<Vec<f64>>();
    let (inner, outer) = (heights(m.inside[0].object), heights(m.inside[0].container));
    assert!(inner.len() == 4 && inner.iter().all(|&z| (z - 12.5).abs() < 1e-6), "{inner:?}");
    assert!(outer.len() == 4 && outer.iter().all(|&z| (z - 10.0).abs() < 1e-6), "{outer:?}");
}
