//! The edges stage's implementations as one value: the launch file's parameters ([`EdgeParams`]) checked and
//! turned into a [`Detector`], which finds the edge pixels of one grey image. The process shell only wires it.
use lineflow_messages::EdgePixel;
use lineflow_runtime::params::{self, ParamError};

use lineflow_imaging::Planes;

use crate::{canny_in, log, pixels_in, sobel_in, DEFAULT_HIGH, DEFAULT_LOW_RATIO};

/// The launch file's parameters of the edges stage; each applies to some implementations only. Thresholds are on
/// the L2 magnitude of the 3×3 Sobel gradient of the 8-bit image (0..1442).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EdgeParams {
    /// canny: hysteresis high threshold [default: 100].
    pub high: Option<f64>,
    /// canny: low threshold [default: 0.4 × high].
    pub low: Option<f64>,
    /// sobel, log: magnitude threshold [default: sobel 100, log 40].
    pub threshold: Option<f64>,
    /// log: Gaussian σ in pixels [default: 1.5].
    pub sigma: Option<f64>,
    /// canny, sobel: how an RGB image's channels take part in the gradient: `off` (the grey image's), `plumb`
    /// (a channel's where it is stronger, across edges near the image's columns) or `all` [default: plumb]. Grey
    /// input is unaffected.
    pub color: Option<lineflow_imaging::ColourEdges>,
}

/// An edge detector with its thresholds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Detector {
    /// Canny with hysteresis between `low` and `high`.
    Canny {
        /// Low threshold.
        low: f64,
        /// High threshold.
        high: f64,
    },
    /// Sobel gradient maxima above `threshold`.
    Sobel {
        /// Magnitude threshold.
        threshold: f64,
    },
    /// Laplacian of Gaussian zero crossings where the gradient exceeds `threshold`.
    Log {
        /// Gaussian σ, pixels.
        sigma: f64,
        /// Magnitude threshold.
        threshold: f64,
    },
}

/// The implementations, as a launch file names them.
pub const IMPLEMENTATIONS: [&str; 3] = ["canny", "sobel", "log"];

/// Why parameters do not make a detector; each names the value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EdgeParamsError {
    /// No such implementation.
    #[error("unknown edges impl '{0}' (available: canny, sobel, log)")]
    UnknownImpl(String),
    /// A parameter the implementation does not take.
    #[error("parameter '{param}' does not apply to impl '{implementation}' (it takes: {takes})")]
    NotApplicable {
        /// The parameter given.
        param: &'static str,
        /// The implementation.
        implementation: &'static str,
        /// What it takes.
        takes: String,
    },
    /// A value out of range.
    #[error(transparent)]
    OutOfRange(#[from] ParamError),
}

impl Detector {
    /// The detector `implementation` with `params`, defaults where they are silent.
    ///
    /// # Errors
    /// An unknown implementation, a parameter it does not take, or a value out of range.
    pub fn new(implementation: &str, params: EdgeParams) -> Result<Detector, EdgeParamsError> {
        let given = [
            ("high", params.high.is_some()),
            ("low", params.low.is_some()),
            ("threshold", params.threshold.is_some()),
            ("sigma", params.sigma.is_some()),
            ("color", params.color.is_some()),
        ];
        let (name, takes): (&'static str, &[&str]) = match implementation {
            "canny" => ("canny", &["high", "low", "color"]),
            "sobel" => ("sobel", &["threshold", "color"]),
            "log" => ("log", &["threshold", "sigma"]),
            other => return Err(EdgeParamsError::UnknownImpl(other.to_owned())),
        };
        if let Some((param, _)) = given.iter().find(|(key, set)| *set && !takes.contains(key)) {
            return Err(EdgeParamsError::NotApplicable {
                param,
                implementation: name,
                takes: takes.join(", "),
            });
        }
        let d = match name {
            "canny" => {
                let high = params.high.unwrap_or(DEFAULT_HIGH);
                Detector::Canny {
                    low: params.low.unwrap_or(DEFAULT_LOW_RATIO * high),
                    high,
                }
            }
            "sobel" => Detector::Sobel {
                threshold: params.threshold.unwrap_or(100.0),
            },
            _ => Detector::Log {
                sigma: params.sigma.unwrap_or(1.5),
                threshold: params.threshold.unwrap_or(40.0),
            },
        };
        match d {
            Detector::Canny { low, high } => {
                params::non_negative("low", low)?;
                params::check(high >= low, "high", &format!(">= low ({low})"), high)?;
            }
            Detector::Sobel { threshold } => params::non_negative("threshold", threshold)?,
            Detector::Log { sigma, threshold } => {
                params::check(sigma > 0.0 && sigma <= 20.0, "sigma", "in (0, 20]", sigma)?;
                params::non_negative("threshold", threshold)?;
            }
        }
        Ok(d)
    }

