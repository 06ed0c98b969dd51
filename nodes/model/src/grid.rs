//! A uniform grid over segments (or points), so that junction candidates are sought among nearby lines only: a
//! façade holds thousands of lines, and all pairs would be millions.
use std::collections::HashMap;

use lineflow_photogrammetry::Vec3;

use crate::ModelLine;

pub struct SegmentGrid {
    cell: f64,
    cells: HashMap<[i64; 3], Vec<usize>>,
}

impl SegmentGrid {
    /// Indexes every line by the cells its bounding box, grown by `reach`, covers. Cells are at least `reach`
    /// wide so that a query touches few of them.
    pub fn new(lines: &[ModelLine], reach: f64) -> Self {
        Self::of_boxes(lines.iter().map(|l| (l.start.inf(&l.end), l.start.sup(&l.end))), reach)
    }

    /// Indexes points (boxes of no size) the same way.
    pub fn of_points(points: impl Iterator<Item = Vec3>, reach: f64) -> Self {
        Self::of_boxes(points.map(|p| (p, p)), reach)
    }

    fn of_boxes(boxes: impl Iterator<Item = (Vec3, Vec3)>, reach: f64) -> Self {
        let cell = (2.0 * reach).max(0.25);
        let mut grid = SegmentGrid {
            cell,
            cells: HashMap::new(),
        };
        for (k, (lo, hi)) in boxes.enumerate() {
            for key in grid.keys(lo, hi, reach) {
                grid.cells.entry(key).or_default().push(k);
            }
        }
        grid
    }

    fn keys(&self, lo: Vec3, hi: Vec3, reach: f64) -> Vec<[i64; 3]> {
        let (lo, hi) = (lo - Vec3::repeat(reach), hi + Vec3::repeat(reach));
        let index = |v: f64| (v / self.cell).floor() as i64;
        let mut keys = Vec::new();
        for x in index(lo.x)..=index(hi.x) {
            for y in index(lo.y)..=index(hi.y) {
                for z in index(lo.z)..=index(hi.z) {
                    keys.push([x, y, z]);
                }
            }
        }
        keys
    }

    /// Every line whose grown box shares a cell with `l`'s grown box, ascending, without repeats.
    pub fn near(&self, l: &ModelLine, reach: f64) -> Vec<usize> {
        self.near_box(l.start.inf(&l.end), l.start.sup(&l.end), reach)
    }

    /// Every indexed item whose grown box shares a cell with the point's, ascending, without repeats (a superset
    /// of those within `reach`).
    pub fn near_point(&self, p: &Vec3, reach: f64) -> Vec<usize> {
        self.near_box(*p, *p, reach)
    }

    fn near_box(&self, lo: Vec3, hi: Vec3, reach: f64) -> Vec<usize> {
        let mut out: Vec<usize> = self
            .keys(lo, hi, reach)
            .iter()
            .filter_map(|k| self.cells.get(k))
            .flatten()
            .copied()
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }
}
