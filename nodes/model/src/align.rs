//! Alignment: the layers, rows and columns a façade is built on, imposed where the lines cannot tell them apart.
//!
//! After regularisation a plumb line, or a level line along one of the building's plan directions, is constant in
//! two coordinates of the building's frame (u along the wall, n across it, z up): a plumb line in u and n, a line
//! along u in n and z, a line along n in u and z. Façades repeat those values: every frame of a storey shares its
//! depth, every window head of a storey its height, every jamb of a column of windows its position along the wall.
//! Each coordinate is gathered over all lines that hold it constant, its modes are found (mean shift, each value
//! spread over its own σ), and a line within `k` σ of a mode of at least `min_lines` lines is moved onto the mode,
//! which is known to σ / √n. Lines whose values lie between two modes are left where they were measured.
use lineflow_photogrammetry::Vec3;

use crate::regular::Regularity;
use crate::ModelLine;

/// Gates of the alignment.
#[derive(Debug, Clone, Copy)]
pub struct AlignParams {
    /// A line joins a mode within this many of its own σ.
    pub k: f64,
    /// A mode counts when this many lines share it.
    pub min_lines: usize,
}

/// How many line coordinates were moved onto a shared value, per family.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AlignCounts {
    /// Along the wall (columns), across it (layers), height (rows).
    pub moved: [usize; 3],
    /// The shared values found, per family.
    pub modes: [usize; 3],
}

/// One line's value of one coordinate.
#[derive(Debug, Clone, Copy)]
struct Value {
    line: usize,
    at: f64,
    sigma: f64,
}

/// The building's frame for plan azimuth `azimuth` (radians): u along it, n across it, z up.
fn frame(azimuth: f64) -> [Vec3; 3] {
    [
        Vec3::new(azimuth.cos(), azimuth.sin(), 0.0),
        Vec3::new(-azimuth.sin(), azimuth.cos(), 0.0),
        Vec3::z(),
    ]
}

/// Which coordinates of the building frame a regularised line holds constant, by frame axis.
fn constant_coordinates(line: &ModelLine, axes: &[Vec3; 3]) -> [bool; 3] {
    let d = line.direction();
    match line.regular {
        Regularity::Fixed => match (0..3).find(|&k| d.dot(&axes[k]).abs() > 1.0 - 1e-9) {
            Some(runs) => [runs != 0, runs != 1, runs != 2],
            None => [false; 3],
        },
        // A level line off the plan directions still keeps its height.
        Regularity::Level => [false, false, true],
        _ => [false; 3],
    }
}

/// The modes of `values` (sorted by position): mean shift from the densest value not yet taken, members within
/// `k` of their own σ. Returns (mode, members) for modes of at least `min_lines` members.
fn modes(values: &[Value], p: &AlignParams) -> Vec<(f64, Vec<usize>)> {
    let reach = p.k * values.iter().map(|v| v.sigma).fold(0.0, f64::max);
    let window = |centre: f64| {
        let lo = values.partition_point(|v| v.at < centre - reach);
        let hi = values.partition_point(|v| v.at <= centre + reach);
        lo..hi
    };
    let weight = |v: &Value, centre: f64| {
        let z = (v.at - centre) / v.sigma;
        (-0.5 * z * z).exp() / (v.sigma * v.sigma)
    };
    let density: Vec<f64> = values
        .iter()
        .map(|v| window(v.at).map(|k| weight(&values[k], v.at)).sum())
        .collect();
    let mut order: Vec<usize> = (0..values.len()).collect();
    order.sort_by(|&a, &b| density[b].total_cmp(&density[a]).then(a.cmp(&b)));
    let mut taken = vec![false; values.len()];
    let mut out = Vec::new();
    for seed in order {
        if taken[seed] {
            continue;
        }
        let mut centre = values[seed].at;
        for _ in 0..50 {
            let (mut sw, mut swx) = (0.0, 0.0);
            for k in window(centre).filter(|&k| !taken[k]) {
                let w = weight(&values[k], centre);
                sw += w;
                swx += w * values[k].at;
            }
            // Weights of values many of their own σ away underflow; with none left the centre stays.
            if sw <= 0.0 {
                break;
            }
            let next = swx / sw;
            let moved = (next - centre).abs();
            centre = next;
            if moved < 1e-9 {
                break;
            }
        }
        let members: Vec<usize> = window(centre)
            .filter(|&k| !taken[k] && (values[k].at - centre).abs() <= p.k * values[k].sigma)
            .collect();
        if members.len() < p.min_lines {
            taken[seed] = true;
            continue;
        }
        // The mode's value: the members' weighted mean.
        let sw: f64 = members.iter().map(|&k| values[k].sigma.powi(-2)).sum();
        let mean = members.iter().map(|&k| values[k].at * values[k].sigma.powi(-2)).sum::<f64>() / sw;
        for &k in &members {
            taken[k] = true;
        }
        out.push((mean, members));
    }
    out
}

