//! Bundle adjustment by collinearity: poses and object points adjusted together to the image observations and the
//! control points' coordinates, with their a-priori standard deviations. Levenberg–Marquardt on the normal
//! equations reduced to the cameras (Schur complement: the 3×3 point blocks are eliminated, so the system solved is
//! 6 × cameras square whatever the number of points), a Huber loss, and the thesis's remove-outliers-and-resolve.
//!
//! With a [`SelfCalibration`] the interior orientation joins as eight unknowns shared by every camera (the fixed
//! ones held), bordering the reduced system; the observations are then measured pixel positions, corrected by the
//! camera of the moment.
use nalgebra::{DMatrix, DVector, Matrix3, SMatrix, Vector3};

use crate::interior::{InteriorScale, N_INTERIOR};
use crate::{Camera, InteriorReport, Pose, SelfCalibration, Vec3};

/// One image measurement: ideal photo coordinates (mm, relative to the principal point, distortion removed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageObservation {
    /// Index into the poses.
    pub camera: usize,
    /// Index into the points.
    pub point: usize,
    /// Ideal photo coordinates, mm.
    pub ideal: [f64; 2],
    /// A-priori standard deviation of each coordinate, mm.
    pub sigma_mm: f64,
}

/// A surveyed point: its coordinates are observations too.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointPrior {
    /// Index into the points.
    pub point: usize,
    /// Surveyed coordinates, metres.
    pub xyz: Vec3,
    /// Standard deviations, metres.
    pub sigma_m: [f64; 3],
}

/// What is adjusted.
#[derive(Debug, Clone)]
pub struct BundleProblem {
    /// Principal distance, mm.
    pub focal_mm: f64,
    /// Exterior orientations (adjusted in place).
    pub poses: Vec<Pose>,
    /// Object points (adjusted in place).
    pub points: Vec<Vec3>,
    /// Image measurements.
    pub observations: Vec<ImageObservation>,
    /// Control points.
    pub priors: Vec<PointPrior>,
    /// Poses held fixed (a datum for a block without control).
    pub fixed: Vec<usize>,
    /// The interior orientation as unknowns (`None`: the observations' ideal coordinates and `focal_mm` are final).
    pub calibration: Option<SelfCalibration>,
}

impl BundleProblem {
    /// The ideal photo coordinates of observation `i` with the camera of the moment.
    fn ideal(&self, i: usize) -> [f64; 2] {
        match &self.calibration {
            Some(c) => c.camera.pixel_to_ideal(c.pixels[i]),
            None => self.observations[i].ideal,
        }
    }

    /// Free interior parameters.
    fn n_interior_free(&self) -> usize {
        self.calibration.as_ref().map_or(0, |c| c.free.len())
    }
}

/// Adjustment settings.
#[derive(Debug, Clone, Copy)]
pub struct BundleOptions {
    /// Levenberg–Marquardt iterations per solve.
    pub max_iterations: usize,
    /// Huber threshold in a-priori standard deviations (0 = plain least squares).
    pub huber_k: f64,
    /// Observations whose residual exceeds this many σ0·σ are removed and the block solved again (0 = never).
    pub outlier_k: f64,
    /// Rounds of removal at most.
    pub outlier_rounds: usize,
}

impl Default for BundleOptions {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            huber_k: 2.0,
            outlier_k: 3.0,
            outlier_rounds: 3,
        }
    }
}

/// How the adjustment went.
#[derive(Debug, Clone, Default)]
pub struct BundleReport {
    /// Iterations of the last solve.
    pub iterations: usize,
    /// A-posteriori standard deviation of unit weight.
    pub sigma0: f64,
    /// RMS of the image residuals of the observations kept, mm.
    pub rms_mm: f64,
    /// Observations removed as outliers (indices into `observations`).
    pub removed: Vec<usize>,
    /// Per pose: standard deviations of the centre (m) and of the small rotation angles (rad); NaN for fixed poses.
    pub pose_sigmas: Vec<([f64; 3], [f64; 3])>,
    /// The adjusted interior orientation with its precision, when it was an unknown.
    pub interior: Option<InteriorReport>,
}

fn skew_exp(w: &Vector3<f64>) -> Matrix3<f64> {
    nalgebra::Rotation3::new(*w).into_inner()
}

/// The pose after a parameter step: rotation increment (applied in the camera frame) and centre shift.
fn stepped(p: &Pose, d: &[f64]) -> Pose {
    Pose {
        rotation: skew_exp(&Vector3::new(d[0], d[1], d[2])) * p.rotation,
        center: p.center + Vector3::new(d[3], d[4], d[5]),
    }
}

fn project(focal: f64, pose: &Pose, x: &Vec3) -> Option<[f64; 2]> {
    let uvw = pose.to_camera(x);
    (uvw.z < 0.0).then(|| [-focal * uvw.x / uvw.z, -focal * uvw.y / uvw.z])
}

type Jac = (SMatrix<f64, 2, 6>, SMatrix<f64, 2, 3>);

