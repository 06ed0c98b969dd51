//! `lineflow-edges`: the edges stage (`impl = "canny"`, `"sobel"` or `"log"`); one EdgeMap per image.
use anyhow::{bail, Result};
use lineflow_edges::{canny, log, pixels, sobel, DEFAULT_HIGH, DEFAULT_LOW_RATIO};
use lineflow_messages::{fixed_str, kinds, EdgeMapHeader};
use lineflow_runtime::{Flow, NodeContext};
use serde::Deserialize;

/// Thresholds on the L2 magnitude of the 3×3 Sobel gradient of the 8-bit image (0..1442).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    /// canny: hysteresis high threshold.
    high: Option<f64>,
    /// canny: low threshold [default: 0.4 × high].
    low: Option<f64>,
    /// sobel, log: magnitude threshold.
    threshold: Option<f64>,
    /// log: Gaussian σ in pixels.
    sigma: Option<f64>,
}

enum Detector {
    Canny { low: f64, high: f64 },
    Sobel { threshold: f64 },
    Log { sigma: f64, threshold: f64 },
}

fn detector(name: &str, impl_: &str, p: Params) -> Result<Detector> {
    let only = |allowed: &[&str]| -> Result<()> {
        for (key, given) in [
            ("high", p.high.is_some()),
            ("low", p.low.is_some()),
            ("threshold", p.threshold.is_some()),
            ("sigma", p.sigma.is_some()),
        ] {
            if given && !allowed.contains(&key) {
                bail!(
                    "node '{name}': parameter '{key}' does not apply to impl '{impl_}' (it takes: {})",
                    allowed.join(", ")
                );
            }
        }
        Ok(())
    };
    let d = match impl_ {
        "canny" => {
            only(&["high", "low"])?;
            let high = p.high.unwrap_or(DEFAULT_HIGH);
            Detector::Canny {
                low: p.low.unwrap_or(DEFAULT_LOW_RATIO * high),
                high,
            }
        }
        "sobel" => {
            only(&["threshold"])?;
            Detector::Sobel {
                threshold: p.threshold.unwrap_or(100.0),
            }
        }
        "log" => {
            only(&["threshold", "sigma"])?;
            Detector::Log {
                sigma: p.sigma.unwrap_or(1.5),
                threshold: p.threshold.unwrap_or(40.0),
            }
        }
        other => bail!("node '{name}': unknown edges impl '{other}' (available: canny, sobel, log)"),
    };
    let ok = match d {
        Detector::Canny { low, high } => low >= 0.0 && high >= low,
        Detector::Sobel { threshold } => threshold >= 0.0,
        Detector::Log { sigma, threshold } => sigma > 0.0 && sigma <= 20.0 && threshold >= 0.0,
    };
    if !ok {
        bail!("node '{name}': thresholds must be >= 0 (canny: low <= high), sigma in (0, 20]");
    }
    Ok(d)
}

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
}

fn body() -> Result<()> {
    let ctx = NodeContext::from_env()?;
    let impl_ = ctx.implementation("canny").to_owned();
    let det = detector(ctx.name(), &impl_, ctx.params()?)?;
    let input = ctx.input::<kinds::Image>("images")?;
    let output = ctx.output::<kinds::EdgeMap>("edges")?;
    ctx.connect()?;
    let mut gray = Vec::new();
    ctx.run(|| {
        lineflow_imaging::for_each_gray(&input, &mut gray, |h, gray| {
            let (w, ht) = (h.width as usize, h.height as usize);
            if w > u16::MAX as usize || ht > u16::MAX as usize {
                bail!("frame {}: {w}x{ht} exceeds the 65535-pixel edge map limit", h.stamp.frame);
            }
            let map = match det {
                Detector::Canny { low, high } => canny(gray, w, ht, low, high),
                Detector::Sobel { threshold } => sobel(gray, w, ht, threshold),
                Detector::Log { sigma, threshold } => log(gray, w, ht, sigma, threshold),
            };
            let px = pixels(gray, w, ht, &map);
            let header = EdgeMapHeader {
                stamp: h.stamp,
                width: h.width,
                height: h.height,
                detector: fixed_str(&impl_),
                name: h.name,
            };
            output.publish(header, &px)
        })?;
        Ok(if input.is_ended() { Flow::Stop } else { Flow::Continue })
    })?;
    output.end_of_stream()?;
    ctx.finish();
    Ok(())
}
