//! Rule four: a new opening takes the sides its row and column agree on. A proposal or a prediction takes each side
//! from the nearest edge it was built on, and around an opening lie others parallel to its outline a few
//! centimetres away: the frame's inner edge (a frame's width inside), a sill's lower arris below the foot, a
//! transom. On a plastered façade (@1001 at full size) 7 of 48 windows came out with one side, or the whole
//! outline, on such an edge, 8–9 cm off, and were not found. The windows of a storey share their head and foot,
//! those of a bay their sides; where an opening's size agrees with its neighbours' and one side, or both sides
//! shifted alike, does not, the neighbours are right. Only openings the lines or faces showed vote: one the grid
//! predicted copies its row's sides (at scale 0.3 on @1006 a row of copies of one foot 8 cm low outvoted the four
//! windows that showed theirs).
use super::grid::STOREY_SHARE;

/// Sides of openings of one row or column within this of each other agree, metres: the noise of a side found on
/// the lines (about 1 GSD at full size) and well under a frame's width.
const SIDE_AGREEMENT_M: f64 = 0.025;
/// A side is moved at most this far, metres: a frame's width or a sill's drop, not another opening's side.
const MAX_MOVE_M: f64 = 0.15;

/// `bounds` `[x0, x1, z0, z1]` with the sides its row and column in `others` (the bounds of the other openings on
/// its wall) agree on. The column is the openings whose span across overlaps this one's by most of the narrower
/// one ([`STOREY_SHARE`]), the row likewise in height; on each axis:
///
/// - a side more than [`SIDE_AGREEMENT_M`] and at most [`MAX_MOVE_M`] from where most of them (at least two) put
///   it, while the opposite side agrees with theirs, moves there;
/// - both sides off alike (the size agrees with theirs) move together;
/// - otherwise (a door among windows, a wider window) the opening keeps its sides.
pub(super) fn agreed_by_rows(bounds: [f64; 4], others: &[[f64; 4]]) -> [f64; 4] {
    let mut out = bounds;
    for axis in [0, 2] {
        let (lo, hi) = (bounds[axis], bounds[axis + 1]);
        let mates: Vec<&[f64; 4]> = others
            .iter()
            .filter(|o| {
                let shared = o[axis + 1].min(hi) - o[axis].max(lo);
                shared >= STOREY_SHARE * (o[axis + 1] - o[axis]).min(hi - lo)
            })
            .collect();
        let (Some(lo_agreed), Some(hi_agreed)) = (agreed(mates.iter().map(|o| o[axis])), agreed(mates.iter().map(|o| o[axis + 1]))) else {
            continue;
        };
        let off = |was: f64, agreed: f64| (was - agreed).abs();
        let movable = |d: f64| d > SIDE_AGREEMENT_M && d <= MAX_MOVE_M;
        let (d_lo, d_hi) = (off(lo, lo_agreed), off(hi, hi_agreed));
        let same_size = ((hi - lo) - (hi_agreed - lo_agreed)).abs() <= SIDE_AGREEMENT_M;
        if (movable(d_lo) && d_hi <= SIDE_AGREEMENT_M)
            || (movable(d_hi) && d_lo <= SIDE_AGREEMENT_M)
            || (movable(d_lo) && movable(d_hi) && same_size)
        {
            out[axis] = lo_agreed;
            out[axis + 1] = hi_agreed;
        }
    }
    out
}

/// Where most of `values` (at least two) agree within [`SIDE_AGREEMENT_M`] of their median: their mean.
fn agreed(values: impl Iterator<Item = f64>) -> Option<f64> {
    let values: Vec<f64> = values.collect();
    let median = lineflow_photogrammetry::median(values.clone())?;
    let near: Vec<f64> = values.iter().copied().filter(|v| (v - median).abs() <= SIDE_AGREEMENT_M).collect();
    (near.len() >= 2 && 2 * near.len() > values.len()).then(|| near.iter().sum::<f64>() / near.len() as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row of windows 1.07 × 1.04 m, 2.5 m apart, foot at 0.74 m.
    fn row() -> Vec<[f64; 4]> {
        (0..4).map(|k| [2.5 * k as f64, 2.5 * k as f64 + 1.07, 0.74, 1.78]).collect()
    }

    #[test]
    fn a_head_on_the_frames_inner_edge_goes_to_its_rows() {
        let others = row();
        let agreed = agreed_by_rows([10.0, 11.07, 0.74, 1.695], &others);
        assert!((agreed[3] - 1.78).abs() < 1e-9, "{agreed:?}");
        assert_eq!(agreed[..3], [10.0, 11.07, 0.74]);
    }

    #[test]
    fn an_outline_shifted_onto_a_sill_and_a_frame_goes_back_whole() {
        let mut others = row();
        // A column above the window, for its sides.
        others.push([10.0, 11.07, 4.0, 5.04]);
        others.push([10.0, 11.07, 7.2, 8.24]);
        let agreed = agreed_by_rows([10.0, 10.985, 0.65, 1.69], &others);
        assert!(
            (agreed[1] - 11.07).abs() < 1e-9 && (agreed[2] - 0.74).abs() < 1e-9 && (agreed[3] - 1.78).abs() < 1e-9,
            "{agreed:?}"
        );
    }

    #[test]
    fn a_door_among_windows_and_a_lone_opening_keep_their_sides() {
        let mut others = row();
        others.push([10.0, 11.07, 4.0, 5.04]);
        others.push([10.0, 11.07, 7.2, 8.24]);
        let door = [10.0 - 0.06, 11.07 + 0.07, 0.12, 2.4];
        assert_eq!(agreed_by_rows(door, &others), door);
        let wider = [10.0 - 0.1, 11.07 + 0.1, 0.74, 1.78];
        assert_eq!(agreed_by_rows(wider, &others), wider);
        let alone = [10.0, 11.07, 0.65, 1.69];
        assert_eq!(agreed_by_rows(alone, &others[..1]), alone, "one neighbour is no row");
    }
}