/// Residual (observed − computed) and its Jacobians by central differences, with the same step rule as the update.
fn linearise(focal: f64, pose: &Pose, x: &Vec3, obs: &[f64; 2]) -> Option<([f64; 2], Jac)> {
    let f0 = project(focal, pose, x)?;
    let mut a = SMatrix::<f64, 2, 6>::zeros();
    let mut b = SMatrix::<f64, 2, 3>::zeros();
    for k in 0..6 {
        let h = if k < 3 { 1e-7 } else { 1e-6 * (1.0 + (pose.center - x).norm()) };
        let mut d = [0.0; 6];
        d[k] = h;
        let plus = project(focal, &stepped(pose, &d), x)?;
        d[k] = -h;
        let minus = project(focal, &stepped(pose, &d), x)?;
        a[(0, k)] = (plus[0] - minus[0]) / (2.0 * h);
        a[(1, k)] = (plus[1] - minus[1]) / (2.0 * h);
    }
    for k in 0..3 {
        let h = 1e-6 * (1.0 + (pose.center - x).norm());
        let mut dx = Vector3::zeros();
        dx[k] = h;
        let plus = project(focal, pose, &(x + dx))?;
        let minus = project(focal, pose, &(x - dx))?;
        b[(0, k)] = (plus[0] - minus[0]) / (2.0 * h);
        b[(1, k)] = (plus[1] - minus[1]) / (2.0 * h);
    }
    Some(([obs[0] - f0[0], obs[1] - f0[1]], (a, b)))
}

fn huber(r: f64, k: f64) -> f64 {
    if k <= 0.0 || r <= k {
        1.0
    } else {
        k / r
    }
}

/// Weighted cost of the current state (robust weights frozen at `weights`).
fn cost(p: &BundleProblem, active: &[bool], k: f64) -> f64 {
    let mut c = 0.0;
    for (i, o) in p.observations.iter().enumerate().filter(|(i, _)| active[*i]) {
        match project(p.focal_mm, &p.poses[o.camera], &p.points[o.point]) {
            Some(f) => {
                let ideal = p.ideal(i);
                let r = ((ideal[0] - f[0]).powi(2) + (ideal[1] - f[1]).powi(2)).sqrt() / o.sigma_mm;
                // Huber's ρ, so that the robust iterations minimise one function.
                c += if k <= 0.0 || r <= k { r * r } else { 2.0 * k * r - k * k };
            }
            None => c += 1e6,
        }
    }
    for q in &p.priors {
        let d = p.points[q.point] - q.xyz;
        c += (0..3).map(|i| (d[i] / q.sigma_m[i]).powi(2)).sum::<f64>();
    }
    c + p.calibration.as_ref().map_or(0.0, SelfCalibration::prior_cost)
}

/// Per point: inverse of its damped block, its gradient, (free camera, W block) pairs, and its block against the
/// interior orientation when that is adjusted.
type PointBlocks = Vec<(Matrix3<f64>, Vector3<f64>, Vec<(usize, SMatrix<f64, 6, 3>)>, Option<InteriorBlock>)>;

/// A point's coupling to the interior unknowns.
type InteriorBlock = SMatrix<f64, N_INTERIOR, 3>;

struct Normal {
    /// Reduced system: the free cameras, then the interior orientation when it is adjusted.
    s: DMatrix<f64>,
    rhs: DVector<f64>,
    points: PointBlocks,
}

/// Derivatives of an observation's model part (projection − correction) with respect to the scaled interior
/// unknowns, by central differences of the correction; columns of fixed parameters are zero.
struct InteriorJacobian {
    plus: [Camera; N_INTERIOR],
    minus: [Camera; N_INTERIOR],
    free: [bool; N_INTERIOR],
}

/// Finite-difference step of the scaled interior, mm at the sensor's corner.
const INTERIOR_STEP: f64 = 1e-6;

impl InteriorJacobian {
    fn new(c: &SelfCalibration) -> Self {
        let scale = InteriorScale::of(&c.camera);
        let v = scale.vector(&c.camera);
        let shifted = |k: usize, h: f64| {
            let mut w = v;
            w[k] += h;
            scale.camera(&c.camera, &w)
        };
        Self {
            plus: std::array::from_fn(|k| shifted(k, INTERIOR_STEP)),
            minus: std::array::from_fn(|k| shifted(k, -INTERIOR_STEP)),
            free: std::array::from_fn(|k| c.free.iter().any(|p| p.index() == k)),
        }
    }

    fn rows(&self, pixel: [f64; 2], projected: [f64; 2], focal: f64) -> SMatrix<f64, 2, N_INTERIOR> {
        let mut c = SMatrix::<f64, 2, N_INTERIOR>::zeros();
        for k in (0..N_INTERIOR).filter(|&k| self.free[k]) {
            let (a, b) = (self.plus[k].pixel_to_ideal(pixel), self.minus[k].pixel_to_ideal(pixel));
            for d in 0..2 {
                c[(d, k)] = -(a[d] - b[d]) / (2.0 * INTERIOR_STEP);
            }
        }
        // The projection is linear in f; one scaled unit of f is a millimetre.
        if self.free[0] {
            c[(0, 0)] += projected[0] / focal;
            c[(1, 0)] += projected[1] / focal;
        }
        c
    }
}

