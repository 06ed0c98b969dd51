//! The interior orientation as unknowns of a self-calibrating bundle adjustment: which of the correction model's
//! parameters are free, their scaled form, and what the adjustment reports about them.
//!
//! The unknowns are scaled so that each is the size of its effect, in millimetres, at the corner of the sensor: a
//! k3 of 10⁻⁸ mm⁻⁶ and a principal point of 0.1 mm then weigh alike in the normal equations, which keeps them
//! conditioned and lets one finite-difference step serve every parameter.
use crate::Camera;

/// One parameter of the interior orientation (`conventions.md`'s correction model).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Interior {
    /// Principal distance f.
    Focal,
    /// Principal point x0.
    X0,
    /// Principal point y0.
    Y0,
    /// Radial k1.
    K1,
    /// Radial k2.
    K2,
    /// Radial k3.
    K3,
    /// Decentering p1.
    P1,
    /// Decentering p2.
    P2,
}

/// Number of interior parameters.
pub const N_INTERIOR: usize = 8;

impl Interior {
    /// Every parameter, in the order of the scaled vector.
    pub const ALL: [Interior; N_INTERIOR] = [
        Interior::Focal,
        Interior::X0,
        Interior::Y0,
        Interior::K1,
        Interior::K2,
        Interior::K3,
        Interior::P1,
        Interior::P2,
    ];

    /// Position in the scaled vector.
    pub fn index(self) -> usize {
        self as usize
    }

    /// The name used in `camera.toml`, launch files and reports.
    pub fn name(self) -> &'static str {
        ["f", "x0", "y0", "k1", "k2", "k3", "p1", "p2"][self.index()]
    }

    /// The parameter named `name` (as [`name`](Self::name)).
    pub fn from_name(name: &str) -> Option<Interior> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// The parameter's value in `c`, natural units.
    pub fn value(self, c: &Camera) -> f64 {
        match self {
            Interior::Focal => c.focal_mm,
            Interior::X0 => c.principal_point_mm[0],
            Interior::Y0 => c.principal_point_mm[1],
            Interior::K1 => c.radial[0],
            Interior::K2 => c.radial[1],
            Interior::K3 => c.radial[2],
            Interior::P1 => c.decentering[0],
            Interior::P2 => c.decentering[1],
        }
    }

    /// Unit of the parameter, for reports.
    pub fn unit(self) -> &'static str {
        ["mm", "mm", "mm", "mm^-2", "mm^-4", "mm^-6", "mm^-1", "mm^-1"][self.index()]
    }
}

/// The scaled interior vector of cameras of one sensor: lengths in mm, each distortion coefficient as its
/// correction at the sensor's half-diagonal `r` (k1·r³, k2·r⁵, k3·r⁷, p·r²).
#[derive(Debug, Clone, Copy)]
pub(crate) struct InteriorScale {
    per_unit: [f64; N_INTERIOR],
}

impl InteriorScale {
    pub(crate) fn of(camera: &Camera) -> Self {
        let r = 0.5 * (camera.width as f64).hypot(camera.height as f64) * camera.pixel_size_mm;
        let r = r.max(1e-6);
        Self {
            per_unit: [1.0, 1.0, 1.0, r.powi(-3), r.powi(-5), r.powi(-7), r.powi(-2), r.powi(-2)],
        }
    }

    /// The natural value of one scaled unit of parameter `k`.
    pub(crate) fn per_unit(&self, k: usize) -> f64 {
        self.per_unit[k]
    }

    pub(crate) fn vector(&self, c: &Camera) -> [f64; N_INTERIOR] {
        std::array::from_fn(|k| Interior::ALL[k].value(c) / self.per_unit[k])
    }

    /// `base` with the interior of the scaled vector `v`.
    pub(crate) fn camera(&self, base: &Camera, v: &[f64; N_INTERIOR]) -> Camera {
        let n: [f64; N_INTERIOR] = std::array::from_fn(|k| v[k] * self.per_unit[k]);
        Camera {
            focal_mm: n[0],
            principal_point_mm: [n[1], n[2]],
            radial: [n[3], n[4], n[5]],
            decentering: [n[6], n[7]],
            ..*base
        }
    }
}

