//! The whole orientation chain on a synthetic strip (SURF → matcher → block), frame by frame as they would
//! arrive, against the scene's true poses and surveyed check points.
use std::collections::BTreeMap;

use lineflow_features::surf::{surf, SurfParams};
use lineflow_matcher::descriptors::{Descriptors, FrameFeatures};
use lineflow_matcher::lsm::Gray;
use lineflow_matcher::{Matcher, MatcherParams};
use lineflow_messages::Encoding;
use lineflow_orientation::{Block, Method, OrientationParams, Surveyed};
use lineflow_photogrammetry::Vec3;
use lineflow_synthetic::Synthetic;

fn features(syn: &Synthetic, frame: usize) -> (FrameFeatures, Gray) {
    let cam = syn.camera();
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut gray = vec![0u8; w * h];
    lineflow_imaging::gray_into(Encoding::Rgb8, w, h, w * 3, &syn.render(frame), &mut gray).unwrap();
    let f = surf(
        &gray,
        w,
        h,
        &SurfParams {
            hessian_threshold: 50.0,
            ..Default::default()
        },
    );
    let features = FrameFeatures {
        px: f.iter().map(|f| [f.at.col as f64, f.at.row as f64]).collect(),
        signs: f.iter().map(|f| f.at.laplacian_sign).collect(),
        descriptors: Descriptors::Float {
            values: f.iter().flat_map(|f| f.descriptor).collect(),
            len: 64,
        },
    };
    let gray = Gray {
        width: w,
        height: h,
        data: gray,
    };
    (features, gray)
}

/// Worst camera-centre error and check-point RMSE per axis (metres) of an oriented block.
fn scores(syn: &Synthetic, block: &Block) -> (f64, Vec<f64>, usize) {
    let worst = block
        .poses
        .iter()
        .map(|(f, p)| (p.center - syn.poses()[*f as usize].center).norm())
        .fold(0.0, f64::max);
    let checks = block.check_points();
    let rmse: Vec<f64> = (0..3)
        .map(|k| (checks.iter().map(|(_, d)| d[k] * d[k]).sum::<f64>() / checks.len().max(1) as f64).sqrt())
        .collect();
    (worst, rmse, checks.len())
}

/// Both implementations are fed the same tie points, frame by frame; the matcher (SURF and LSM) runs once.
#[test]
fn a_strip_is_oriented_as_it_arrives_by_both_methods_and_the_bundle_meets_the_check_points() {
    let syn = Synthetic::new("d2x-strip", 0.3, 1).unwrap();
    let cam = *syn.camera();
    let n = syn.poses().len();
    let mut matcher = Matcher::new(MatcherParams::default(), cam);
    let surveyed: BTreeMap<String, Surveyed> = syn
        .building
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
        .collect();
    let mut blocks: Vec<Block> = [Method::Bundle, Method::Essential]
        .into_iter()
        .map(|m| {
            let mut b = Block::new(OrientationParams::default(), cam).with_method(m);
            b.set_surveyed(surveyed.clone());
            b
        })
        .collect();
    let targets = syn.target_observations();
    for k in 0..n {
        let r = {
            let (f, g) = features(&syn, k);
            matcher.add_frame(k as u64, f, Some(g))
        };
        eprintln!("partners {:?}", r.partners);
        for block in &mut blocks {
            block.add_ties(r.observations.iter().map(|o| (o.track, o.frame, o.px)));
            for t in targets.iter().filter(|t| t.frame == k) {
                block.add_target(&t.id, k as u64, t.px);
            }
            let oriented = block.orient(k as u64);
            eprintln!(
                "frame {k}: oriented {oriented}, georeferenced {}, sigma0 {:.2}",
                block.georeferenced, block.report.sigma0
            );
        }
    }
    // The strip stands 19.3 m from the façade.
    let gsd = cam.gsd_m(19.3);
    let mut figures = Vec::new();
    for (block, name) in blocks.iter_mut().zip(["bundle", "essential"]) {
        block.finish();
        let (worst, rmse, n_checks) = scores(&syn, block);
        eprintln!(
            "{name}: {} of {n} oriented, worst centre {:.1} mm, check-point RMSE {:?} mm over {n_checks} points, GSD {:.1} mm, sigma0 {:.2}, removed {}",
            block.poses.len(),
            worst * 1e3,
            rmse.iter().map(|r| (r * 1e4).round() / 10.0).collect::<Vec<_>>(),
            gsd * 1e3,
            block.report.sigma0,
            block.report.removed.len()
        );
        assert_eq!(block.poses.len(), n, "{name}: every frame oriented");
        assert!(block.georeferenced, "{name}");
        assert!(n_checks >= 5, "{name}: {n_checks} check points");
        figures.push((worst, rmse));
    }
    // Issue #6's targets for the bundle: camera centres within 2 GSD, check points within 1 GSD per axis (with tie
    // points refined by least-squares matching; SURF's positions alone gave 2.4 GSD and 1.04 GSD).
    let (worst, rmse) = &figures[0];
    assert!(*worst < 2.0 * gsd, "worst camera centre {worst} m");
    // The tie points' σ re-estimated from the adjustment: least-squares matched ties are far more precise than the
    // 0.5 px a priori (σ̂0 0.25 with it), and the estimate brings σ̂0 near 1.
    let estimated = blocks[0].tie_sigma_px;
    assert!(
        estimated < 0.5 * OrientationParams::default().tie_sigma_px,
        "tie σ estimated {estimated} px"
    );
    assert!(
        (blocks[0].report.sigma0 - 1.0).abs() < 0.3,
        "σ0 {} after the estimate",
        blocks[0].report.sigma0
    );
    assert!(rmse.iter().all(|&r| r < gsd), "check-point RMSE {rmse:?}");
    // The chained relative orientations (polished, with nothing adjusting the chain) drift along the strip, but far
    // less than the linear essential matrices alone, which put centres metres off on this nearly flat façade
    // (measured: worst 2.8 GSD, check points within 0.7 GSD; the linear method 470 GSD).
    let (worst, rmse) = &figures[1];
    assert!(*worst < 5.0 * gsd, "essential: worst camera centre {worst} m");
    assert!(rmse.iter().all(|&r| r < 1.5 * gsd), "essential: check-point RMSE {rmse:?}");
}