/// Builds and reduces the damped normal equations.
fn normal_equations(p: &BundleProblem, active: &[bool], free: &[Option<usize>], n_free: usize, lambda: f64, k: f64) -> Normal {
    let interior = p.calibration.as_ref().map(|c| (InteriorJacobian::new(c), &c.pixels));
    let mut u = vec![SMatrix::<f64, 6, 6>::zeros(); n_free];
    let mut gc = vec![SMatrix::<f64, 6, 1>::zeros(); n_free];
    let mut v = vec![Matrix3::<f64>::zeros(); p.points.len()];
    let mut gp = vec![Vector3::<f64>::zeros(); p.points.len()];
    let mut w: Vec<Vec<(usize, SMatrix<f64, 6, 3>)>> = vec![Vec::new(); p.points.len()];
    let mut u_int = SMatrix::<f64, N_INTERIOR, N_INTERIOR>::zeros();
    let mut g_int = SMatrix::<f64, N_INTERIOR, 1>::zeros();
    let mut u_cam_int = vec![SMatrix::<f64, 6, N_INTERIOR>::zeros(); if interior.is_some() { n_free } else { 0 }];
    let mut w_int: Vec<Option<InteriorBlock>> = vec![None; p.points.len()];
    for (i, o) in p.observations.iter().enumerate().filter(|(i, _)| active[*i]) {
        let ideal = p.ideal(i);
        let Some((e, (a, b))) = linearise(p.focal_mm, &p.poses[o.camera], &p.points[o.point], &ideal) else {
            continue;
        };
        let r = (e[0] * e[0] + e[1] * e[1]).sqrt() / o.sigma_mm;
        let wt = huber(r, k) / (o.sigma_mm * o.sigma_mm);
        let c = interior
            .as_ref()
            .map(|(jac, pixels)| jac.rows(pixels[i], [ideal[0] - e[0], ideal[1] - e[1]], p.focal_mm));
        let e = nalgebra::Vector2::new(e[0], e[1]);
        v[o.point] += b.transpose() * b * wt;
        gp[o.point] += b.transpose() * e * wt;
        if let Some(c) = &c {
            u_int += c.transpose() * c * wt;
            g_int += c.transpose() * e * wt;
            *w_int[o.point].get_or_insert_with(InteriorBlock::zeros) += c.transpose() * b * wt;
        }
        if let Some(j) = free[o.camera] {
            u[j] += a.transpose() * a * wt;
            gc[j] += a.transpose() * e * wt;
            if let Some(c) = &c {
                u_cam_int[j] += a.transpose() * c * wt;
            }
            let wb = a.transpose() * b * wt;
            match w[o.point].iter_mut().find(|(c, _)| *c == j) {
                Some((_, m)) => *m += wb,
                None => w[o.point].push((j, wb)),
            }
        }
    }
    for q in &p.priors {
        let d = q.xyz - p.points[q.point];
        for i in 0..3 {
            let wt = 1.0 / (q.sigma_m[i] * q.sigma_m[i]);
            v[q.point][(i, i)] += wt;
            gp[q.point][i] += wt * d[i];
        }
    }
    let base = 6 * n_free;
    let dim = base + if interior.is_some() { N_INTERIOR } else { 0 };
    let mut s = DMatrix::<f64>::zeros(dim, dim);
    let mut rhs = DVector::<f64>::zeros(dim);
    for j in 0..n_free {
        let mut uj = u[j];
        for i in 0..6 {
            uj[(i, i)] += lambda * uj[(i, i)].max(1e-9);
        }
        s.view_mut((6 * j, 6 * j), (6, 6)).copy_from(&uj);
        rhs.rows_mut(6 * j, 6).copy_from(&gc[j]);
    }
    if let (Some((jac, _)), Some(cal)) = (&interior, &p.calibration) {
        let v = InteriorScale::of(&cal.camera).vector(&cal.camera);
        for (k, value, weight) in cal.scaled_priors() {
            u_int[(k, k)] += weight;
            g_int[k] += weight * (value - v[k]);
        }
        for (j, uc) in u_cam_int.iter().enumerate() {
            s.view_mut((6 * j, base), (6, N_INTERIOR)).copy_from(uc);
            s.view_mut((base, 6 * j), (N_INTERIOR, 6)).copy_from(&uc.transpose());
        }
        for d in 0..N_INTERIOR {
            // A fixed parameter's row is empty: a unit diagonal keeps the system regular and its step zero.
            u_int[(d, d)] = if jac.free[d] {
                u_int[(d, d)] + lambda * u_int[(d, d)].max(1e-9)
            } else {
                1.0
            };
        }
        s.view_mut((base, base), (N_INTERIOR, N_INTERIOR)).copy_from(&u_int);
        rhs.rows_mut(base, N_INTERIOR).copy_from(&g_int);
    }
    let mut points = Vec::with_capacity(p.points.len());
    for i in 0..p.points.len() {
        let mut vi = v[i];
        for d in 0..3 {
            vi[(d, d)] += lambda * vi[(d, d)].max(1e-9) + 1e-12;
        }
        let vinv = vi.try_inverse().unwrap_or_else(Matrix3::zeros);
        for (j, wj) in &w[i] {
            let wv = wj * vinv;
            let mut r = rhs.rows_mut(6 * j, 6);
            r -= wv * gp[i];
            for (k2, wk) in &w[i] {
                let mut blk = s.view_mut((6 * j, 6 * k2), (6, 6));
                blk -= wv * wk.transpose();
            }
            if let Some(wi) = &w_int[i] {
                let mut blk = s.view_mut((6 * j, base), (6, N_INTERIOR));
                blk -= wv * wi.transpose();
            }
        }
        if let Some(wi) = &w_int[i] {
            let wv = wi * vinv;
            let mut r = rhs.rows_mut(base, N_INTERIOR);
            r -= wv * gp[i];
            for (k2, wk) in &w[i] {
                let mut blk = s.view_mut((base, 6 * k2), (N_INTERIOR, 6));
                blk -= wv * wk.transpose();
            }
            let mut blk = s.view_mut((base, base), (N_INTERIOR, N_INTERIOR));
            blk -= wv * wi.transpose();
        }
        points.push((vinv, gp[i], std::mem::take(&mut w[i]), w_int[i]));
    }
    Normal { s, rhs, points }
}

