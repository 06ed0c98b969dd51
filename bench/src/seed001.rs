//! `lineflow experiment seed001`: seed 001's simulated stereo pair (`docs/sources.md`), run through both
//! orientation methods it compares, as a Monte-Carlo experiment instead of the thesis's single noise draw.
//!
//! Collinearity: each image resected from the ten control points, the check points intersected by least squares
//! on the collinearity equations. Essential matrix: the normalised eight-point algorithm on all twenty
//! correspondences (control and check), the four-fold decomposition with the cheirality vote, model coordinates
//! by intersection, then the 12-parameter 3-D affine (the thesis) or the 7-parameter similarity from the control
//! points' model coordinates into object space.
use lineflow_photogrammetry::bundle::{adjust, resect, BundleOptions, BundleProblem, ImageObservation, PointPrior};
use lineflow_photogrammetry::epipolar::{eight_point, relative_pose, Ray};
use lineflow_photogrammetry::intersect::{affine, intersect_collinearity, intersect_rays, similarity};
use lineflow_photogrammetry::rotation_from_opk;
use lineflow_photogrammetry::{Mat3, Pose, Vec3};
use lineflow_synthetic::rng::Rng;

const FOCAL_MM: f64 = 28.0;
const HALF_FORMAT_MM: [f64; 2] = [11.5, 7.75];
const HEIGHT_M: f64 = 100.0;
/// 60 % forward overlap of the 82.14 m footprint at Z = 0.
const BASE_M: f64 = 0.4 * 23.0 / FOCAL_MM * HEIGHT_M;
const NOISE_MM: f64 = 0.32;
const POINTS: usize = 10;

/// Where the control points lie in the 3 × 3 grid over the overlap (seed 001 §3.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Layout {
    /// At least one in each of the nine blocks.
    Uniform,
    /// In the eight outer blocks only.
    Edge,
    /// All in the central block.
    Center,
    /// All in the bottom row of blocks.
    Bottom,
}

/// One configuration of the experiment and the thesis's published check-point RMSE (X, Y, Z, total; metres) for
/// the collinearity and the essential-matrix method.
pub struct Config {
    /// Name as in the thesis's tables.
    pub name: &'static str,
    /// Control-point layout.
    pub layout: Layout,
    /// Rotation of the second image (ω, φ, κ), degrees.
    pub rotation_deg: [f64; 3],
    /// Published RMSE of the collinearity method.
    pub thesis_collinearity: [f64; 4],
    /// Published RMSE of the essential-matrix method.
    pub thesis_essential: [f64; 4],
}

/// Tables 5-4, 5-9 and 5-10 of the thesis.
pub fn configs() -> Vec<Config> {
    let c = |name, layout, rotation_deg, thesis_collinearity, thesis_essential| Config {
        name,
        layout,
        rotation_deg,
        thesis_collinearity,
        thesis_essential,
    };
    let flat = [0.0; 3];
    vec![
        c(
            "uniform",
            Layout::Uniform,
            flat,
            [1.052, 1.180, 3.376, 2.152],
            [0.706, 1.389, 3.886, 2.417],
        ),
        c(
            "edge",
            Layout::Edge,
            flat,
            [1.437, 1.138, 4.521, 2.817],
            [0.706, 1.389, 3.886, 2.417],
        ),
        c(
            "center",
            Layout::Center,
            flat,
            [1.833, 2.330, 8.338, 5.109],
            [0.706, 1.389, 3.886, 2.417],
        ),
        c(
            "bottom",
            Layout::Bottom,
            flat,
            [1.293, 2.229, 5.356, 3.432],
            [0.706, 1.389, 3.886, 2.417],
        ),
        c(
            "RoX",
            Layout::Uniform,
            [10.0, 0.0, 0.0],
            [1.039, 0.967, 2.975, 1.903],
            [1.015, 1.007, 2.924, 1.879],
        ),
        c(
            "RoY",
            Layout::Uniform,
            [0.0, 10.0, 0.0],
            [1.046, 1.028, 3.053, 1.955],
            [1.031, 1.004, 3.002, 1.922],
        ),
        c(
            "RoZ",
            Layout::Uniform,
            [0.0, 0.0, 10.0],
            [1.199, 1.108, 3.165, 2.056],
            [1.188, 1.089, 3.216, 2.077],
        ),
        c(
            "RoXY",
            Layout::Uniform,
            [10.0, 10.0, 0.0],
            [0.947, 0.909, 2.562, 1.662],
            [0.950, 0.992, 2.607, 1.701],
        ),
        c(
            "RoXZ",
            Layout::Uniform,
            [10.0, 0.0, 10.0],
            [1.180, 0.892, 3.082, 1.974],
            [1.163, 0.907, 3.049, 1.955],
        ),
        c(
            "RoYZ",
            Layout::Uniform,
            [0.0, 10.0, 10.0],
            [1.074, 1.276, 3.505, 2.241],
            [1.053, 1.252, 3.459, 2.209],
        ),
        c(
            "RoXYZ",
            Layout::Uniform,
            [10.0; 3],
            [0.944, 0.873, 2.926, 1.845],
            [0.918, 0.958, 2.776, 1.776],
        ),
    ]
}

