//! The whole orientation chain on a synthetic strip (SURF → matcher → block), frame by frame as they would
//! arrive, against the scene's true poses and surveyed check points.
use std::collections::BTreeMap;

use lineflow_capture::synth::Synthetic;
use lineflow_features::surf::{surf, SurfParams};
use lineflow_matcher::descriptors::FrameFeatures;
use lineflow_matcher::{Matcher, MatcherParams};
use lineflow_messages::Encoding;
use lineflow_orientation::{Block, OrientationParams, Surveyed};
use lineflow_photogrammetry::Vec3;

fn features(syn: &Synthetic, frame: usize) -> FrameFeatures {
    let cam = syn.camera();
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut gray = vec![0u8; w * h];
    lineflow_convert::gray_into(Encoding::Rgb8, w, h, w * 3, &syn.render(frame), &mut gray).unwrap();
    let f = surf(
        &gray,
        w,
        h,
        &SurfParams {
            hessian_threshold: 15.0,
            ..Default::default()
        },
    );
    FrameFeatures {
        px: f.iter().map(|f| [f.at.col as f64, f.at.row as f64]).collect(),
        signs: f.iter().map(|f| f.at.laplacian_sign).collect(),
        descriptors: f.iter().flat_map(|f| f.descriptor).collect(),
        len: 64,
    }
}

#[test]
fn a_strip_is_oriented_as_it_arrives_and_meets_the_check_points() {
    let syn = Synthetic::new("d2x-strip", 0.3, 1).unwrap();
    let cam = *syn.camera();
    let n = syn.poses().len();
    let mut matcher = Matcher::new(
        MatcherParams {
            ratio: 0.7,
            retrieval: 0,
            ..Default::default()
        },
        cam,
    );
    let mut block = Block::new(OrientationParams::default(), cam);
    block.set_surveyed(
        syn.building
            .targets
            .iter()
            .map(|t| {
                (
                    t.id.clone(),
                    Surveyed {
                        xyz: Vec3::from(t.xyz),
                        sigma_m: [0.002; 3],
                        control: t.control,
                    },
                )
            })
            .collect::<BTreeMap<_, _>>(),
    );
    let targets = syn.target_observations();
    let mut all: Vec<lineflow_matcher::Observation> = Vec::new();
    for k in 0..n {
        let r = matcher.add_frame(k as u64, features(&syn, k));
        eprintln!("partners {:?}", r.partners);
        block.add_ties(r.observations.iter().map(|o| (o.track, o.frame, o.px)));
        all.extend(r.observations.iter().cloned());
        if k == 3 || k == 5 {
            // DEBUG: how many of this frame's observations agree with the true geometry of their track's other view
            let mut good = 0;
            let mut total = 0;
            for o in r.observations.iter().filter(|o| o.frame == k as u64) {
                if let Some(other) = all.iter().find(|p| p.track == o.track && p.frame != o.frame) {
                    let cam = syn.camera();
                    let (pa, pb) = (&syn.poses()[o.frame as usize], &syn.poses()[other.frame as usize]);
                    let (da, db) = (pa.ray_of_pixel(cam, o.px), pb.ray_of_pixel(cam, other.px));
                    let w0 = pa.center - pb.center;
                    let n = da.cross(&db);
                    let dist = (w0.dot(&n)).abs() / n.norm();
                    total += 1;
                    if dist < 0.02 {
                        good += 1;
                    }
                }
            }
            eprintln!("DEBUG frame {k}: {good} of {total} new observations have rays meeting within 2 cm");
        }
        for t in targets.iter().filter(|t| t.frame == k) {
            block.add_target(&t.id, k as u64, t.px);
        }
        let oriented = block.orient(k as u64);
        if k <= 3 {
            let p0 = syn.poses()[0];
            for (f, p) in &block.poses {
                let t = syn.poses()[*f as usize];
                // true relative pose in camera-0 frame
                let rt = t.rotation * p0.rotation.transpose();
                let ct = p0.rotation * (t.center - p0.center);
                eprintln!(
                    "  pose {f}: R err {:.4}, centre {:?} vs true dir {:?} (|{:.3}|)",
                    (p.rotation - rt).norm(),
                    p.center.as_slice(),
                    (ct / ct.norm()).as_slice(),
                    ct.norm()
                );
            }
        }
        eprintln!(
            "frame {k}: oriented {oriented}, georeferenced {}, sigma0 {:.2}",
            block.georeferenced, block.report.sigma0
        );
    }
    block.finish();
    let gsd = cam.gsd_m(12.0);
    let errors: Vec<f64> = block
        .poses
        .iter()
        .map(|(f, p)| (p.center - syn.poses()[*f as usize].center).norm())
        .collect();
    let worst = errors.iter().cloned().fold(0.0, f64::max);
    let checks = block.check_points();
    let rmse: Vec<f64> = (0..3)
        .map(|k| (checks.iter().map(|(_, d)| d[k] * d[k]).sum::<f64>() / checks.len().max(1) as f64).sqrt())
        .collect();
    eprintln!(
        "{} of {n} oriented, worst centre {:.1} mm, check-point RMSE {:?} mm over {} points, GSD {:.1} mm, sigma0 {:.2}, removed {}",
        block.poses.len(),
        worst * 1e3,
        rmse.iter().map(|r| (r * 1e4).round() / 10.0).collect::<Vec<_>>(),
        checks.len(),
        gsd * 1e3,
        block.report.sigma0,
        block.report.removed.len()
    );
    assert_eq!(block.poses.len(), n, "every frame oriented");
    assert!(block.georeferenced);
    assert!(worst < 5.0 * gsd, "worst camera centre {worst} m");
    assert!(
        checks.len() >= 5 && rmse.iter().all(|&r| r < 3.0 * gsd),
        "check-point RMSE {rmse:?}"
    );
}
