//! The linemap stage: 3-D lines from the 2-D segments of every oriented image, designed for completeness.
//!
//! Where `linematch` searches each master image's lines in depth in front of a wall and scores them by correlation
//! over a few neighbours, linemap works on segments alone and treats every image alike:
//! 1. [`hypotheses`]: every segment of every image is cut with the interpretation planes of the segments of every
//!    other image that could show the same edge (no wall needed; the site model only bounds the search region).
//! 2. [`support`]: each hypothesis is projected into all the other images, and each image adds the Gaussian weight
//!    of its best segment along it; a segment keeps its best-supported hypothesis.
//! 3. [`tracks`]: from the best-supported down, each hypothesis is re-estimated from every image's segment along
//!    it, cut to the stretches that enough images cover without a gap, and claims its segments.
#![warn(missing_docs)]

pub mod appearance;
pub mod guide;
pub mod hypotheses;
pub mod junctions;
pub mod line;
pub mod meeting;
pub mod stage;
pub mod support;
pub mod surfaces;
pub mod tracks;
pub mod views;

use lineflow_runtime::params::{at_least, check, in_closed, in_half_open, non_negative, positive, ParamError};
use serde::Deserialize;

pub use guide::{Bounds, Guide};
pub use hypotheses::Hypothesis;
pub use line::MappedLine;
pub use lineflow_linegeom::Photo;
pub use stage::MapStage;
pub use tracks::{best_hypothesis, line_messages, map_lines, map_lines_with_stats, MapStats, Scored};
pub use views::View;

/// Parameters of the `linemap` node.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MapParams {
    /// Shortest 2-D segment used, pixels.
    pub min_length_px: f64,
    /// Smallest angle between an endpoint ray and the other image's interpretation plane, degrees: below it the
    /// pair does not fix the depth.
    pub min_plane_angle_deg: f64,
    /// Smallest angle between a line and either image's line of sight, degrees.
    pub min_ray_angle_deg: f64,
    /// Smallest overlap of two segments along the line, as a share of the shorter.
    pub min_overlap: f64,
    /// Each image's segments are paired with those of this many other images, the nearest (0 = every image).
    pub max_partners: usize,
    /// Largest distance of a supporting segment's endpoints from the projected line, pixels.
    pub max_distance_px: f64,
    /// Largest angle between a supporting segment and the projected line, degrees.
    pub max_angle_deg: f64,
    /// Standard deviation of the support's Gaussian weight, pixels.
    pub sigma_px: f64,
    /// Support a hypothesis needs from images other than its pair (about one per confirming image).
    pub min_score: f64,
    /// A segment whose best hypothesis has a rival placing it elsewhere with at least this share of its support is
    /// ambiguous and left to the junctions (1 keeps every best).
    pub max_ambiguity: f64,
    /// Hypotheses whose midpoints lie this many pixels of the source image apart place a segment elsewhere.
    pub distinct_px: f64,
    /// Images a line needs to be re-estimated.
    pub min_views: usize,
    /// A segment whose interpretation plane misses the re-estimated line by more than this many pixels leaves it.
    pub max_residual_px: f64,
    /// A-priori standard deviation of a 2-D segment across itself, pixels (weights of the re-estimate).
    pub segment_sigma_px: f64,
    /// Directions across a line that its segments' planes determine worse than this (standard deviation, metres)
    /// keep the hypothesis's position in the re-estimate.
    pub max_sigma_m: f64,
    /// Distinct images that must cover a stretch of a line for it to be kept.
    pub min_cover: usize,
    /// A line whose estimate lies within this angle of a preferred direction (the vertical, along or across a
    /// wall of the site model) is re-estimated with that direction, degrees; 0 turns it off.
    pub snap_angle_deg: f64,
    /// Offer every segment the hypotheses of the corners it makes with the vertical lines of a first pass.
    pub junctions: bool,
    /// With `junctions`, a pair whose planes meet at less than this angle, degrees, proposes no horizontal line.
    pub weak_plane_angle_deg: f64,
    /// Largest distance of a segment's endpoint from a vertical's projection to make a corner with it, pixels.
    pub junction_px: f64,
    /// Shortest 3-D line kept, metres.
    pub min_length_m: f64,
    /// Margin around the site model's walls within which lines are sought, metres (without a site model, every
    /// depth in front of the cameras).
    pub site_margin_m: f64,
    /// A line more than this far behind every wall of the site model it lies over is inside the building, where
    /// no image sees, and is not made, metres.
    pub max_behind_m: f64,
    /// A hypothesis within this distance of a wall of the site model (or over none) keeps its support, metres…
    pub near_wall_m: f64,
    /// …one farther off has its support multiplied by this (1 = no preference).
    pub off_wall_weight: f64,
    /// While the stream runs, the map is recomputed from every oriented frame once their number has grown by this
    /// factor since the last map (1 = after every frame; the cost of the whole stream stays within a few times
    /// that of the final map). The final map always uses every frame and the final poses.
    pub remap_growth: f64,
    /// A line whose images correlate less than this along it (the median over its images of the normalised
    /// cross-correlation of a ribbon on the better side of the line with the image that sees it longest) is at a
    /// wrong depth and is not made; -1 turns the test off. Needs the images (the `images` input).
    pub min_correlation: f64,
    /// Rows of that ribbon on either side of the line, pixels.
    pub correlation_half_width_px: usize,
    /// The other images are also compared shifted across the line by up to this many pixels…
    pub correlation_search_px: usize,
    /// …and a line whose images match best farther than this from it (median over the images, pixels) is at a
    /// slightly wrong depth and is not made.
    pub max_offset_px: f64,
    /// A line whose own segments leave its depth within this many of its σ of its wall's surface (the mode of the
    /// depths of the lines along the wall) is moved onto that surface; 0 turns this off.
    pub surface_k: f64,
    /// Lines along a wall within this distance of the site model's wall are candidates of its surface, metres.
    pub surface_search_m: f64,
    /// Fewest lines that make a wall's surface.
    pub min_surface_lines: usize,
    /// A level line of a wall whose end meets a vertical line (within `corner_reach_px`, and within this many joint
    /// σ in depth) takes that vertical's depth; 0 (the default) turns this off: it gains at full size on the
    /// tuning buildings and not on the held-out ones (`docs/lines3d.md`).
    pub corner_k: f64,
    /// How far a level line's end may lie from the vertical it meets, pixels of the nearest image.
    pub corner_reach_px: f64,
    /// Class each line as structure or texture ([`lineflow_linegeom::class`]; the `class` column of
    /// `lines3d.csv`); off, every line is left unclassed.
    pub classify: bool,
    /// The classing's settings.
    pub class: lineflow_linegeom::ClassRule,
    /// Name of the result files it writes in the run's folder (`NAME.csv`, `NAME.ply`): another than linefit's
    /// `lines3d` when both stages run in one graph.
    pub results: String,
}