/// Check-point RMSE per axis and in total (the thesis's total: the RMS over all thirty components).
pub type Rmse = [f64; 4];

/// One trial's results: collinearity, essential + affine, essential + similarity (`None` where a method failed).
#[derive(Debug, Clone, Copy)]
pub struct Trial {
    /// Resection and intersection.
    pub collinearity: Option<Rmse>,
    /// Eight-point essential matrix, 12-parameter affine.
    pub essential_affine: Option<Rmse>,
    /// Eight-point essential matrix, 7-parameter similarity.
    pub essential_similarity: Option<Rmse>,
    /// lineflow's method: one bundle adjustment of both images, control points as weighted observations.
    pub bundle: Option<Rmse>,
}

fn rmse(errors: &[Vec3]) -> Rmse {
    let n = errors.len() as f64;
    let axis = |k: usize| (errors.iter().map(|e| e[k] * e[k]).sum::<f64>() / n).sqrt();
    let (x, y, z) = (axis(0), axis(1), axis(2));
    [x, y, z, ((x * x + y * y + z * z) / 3.0).sqrt()]
}

fn project(pose: &Pose, x: &Vec3) -> Option<[f64; 2]> {
    let u = pose.to_camera(x);
    let p = [-FOCAL_MM * u.x / u.z, -FOCAL_MM * u.y / u.z];
    (u.z < 0.0 && p[0].abs() <= HALF_FORMAT_MM[0] && p[1].abs() <= HALF_FORMAT_MM[1]).then_some(p)
}

/// The overlap of the two footprints on the plane Z = 20 m (mean terrain height), as an axis-aligned box
/// ([x0, x1], [y0, y1]): the intersection of each footprint's bounding box.
fn overlap(cams: &[Pose; 2]) -> [[f64; 2]; 2] {
    let mut bounds = [[f64::NEG_INFINITY, f64::INFINITY]; 2];
    for cam in cams {
        let corners = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]].map(|[sx, sy]| {
            let d = cam.rotation.transpose() * Vec3::new(sx * HALF_FORMAT_MM[0], sy * HALF_FORMAT_MM[1], -FOCAL_MM);
            cam.center + d * ((20.0 - cam.center.z) / d.z)
        });
        for (axis, b) in bounds.iter_mut().enumerate() {
            let lo = corners.iter().map(|c| c[axis]).fold(f64::INFINITY, f64::min);
            let hi = corners.iter().map(|c| c[axis]).fold(f64::NEG_INFINITY, f64::max);
            *b = [b[0].max(lo), b[1].min(hi)];
        }
    }
    bounds
}

/// A point in grid block `block` (row-major from the bottom-left, 0..9) of the overlap, at a height U(0, 40) m,
/// inside both formats (drawn again until it is; from the whole overlap if the block's corner is not seen).
fn point_in(rng: &mut Rng, block: usize, cams: &[Pose; 2]) -> Vec3 {
    let [[x0, x1], [y0, y1]] = overlap(cams);
    let (bx, by) = ((block % 3) as f64, (block / 3) as f64);
    for attempt in 0.. {
        let (fx, fy) = if attempt < 200 {
            ((bx + rng.uniform(0.0, 1.0)) / 3.0, (by + rng.uniform(0.0, 1.0)) / 3.0)
        } else {
            (rng.uniform(0.0, 1.0), rng.uniform(0.0, 1.0))
        };
        let p = Vec3::new(x0 + (x1 - x0) * fx, y0 + (y1 - y0) * fy, rng.uniform(0.0, 40.0));
        if cams.iter().all(|c| project(c, &p).is_some()) {
            return p;
        }
    }
    unreachable!("the loop above only ends by returning")
}

