//! Implementation `essential` (seed 001): each frame's relative orientation to the oriented frame it shares most
//! tracks with, from the normalised eight-point essential matrix (RANSAC-verified correspondences, the four-fold
//! decomposition and the cheirality test), chained along the strip; the baseline's length from the tracks both
//! frames see that are already intersected; new tracks intersected. No bundle adjustment: the model is moved into
//! the control frame by a 7-parameter similarity as soon as three control points are intersected (again whenever
//! more are), and at the end by the seed's 12-parameter 3-D affine where at least five control points spread in
//! depth determine it, the similarity otherwise (façade control points are nearly coplanar).
//!
//! This is the seed's comparison method, not the default: a façade is nearly a plane, where the linear essential
//! matrix is ill-conditioned, and chained relative orientations drift along a strip with nothing to hold them.
use lineflow_photogrammetry::epipolar::{eight_point, refine_relative, relative_pose, Ray};
use lineflow_photogrammetry::intersect::{affine, intersect_rays, similarity};
use lineflow_photogrammetry::{Mat3, Pose, Vec3};

use crate::{Block, VerifiedPair};

/// Tracks with an intersected point needed to fix the length of a new baseline.
const MIN_SCALE_POINTS: usize = 3;

/// A transformation of the model into the control frame.
enum ToControl {
    Similarity(lineflow_photogrammetry::intersect::Similarity),
    Affine(lineflow_photogrammetry::intersect::Affine),
}

impl ToControl {
    fn point(&self, x: &Vec3) -> Vec3 {
        match self {
            ToControl::Similarity(s) => s.apply(x),
            ToControl::Affine(a) => a.apply(x),
        }
    }

    /// The camera's rotation after the transformation: a direction `d` becomes `A·d`, so `M` becomes `M·A⁻¹` up to
    /// scale; an affine's shear is not a rotation, and the nearest rotation is taken.
    fn rotation(&self, m: &Mat3) -> Mat3 {
        match self {
            ToControl::Similarity(s) => m * s.rotation.transpose(),
            ToControl::Affine(a) => {
                let Some(inverse) = a.linear.try_inverse() else { return *m };
                nearest_rotation(&(m * inverse))
            }
        }
    }
}

/// The rotation nearest to `m` (Frobenius norm), by its singular value decomposition.
fn nearest_rotation(m: &Mat3) -> Mat3 {
    let svd = m.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else { return *m };
    let r = u * v_t;
    if r.determinant() < 0.0 {
        let mut u = u;
        u.column_mut(2).neg_mut();
        u * v_t
    } else {
        r
    }
}

impl Block {
    /// Orients frame `k` by its relative orientation to the best-connected oriented frame (or, for the first
    /// frame, to the frame it shares most tracks with, which then becomes the origin).
    pub(crate) fn orient_relative(&mut self, k: u64) -> bool {
        let first = self.poses.is_empty();
        let partners: Vec<u64> = if first {
            self.frames_but(k)
        } else {
            self.poses.keys().copied().collect()
        };
        let Some(VerifiedPair {
            partner: j,
            common,
            a,
            b,
            inliers,
        }) = self.verified_pair(k, partners, 0x0E55)
        else {
            return false;
        };
        if inliers.is_empty() {
            tracing::warn!("frame {k}: no essential matrix with frame {j} ({} common tracks)", common.len());
            return false;
        }
        let (a_in, b_in): (Vec<Ray>, Vec<Ray>) = inliers.iter().map(|&i| (a[i], b[i])).unzip();
        let Some((linear, front)) = eight_point(&a_in, &b_in).and_then(|e| relative_pose(&e, &a_in, &b_in)) else {
            return false;
        };
        // The strip's motion as a second start: turned like the first camera, moved against the image flow.
        let flow = inliers.iter().fold(Vec3::zeros(), |acc, &i| {
            let (p, q) = (common[i].0, common[i].1);
            acc + Vec3::new(p[0] - q[0], p[1] - q[1], 0.0)
        });
        let prior = Pose {
            center: flow,
            rotation: Mat3::identity(),
        };
        let rel = if self.params.refine_relative {
            [linear, prior]
                .iter()
                .filter_map(|s| refine_relative(&a_in, &b_in, s))
                .min_by(|x, y| x.1.total_cmp(&y.1))
                .map_or(linear, |r| r.0)
        } else {
            linear
        };
        if first {
            self.poses.insert(
                j,
                Pose {
                    center: Vec3::zeros(),
                    rotation: Mat3::identity(),
                },
            );
            self.poses.insert(k, rel);
            self.mark_oriented(j);
            self.mark_oriented(k);
            tracing::info!(
                "initial pair: frames {j} and {k}, {} of {} common tracks verified, {front} in front of both",
                inliers.len(),
                common.len()
            );
            return true;
        }
        let pj = self.poses[&j];
        // The unit baseline's model of each verified track already intersected, against its distance from j.
        let mut ratios: Vec<f64> = inliers
            .iter()
            .filter_map(|&i| {
                let x = self.tracks.get(&common[i].2)?.point?;
                let rays = [(Vec3::zeros(), a[i]), (rel.center, rel.rotation.transpose() * b[i])];
                let (unit, _) = intersect_rays(&rays)?;
                let d = unit.norm();
                (d > 0.0 && unit.dot(&a[i]) > 0.0).then(|| (x - pj.center).norm() / d)
            })
            .collect();
        if ratios.len() < MIN_SCALE_POINTS {
            tracing::warn!(
                "frame {k}: only {} intersected tracks shared with frame {j}, the baseline's length is unknown",
                ratios.len()
            );
            return false;
        }
        ratios.sort_by(f64::total_cmp);
        let scale = ratios[ratios.len() / 2];
        self.poses.insert(
            k,
            Pose {
                center: pj.center + pj.rotation.transpose() * rel.center * scale,
                rotation: rel.rotation * pj.rotation,
            },
        );
        self.mark_oriented(k);
        true
    }

