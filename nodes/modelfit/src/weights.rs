//! The edge-pixel weighting schemes of seed 004 §3.
use serde::Deserialize;

/// How an edge pixel inside the buffer of a projected model line is weighted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Weighting {
    /// w = 1.
    Equal,
    /// w = G / G_max of the image (eq. 1).
    Magnitude,
    /// w = ½ [sin(2λ − 90°) + 1] = sin² λ, λ the angle between the gradient and the projected line (eq. 2).
    Angle,
    /// Pixels whose λ is more than the gate (30°) from 90°/270° dropped, the rest weighted by G / G_max (§3.3).
    #[default]
    Combined,
}

impl Weighting {
    /// Every scheme, in the order of the seed's figure.
    pub const ALL: [Weighting; 4] = [Weighting::Equal, Weighting::Magnitude, Weighting::Angle, Weighting::Combined];

    /// The scheme's name as the launch file spells it.
    pub fn name(self) -> &'static str {
        match self {
            Weighting::Equal => "equal",
            Weighting::Magnitude => "magnitude",
            Weighting::Angle => "angle",
            Weighting::Combined => "combined",
        }
    }

    /// The scheme of a launch-file or command-line name.
    pub fn parse(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|w| w.name() == name)
            .ok_or_else(|| format!("unknown weighting '{name}' (available: equal, magnitude, angle, combined)"))
    }

    /// The weight of a pixel with relative gradient magnitude `relative` (G / G_max) and `cos_lambda`, the cosine
    /// of the angle between its gradient and the projected line; `gate_cos` = sin(gate) (0.5 for ±30°).
    /// Zero means the pixel is not used.
    #[inline]
    pub fn weight(self, relative: f64, cos_lambda: f64, gate_cos: f64) -> f64 {
        match self {
            Weighting::Equal => 1.0,
            Weighting::Magnitude => relative,
            Weighting::Angle => angle_weight(cos_lambda),
            Weighting::Combined => {
                if cos_lambda.abs() <= gate_cos {
                    relative
                } else {
                    0.0
                }
            }
        }
    }
}

/// Eq. 2 of the seed written through cos λ: ½ [sin(2λ − 90°) + 1] = ½ (1 − cos 2λ) = 1 − cos² λ.
#[inline]
pub fn angle_weight(cos_lambda: f64) -> f64 {
    (1.0 - cos_lambda * cos_lambda).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eq2(lambda_deg: f64) -> f64 {
        0.5 * ((2.0 * lambda_deg - 90.0).to_radians().sin() + 1.0)
    }

    /// Seed fact C1: w(90°) = w(270°) = 1, w(0°) = w(180°) = 0, w(45°) = 0.5, and eq. 2 is sin² λ.
    #[test]
    fn angle_weight_is_the_seeds_equation_two() {
        for (deg, w) in [(90.0, 1.0), (270.0, 1.0), (0.0, 0.0), (180.0, 0.0), (45.0, 0.5)] {
            assert!((angle_weight(f64::to_radians(deg).cos()) - w).abs() < 1e-12, "{deg}");
        }
        for k in 0..=720 {
            let deg = k as f64 * 0.5;
            let c = deg.to_radians().cos();
            assert!((angle_weight(c) - eq2(deg)).abs() < 1e-12);
            assert!((angle_weight(c) - deg.to_radians().sin().powi(2)).abs() < 1e-12);
        }
    }

    /// Seed fact C3: the combined gate keeps λ in [60°, 120°] ∪ [240°, 300°] and nothing else.
    #[test]
    fn combined_gate_keeps_sixty_degrees_around_perpendicular() {
        let gate = 30f64.to_radians().sin();
        for k in 0..3600 {
            let deg = k as f64 * 0.1;
            let kept = Weighting::Combined.weight(0.7, deg.to_radians().cos(), gate) > 0.0;
            let inside = (60.0 + 1e-9..=120.0 - 1e-9).contains(&deg) || (240.0 + 1e-9..=300.0 - 1e-9).contains(&deg);
            let outside = deg < 60.0 - 1e-9 || (120.0 + 1e-9..240.0 - 1e-9).contains(&deg) || deg > 300.0 + 1e-9;
            if inside {
                assert!(kept, "{deg}");
            }
            if outside {
                assert!(!kept, "{deg}");
            }
        }
        assert_eq!(Weighting::Combined.weight(0.7, 0.0, gate), 0.7, "kept pixels weigh G/Gmax");
    }
}