/// One Levenberg–Marquardt solve of the active observations.
fn solve(p: &mut BundleProblem, active: &[bool], o: &BundleOptions) -> (usize, Option<DMatrix<f64>>) {
    let mut free = vec![None; p.poses.len()];
    let mut n_free = 0;
    for (c, f) in free.iter_mut().enumerate() {
        if !p.fixed.contains(&c) {
            *f = Some(n_free);
            n_free += 1;
        }
    }
    let mut lambda = 1e-3;
    let mut current = cost(p, active, o.huber_k);
    let mut iterations = 0;
    for _ in 0..o.max_iterations {
        iterations += 1;
        let ne = normal_equations(p, active, &free, n_free, lambda, o.huber_k);
        let Some(chol) = ne.s.clone().cholesky() else {
            lambda *= 10.0;
            continue;
        };
        let dc = chol.solve(&ne.rhs);
        let saved = (
            p.poses.clone(),
            p.points.clone(),
            p.calibration.as_ref().map(|c| c.camera),
            p.focal_mm,
        );
        for (c, f) in free.iter().enumerate() {
            if let Some(j) = f {
                p.poses[c] = stepped(&p.poses[c], dc.rows(6 * j, 6).as_slice());
            }
        }
        if let Some(cal) = &mut p.calibration {
            let scale = InteriorScale::of(&cal.camera);
            let mut v = scale.vector(&cal.camera);
            for (k, x) in v.iter_mut().enumerate() {
                *x += dc[6 * n_free + k];
            }
            cal.camera = scale.camera(&cal.camera, &v);
            p.focal_mm = cal.camera.focal_mm;
        }
        let mut step = 0.0f64;
        for (i, (vinv, g, w, wi)) in ne.points.iter().enumerate() {
            let mut r = *g;
            for (j, wj) in w {
                r -= wj.transpose() * dc.rows(6 * j, 6);
            }
            if let Some(wi) = wi {
                r -= wi.transpose() * dc.rows(6 * n_free, N_INTERIOR);
            }
            let dp = vinv * r;
            step = step.max(dp.norm());
            p.points[i] += dp;
        }
        let next = cost(p, active, o.huber_k);
        if next < current {
            let gain = (current - next) / current.max(1e-300);
            current = next;
            lambda = (lambda / 3.0).max(1e-12);
            if gain < 1e-10 || (step < 1e-9 && dc.norm() < 1e-12) {
                break;
            }
        } else {
            let camera;
            (p.poses, p.points, camera, p.focal_mm) = saved;
            if let (Some(cal), Some(camera)) = (&mut p.calibration, camera) {
                cal.camera = camera;
            }
            lambda *= 4.0;
            if lambda > 1e12 {
                break;
            }
        }
    }
    // Covariance of the cameras (and the interior): the undamped reduced system's inverse. Rounding in the Schur
    // complement of a large block (points whose rays nearly coincide) can leave it short of positive definite; a
    // damping far below the precision of any parameter then stands in for none.
    let cov = [0.0, 1e-12, 1e-10, 1e-8]
        .iter()
        .find_map(|&l| normal_equations(p, active, &free, n_free, l, o.huber_k).s.cholesky())
        .map(|c| c.inverse());
    (iterations, cov)
}