    /// Nothing adjusts a chained pose later, but it moves with the model until the model is in the control frame.
    fn mark_oriented(&mut self, k: u64) {
        let georeferenced = self.georeferenced;
        let state = self.states.entry(k).or_default();
        state.revision += 1;
        state.settled = georeferenced;
    }

    /// Moves the model into the control frame when more control points are intersected than at the last move;
    /// with `last`, always, and by the affine where the control points determine it.
    pub(crate) fn georeference_model(&mut self, last: bool) {
        let pairs = self.control_pairs();
        if pairs.len() < 3 || (!last && pairs.len() <= self.georeferenced_with) {
            return;
        }
        let (from, to): (Vec<Vec3>, Vec<Vec3>) = pairs.into_iter().unzip();
        // `affine` refuses control points (nearly) in one plane.
        let transform = match (last && from.len() >= 5).then(|| affine(&from, &to)).flatten() {
            Some(a) => ToControl::Affine(a),
            None => match similarity(&from, &to) {
                Some(s) => ToControl::Similarity(s),
                None => return,
            },
        };
        self.move_block(|x| transform.point(x), |m| transform.rotation(m));
        for s in self.states.values_mut() {
            s.revision += 1;
            s.settled = true;
        }
        self.georeferenced = true;
        self.georeferenced_with = from.len();
        tracing::info!(
            "model moved into the control frame by a{} with {} control points",
            match transform {
                ToControl::Affine(_) => " 3-D affine",
                ToControl::Similarity(_) => " similarity",
            },
            from.len()
        );
    }

    /// The report of a block nothing adjusts: the intersected tracks' reprojection RMS (mm in the image) and σ0
    /// against the tie points' a-priori standard deviation.
    pub(crate) fn report_chain(&mut self) {
        let (mut sum, mut n) = (0.0, 0usize);
        for t in self.tracks.values() {
            let Some(x) = t.point else { continue };
            for (f, ideal) in &t.obs {
                if let Some(p) = self.poses.get(f).and_then(|pose| pose.project_ideal(&self.camera, &x)) {
                    sum += (p[0] - ideal[0]).powi(2) + (p[1] - ideal[1]).powi(2);
                    n += 1;
                }
            }
        }
        self.report.rms_mm = if n == 0 { f64::NAN } else { (sum / n as f64).sqrt() };
        self.report.sigma0 = self.report.rms_mm / (self.params.tie_sigma_px * self.camera.pixel_size_mm);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_affine_that_is_a_similarity_moves_cameras_as_the_similarity_does() {
        use lineflow_photogrammetry::intersect::{Affine, Similarity};
        let r = lineflow_photogrammetry::rotation_from_opk(0.1, 0.2, -0.3);
        let t = Vec3::new(5.0, -2.0, 1.0);
        let similarity = ToControl::Similarity(Similarity {
            scale: 2.5,
            rotation: r,
            translation: t,
        });
        let affine = ToControl::Affine(Affine {
            linear: r * 2.5,
            translation: t,
        });
        let camera = lineflow_photogrammetry::rotation_from_opk(1.4, -0.05, 0.02);
        let x = Vec3::new(0.3, 19.0, -1.2);
        assert!((similarity.point(&x) - affine.point(&x)).norm() < 1e-12);
        assert!((similarity.rotation(&camera) - affine.rotation(&camera)).norm() < 1e-12);
        // A camera's ray to a point stays its ray to the moved point.
        let (c, moved) = (Vec3::new(1.0, 2.0, 3.0), affine.rotation(&camera));
        let before = (camera * (x - c)).normalize();
        let after = (moved * (affine.point(&x) - affine.point(&c))).normalize();
        assert!((before - after).norm() < 1e-12);
    }

    #[test]
    fn the_nearest_rotation_of_a_rotation_is_itself_and_of_a_sheared_one_is_orthonormal() {
        let r = lineflow_photogrammetry::rotation_from_opk(0.3, -0.2, 1.1);
        assert!((nearest_rotation(&r) - r).norm() < 1e-12);
        let sheared = r * Mat3::new(1.0, 0.02, 0.0, 0.0, 0.98, 0.01, 0.0, 0.0, 1.03);
        let n = nearest_rotation(&sheared);
        assert!((n.transpose() * n - Mat3::identity()).norm() < 1e-12);
        assert!((n.determinant() - 1.0).abs() < 1e-12);
        assert!((n - r).norm() < 0.05);
    }
}