/// Moves the regularised lines onto the coordinates they share, in the frame of plan azimuth `azimuth`.
pub fn align(lines: &mut [ModelLine], azimuth: f64, p: &AlignParams) -> AlignCounts {
    let axes = frame(azimuth);
    let mut counts = AlignCounts::default();
    let constant: Vec<[bool; 3]> = lines.iter().map(|l| constant_coordinates(l, &axes)).collect();
    for (family, axis) in axes.iter().enumerate() {
        let mut values: Vec<Value> = constant
            .iter()
            .enumerate()
            .filter(|(_, c)| c[family])
            .map(|(l, _)| {
                let line = &lines[l];
                // The line's position from two endpoints: σ / √2 per coordinate.
                let sigma = match family {
                    2 => line.sigma_along(2),
                    _ => line.sigma_along(0).max(line.sigma_along(1)),
                } / std::f64::consts::SQRT_2;
                Value {
                    line: l,
                    at: line.midpoint().dot(axis),
                    sigma: sigma.max(1e-9),
                }
            })
            .collect();
        values.sort_by(|a, b| a.at.total_cmp(&b.at).then(a.line.cmp(&b.line)));
        let found = modes(&values, p);
        counts.modes[family] = found.len();
        for (mode, members) in found {
            for k in members {
                let v = values[k];
                let shift = axis * (mode - v.at);
                let line = &mut lines[v.line];
                line.start += shift;
                line.end += shift;
                counts.moved[family] += 1;
            }
        }
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plumb(u: f64, n: f64, sigma: f64) -> ModelLine {
        let mut l = ModelLine::new(Vec3::new(u, n, 0.0), Vec3::new(u, n, 1.0), sigma);
        l.regular = Regularity::Fixed;
        l
    }

    #[test]
    fn a_layer_of_plumb_lines_is_pulled_onto_its_mean_and_a_lone_line_stays() {
        // Five jambs in the wall's plane (n = 0, within their noise) and one 5 cm behind it.
        let offsets = [0.004, -0.003, 0.002, -0.001, 0.003];
        let mut lines: Vec<ModelLine> = offsets.iter().enumerate().map(|(k, &n)| plumb(k as f64, n, 0.005)).collect();
        lines.push(plumb(7.0, 0.05, 0.005));
        let counts = align(&mut lines, 0.0, &AlignParams { k: 2.5, min_lines: 3 });
        let mean = offsets.iter().sum::<f64>() / 5.0;
        for l in &lines[..5] {
            assert!((l.start.y - mean).abs() < 1e-12 && (l.end.y - mean).abs() < 1e-12);
        }
        assert_eq!(lines[5].start.y, 0.05);
        // The jambs' positions along the wall are all different: no column.
        assert_eq!(counts.modes, [0, 1, 0]);
        assert_eq!(counts.moved, [0, 5, 0]);
    }

    #[test]
    fn two_layers_a_reveal_apart_stay_two() {
        // Frames at n = 0 and glazing at n = 4 cm, σ 5 mm per endpoint (3.5 mm per line): eight σ apart.
        let mut lines: Vec<ModelLine> = (0..8)
            .map(|k| plumb(k as f64, if k % 2 == 0 { 0.0 } else { 0.04 }, 0.005))
            .collect();
        align(&mut lines, 0.0, &AlignParams { k: 2.5, min_lines: 3 });
        for (k, l) in lines.iter().enumerate() {
            assert!(
                (l.start.y - if k % 2 == 0 { 0.0 } else { 0.04 }).abs() < 1e-12,
                "{k}: {}",
                l.start.y
            );
        }
    }
}