/// Adjusts the block: solves, removes observations beyond `outlier_k`·σ0·σ, solves again; reports σ0, the RMS and
/// the poses' standard deviations.
pub fn adjust(p: &mut BundleProblem, o: &BundleOptions) -> BundleReport {
    let mut active = vec![true; p.observations.len()];
    let mut report = BundleReport::default();
    let mut round = 0;
    loop {
        let (iterations, cov) = solve(p, &active, o);
        report.iterations = iterations;
        // σ0 from the plain (unweighted by Huber) residuals of the active observations and the priors.
        let mut sum = 0.0;
        let mut sum_mm = 0.0;
        let mut n_obs = 0usize;
        let mut normalised = vec![0.0; p.observations.len()];
        for (i, ob) in p.observations.iter().enumerate() {
            let ideal = p.ideal(i);
            let r = project(p.focal_mm, &p.poses[ob.camera], &p.points[ob.point])
                .map(|f| ((ideal[0] - f[0]).powi(2) + (ideal[1] - f[1]).powi(2)).sqrt())
                .unwrap_or(f64::INFINITY);
            normalised[i] = r / ob.sigma_mm;
            if active[i] {
                sum += normalised[i] * normalised[i];
                sum_mm += r * r;
                n_obs += 1;
            }
        }
        for q in &p.priors {
            let d = p.points[q.point] - q.xyz;
            sum += (0..3).map(|i| (d[i] / q.sigma_m[i]).powi(2)).sum::<f64>();
        }
        let n_interior_priors = p.calibration.as_ref().map_or(0, |c| c.scaled_priors().len());
        sum += p.calibration.as_ref().map_or(0.0, SelfCalibration::prior_cost);
        let unknowns = 6 * (p.poses.len() - p.fixed.len()) + 3 * p.points.len() + p.n_interior_free();
        let redundancy = (2 * n_obs + 3 * p.priors.len() + n_interior_priors) as f64 - unknowns as f64;
        report.sigma0 = (sum / redundancy.max(1.0)).sqrt();
        report.rms_mm = (sum_mm / n_obs.max(1) as f64).sqrt();
        report.pose_sigmas = sigmas(p, cov.as_ref(), report.sigma0);
        report.interior = p
            .calibration
            .as_ref()
            .map(|c| interior_report(c, cov.as_ref(), 6 * (p.poses.len() - p.fixed.len()), report.sigma0));
        if o.outlier_k <= 0.0 || round >= o.outlier_rounds {
            break;
        }
        // The scale of the residuals from their median, not from σ0: the blunders being looked for inflate σ0 and
        // would hide themselves. For a 2-D residual whose coordinates have σ, the median length is 1.1774 σ.
        let mut lengths: Vec<f64> = (0..active.len()).filter(|&i| active[i]).map(|i| normalised[i]).collect();
        lengths.sort_by(f64::total_cmp);
        let robust = lengths.get(lengths.len() / 2).map_or(1.0, |m| m / 1.1774);
        let limit = o.outlier_k * robust.max(1.0) * std::f64::consts::SQRT_2;
        let bad: Vec<usize> = (0..active.len()).filter(|&i| active[i] && normalised[i] > limit).collect();
        if bad.is_empty() {
            break;
        }
        for &i in &bad {
            active[i] = false;
        }
        report.removed.extend(bad);
        round += 1;
    }
    report.removed.sort_unstable();
    report
}

/// [`resect_once`], then the points whose residual exceeds three times the median (at least 3σ) are dropped and
/// the pose solved again, twice: a block's wrong tie points are not random, a Huber loss alone is pulled by them.
pub fn resect(focal: f64, initial: &Pose, points: &[Vec3], ideal: &[[f64; 2]], sigma_mm: f64) -> Option<(Pose, f64)> {
    let (mut pose, mut median) = resect_once(focal, initial, points, ideal, sigma_mm)?;
    for _ in 0..2 {
        let limit = (3.0 * median).max(3.0 * sigma_mm);
        let (kept_x, kept_o): (Vec<Vec3>, Vec<[f64; 2]>) = points
            .iter()
            .zip(ideal)
            .filter(|(x, o)| project(focal, &pose, x).is_some_and(|f| (o[0] - f[0]).hypot(o[1] - f[1]) <= limit))
            .map(|(x, o)| (*x, *o))
            .unzip();
        if kept_x.len() == points.len() || kept_x.len() < 4 {
            break;
        }
        (pose, median) = resect_once(focal, &pose, &kept_x, &kept_o, sigma_mm)?;
    }
    Some((pose, median))
}

/// Space resection: the pose that best fits known object points to their ideal photo coordinates, by Gauss–Newton
/// with a Huber loss from an initial pose (the neighbouring frame's, in a strip). Returns the pose and the median
/// residual (mm; robust to the wrong tie points a block still holds), or `None` with fewer than four points or when
/// the iteration fails.
fn resect_once(focal: f64, initial: &Pose, points: &[Vec3], ideal: &[[f64; 2]], sigma_mm: f64) -> Option<(Pose, f64)> {
    if points.len() < 4 || points.len() != ideal.len() {
        return None;
    }
    let mut pose = *initial;
    let mut lambda = 1e-3;
    // Huber's ρ summed: the function the weighted iterations minimise.
    let rms = |pose: &Pose| -> f64 {
        let mut sum = 0.0;
        for (x, o) in points.iter().zip(ideal) {
            match project(focal, pose, x) {
                Some(f) => {
                    let r = ((o[0] - f[0]).powi(2) + (o[1] - f[1]).powi(2)).sqrt() / sigma_mm;
                    sum += if r <= 2.0 { r * r } else { 4.0 * r - 4.0 };
                }
                None => return f64::INFINITY,
            }
        }
        sum
    };
    let mut current = rms(&pose);
    for _ in 0..100 {
        let mut h = SMatrix::<f64, 6, 6>::zeros();
        let mut g = SMatrix::<f64, 6, 1>::zeros();
        for (x, o) in points.iter().zip(ideal) {
            let Some((e, (a, _))) = linearise(focal, &pose, x, o) else {
                continue;
            };
            let w = huber((e[0] * e[0] + e[1] * e[1]).sqrt() / sigma_mm, 2.0);
            let e = nalgebra::Vector2::new(e[0], e[1]);
            h += a.transpose() * a * w;
            g += a.transpose() * e * w;
        }
        for i in 0..6 {
            h[(i, i)] *= 1.0 + lambda;
        }
        let d = h.cholesky()?.solve(&g);
        let next = stepped(&pose, d.as_slice());
        let r = rms(&next);
        if r < current {
            let done = (current - r) < 1e-12 * current.max(1e-300) || d.norm() < 1e-12;
            pose = next;
            current = r;
            lambda = (lambda / 3.0).max(1e-12);
            if done {
                break;
            }
        } else {
            lambda *= 4.0;
            if lambda > 1e10 {
                break;
            }
        }
    }
    if !current.is_finite() {
        return None;
    }
    let mut residuals: Vec<f64> = points
        .iter()
        .zip(ideal)
        .filter_map(|(x, o)| project(focal, &pose, x).map(|f| (o[0] - f[0]).hypot(o[1] - f[1])))
        .collect();
    residuals.sort_by(f64::total_cmp);
    Some((pose, residuals[residuals.len() / 2]))
}