    /// The edge pixels of a grey image, row-major.
    pub fn detect(&self, gray: &[u8], width: usize, height: usize) -> Vec<EdgePixel> {
        self.detect_in(&Planes::gray(gray), width, height)
    }

    /// The edge pixels on the gradient of the strongest plane (Laplacian of Gaussian: on the first plane).
    pub fn detect_in(&self, planes: &Planes, width: usize, height: usize) -> Vec<EdgePixel> {
        let map = match *self {
            Detector::Canny { low, high } => canny_in(planes, width, height, low, high),
            Detector::Sobel { threshold } => sobel_in(planes, width, height, threshold),
            Detector::Log { sigma, threshold } => {
                let first = planes.iter().next().unwrap_or_default();
                log(first, width, height, sigma, threshold)
            }
        };
        pixels_in(planes, width, height, &map)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_follow_the_thesis_and_opencv() {
        assert_eq!(
            Detector::new("canny", EdgeParams::default()),
            Ok(Detector::Canny { low: 40.0, high: 100.0 })
        );
        let p = EdgeParams {
            high: Some(50.0),
            ..EdgeParams::default()
        };
        assert_eq!(Detector::new("canny", p), Ok(Detector::Canny { low: 20.0, high: 50.0 }));
        assert_eq!(
            Detector::new("sobel", EdgeParams::default()),
            Ok(Detector::Sobel { threshold: 100.0 })
        );
        assert_eq!(
            Detector::new("log", EdgeParams::default()),
            Ok(Detector::Log {
                sigma: 1.5,
                threshold: 40.0
            })
        );
    }

    #[test]
    fn bad_parameters_are_named() {
        let e = Detector::new("prewitt", EdgeParams::default()).unwrap_err();
        assert_eq!(e.to_string(), "unknown edges impl 'prewitt' (available: canny, sobel, log)");
        let sigma = EdgeParams {
            sigma: Some(2.0),
            ..EdgeParams::default()
        };
        let e = Detector::new("canny", sigma).unwrap_err();
        assert_eq!(
            e.to_string(),
            "parameter 'sigma' does not apply to impl 'canny' (it takes: high, low, color)"
        );
        let colour = EdgeParams {
            color: Some(lineflow_imaging::ColourEdges::All),
            ..EdgeParams::default()
        };
        assert_eq!(
            Detector::new("log", colour).unwrap_err().to_string(),
            "parameter 'color' does not apply to impl 'log' (it takes: threshold, sigma)"
        );
        let inverted = EdgeParams {
            high: Some(10.0),
            low: Some(20.0),
            ..EdgeParams::default()
        };
        assert!(matches!(Detector::new("canny", inverted), Err(EdgeParamsError::OutOfRange(_))));
        let wide = EdgeParams {
            sigma: Some(25.0),
            ..EdgeParams::default()
        };
        assert!(Detector::new("log", wide)
            .unwrap_err()
            .to_string()
            .ends_with("sigma must be in (0, 20], got 25"));
    }

    #[test]
    fn a_step_is_found_by_every_detector() {
        let (w, h) = (40, 30);
        let gray: Vec<u8> = (0..w * h).map(|i| if i % w < 20 { 30 } else { 200 }).collect();
        for name in IMPLEMENTATIONS {
            let px = Detector::new(name, EdgeParams::default()).unwrap().detect(&gray, w, h);
            assert!(!px.is_empty(), "{name}");
            assert!(px.iter().all(|p| (18..=21).contains(&p.col)), "{name}: edges at the step only");
        }
    }
}