fn blocks(layout: Layout, rng: &mut Rng) -> Vec<usize> {
    let pool: Vec<usize> = match layout {
        Layout::Uniform => (0..9).collect(),
        Layout::Edge => (0..9).filter(|&b| b != 4).collect(),
        Layout::Center => vec![4],
        Layout::Bottom => vec![0, 1, 2],
    };
    let mut chosen: Vec<usize> = pool.iter().copied().cycle().take(pool.len().min(POINTS)).collect();
    while chosen.len() < POINTS {
        chosen.push(pool[(rng.next_u64() % pool.len() as u64) as usize]);
    }
    chosen
}

fn observe(rng: &mut Rng, cams: &[Pose; 2], points: &[Vec3], noise_mm: f64) -> Vec<[[f64; 2]; 2]> {
    points
        .iter()
        .map(|p| {
            [0, 1].map(|k| {
                let f = project(&cams[k], p).expect("points are generated inside both formats");
                [f[0] + noise_mm * rng.normal(), f[1] + noise_mm * rng.normal()]
            })
        })
        .collect()
}

/// One Monte-Carlo trial of `config` (`trial` seeds everything; `noise_mm` = 0.32 in the thesis).
pub fn run_trial(config: &Config, seed: u64, trial: u64, noise_mm: f64) -> Trial {
    let r = config.rotation_deg.map(f64::to_radians);
    let cams = [
        Pose {
            center: Vec3::new(0.0, 0.0, HEIGHT_M),
            rotation: Mat3::identity(),
        },
        Pose {
            center: Vec3::new(BASE_M, 0.0, HEIGHT_M),
            rotation: rotation_from_opk(r[0], r[1], r[2]),
        },
    ];
    // The same check points (and their noise) for every layout of a trial, as in the thesis.
    let mut rng = Rng::new(seed, trial);
    let checks: Vec<Vec3> = (0..POINTS)
        .map(|_| {
            let block = (rng.next_u64() % 9) as usize;
            point_in(&mut rng, block, &cams)
        })
        .collect();
    let check_obs = observe(&mut rng, &cams, &checks, noise_mm);
    let mut rng = Rng::new(seed ^ (config.layout as u64 + 1), trial);
    let controls: Vec<Vec3> = blocks(config.layout, &mut rng)
        .into_iter()
        .map(|b| point_in(&mut rng, b, &cams))
        .collect();
    let control_obs = observe(&mut rng, &cams, &controls, noise_mm);
    let resected = resect_pair(&cams, &controls, &control_obs, &mut rng, noise_mm);
    Trial {
        collinearity: resected.and_then(|poses| intersect_checks(&poses, &checks, &check_obs)),
        essential_affine: essential(&controls, &control_obs, &checks, &check_obs, true),
        essential_similarity: essential(&controls, &control_obs, &checks, &check_obs, false),
        bundle: resected.and_then(|poses| bundle(poses, &controls, &control_obs, &checks, &check_obs, noise_mm)),
    }
}

/// Each image resected from the control points, from initial values up to ±5 m and ±3° off (spec §2.2, ENG).
fn resect_pair(cams: &[Pose; 2], controls: &[Vec3], control_obs: &[[[f64; 2]; 2]], rng: &mut Rng, noise_mm: f64) -> Option<[Pose; 2]> {
    let mut poses = [cams[0], cams[1]];
    for (k, pose) in poses.iter_mut().enumerate() {
        let start = Pose {
            center: cams[k].center + Vec3::new(rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0)),
            rotation: rotation_from_opk(
                rng.uniform(-3.0, 3.0).to_radians(),
                rng.uniform(-3.0, 3.0).to_radians(),
                rng.uniform(-3.0, 3.0).to_radians(),
            ) * cams[k].rotation,
        };
        let obs: Vec<[f64; 2]> = control_obs.iter().map(|o| o[k]).collect();
        *pose = resect(FOCAL_MM, &start, controls, &obs, noise_mm.max(1e-3))?.0;
    }
    Some(poses)
}