/// The interior's σ and correlations from the covariance of the reduced system, whose interior rows start at `base`.
fn interior_report(c: &SelfCalibration, cov: Option<&DMatrix<f64>>, base: usize, sigma0: f64) -> InteriorReport {
    let scale = InteriorScale::of(&c.camera);
    let free: [bool; N_INTERIOR] = std::array::from_fn(|k| c.free.iter().any(|p| p.index() == k));
    let var = |a: usize, b: usize| cov.filter(|_| free[a] && free[b]).map_or(f64::NAN, |m| m[(base + a, base + b)]);
    let focal_exterior_correlation = match cov.filter(|_| free[0]) {
        Some(m) => (0..base)
            .filter(|i| i % 6 >= 3)
            .map(|i| m[(base, i)] / (m[(base, base)] * m[(i, i)]).sqrt())
            .filter(|r| r.is_finite())
            .max_by(|a, b| a.abs().total_cmp(&b.abs()))
            .unwrap_or(f64::NAN),
        None => f64::NAN,
    };
    InteriorReport {
        focal_exterior_correlation,
        camera: c.camera,
        free: c.free.clone(),
        sigmas: std::array::from_fn(|k| match var(k, k) {
            v if v.is_nan() => f64::NAN,
            v => sigma0 * v.max(0.0).sqrt() * scale.per_unit(k),
        }),
        correlations: std::array::from_fn(|a| std::array::from_fn(|b| var(a, b) / (var(a, a) * var(b, b)).sqrt())),
    }
}

