//! The stats sink: a record of every frame that reached the end of the graph.
#![warn(missing_docs)]

use lineflow_messages::{str_from_fixed, EdgeMapHeader, EdgePixel, Encoding, ImageHeader, Lines2DHeader};

pub use lineflow_messages::checksum::{fnv1a64, fnv1a64_extend, FNV1A64_START};

/// The header line of `frames.csv`.
pub const FRAMES_CSV_HEADER: &str = "frame,image,width,height,encoding,capture_time_ns,fnv1a64";
/// The header line of `edges.csv`.
pub const EDGES_CSV_HEADER: &str = "frame,detector,n_pixels,fnv1a64";
/// The header line of `segments.csv`.
pub const SEGMENTS_CSV_HEADER: &str = "frame,image,n_segments,n_chain,fnv1a64";

/// The stage's launch-file parameters.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StatsParams {
    /// The frames file's name in the run's output folder.
    pub file: String,
}

impl Default for StatsParams {
    fn default() -> Self {
        StatsParams { file: "frames.csv".into() }
    }
}

impl lineflow_runtime::StageParams for StatsParams {
    fn validate(&self) -> Result<(), lineflow_runtime::ParamError> {
        lineflow_runtime::params::file_name("file", &self.file)
    }
}

/// One image's row of `frames.csv` (without the line end).
pub fn frame_row(h: &ImageHeader, payload: &[u8]) -> String {
    let enc = Encoding::from_u32(h.encoding).map(Encoding::name).unwrap_or("unknown");
    format!(
        "{},{},{},{},{enc},{},{:016x}",
        h.stamp.frame,
        h.name(),
        h.width,
        h.height,
        h.stamp.capture_time_ns,
        fnv1a64(payload)
    )
}

/// One edge map's row of `edges.csv`. The checksum runs field by field in little-endian order, so that it does
/// not depend on the struct's layout.
pub fn edges_row(h: &EdgeMapHeader, pixels: &[EdgePixel]) -> String {
    let sum = pixels.iter().fold(FNV1A64_START, |h, p| {
        let h = fnv1a64_extend(h, &p.col.to_le_bytes());
        let h = fnv1a64_extend(h, &p.row.to_le_bytes());
        let h = fnv1a64_extend(h, &p.magnitude.to_le_bytes());
        fnv1a64_extend(h, &p.direction_rad.to_le_bytes())
    });
    format!("{},{},{},{:016x}", h.stamp.frame, str_from_fixed(&h.detector), pixels.len(), sum)
}

/// One Lines2D message's row of `segments.csv`.
pub fn segments_row(h: &Lines2DHeader, payload: &[u8]) -> String {
    format!(
        "{},{},{},{},{:016x}",
        h.stamp.frame,
        h.name(),
        h.n_segments,
        h.n_chain,
        fnv1a64(payload)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_hold_the_frame_the_counts_and_a_checksum_of_the_content() {
        use lineflow_messages::{fixed_str, Stamp};
        let stamp = Stamp {
            frame: 2,
            capture_time_ns: 5,
            ..Stamp::default()
        };
        let image = ImageHeader {
            stamp,
            width: 2,
            height: 1,
            step: 2,
            encoding: Encoding::Mono8 as u32,
            name: fixed_str("IMG_2.png"),
        };
        assert_eq!(
            super::frame_row(&image, b"ab"),
            format!("2,IMG_2.png,2,1,mono8,5,{:016x}", super::fnv1a64(b"ab"))
        );
        let edges = EdgeMapHeader {
            stamp,
            width: 2,
            height: 1,
            detector: fixed_str("canny"),
            name: fixed_str("IMG_2.png"),
        };
        let px = EdgePixel {
            col: 1,
            row: 0,
            magnitude: 3.0,
            direction_rad: 0.5,
        };
        let row = super::edges_row(&edges, &[px]);
        assert!(row.starts_with("2,canny,1,"), "{row}");
        let moved = EdgePixel { col: 0, ..px };
        assert_ne!(super::edges_row(&edges, &[moved]), row, "the checksum sees every field");
        assert_eq!(super::edges_row(&edges, &[]), format!("2,canny,0,{:016x}", super::FNV1A64_START));
    }
}