/// The check points intersected by least squares on the collinearity equations.
fn intersect_checks(poses: &[Pose; 2], checks: &[Vec3], check_obs: &[[[f64; 2]; 2]]) -> Option<Rmse> {
    let errors: Option<Vec<Vec3>> = checks
        .iter()
        .zip(check_obs)
        .map(|(x, o)| Some(intersect_collinearity(FOCAL_MM, poses, o)? - x))
        .collect();
    Some(rmse(&errors?))
}

/// Both images and every point in one adjustment: the control points' image and object coordinates are all
/// observations (σ 0.32 mm and 1 mm), so the check points' rays also orient the images.
fn bundle(
    poses: [Pose; 2],
    controls: &[Vec3],
    control_obs: &[[[f64; 2]; 2]],
    checks: &[Vec3],
    check_obs: &[[[f64; 2]; 2]],
    noise_mm: f64,
) -> Option<Rmse> {
    let start: Vec<Vec3> = check_obs
        .iter()
        .map(|o| intersect_collinearity(FOCAL_MM, &poses, o))
        .collect::<Option<_>>()?;
    let points: Vec<Vec3> = controls.iter().chain(&start).copied().collect();
    let sigma_mm = noise_mm.max(1e-3);
    let observations = control_obs
        .iter()
        .chain(check_obs)
        .enumerate()
        .flat_map(|(point, o)| {
            (0..2).map(move |camera| ImageObservation {
                camera,
                point,
                ideal: o[camera],
                sigma_mm,
            })
        })
        .collect();
    let priors = controls
        .iter()
        .enumerate()
        .map(|(point, xyz)| PointPrior {
            point,
            xyz: *xyz,
            sigma_m: [0.001; 3],
        })
        .collect();
    let mut problem = BundleProblem {
        focal_mm: FOCAL_MM,
        poses: poses.to_vec(),
        points,
        observations,
        priors,
        fixed: Vec::new(),
        calibration: None,
    };
    // No outlier removal: the noise is Gaussian by construction, and ten points have no outliers to spare.
    adjust(
        &mut problem,
        &BundleOptions {
            outlier_rounds: 0,
            huber_k: 0.0,
            ..Default::default()
        },
    );
    let errors: Vec<Vec3> = problem.points[controls.len()..].iter().zip(checks).map(|(e, x)| e - x).collect();
    Some(rmse(&errors))
}

fn essential(
    controls: &[Vec3],
    control_obs: &[[[f64; 2]; 2]],
    checks: &[Vec3],
    check_obs: &[[[f64; 2]; 2]],
    use_affine: bool,
) -> Option<Rmse> {
    let all: Vec<[[f64; 2]; 2]> = control_obs.iter().chain(check_obs).copied().collect();
    let ray = |p: [f64; 2]| Ray::new(p[0] / FOCAL_MM, p[1] / FOCAL_MM, -1.0);
    let a: Vec<Ray> = all.iter().map(|o| ray(o[0])).collect();
    let b: Vec<Ray> = all.iter().map(|o| ray(o[1])).collect();
    let e = eight_point(&a, &b)?;
    let (second, _) = relative_pose(&e, &a, &b)?;
    let model = [
        Pose {
            center: Vec3::zeros(),
            rotation: Mat3::identity(),
        },
        second,
    ];
    // A noisy relative orientation can put a point behind a camera, where the collinearity iteration stops; the
    // linear method of the thesis still gives it model coordinates (the rays' closest point).
    let model_of = |o: &[[f64; 2]; 2]| {
        intersect_collinearity(FOCAL_MM, &model, o).or_else(|| {
            let rays: Vec<(Vec3, Vec3)> = (0..2)
                .map(|k| {
                    (
                        model[k].center,
                        model[k].rotation.transpose() * Vec3::new(o[k][0], o[k][1], -FOCAL_MM),
                    )
                })
                .collect();
            intersect_rays(&rays).map(|(x, _)| x)
        })
    };
    let control_model: Vec<Vec3> = control_obs.iter().map(model_of).collect::<Option<_>>()?;
    let check_model: Vec<Vec3> = check_obs.iter().map(model_of).collect::<Option<_>>()?;
    let to_world: Box<dyn Fn(&Vec3) -> Vec3> = if use_affine {
        let t = affine(&control_model, controls)?;
        Box::new(move |x| t.apply(x))
    } else {
        let t = similarity(&control_model, controls)?;
        Box::new(move |x| t.apply(x))
    };
    let errors: Vec<Vec3> = check_model.iter().zip(checks).map(|(m, x)| to_world(m) - x).collect();
    Some(rmse(&errors))
}