impl Default for MapParams {
    fn default() -> Self {
        MapParams {
            min_length_px: 15.0,
            min_plane_angle_deg: 2.0,
            min_ray_angle_deg: 5.0,
            min_overlap: 0.25,
            max_partners: 10,
            max_distance_px: 2.0,
            max_angle_deg: 2.0,
            sigma_px: 1.0,
            min_score: 1.5,
            max_ambiguity: 1.0,
            distinct_px: 10.0,
            min_views: 3,
            max_residual_px: 1.0,
            segment_sigma_px: 0.3,
            max_sigma_m: 0.05,
            min_cover: 2,
            snap_angle_deg: 8.0,
            junctions: true,
            junction_px: 3.0,
            weak_plane_angle_deg: 0.0,
            min_length_m: 0.1,
            site_margin_m: 3.0,
            max_behind_m: 1.0,
            near_wall_m: 0.6,
            off_wall_weight: 0.2,
            remap_growth: 1.5,
            min_correlation: 0.85,
            correlation_half_width_px: 3,
            correlation_search_px: 2,
            max_offset_px: 0.5,
            surface_k: 3.0,
            surface_search_m: 0.3,
            min_surface_lines: 10,
            corner_k: 0.0,
            corner_reach_px: 4.0,
            classify: true,
            class: lineflow_linegeom::ClassRule::default(),
            results: "lines3d".into(),
        }
    }
}

impl MapParams {
    /// The settings of the appearance test.
    pub fn appearance(&self) -> appearance::AppearanceParams {
        appearance::AppearanceParams {
            half_width_px: self.correlation_half_width_px,
            search_px: self.correlation_search_px,
            ..Default::default()
        }
    }

