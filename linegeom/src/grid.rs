//! Segments indexed by the cells of a regular grid they pass through, for finding each one's neighbours.
use std::collections::HashMap;

use lineflow_photogrammetry::Vec3;

/// The lines by the cells (of `cell` metres) they pass through, so that each line's neighbours are found among
/// the lines of the cells around its own.
pub(crate) struct Grid {
    cell: f64,
    cells: HashMap<[i64; 3], Vec<usize>>,
}

impl Grid {
    pub(crate) fn of(lines: &[[Vec3; 2]], cell: f64) -> Grid {
        let mut grid = Grid {
            cell,
            cells: HashMap::new(),
        };
        for (k, l) in lines.iter().enumerate() {
            let mut keys = grid.keys(l);
            keys.sort_unstable();
            keys.dedup();
            for key in keys {
                grid.cells.entry(key).or_default().push(k);
            }
        }
        grid
    }

    /// The cells a segment passes through, sampled every half cell.
    fn keys(&self, l: &[Vec3; 2]) -> Vec<[i64; 3]> {
        let steps = ((l[1] - l[0]).norm() / (self.cell / 2.0)).ceil().clamp(1.0, 1e5) as usize;
        (0..=steps)
            .map(|s| {
                let p = l[0] + (l[1] - l[0]) * (s as f64 / steps as f64);
                [p.x, p.y, p.z].map(|c| (c / self.cell).floor() as i64)
            })
            .collect()
    }

    /// The other lines in the cells around those of line `k`, once each, into `out` (`seen` marks them by `k`).
    pub(crate) fn near(&self, l: &[Vec3; 2], k: usize, seen: &mut [usize], out: &mut Vec<usize>) {
        seen[k] = k;
        self.around(l, k, seen, out);
    }

    /// The lines in the cells around those of segment `l`, once each, into `out`; `seen` (one entry per line of
    /// the grid) marks them by `query`, which must differ from one call to the next.
    pub(crate) fn around(&self, l: &[Vec3; 2], query: usize, seen: &mut [usize], out: &mut Vec<usize>) {
        for key in self.keys(l) {
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(members) = self.cells.get(&[key[0] + dx, key[1] + dy, key[2] + dz]) else {
                            continue;
                        };
                        for &j in members {
                            if seen[j] != query {
                                seen[j] = query;
                                out.push(j);
                            }
                        }
                    }
                }
            }
        }
    }
}