/// A method's name, its result in a trial, and the thesis's figures for it.
type Method = (&'static str, fn(&Trial) -> Option<Rmse>, Option<[f64; 4]>);

/// Median and 10 % / 90 % quantiles.
fn band(mut v: Vec<f64>) -> Option<[f64; 3]> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let q = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
    Some([q(0.5), q(0.1), q(0.9)])
}

/// Runs every configuration `trials` times and returns the Markdown table of medians and 10–90 % bands beside the
/// thesis's published single draw.
pub fn experiment(trials: u64, seed: u64) -> String {
    let mut out = String::new();
    out.push_str(&format!(
        "Seed 001 Monte Carlo: {trials} trials per configuration (seed {seed}), σ = {NOISE_MM} mm on every image \
         coordinate, 10 control and 10 check points, heights U(0, 40) m, H = {HEIGHT_M} m, B = {BASE_M:.3} m.\n\
         Check-point RMSE in metres: median [10 %–90 %] of the trials; the thesis's single draw beside it.\n\n\
         | configuration | method | RMSE X | RMSE Y | RMSE Z | total | thesis X / Y / Z / total | failed |\n\
         |---|---|---|---|---|---|---|---|\n"
    ));
    for config in configs() {
        let results: Vec<Trial> = (0..trials).map(|t| run_trial(&config, seed, t, NOISE_MM)).collect();
        let methods: [Method; 4] = [
            ("collinearity", |t| t.collinearity, Some(config.thesis_collinearity)),
            ("essential + affine", |t| t.essential_affine, Some(config.thesis_essential)),
            ("essential + similarity", |t| t.essential_similarity, None),
            ("bundle (lineflow)", |t| t.bundle, None),
        ];
        for (name, get, thesis) in methods {
            let ok: Vec<Rmse> = results.iter().filter_map(get).collect();
            let cells: Vec<String> = (0..4)
                .map(|k| match band(ok.iter().map(|r| r[k]).collect()) {
                    Some([m, lo, hi]) => format!("{m:.3} [{lo:.2}–{hi:.2}]"),
                    None => "—".into(),
                })
                .collect();
            let thesis = thesis.map_or("—".into(), |t| format!("{:.3} / {:.3} / {:.3} / {:.3}", t[0], t[1], t[2], t[3]));
            out.push_str(&format!(
                "| {} | {name} | {} | {} | {} | {} | {thesis} | {} |\n",
                config.name,
                cells[0],
                cells[1],
                cells[2],
                cells[3],
                results.len() - ok.len()
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn without_noise_both_methods_are_exact_for_every_configuration() {
        for config in configs() {
            for trial in 0..3 {
                let t = run_trial(&config, 7, trial, 0.0);
                for (name, r) in [
                    ("collinearity", t.collinearity),
                    ("essential + affine", t.essential_affine),
                    ("essential + similarity", t.essential_similarity),
                    ("bundle", t.bundle),
                ] {
                    let r = r.unwrap_or_else(|| panic!("{} {name} failed", config.name));
                    assert!(r[3] < 1e-6, "{} {name}: {r:?}", config.name);
                }
            }
        }
    }

    #[test]
    fn with_the_thesis_noise_the_collinearity_errors_have_the_expected_size() {
        let config = &configs()[0];
        let totals: Vec<f64> = (0..60)
            .filter_map(|t| run_trial(config, 3, t, NOISE_MM).collinearity)
            .map(|r| r[3])
            .collect();
        let [median, _, _] = band(totals).unwrap();
        // Normal-case precision (spec §3.1): σ_XY ≈ 1 m, σ_Z ≈ 3–5 m, so a total of roughly 2–3 m.
        assert!((1.5..3.5).contains(&median), "median total RMSE {median} m");
    }
}