/// The interior orientation as unknowns: the camera, adjusted in place, and the measured pixel position of every
/// observation, from which its ideal coordinates are computed afresh as the camera changes.
#[derive(Debug, Clone)]
pub struct SelfCalibration {
    /// The camera (adjusted in place; its fixed parameters stay as given).
    pub camera: Camera,
    /// The parameters adjusted.
    pub free: Vec<Interior>,
    /// Measured pixel positions, one per observation of the problem, in its order.
    pub pixels: Vec<[f64; 2]>,
    /// Parameters known beforehand: (parameter, value, standard deviation) in natural units, observations of the
    /// free parameters (a lens's marked focal length within a percent or so).
    pub priors: Vec<(Interior, f64, f64)>,
}

impl SelfCalibration {
    /// The priors of free parameters in scaled units: (index, value, weight).
    pub(crate) fn scaled_priors(&self) -> Vec<(usize, f64, f64)> {
        let scale = InteriorScale::of(&self.camera);
        self.priors
            .iter()
            .filter(|(p, _, sigma)| self.free.contains(p) && *sigma > 0.0)
            .map(|&(p, value, sigma)| {
                let k = p.index();
                let unit = scale.per_unit(k);
                (k, value / unit, (unit / sigma).powi(2))
            })
            .collect()
    }

    /// The priors' weighted squared residuals at the camera of the moment.
    pub(crate) fn prior_cost(&self) -> f64 {
        let v = InteriorScale::of(&self.camera).vector(&self.camera);
        self.scaled_priors()
            .iter()
            .map(|&(k, value, weight)| weight * (v[k] - value).powi(2))
            .sum()
    }
}

/// What a self-calibrating adjustment found about the interior orientation.
#[derive(Debug, Clone, PartialEq)]
pub struct InteriorReport {
    /// The adjusted camera.
    pub camera: Camera,
    /// The parameters adjusted.
    pub free: Vec<Interior>,
    /// Standard deviation of each parameter ([`Interior::ALL`]'s order, natural units); NaN where fixed.
    pub sigmas: [f64; N_INTERIOR],
    /// Correlation coefficients of the parameters; NaN where either is fixed.
    pub correlations: [[f64; N_INTERIOR]; N_INTERIOR],
    /// The strongest correlation of the principal distance with a coordinate of a camera centre (signed; NaN when f
    /// is held): near ±1 the block cannot tell f from the distance to the object.
    pub focal_exterior_correlation: f64,
}

impl InteriorReport {
    /// The most strongly correlated pair of free parameters and their coefficient.
    pub fn strongest_correlation(&self) -> Option<(Interior, Interior, f64)> {
        let mut best: Option<(Interior, Interior, f64)> = None;
        for (i, &a) in self.free.iter().enumerate() {
            for &b in &self.free[i + 1..] {
                let r = self.correlations[a.index()][b.index()];
                if r.is_finite() && best.is_none_or(|(_, _, s)| r.abs() > s.abs()) {
                    best = Some((a, b, r));
                }
            }
        }
        best
    }
}

/// The parameters a camera file may fix, parsed from names (`f`, `x0`, `y0`, `k1`–`k3`, `p1`, `p2`); an unknown
/// name is an error naming it.
pub fn parse_interior(names: &[String]) -> Result<Vec<Interior>, String> {
    let mut out: Vec<Interior> = Vec::new();
    for n in names {
        let p = Interior::from_name(n.trim()).ok_or_else(|| format!("unknown interior parameter '{n}' (f, x0, y0, k1, k2, k3, p1, p2)"))?;
        if !out.contains(&p) {
            out.push(p);
        }
    }
    out.sort();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scaled_vector_round_trips_and_weighs_each_coefficient_by_its_effect_at_the_corner() {
        let c = Camera {
            width: 4912,
            height: 3264,
            pixel_size_mm: 0.0048,
            focal_mm: 18.007,
            principal_point_mm: [-0.229, 0.1067],
            radial: [1.74e-4, -2.0e-7, 3.0e-10],
            decentering: [6e-6, -4e-6],
        };
        let s = InteriorScale::of(&c);
        let v = s.vector(&c);
        let back = s.camera(&c, &v);
        assert!((back.radial[2] - c.radial[2]).abs() < 1e-22 && (back.focal_mm - c.focal_mm).abs() < 1e-12);
        // k1 = 1.74e-4 at a half-diagonal of 14.2 mm corrects about 0.5 mm there.
        assert!((0.4..0.6).contains(&v[3]), "{}", v[3]);
    }

    #[test]
    fn names_parse_and_an_unknown_one_is_named() {
        let ok = parse_interior(&["k3".into(), "f".into(), "k3".into()]).unwrap();
        assert_eq!(ok, vec![Interior::Focal, Interior::K3]);
        let err = parse_interior(&["k4".into()]).unwrap_err();
        assert!(err.contains("'k4'"), "{err}");
    }
}