fn sigmas(p: &BundleProblem, cov: Option<&DMatrix<f64>>, sigma0: f64) -> Vec<([f64; 3], [f64; 3])> {
    let mut j = 0;
    (0..p.poses.len())
        .map(|c| {
            if p.fixed.contains(&c) {
                return ([f64::NAN; 3], [f64::NAN; 3]);
            }
            let s = |k: usize| cov.map_or(f64::NAN, |m| sigma0 * m[(6 * j + k, 6 * j + k)].max(0.0).sqrt());
            let out = ([s(3), s(4), s(5)], [s(0), s(1), s(2)]);
            j += 1;
            out
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{look_at, Interior};

    /// A strip of cameras in front of a wall with relief, its points, and exact observations.
    fn block(noise_mm: f64) -> (BundleProblem, Vec<Pose>, Vec<Vec3>) {
        let f = 18.0;
        let poses: Vec<Pose> = (0..6)
            .map(|i| {
                let c = Vec3::new(i as f64 * 1.5, -12.0, 1.6);
                Pose {
                    center: c,
                    rotation: look_at(&c, &Vec3::new(i as f64 * 1.5 + 0.3, 0.0, 3.0), &Vec3::z()),
                }
            })
            .collect();
        let mut points = Vec::new();
        for k in 0..150 {
            let (x, z) = ((k % 15) as f64 * 0.7 - 1.0, (k / 15) as f64 * 0.6);
            points.push(Vec3::new(x, ((k * 7) % 5) as f64 * 0.08, z));
        }
        let mut state = 12345u64;
        let mut gauss = move || {
            // Sum of uniforms: close enough to a normal for a test.
            (0..12)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state >> 11) as f64 / (1u64 << 53) as f64
                })
                .sum::<f64>()
                - 6.0
        };
        let mut observations = Vec::new();
        for (c, pose) in poses.iter().enumerate() {
            for (i, x) in points.iter().enumerate() {
                if let Some(p) = project(f, pose, x) {
                    if p[0].abs() < 11.0 && p[1].abs() < 7.5 {
                        observations.push(ImageObservation {
                            camera: c,
                            point: i,
                            ideal: [p[0] + noise_mm * gauss(), p[1] + noise_mm * gauss()],
                            sigma_mm: 0.005,
                        });
                    }
                }
            }
        }
        let priors = [0usize, 14, 135, 149, 70]
            .iter()
            .map(|&i| PointPrior {
                point: i,
                xyz: points[i],
                sigma_m: [0.002; 3],
            })
            .collect();
        let problem = BundleProblem {
            focal_mm: f,
            poses: poses.clone(),
            points: points.clone(),
            observations,
            priors,
            fixed: vec![],
            calibration: None,
        };
        (problem, poses, points)
    }

    fn perturb(p: &mut BundleProblem) {
        for (k, pose) in p.poses.iter_mut().enumerate() {
            let s = (k as f64 * 0.37).sin();
            *pose = stepped(pose, &[0.01 * s, -0.008, 0.012 * s, 0.2 * s, -0.15, 0.1]);
        }
        for (k, x) in p.points.iter_mut().enumerate() {
            *x += Vec3::new(0.05 * (k as f64).cos(), 0.08, -0.04 * (k as f64).sin());
        }
    }

    #[test]
    fn a_perturbed_block_returns_to_the_truth_within_the_noise() {
        let (mut p, poses, points) = block(0.003);
        perturb(&mut p);
        let r = adjust(&mut p, &BundleOptions::default());
        for ((est, truth), (sigma, _)) in p.poses.iter().zip(&poses).zip(&r.pose_sigmas) {
            for (k, &sigma_k) in sigma.iter().enumerate() {
                let off = (est.center[k] - truth.center[k]).abs();
                // The stated precision is honest (4 σ) and useful (a centimetre at 12 m).
                assert!(
                    off < 4.0 * sigma_k && sigma_k < 0.01,
                    "centre axis {k} off by {off} m, sigma {sigma_k}"
                );
            }
        }
        let worst = p.points.iter().zip(&points).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        assert!(worst < 0.02, "worst point off by {worst} m");
        // Noise 3 µm against an a-priori 5 µm: σ0 near 0.6.
        assert!((0.4..0.9).contains(&r.sigma0), "sigma0 {}", r.sigma0);
        assert!(r
            .pose_sigmas
            .iter()
            .all(|(c, a)| c.iter().chain(a).all(|s| s.is_finite() && *s > 0.0)));
    }

    /// Two strips of a wall with 0.6 m of relief seen by a distorted camera, observed in measured pixels with
    /// 0.2 px of noise; five control points. Returns the problem started from the nominal camera (EXIF-like: the
    /// focal length 2 % off, no principal point offset, no distortion), the true camera and poses.
    fn self_calibration_block() -> (BundleProblem, Camera, Vec<Pose>) {
        let truth = Camera {
            width: 1600,
            height: 1064,
            pixel_size_mm: 0.0147,
            focal_mm: 18.0,
            principal_point_mm: [0.12, -0.08],
            radial: [1.7e-4, -2.0e-7, 0.0],
            decentering: [6e-6, -4e-6],
        };
        let poses: Vec<Pose> = (0..16)
            .map(|i| {
                let (k, strip) = ((i % 8) as f64, (i / 8) as f64);
                let c = Vec3::new(k * 1.6 - 1.0, -11.0 + 0.8 * strip, 1.5 + 3.0 * strip);
                let aim = Vec3::new(k * 1.6 - 0.6 + 0.8 * (k * 0.9).sin(), 0.0, 2.8 + 0.6 * (k * 1.3).cos());
                Pose {
                    center: c,
                    rotation: look_at(&c, &aim, &Vec3::z()),
                }
            })
            .collect();
        let points: Vec<Vec3> = (0..600)
            .map(|k| {
                let (x, z) = ((k % 40) as f64 * 0.33 - 3.0, (k / 40) as f64 * 0.42 - 0.5);
                Vec3::new(x, ((k * 7) % 5) as f64 * 0.15, z)
            })
            .collect();
        let mut state = 99u64;
        let mut noise = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.7
        };
        let (mut observations, mut pixels) = (Vec::new(), Vec::new());
        for (c, pose) in poses.iter().enumerate() {
            for (i, x) in points.iter().enumerate() {
                let Some(px) = project(truth.focal_mm, pose, x).and_then(|q| truth.ideal_to_pixel(q)) else {
                    continue;
                };
                if truth.contains(px, 2.0) {
                    observations.push(ImageObservation {
                        camera: c,
                        point: i,
                        ideal: [0.0; 2],
                        sigma_mm: 0.3 * truth.pixel_size_mm,
                    });
                    pixels.push([px[0] + noise(), px[1] + noise()]);
                }
            }
        }
        let priors = [0usize, 39, 560, 599, 300]
            .iter()
            .map(|&i| PointPrior {
                point: i,
                xyz: points[i],
                sigma_m: [0.003; 3],
            })
            .collect();
        let nominal = Camera {
            focal_mm: 18.0 * 1.02,
            ..Camera::pinhole(1600, 1064, 0.0147, 18.0)
        };
        let mut problem = BundleProblem {
            focal_mm: nominal.focal_mm,
            poses: poses
                .iter()
                .map(|q| stepped(q, &[0.003, -0.002, 0.004, 0.05, -0.04, 0.03]))
                .collect(),
            points: points
                .iter()
                .enumerate()
                .map(|(k, x)| x + Vec3::new(0.02 * (k as f64).cos(), 0.03, 0.0))
                .collect(),
            observations,
            priors,
            fixed: vec![],
            calibration: Some(SelfCalibration {
                camera: nominal,
                free: Interior::ALL.to_vec(),
                pixels,
                priors: vec![],
            }),
        };
        for (i, o) in problem.observations.iter_mut().enumerate() {
            o.ideal = nominal.pixel_to_ideal(problem.calibration.as_ref().unwrap().pixels[i]);
        }
        (problem, truth, poses)
    }

    /// RMS distance over the frame between the pixels two cameras give the same ray, pixels, once their mean
    /// offset is taken out (a common shift is a small rotation, which the poses take up).
    fn disagreement(a: &Camera, b: &Camera) -> f64 {
        let mut d = Vec::new();
        for r in (0..a.height).step_by(53) {
            for c in (0..a.width).step_by(61) {
                let ray = a.pixel_to_ideal([c as f64, r as f64]);
                let ray = [ray[0] / a.focal_mm, ray[1] / a.focal_mm];
                let q = b.ideal_to_pixel([ray[0] * b.focal_mm, ray[1] * b.focal_mm]).expect("inverts");
                d.push([q[0] - c as f64, q[1] - r as f64]);
            }
        }
        let n = d.len() as f64;
        let mean = [d.iter().map(|v| v[0]).sum::<f64>() / n, d.iter().map(|v| v[1]).sum::<f64>() / n];
        (d.iter().map(|v| (v[0] - mean[0]).powi(2) + (v[1] - mean[1]).powi(2)).sum::<f64>() / n).sqrt()
    }

    #[test]
    fn a_self_calibrating_adjustment_recovers_the_camera_from_a_nominal_start() {
        let (mut p, truth, poses) = self_calibration_block();
        let start = p.calibration.as_ref().unwrap().camera;
        assert!(
            disagreement(&truth, &start) > 10.0,
            "the nominal camera must be far off: {}",
            disagreement(&truth, &start)
        );
        let r = adjust(&mut p, &BundleOptions::default());
        let cal = r.interior.as_ref().expect("an interior report");
        let off = disagreement(&truth, &cal.camera);
        assert!(off < 0.5, "adjusted camera {:?} disagrees by {off} px", cal.camera);
        // The principal point trades against p1/p2 (correlation −0.98 here) and only their sum is determined.
        let pp = (cal.camera.principal_point_mm[0] - truth.principal_point_mm[0]).abs();
        assert!(pp < 4.0 * cal.sigmas[1], "x0 off by {pp} mm, sigma {}", cal.sigmas[1]);
        assert!((cal.camera.focal_mm - truth.focal_mm).abs() < 4.0 * cal.sigmas[0] + 0.01, "{cal:?}");
        for (est, t) in p.poses.iter().zip(&poses) {
            assert!(
                (est.center - t.center).norm() < 0.02,
                "centre off by {}",
                (est.center - t.center).norm()
            );
        }
        // Noise of 0.2 px RMS against an a-priori 0.3 px.
        assert!((0.4..1.0).contains(&r.sigma0), "sigma0 {}", r.sigma0);
        assert!(cal.sigmas.iter().all(|s| s.is_finite() && *s > 0.0), "{:?}", cal.sigmas);
        let (_, _, rho) = cal.strongest_correlation().unwrap();
        assert!(rho.abs() <= 1.0 + 1e-9);
        // The same block with the camera's distortion held: the interior stays where it was.
        let (mut q, _, _) = self_calibration_block();
        q.calibration.as_mut().unwrap().free = vec![Interior::Focal];
        let r = adjust(&mut q, &BundleOptions::default());
        let cal = r.interior.unwrap();
        assert_eq!(cal.camera.radial, [0.0; 3]);
        assert!(cal.sigmas[3].is_nan() && cal.correlations[0][3].is_nan());
    }

    #[test]
    fn resection_recovers_a_pose_from_a_neighbouring_start() {
        let (p, poses, points) = block(0.0);
        let (obs, xyz): (Vec<[f64; 2]>, Vec<Vec3>) = p
            .observations
            .iter()
            .filter(|o| o.camera == 3)
            .map(|o| (o.ideal, points[o.point]))
            .unzip();
        let (pose, rms) = resect(p.focal_mm, &poses[2], &xyz, &obs, 0.005).unwrap();
        assert!((pose.center - poses[3].center).norm() < 1e-6, "{:?}", pose.center);
        assert!(rms < 1e-6);
        assert!(resect(p.focal_mm, &poses[2], &xyz[..3], &obs[..3], 0.005).is_none());
        // A fifth of the points are wrong tie points (shifted one "brick" along x): trimmed away, not averaged in.
        let wrong: Vec<Vec3> = xyz
            .iter()
            .enumerate()
            .map(|(i, x)| if i % 5 == 0 { x + Vec3::new(0.25, 0.0, 0.0) } else { *x })
            .collect();
        let (pose, median) = resect(p.focal_mm, &poses[2], &wrong, &obs, 0.005).unwrap();
        assert!((pose.center - poses[3].center).norm() < 1e-3, "{:?}", pose.center - poses[3].center);
        assert!(median < 1e-4, "median residual {median} mm");
    }

    #[test]
    fn gross_errors_are_removed_and_the_block_solved_again() {
        let (mut p, poses, _) = block(0.002);
        let n = p.observations.len();
        for k in (0..n).step_by(37) {
            p.observations[k].ideal[0] += 0.2;
        }
        perturb(&mut p);
        let r = adjust(&mut p, &BundleOptions::default());
        let planted: Vec<usize> = (0..n).step_by(37).collect();
        // A point seen twice can absorb an error along the baseline: not every blunder is detectable.
        let found = planted.iter().filter(|k| r.removed.contains(k)).count();
        assert!(
            found * 10 >= planted.len() * 9,
            "found {found} of {} planted: removed {:?}",
            planted.len(),
            r.removed
        );
        assert!(
            r.removed.len() < planted.len() + n / 50,
            "removed {} for {} planted",
            r.removed.len(),
            planted.len()
        );
        for (est, truth) in p.poses.iter().zip(&poses) {
            assert!((est.center - truth.center).norm() < 0.02);
        }
    }
}