    /// The settings of the wall surfaces.
    pub fn surfaces(&self) -> surfaces::SurfaceParams {
        surfaces::SurfaceParams {
            k: self.surface_k,
            search_m: self.surface_search_m,
            min_lines: self.min_surface_lines,
        }
    }

    /// The settings of the corner depths.
    pub fn meeting(&self) -> meeting::MeetingParams {
        meeting::MeetingParams {
            k: self.corner_k,
            reach_px: self.corner_reach_px,
        }
    }

    /// The settings of the re-estimate from every image.
    pub fn multiview(&self) -> lineflow_linegeom::MultiviewParams {
        lineflow_linegeom::MultiviewParams {
            max_distance_px: self.max_distance_px,
            max_angle_deg: self.max_angle_deg,
            sigma_px: self.segment_sigma_px,
            max_sigma_m: self.max_sigma_m,
            max_residual_px: self.max_residual_px,
            min_views: self.min_views,
        }
    }
}

impl lineflow_runtime::StageParams for MapParams {
    fn validate(&self) -> Result<(), ParamError> {
        let plain = !self.results.is_empty() && !self.results.contains(['/', '\\']) && !self.results.starts_with('.');
        if !plain {
            return Err(ParamError::new("results", "a file name without a folder", &self.results));
        }
        check(self.min_length_px >= 2.0, "min_length_px", "at least 2", self.min_length_px)?;
        in_half_open("min_plane_angle_deg", self.min_plane_angle_deg, 0.0, 90.0)?;
        in_half_open("min_ray_angle_deg", self.min_ray_angle_deg, 0.0, 90.0)?;
        in_closed("min_overlap", self.min_overlap, 0.0, 1.0)?;
        positive("max_distance_px", self.max_distance_px)?;
        in_half_open("max_angle_deg", self.max_angle_deg, 0.0, 90.0)?;
        positive("sigma_px", self.sigma_px)?;
        non_negative("min_score", self.min_score)?;
        in_closed("max_ambiguity", self.max_ambiguity, 0.0, 1.0)?;
        positive("distinct_px", self.distinct_px)?;
        at_least("min_views", self.min_views, 2)?;
        positive("max_residual_px", self.max_residual_px)?;
        positive("segment_sigma_px", self.segment_sigma_px)?;
        positive("max_sigma_m", self.max_sigma_m)?;
        at_least("min_cover", self.min_cover, 1)?;
        in_half_open("snap_angle_deg", self.snap_angle_deg, 0.0, 45.0)?;
        positive("junction_px", self.junction_px)?;
        in_closed("weak_plane_angle_deg", self.weak_plane_angle_deg, 0.0, 89.0)?;
        non_negative("min_length_m", self.min_length_m)?;
        non_negative("site_margin_m", self.site_margin_m)?;
        non_negative("max_behind_m", self.max_behind_m)?;
        non_negative("near_wall_m", self.near_wall_m)?;
        in_closed("off_wall_weight", self.off_wall_weight, 0.0, 1.0)?;
        in_closed("min_correlation", self.min_correlation, -1.0, 1.0)?;
        at_least("correlation_half_width_px", self.correlation_half_width_px, 1)?;
        non_negative("max_offset_px", self.max_offset_px)?;
        non_negative("surface_k", self.surface_k)?;
        non_negative("surface_search_m", self.surface_search_m)?;
        at_least("min_surface_lines", self.min_surface_lines, 1)?;
        non_negative("corner_k", self.corner_k)?;
        positive("corner_reach_px", self.corner_reach_px)?;
        check(self.remap_growth >= 1.0, "remap_growth", "at least 1", self.remap_growth)?;
        self.class.validate().map_err(|e| ParamError::new(e.name, e.requirement, e.value))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_runtime::StageParams;

    #[test]
    fn the_results_name_is_a_plain_file_name() {
        for good in ["lines3d", "lines3d_linemap", "a.b"] {
            let p = MapParams {
                results: good.into(),
                ..MapParams::default()
            };
            assert!(p.validate().is_ok(), "{good}");
        }
        for bad in ["", "../lines3d", "out/lines3d", "..", ".hidden", "a\\b", "/tmp/x"] {
            let p = MapParams {
                results: bad.into(),
                ..MapParams::default()
            };
            let e = p.validate().expect_err(bad);
            assert!(format!("{e}").contains("results"), "{e}");
        }
    }
}
