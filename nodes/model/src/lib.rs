//! The model stage: a polyhedral wire-frame from unordered, incomplete, noisy 3-D lines, after seed 003's
//! Construct-Shape-Refine (CSR), applied to façades.
//!
//! - Construct ([`junction`], [`corners`]): candidate junctions between lines, the seed's acceptance conditions
//!   (error-free logic, distance checks, topology), junctions clustered into corners, lines grouped into objects.
//! - Shape ([`adjust`]): the corners of each object adjusted from its lines in the Gauss-Helmert model, with
//!   standard deviations.
//! - Occluded edges ([`occlusion`]): an open face boundary closed along the outline of the structure in front of
//!   it that hides the rest (the shortest path through its corners), or, where the façade's relief hides an
//!   opening's edge, by the chord between its seen ends.
//! - Faces ([`faces`]): closed planar cycles of edges become wall, roof and opening surfaces; a face inside another
//!   face of the same plane is its opening (the seed's "roof inside a roof").
//! - Refine ([`refine`], optional): every adjusted edge measured again in the images' 2-D lines, intersected
//!   through interpretation planes, and adjusted together with its 3-D line.
//! - Export ([`export`]): `model.obj` and `model.city.json` (CityJSON 2.0, LOD 3).
//!
//! Model-image fitting (LSMIF, seed 004) is the `modelfit` stage.
pub mod adjust;
pub mod align;
pub mod corners;
mod disjoint;
pub mod export;
pub mod faces;
mod grid;
mod inside;
pub mod junction;
pub mod occlusion;
mod openings;
pub mod refine;
pub mod regular;
pub mod stage;
mod surface;
mod surface_lines;
#[cfg(test)]
mod test_views;

use lineflow_formats::LineClass;
use lineflow_linegeom::ClassRule;
use lineflow_photogrammetry::{Camera, Vec3};
use serde::Deserialize;

pub use inside::Inside;
use junction::Resolution;
pub use surface::{Face, SurfaceKind};

/// A 3-D line given to the model.
#[derive(Debug, Clone)]
pub struct ModelLine {
    pub start: Vec3,
    pub end: Vec3,
    /// Standard deviation of each endpoint coordinate across the line, metres.
    pub sigma_m: f64,
    /// Per object axis (X, Y, Z) in place of `sigma_m`, where a line is better known in some directions than in
    /// others (one measured in images: sharp across the viewing rays, weak along them).
    pub sigma_axes_m: Option<Vec3>,
    /// Which of its slopes regularisation made exact ([`regular`]).
    pub regular: regular::Regularity,
    /// Standard deviation of its endpoints along it, metres, where known (lines whose endpoints carry the
    /// isotropic `sigma_m`); a fitted line's σ says how well its position is known, not where it ends.
    pub sigma_end_m: Option<f64>,
    /// Classed texture by the line stage (a line inside a surface): it takes part in the model like every line
    /// (the openings' rules read the courses), and is set aside with the surface lines at the end.
    pub texture: bool,
}

impl ModelLine {
    pub fn new(start: Vec3, end: Vec3, sigma_m: f64) -> Self {
        ModelLine {
            start,
            end,
            sigma_m,
            sigma_axes_m: None,
            regular: regular::Regularity::Free,
            sigma_end_m: None,
            texture: false,
        }
    }
    /// The standard deviation of each endpoint coordinate along object axis `axis`, metres.
    pub fn sigma_along(&self, axis: usize) -> f64 {
        self.sigma_axes_m.map_or(self.sigma_m, |s| s[axis])
    }
    pub fn length(&self) -> f64 {
        (self.end - self.start).norm()
    }
    pub fn direction(&self) -> Vec3 {
        (self.end - self.start).normalize()
    }
    /// How far a junction may lie beyond this line's end, or inside it and still belong to the end, metres:
    /// `reach_k` joint σ of the end and of the other line's position along this one (`other_sigma_m`), at most
    /// `max_reach_m`.
    pub fn reach(&self, other_sigma_m: f64, params: &ModelParams) -> f64 {
        self.sigma_end_m.map_or(params.max_reach_m, |s| {
            (params.reach_k * s.hypot(other_sigma_m)).min(params.max_reach_m)
        })
    }
    pub fn midpoint(&self) -> Vec3 {
        (self.start + self.end) * 0.5
    }
}

/// What the model does with the lines the line stage classed texture (lines inside a surface: mortar, tile and
/// panel joints). Measured in docs/model.md ("Texture lines").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TextureLines {
    /// Left out before the model is built: no junctions, faces or openings from them.
    Drop,
    /// Built into the model like every line (the openings' rules read the courses between windows), then set
    /// aside with the surface lines unless a corner of a window, door or roof face or inside an opening.
    Aside,
    /// Treated as every other line (and lines that come unclassed are not classed).
    Keep,
}

/// What becomes of the lines that reach no corner, the model's loose edges. Measured in docs/model.md ("Loose
/// lines"). In a launch file a name (`"keep"`, `"openings"`, `"drop"`), or `true` (keep) and `false` (drop).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(try_from = "LooseLinesSetting")]
pub enum LooseLines {
    /// Every loose line is an edge of the model.
    Keep,
    /// Those at an opening stay (its outline, frame, panes and sill: on plaster most are true edges whose
    /// neighbours were not found); away from every opening they go (fragments of eaves, balconies, the ground
    /// line, courses: on the held-out buildings 1 to 4 of 200-350 were true edges).
    Openings,
    /// Left out unless a face uses them.
    Drop,
}

/// How a launch file may spell [`LooseLines`].
#[derive(Deserialize)]
#[serde(untagged)]
enum LooseLinesSetting {
    Flag(bool),
    Name(String),
}

impl TryFrom<LooseLinesSetting> for LooseLines {
    type Error = String;
    fn try_from(setting: LooseLinesSetting) -> Result<Self, String> {
        match setting {
            LooseLinesSetting::Flag(true) => Ok(LooseLines::Keep),
            LooseLinesSetting::Flag(false) => Ok(LooseLines::Drop),
            LooseLinesSetting::Name(name) => match name.as_str() {
                "keep" => Ok(LooseLines::Keep),
                "openings" => Ok(LooseLines::Openings),
                "drop" => Ok(LooseLines::Drop),
                other => Err(format!(
                    "loose_lines: expected \"keep\", \"openings\" or \"drop\" (or true / false), found \"{other}\""
                )),
            },
        }
    }
}

/// Parameters of the model stage (launch-file `params` of node `model`).
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ModelParams {
    /// Endpoint standard deviation for lines that carry no RMS (e.g. a lines3d.csv without statistics), metres.
    pub sigma_m: f64,
    /// Smallest endpoint standard deviation credited to any line, metres (a fitted line's RMS over many points
    /// can be optimistic).
    pub min_sigma_m: f64,
    /// Lines shorter than this are ignored, metres.
    pub min_length_m: f64,
    /// Distance gate: a junction may lie at most this far beyond a segment, and must lie this close to an end of
    /// one of the two lines, metres.
    pub max_reach_m: f64,
    /// The distance gate of a line whose endpoints' σ is known (one without RMS, at `sigma_m`), in joint σ.
    pub reach_k: f64,
    /// Gap gate: two lines meet when their common perpendicular is shorter than this many joint σ.
    pub gap_k: f64,
    /// Smallest angle between two lines that are intersected, degrees (the seed's 3σ gate is clamped to
    /// [this, 20°]).
    pub min_angle_deg: f64,
    /// Junctions closer than this many joint σ are one corner.
    pub corner_k: f64,
    /// Two planes of faces are one when their normals differ by less than this, degrees.
    pub plane_angle_deg: f64,
    /// Refine with the images' 2-D lines when the node has them (the `lines2d`, `camera` and `poses` inputs
    /// wired; `lineflow model` with `--lines2d`).
    pub refine: bool,
    /// Look in the images' 2-D lines, when the node has them, for the sides of the openings a façade's rows and
    /// columns predict where the 3-D lines missed them ([`openings`], "Openings confirmed in the images").
    pub verify_openings: bool,
    /// Move each new opening's sides to where the images' 2-D lines place them, when the node has them
    /// ([`openings`], "Openings settled in the images").
    pub settle_openings: bool,
    /// Refine's thresholds, in standard deviations (the seed: two or three).
    pub refine_k: f64,
    /// Standard deviation of an image line's endpoints across it, pixels.
    pub refine_image_sigma_px: f64,
    /// Shortest image line used, pixels.
    pub refine_min_image_line_px: f64,
    /// Interpretation planes closer than this angle are not intersected, degrees.
    pub refine_min_plane_angle_deg: f64,
    /// The live stage keeps the 2-D lines of the newest this many frames for the openings' evidence and Refine
    /// and lets older ones go, so that its memory does not grow with the stream (0 keeps every frame). On a long
    /// pass along a street the openings of buildings left behind are then built from the 3-D lines alone.
    pub keep_frames: usize,
    /// Occluded-edge completion: how far a free end of an open face boundary may lie from the outline of the
    /// structure in front of it that hides the rest, metres; 0 turns the completion off.
    pub occlusion_reach_m: f64,
    /// How far in front of a face (along Z for roofs, towards the cameras for walls) the structure that hides part
    /// of it stands at least, metres: a neighbouring building, a wing, a balcony, not the façade's own relief.
    pub occlusion_min_depth_m: f64,
    /// Turn lines within their noise of plumb, level or the building's plan directions onto them ([`regular`]).
    pub regularise: bool,
    /// Regularisation's gate, in the line's own direction σ.
    pub regular_k: f64,
    /// The most a line is turned by regularisation, degrees.
    pub regular_max_deg: f64,
    /// Move regularised lines onto the depths, heights and positions along the wall they share with others
    /// ([`align`]); only where the building has one pair of plan directions.
    pub align: bool,
    /// Alignment's gate, in the line's own position σ.
    pub align_k: f64,
    /// The fewest lines that make a shared value.
    pub align_min_lines: usize,
    /// What becomes of the lines that reach no corner ([`LooseLines`]; those at an opening stay by default).
    pub loose_lines: LooseLines,
    /// Leave out the observed edges parallel to a wall that float at an opening where no surface is: in its reveal
    /// in front of the frame, or in front of the wall (up to `sill_proud_max_m`) where it has no sill ([`openings`],
    /// "Floating edges").
    pub floating_edges: bool,
    /// Keep the lines lying inside a wall's surface (mortar, tile and panel joints) out of the model's edges, as
    /// `surface_lines` ([`surface_lines`]).
    pub surface_lines: bool,
    /// How far off a wall's surface a surface line's ends may lie, metres.
    pub surface_band_m: f64,
    /// How far inside the wall's extent a surface line's ends lie at least, metres (the wall's outline stays).
    pub surface_margin_m: f64,
    /// A surface line lies in a field of its kind (courses, rows of tiles): this many parallel surface lines…
    pub surface_neighbours: usize,
    /// …within this distance across, metres.
    pub surface_reach_m: f64,
    /// What becomes of the lines the line stage classed texture ([`TextureLines`]); lines that come unclassed are
    /// classed here with `class` unless this is `keep`.
    pub texture_lines: TextureLines,
    /// The classing of unclassed lines ([`lineflow_linegeom::class`]).
    pub class: ClassRule,
    /// How far behind its wall a recessed face or the sides of an opening may lie to make an opening, metres: less
    /// than `recess_min_m` is on the wall (a nearly flush frame, or a pane inside its frame)…
    pub recess_min_m: f64,
    /// …and at most this.
    pub recess_max_m: f64,
    /// The narrowest and lowest opening inferred, metres (also the shortest bay of a façade's grid of openings)…
    pub opening_min_m: f64,
    /// …and the widest and highest.
    pub opening_max_m: f64,
    /// A frame's outer edges lie at least this far outside its glazing, metres…
    pub frame_min_m: f64,
    /// …and at most this.
    pub frame_max_m: f64,
    /// Give the windows whose sill's nose the 3-D lines show their sills, as boxes shaped by the wall's sills
    /// together ([`openings`], "Sills").
    pub sills: bool,
    /// A sill's nose lies at least this far in front of its wall, metres…
    pub sill_proud_min_m: f64,
    /// …and at most this.
    pub sill_proud_max_m: f64,
    /// How far below its window's foot a sill's top may lie, metres.
    pub sill_reach_m: f64,
    /// Give every window whose frame the model knows the panes its lines, or those of the wall's windows of its
    /// size, lay out and it lacks ([`openings`], "Panes").
    pub panes: bool,
    /// Give every pane its glass behind it, with the reveals from the frame's face to the glass ([`openings`],
    /// "Glass").
    pub glass: bool,
    /// How far the glass lies behind its pane's frame where the lines do not show it, metres (a glazing bead's
    /// depth; the lines' own measure, where enough of them show it, comes first).
    pub glass_inset_m: f64,
}

impl Default for ModelParams {
    fn default() -> Self {
        ModelParams {
            sigma_m: 0.01,
            min_sigma_m: 0.002,
            min_length_m: 0.02,
            max_reach_m: 0.05,
            reach_k: 3.0,
            gap_k: 3.0,
            min_angle_deg: 5.0,
            corner_k: 3.0,
            plane_angle_deg: 2.0,
            // Off by default: on the pipeline's own lines it changes nothing measurable (docs/model.md, Refine).
            refine: false,
            verify_openings: true,
            settle_openings: true,
            refine_k: refine::RefineParams::default().k,
            refine_image_sigma_px: refine::RefineParams::default().image_sigma_px,
            refine_min_image_line_px: refine::RefineParams::default().min_image_line_px,
            refine_min_plane_angle_deg: refine::RefineParams::default().min_plane_angle_deg,
            keep_frames: 200,
            occlusion_reach_m: 0.5,
            occlusion_min_depth_m: 0.5,
            regularise: true,
            regular_k: 3.0,
            regular_max_deg: 15.0,
            align: true,
            align_k: 2.0,
            align_min_lines: 3,
            loose_lines: LooseLines::Openings,
            floating_edges: true,
            surface_lines: true,
            surface_band_m: 0.03,
            surface_margin_m: 0.1,
            surface_neighbours: 4,
            surface_reach_m: 0.3,
            texture_lines: TextureLines::Drop,
            class: ClassRule::default(),
            recess_min_m: 0.06,
            recess_max_m: 0.5,
            opening_min_m: 0.8,
            opening_max_m: 4.0,
            frame_min_m: 0.02,
            frame_max_m: 0.15,
            sills: true,
            sill_proud_min_m: 0.02,
            sill_proud_max_m: 0.3,
            sill_reach_m: 0.3,
            panes: true,
            glass: true,
            glass_inset_m: 0.015,
        }
    }
}

impl ModelParams {
    /// Refine's parameters.
    pub fn refine_params(&self) -> refine::RefineParams {
        refine::RefineParams {
            k: self.refine_k,
            image_sigma_px: self.refine_image_sigma_px,
            min_image_line_px: self.refine_min_image_line_px,
            min_plane_angle_deg: self.refine_min_plane_angle_deg,
            ..refine::RefineParams::default()
        }
    }

    /// The sizes the opening rules assume.
    pub(crate) fn opening_sizes(&self) -> openings::OpeningSizes {
        openings::OpeningSizes {
            recess_m: (self.recess_min_m, self.recess_max_m),
            opening_m: (self.opening_min_m, self.opening_max_m),
            frame_m: (self.frame_min_m, self.frame_max_m),
        }
    }

    /// The sills' rule.
    pub(crate) fn sill_rule(&self) -> openings::SillRule {
        openings::SillRule {
            proud_m: (self.sill_proud_min_m, self.sill_proud_max_m),
            reach_m: self.sill_reach_m,
        }
    }

    /// Alignment's parameters.
    pub fn align_params(&self) -> align::AlignParams {
        align::AlignParams {
            k: self.align_k,
            min_lines: self.align_min_lines,
        }
    }

    /// Regularisation's parameters.
    pub fn regular_params(&self) -> regular::RegularParams {
        regular::RegularParams {
            k: self.regular_k,
            max_deg: self.regular_max_deg,
            min_share: 0.1,
        }
    }

    /// The defaults with `PARAM=VALUE` overrides (VALUE as TOML) applied, validated: `lineflow model --set` and
    /// `lineflow bench model --set`.
    ///
    /// # Errors
    /// A malformed item, an unknown or mistyped parameter, or a value out of range.
    pub fn with_overrides(set: &[String]) -> anyhow::Result<ModelParams> {
        let params: ModelParams = lineflow_runtime::launch::params_from_overrides(set)?;
        lineflow_runtime::StageParams::validate(&params)?;
        Ok(params)
    }

    /// The endpoint σ of a fitted line: the RMS of its points about it, shrunk by the points' number as the end
    /// of a least-squares line is (≈ 2 RMS / √n), never below `min_sigma_m`; `sigma_m` when unknown. An RMS below
    /// a nanometre is unknown too: points placed exactly on their line (by the slaves' 2-D lines) say nothing of
    /// its precision, and `lines3d.csv` writes such an RMS as 0, so the model of the file and the live one agree.
    pub fn line_sigma(&self, rms_m: Option<f64>, n_points: Option<u32>) -> f64 {
        self.fitted_sigma(rms_m, n_points).unwrap_or(self.sigma_m)
    }

    /// A fitted line's σ from its statistics, if they say anything. An RMS that `lines3d.csv` writes as 0.000000
    /// does not: a line through two images' segments fits them exactly whatever its error, and a model built live
    /// must be the model `lineflow model` builds from the run's file (taking sub-micrometre RMS values as 2 mm
    /// lines live, and as unknown from the file, cost 11 of 36 openings on a tuning building).
    fn fitted_sigma(&self, rms_m: Option<f64>, n_points: Option<u32>) -> Option<f64> {
        let rms_m = rms_m.map(lineflow_formats::metres_as_written);
        match (rms_m, n_points) {
            (Some(rms), Some(n)) if rms.is_finite() && rms > 0.0 && n > 0 => Some((2.0 * rms / (n as f64).sqrt()).max(self.min_sigma_m)),
            _ => None,
        }
    }
}

impl lineflow_runtime::StageParams for ModelParams {
    fn validate(&self) -> Result<(), lineflow_runtime::ParamError> {
        use lineflow_runtime::params::{at_least, in_half_open, non_negative, positive};
        for (name, v) in [
            ("sigma_m", self.sigma_m),
            ("min_sigma_m", self.min_sigma_m),
            ("max_reach_m", self.max_reach_m),
            ("reach_k", self.reach_k),
            ("gap_k", self.gap_k),
            ("corner_k", self.corner_k),
            ("plane_angle_deg", self.plane_angle_deg),
            ("refine_k", self.refine_k),
            ("refine_image_sigma_px", self.refine_image_sigma_px),
            ("regular_k", self.regular_k),
            ("align_k", self.align_k),
            ("surface_band_m", self.surface_band_m),
            ("surface_reach_m", self.surface_reach_m),
            ("recess_min_m", self.recess_min_m),
            ("opening_min_m", self.opening_min_m),
            ("frame_max_m", self.frame_max_m),
            ("sill_reach_m", self.sill_reach_m),
        ] {
            positive(name, v)?;
        }
        in_half_open("min_angle_deg", self.min_angle_deg, 0.0, 45.0)?;
        at_least("align_min_lines", self.align_min_lines, 2)?;
        in_half_open("regular_max_deg", self.regular_max_deg, 0.0, 45.0)?;
        in_half_open("refine_min_plane_angle_deg", self.refine_min_plane_angle_deg, 0.0, 45.0)?;
        for (name, v) in [
            ("refine_min_image_line_px", self.refine_min_image_line_px),
            ("occlusion_reach_m", self.occlusion_reach_m),
            ("occlusion_min_depth_m", self.occlusion_min_depth_m),
            ("min_length_m", self.min_length_m),
            ("surface_margin_m", self.surface_margin_m),
            ("frame_min_m", self.frame_min_m),
            ("sill_proud_min_m", self.sill_proud_min_m),
            ("glass_inset_m", self.glass_inset_m),
        ] {
            non_negative(name, v)?;
        }
        for (name, lo, hi) in [
            ("recess_max_m", self.recess_min_m, self.recess_max_m),
            ("opening_max_m", self.opening_min_m, self.opening_max_m),
            ("frame_max_m", self.frame_min_m, self.frame_max_m),
            ("sill_proud_max_m", self.sill_proud_min_m, self.sill_proud_max_m),
        ] {
            lineflow_runtime::params::check(hi > lo, name, "more than its minimum", hi)?;
        }
        self.class
            .validate()
            .map_err(|e| lineflow_runtime::ParamError::new(e.name, e.requirement, e.value))
    }
}

/// The farthest Shape may move a corner from its junctions' mean, metres.
const MAX_CORNER_MOVE_M: f64 = 1.0;

/// A vertex of the wire-frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Vertex {
    pub point: Vec3,
    /// Posterior standard deviations of an adjusted corner; `None` for a free line end.
    pub sigma: Option<Vec3>,
}

/// An edge of the wire-frame: two vertices and the input line it comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Edge {
    pub a: usize,
    pub b: usize,
    /// Index of the input line; `usize::MAX` for an edge no line observed.
    pub line: usize,
    pub origin: EdgeOrigin,
}

/// Where an edge of the wire-frame comes from. Scores and fits treat inferred edges as seen (a camera sees an
/// opening's outline, its frame and its reveals wherever the model puts them) and leave hidden ones out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeOrigin {
    /// An input 3-D line.
    Observed,
    /// Placed by the model's rules where no line gave it: an opening's outline, its frame and reveals
    /// ([`openings`]).
    Inferred,
    /// Completed behind an occluder ([`occlusion`]): no camera sees it.
    Hidden,
}

impl Edge {
    /// Whether an input line gave this edge.
    pub fn observed(&self) -> bool {
        self.origin == EdgeOrigin::Observed
    }
}

/// What the model was built from and how, for the log and the report.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Diagnostics {
    pub lines_in: usize,
    /// Lines that reached at least one corner (the others are loose: left out unless `loose_lines`).
    pub lines_used: usize,
    /// Edges of loose lines left out of the model ([`LooseLines`]).
    pub loose_dropped: usize,
    /// Observed edges left out where they floated at an opening ([`ModelParams::floating_edges`]).
    pub floating_dropped: usize,
    /// Lines the line stage (or the model, for unclassed lines) classed texture.
    pub texture_lines: usize,
    pub junction_candidates: usize,
    pub junctions_accepted: usize,
    /// Line ends resolved by stage 1, 2 and 3, and left free.
    pub ends_by_stage: [usize; 4],
    pub objects: usize,
    /// Objects whose adjustment failed (initial corners kept).
    pub objects_unadjusted: usize,
    /// Corners an adjustment took implausibly far (their junctions' mean kept).
    pub corners_unadjusted: usize,
    /// Median σ̂0 over the objects with redundancy.
    pub median_sigma0: Option<f64>,
    /// Edges measured again in the images by Refine (each a second observation in its object's adjustment).
    pub lines_refined: usize,
    /// Open chains closed along the outline of an occluder in front of them.
    pub chains_completed: usize,
    /// Lines turned onto the building's directions.
    pub regularised: regular::RegularCounts,
    /// Line coordinates moved onto shared values.
    pub aligned: align::AlignCounts,
}

/// The wire-frame model.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Model {
    pub vertices: Vec<Vertex>,
    pub edges: Vec<Edge>,
    /// Lines lying inside a wall's surface (mortar, tile and panel joints): observed, but no edges of the building
    /// ([`surface_lines`]); vertex pairs.
    pub surface_lines: Vec<[usize; 2]>,
    pub faces: Vec<Face>,
    /// The objects Construct grouped the lines into, each as its corners (indices into `vertices`).
    pub objects: Vec<Vec<usize>>,
    /// Objects inside another in plan (seed 003 §3.4.3: a stair tower or penthouse on a roof), by index into
    /// `objects`.
    pub inside: Vec<Inside>,
    pub diagnostics: Diagnostics,
}

impl Model {
    /// The edges a camera sees, as vertex pairs: those completed behind an occluder left out (they have no image
    /// evidence, and a ground truth of seen edges does not hold them).
    pub fn visible_edges(&self) -> Vec<[usize; 2]> {
        self.edges
            .iter()
            .filter(|e| e.origin != EdgeOrigin::Hidden)
            .map(|e| [e.a, e.b])
            .collect()
    }

    /// The window and door faces: whether a door, and the points of the outer ring.
    pub fn openings(&self) -> Vec<(bool, Vec<Vec3>)> {
        self.faces
            .iter()
            .filter(|f| matches!(f.kind, SurfaceKind::Window | SurfaceKind::Door))
            .map(|f| {
                (
                    f.kind == SurfaceKind::Door,
                    f.ring.iter().map(|&v| self.vertices[v].point).collect(),
                )
            })
            .collect()
    }

    /// The faces of the given kinds.
    pub fn count(&self, kinds: &[SurfaceKind]) -> usize {
        self.faces.iter().filter(|f| kinds.contains(&f.kind)).count()
    }

    /// One line for logs: what was used, what came out, how the line ends were resolved, σ̂0.
    pub fn summary(&self) -> String {
        let d = &self.diagnostics;
        format!(
            "{} of {} lines used ({} classed texture, {} edges of loose lines and {} floating at openings left out), {} objects ({} left unadjusted, {} corners kept where their lines met), {} vertices, {} edges ({} lines inside a wall's surface set aside), {} faces ({} walls, {} window/door, {} roof), ends resolved by stage 1/2/3: {}/{}/{}, free {}, median sigma0 {}, {} edges refined by image lines, {} occluded boundaries completed, {} objects inside another in plan, lines turned plumb/level/level on a plan direction/sloped on one: {}/{}/{}/{} ({} plan directions), line coordinates aligned along/across the wall/in height: {}/{}/{} ({}/{}/{} shared values)",
            d.lines_used,
            d.lines_in,
            d.texture_lines,
            d.loose_dropped,
            d.floating_dropped,
            d.objects,
            d.objects_unadjusted,
            d.corners_unadjusted,
            self.vertices.len(),
            self.edges.len(),
            self.surface_lines.len(),
            self.faces.len(),
            self.count(&[SurfaceKind::Wall]),
            self.count(&[SurfaceKind::Window, SurfaceKind::Door]),
            self.count(&[SurfaceKind::Roof]),
            d.ends_by_stage[0],
            d.ends_by_stage[1],
            d.ends_by_stage[2],
            d.ends_by_stage[3],
            d.median_sigma0.map_or("-".into(), |s| format!("{s:.2}")),
            d.lines_refined,
            d.chains_completed,
            self.inside.len(),
            d.regularised.plumb,
            d.regularised.level,
            d.regularised.level_on_axis,
            d.regularised.sloped_on_axis,
            d.regularised.plan_directions,
            d.aligned.moved[0],
            d.aligned.moved[1],
            d.aligned.moved[2],
            d.aligned.modes[0],
            d.aligned.modes[1],
            d.aligned.modes[2]
        )
    }
}

/// Where the images were taken from: the camera centres. Their mean tells a wall's front from its back; their
/// spread, which side of an opening no camera could see.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Cameras {
    centres: Vec<Vec3>,
}

impl Cameras {
    pub fn new(centres: Vec<Vec3>) -> Cameras {
        Cameras { centres }
    }

    /// The mean centre; none without cameras.
    pub fn mean(&self) -> Option<Vec3> {
        (!self.centres.is_empty()).then(|| self.centres.iter().sum::<Vec3>() / self.centres.len() as f64)
    }

    pub fn centres(&self) -> &[Vec3] {
        &self.centres
    }
}

/// One viewpoint standing for all the cameras.
impl From<Vec3> for Cameras {
    fn from(centre: Vec3) -> Cameras {
        Cameras { centres: vec![centre] }
    }
}

/// Construct and Shape: the wire-frame of `lines`, then its faces, oriented towards the `cameras` when there are
/// any. Deterministic for a given line order.
pub fn build(lines: &[ModelLine], params: &ModelParams, cameras: &Cameras) -> Model {
    build_with_images(lines, params, cameras, None)
}

/// The oriented images' 2-D lines, for Refine and for confirming predicted openings.
#[derive(Debug, Clone, Copy)]
pub struct Images<'a> {
    pub camera: &'a Camera,
    pub lines: &'a [refine::ImageLines],
    pub params: refine::RefineParams,
}

/// [`build`] with the images' 2-D lines: with `refine`, every adjusted edge is measured again in them and its
/// corners adjusted from both observations; with `verify_openings`, they confirm the openings a façade's rows and
/// columns predict.
pub fn build_with_images(lines: &[ModelLine], params: &ModelParams, cameras: &Cameras, images: Option<&Images>) -> Model {
    let drop_texture = params.texture_lines == TextureLines::Drop;
    let kept: Vec<usize> = (0..lines.len())
        .filter(|&k| {
            lines[k].length() >= params.min_length_m.max(1e-6)
                && lines[k].start.iter().chain(lines[k].end.iter()).all(|v| v.is_finite())
                && !(drop_texture && lines[k].texture)
        })
        .collect();
    let mut used_lines: Vec<ModelLine> = kept.iter().map(|&k| lines[k].clone()).collect();
    let (regularised, plan_azimuths) = if params.regularise {
        regular::regularise(&mut used_lines, &params.regular_params())
    } else {
        Default::default()
    };
    let aligned = match plan_azimuths[..] {
        [azimuth] if params.align => align::align(&mut used_lines, azimuth, &params.align_params()),
        _ => align::AlignCounts::default(),
    };
    let candidates = junction::candidates(&used_lines, params);
    let accepted = junction::accept(&used_lines, &candidates, params);
    let corners = corners::cluster(&candidates, &accepted.junctions, &used_lines, params.corner_k, params.min_angle_deg);
    let object_of = corners::objects(used_lines.len(), &corners);

    let mut diagnostics = Diagnostics {
        lines_in: lines.len(),
        texture_lines: lines.iter().filter(|l| l.texture).count(),
        junction_candidates: candidates.len(),
        junctions_accepted: accepted.junctions.len(),
        regularised,
        aligned,
        ..Default::default()
    };
    // The ends that stay free: none of their junctions was accepted, or their corner went to another line's end
    // (`corners::cluster`).
    let held_ends: std::collections::HashSet<(usize, usize)> = corners.iter().flat_map(|c| c.ends.iter().copied()).collect();
    let free_end = |l: usize, end: usize| accepted.ends[l][end] == Resolution::Free || !held_ends.contains(&(l, end));
    for (l, ends) in accepted.ends.iter().enumerate() {
        for (end, r) in ends.iter().enumerate() {
            let slot = match r {
                _ if free_end(l, end) => 3,
                Resolution::Logic => 0,
                Resolution::Distance => 1,
                Resolution::Topology => 2,
                Resolution::Free => 3,
            };
            diagnostics.ends_by_stage[slot] += 1;
        }
    }

    // Shape, object by object.
    let n_objects = object_of.iter().copied().max().map_or(0, |m| m + 1);
    let mut corner_point: Vec<Vec3> = corners.iter().map(|c| c.point).collect();
    let mut corner_sigma: Vec<Option<Vec3>> = vec![None; corners.len()];
    let mut line_axis: Vec<Option<(Vec3, Vec3)>> = vec![None; used_lines.len()];
    let mut sigma0s = Vec::new();
    // Corners and lines bucketed by object once (ascending within each).
    let mut corners_of: Vec<Vec<usize>> = vec![Vec::new(); n_objects];
    for (c, corner) in corners.iter().enumerate() {
        corners_of[object_of[corner.lines[0]]].push(c);
    }
    let mut lines_of: Vec<Vec<usize>> = vec![Vec::new(); n_objects];
    for (l, &o) in object_of.iter().enumerate() {
        lines_of[o].push(l);
    }
    for (object_corners, object_lines) in corners_of.iter().zip(&lines_of) {
        if object_corners.is_empty() {
            continue;
        }
        diagnostics.objects += 1;
        let local_line = |l: usize| object_lines.binary_search(&l).ok();
        let incidences: Vec<(usize, usize)> = object_corners
            .iter()
            .enumerate()
            .flat_map(|(ci, &c)| corners[c].lines.iter().filter_map(move |&l| local_line(l).map(|ll| (ci, ll))))
            .collect();
        let sub_lines: Vec<ModelLine> = object_lines.iter().map(|&l| used_lines[l].clone()).collect();
        let start: Vec<Vec3> = object_corners.iter().map(|&c| corners[c].point).collect();
        // Where the normal equations are singular (three or more corners on one line give more conditions than
        // the line has parameters; a reveal a few σ long gives a direction that is noise), the object keeps its
        // junctions' means. Measured on all three presets, that beats the mixed model (the incidences as
        // observations of a tiny σ) and dropping the worst incidences of crowded lines: such objects usually hold
        // a wrong incidence.
        let Some(mut r) = adjust::adjust(&sub_lines, &start, &incidences) else {
            diagnostics.objects_unadjusted += 1;
            continue;
        };
        if let Some(images) = images.filter(|_| params.refine) {
            // Refine: each edge measured again in the images, then both observations of it adjusted together.
            let mut lines = sub_lines.clone();
            let mut with_images = incidences.clone();
            for (ll, refined) in refine_object(images, &sub_lines, &incidences, &r) {
                lines.push(refined.line);
                with_images.extend(incidences.iter().filter(|i| i.1 == ll).map(|i| (i.0, lines.len() - 1)));
            }
            if lines.len() > sub_lines.len() {
                if let Some(fused) = adjust::adjust(&lines, &r.corners, &with_images) {
                    diagnostics.lines_refined += lines.len() - sub_lines.len();
                    r = fused;
                }
            }
        }
        for (ci, &c) in object_corners.iter().enumerate() {
            // A corner the adjustment takes farther than a metre from where its lines met is ill-posed (nearly
            // parallel lines: one went hundreds of kilometres on a held-out building): it keeps its junctions'
            // mean. Moves of 10 to 50 cm are real (junctions of lines at small angles) and help the openings.
            if (r.corners[ci] - start[ci]).norm() > MAX_CORNER_MOVE_M {
                diagnostics.corners_unadjusted += 1;
                continue;
            }
            corner_point[c] = r.corners[ci];
            corner_sigma[c] = Some(r.sigmas[ci]);
        }
        for (li, &l) in object_lines.iter().enumerate() {
            line_axis[l] = Some(r.lines[li]);
        }
        sigma0s.extend(r.sigma0);
    }
    sigma0s.sort_by(f64::total_cmp);
    diagnostics.median_sigma0 = sigma0s.get(sigma0s.len() / 2).copied();

    // Vertices: the corners, then free ends; edges: consecutive vertices along each line.
    let mut vertices: Vec<Vertex> = corner_point
        .iter()
        .zip(&corner_sigma)
        .map(|(p, s)| Vertex { point: *p, sigma: *s })
        .collect();
    let mut on_line: Vec<Vec<usize>> = vec![Vec::new(); used_lines.len()];
    for (c, corner) in corners.iter().enumerate() {
        for &l in &corner.lines {
            on_line[l].push(c);
        }
    }
    let mut edges = Vec::new();
    // Two fragments of one edge reach the same corners: one edge.
    let mut seen = std::collections::HashSet::new();
    for (l, line) in used_lines.iter().enumerate() {
        if !on_line[l].is_empty() {
            diagnostics.lines_used += 1;
        }
        let (origin, dir) = line_axis[l].unwrap_or((line.start, line.direction()));
        let t = |p: &Vec3| (p - origin).dot(&dir);
        let mut along: Vec<(f64, usize)> = on_line[l].iter().map(|&c| (t(&vertices[c].point), c)).collect();
        along.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // A free end beyond the outermost corner by more than the noise is kept as a vertex: the edge goes on.
        let gate = (3.0 * line.sigma_m).max(0.02);
        for (end, p) in [(0, line.start), (1, line.end)] {
            if !free_end(l, end) {
                continue;
            }
            let tp = t(&p);
            // A line that reached no corner is kept whole: an observed edge, if not part of any face.
            let (lo, hi) = along
                .first()
                .zip(along.last())
                .map_or((f64::INFINITY, f64::NEG_INFINITY), |(a, b)| (a.0, b.0));
            if tp < lo - gate || tp > hi + gate {
                vertices.push(Vertex {
                    point: origin + dir * tp,
                    sigma: None,
                });
                along.push((tp, vertices.len() - 1));
            }
        }
        along.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for w in along.windows(2) {
            if w[0].1 != w[1].1 && seen.insert((w[0].1.min(w[1].1), w[0].1.max(w[1].1))) {
                edges.push(Edge {
                    a: w[0].1,
                    b: w[1].1,
                    line: kept[l],
                    origin: EdgeOrigin::Observed,
                });
            }
        }
    }
    // The objects' edges between their corners, before completion and inference add edges of no object.
    let mut object_edges: Vec<Vec<[Vec3; 2]>> = vec![Vec::new(); n_objects];
    for e in edges.iter().filter(|e| e.a < corners.len() && e.b < corners.len()) {
        object_edges[object_of[corners[e.a].lines[0]]].push([vertices[e.a].point, vertices[e.b].point]);
    }
    let inside = inside::objects_inside(&object_edges);
    diagnostics.chains_completed = occlusion::complete(&mut vertices, &mut edges, params, cameras.mean());
    // The texture lines left out still show where the walls' surfaces are (a brick wall whose openings' outlines
    // are few would lose to the frames' plane behind it).
    let surface: Vec<[Vec3; 2]> = lines
        .iter()
        .filter(|l| drop_texture && l.texture)
        .map(|l| [l.start, l.end])
        .collect();
    let evidence = images
        .filter(|_| params.verify_openings || params.settle_openings)
        .map(|i| openings::Evidence {
            camera: i.camera,
            images: i.lines,
        });
    let (mut faces, walls) = faces::find_with_walls(&mut vertices, &mut edges, params, cameras, &surface, evidence.as_ref());
    let mut leaving: std::collections::HashSet<[usize; 2]> = std::collections::HashSet::new();
    if params.loose_lines != LooseLines::Keep {
        let mut loose = vec![false; lines.len()];
        for (l, corners_on) in on_line.iter().enumerate() {
            loose[kept[l]] = corners_on.is_empty();
        }
        let boxes = (params.loose_lines == LooseLines::Openings).then(|| openings_boxes(&vertices, &faces, &walls));
        let at_opening = |e: &Edge| {
            boxes
                .as_ref()
                .is_some_and(|b| b.holds(&((vertices[e.a].point + vertices[e.b].point) / 2.0)))
        };
        leaving.extend(
            edges
                .iter()
                .filter(|e| loose.get(e.line).copied().unwrap_or(false) && !at_opening(e))
                .map(|e| sorted_pair(e.a, e.b)),
        );
    }
    let floating: std::collections::HashSet<[usize; 2]> = if params.floating_edges {
        let floating = openings::floating_at_openings(&walls, &vertices, &edges, &faces, params, LOOSE_REACH_M);
        edges
            .iter()
            .zip(floating)
            .filter(|(_, f)| *f)
            .map(|(e, _)| sorted_pair(e.a, e.b))
            .collect()
    } else {
        Default::default()
    };
    if !leaving.is_empty() || !floating.is_empty() {
        let dropped = drop_loose_edges(&mut vertices, &mut edges, &mut faces, corners.len(), |pair| {
            leaving.contains(pair) || floating.contains(pair)
        });
        diagnostics.floating_dropped = dropped.iter().filter(|p| floating.contains(*p)).count();
        diagnostics.loose_dropped = dropped.len() - diagnostics.floating_dropped;
    }
    let surface_lines = if params.surface_lines {
        let rule = surface_lines::SurfaceRule {
            band_m: params.surface_band_m,
            margin_m: params.surface_margin_m,
            neighbours: params.surface_neighbours,
            reach_m: params.surface_reach_m,
            plan_azimuths: plan_azimuths.clone(),
            angle_rad: params.plane_angle_deg.to_radians(),
        };
        let texture: Vec<bool> = lines
            .iter()
            .map(|l| params.texture_lines == TextureLines::Aside && l.texture)
            .collect();
        surface_lines::separate(&vertices, &mut edges, &mut faces, &walls, &texture, &rule)
    } else {
        Vec::new()
    };
    Model {
        vertices,
        edges,
        surface_lines,
        faces,
        objects: corners_of,
        inside,
        diagnostics,
    }
}

/// The window and door faces as boxes in their walls' coordinates, grown by [`LOOSE_REACH_M`]: what lies there is
/// the opening's (its outline, frame, panes, sill).
fn openings_boxes<'a>(vertices: &[Vertex], faces: &[Face], walls: &'a [openings::Wall]) -> surface_lines::OpeningBoxes<'a> {
    surface_lines::OpeningBoxes::of(vertices, faces, walls.iter().collect(), LOOSE_REACH_M)
}

/// How far around an opening's outline its frame, sill and panes' loose lines lie, metres: a sill's nose below
/// the foot, a frame's width around.
const LOOSE_REACH_M: f64 = 0.15;

/// Removes the edges (by their ends) that `leaves` picks and no face uses, and the vertices left without an edge or
/// a face; returns the ends of the edges removed, as they were numbered before. The first `n_corners` vertices
/// (the corners, which the objects index) keep their indices; the others are renumbered in order.
fn drop_loose_edges(
    vertices: &mut Vec<Vertex>,
    edges: &mut Vec<Edge>,
    faces: &mut [Face],
    n_corners: usize,
    leaves: impl Fn(&[usize; 2]) -> bool,
) -> Vec<[usize; 2]> {
    let on_face: std::collections::HashSet<[usize; 2]> = faces
        .iter()
        .flat_map(|f| std::iter::once(&f.ring).chain(&f.holes))
        .flat_map(|ring| (0..ring.len()).map(move |i| sorted_pair(ring[i], ring[(i + 1) % ring.len()])))
        .collect();
    let mut dropped = Vec::new();
    edges.retain(|e| {
        let pair = sorted_pair(e.a, e.b);
        let stays = !leaves(&pair) || on_face.contains(&pair);
        if !stays {
            dropped.push(pair);
        }
        stays
    });
    let mut used = vec![false; vertices.len()];
    used[..n_corners.min(vertices.len())].fill(true);
    for e in edges.iter() {
        used[e.a] = true;
        used[e.b] = true;
    }
    for f in faces.iter() {
        for &v in f.ring.iter().chain(f.holes.iter().flatten()) {
            used[v] = true;
        }
    }
    let new_index: Vec<usize> = used
        .iter()
        .scan(0, |next, &u| {
            *next += u as usize;
            Some(if u { *next - 1 } else { usize::MAX })
        })
        .collect();
    *vertices = std::mem::take(vertices)
        .into_iter()
        .zip(&used)
        .filter_map(|(v, &u)| u.then_some(v))
        .collect();
    for e in edges.iter_mut() {
        e.a = new_index[e.a];
        e.b = new_index[e.b];
    }
    for f in faces.iter_mut() {
        for idx in f.ring.iter_mut().chain(f.holes.iter_mut().flatten()) {
            *idx = new_index[*idx];
        }
    }
    dropped
}

fn sorted_pair(a: usize, b: usize) -> [usize; 2] {
    [a.min(b), a.max(b)]
}

/// The image-line estimates of an adjusted object's lines, by local line index: each line's span between its
/// corners (or from its one corner to its far end), with the corners' σ and a neighbouring edge at each corner.
fn refine_object(
    images: &Images,
    lines: &[ModelLine],
    incidences: &[(usize, usize)],
    r: &adjust::Adjusted,
) -> Vec<(usize, refine::Refined)> {
    let mut out = Vec::new();
    for (ll, line) in lines.iter().enumerate() {
        let (origin, dir) = r.lines[ll];
        let t = |p: &Vec3| (p - origin).dot(&dir);
        let mut on: Vec<(f64, usize)> = incidences.iter().filter(|i| i.1 == ll).map(|i| (t(&r.corners[i.0]), i.0)).collect();
        on.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let (Some(&first), Some(&last)) = (on.first(), on.last()) else {
            continue;
        };
        // A neighbouring edge at a corner: another line through it, well away from this one's direction.
        let neighbour = |corner: usize| {
            incidences
                .iter()
                .filter(|i| i.0 == corner && i.1 != ll)
                .map(|i| r.lines[i.1].1)
                .find(|d| d.dot(&dir).abs() < 20f64.to_radians().cos())
                .map(|d| (r.corners[corner], d))
        };
        let free = Vec3::from_fn(|k, _| line.sigma_along(k));
        let end_of = |(tc, c): (f64, usize)| (origin + dir * tc, r.sigmas[c], neighbour(c));
        let (start, end) = if first.1 != last.1 {
            (end_of(first), end_of(last))
        } else {
            // One corner: the span runs to the line's end farther from it.
            let (ts, te) = (t(&line.start), t(&line.end));
            let far = if (ts - first.0).abs() > (te - first.0).abs() { ts } else { te };
            let corner = end_of(first);
            let free_end = (origin + dir * far, free, None);
            if far < first.0 {
                (free_end, corner)
            } else {
                (corner, free_end)
            }
        };
        let s = refine::StructureLine {
            start: start.0,
            end: end.0,
            sigma: [start.1, end.1],
            neighbours: [start.2, end.2],
        };
        if let Some(refined) = refine::refine_line(images.camera, images.lines, &s, &images.params) {
            out.push((ll, refined));
        }
    }
    out
}

/// `lineflow classify`: the lines of `lines` (a lines3d.csv) classed with `rule`, by their support too when
/// `cameras` gives a poses.csv and a camera.toml, written to `out`; `set` holds the rule's settings
/// (`PARAM=VALUE`). Returns how many lines and how many texture.
pub fn classify_file(
    lines: &std::path::Path,
    out: &std::path::Path,
    cameras: Option<(std::path::PathBuf, std::path::PathBuf)>,
    set: &[String],
) -> anyhow::Result<(usize, usize)> {
    let rule: ClassRule = lineflow_runtime::launch::params_from_overrides(set)?;
    rule.validate()
        .map_err(|e| anyhow::anyhow!("{} must be {}, got {}", e.name, e.requirement, e.value))?;
    let mut rows = lineflow_formats::read_lines3d(lines)?;
    let (poses, camera) = match cameras {
        Some((poses, camera)) => (
            lineflow_formats::read_poses(&poses)?,
            Some(lineflow_formats::project::read_camera(&camera)?.camera()),
        ),
        None => (Vec::new(), None),
    };
    let poses: Vec<lineflow_photogrammetry::Pose> = poses.iter().map(|p| p.pose).collect();
    let sight = camera.as_ref().map(|camera| lineflow_linegeom::Sight { camera, poses: &poses });
    let texture = classify_rows(&mut rows, &rule, sight);
    lineflow_formats::write_lines3d(out, &rows)?;
    Ok((rows.len(), texture))
}

/// Classes `rows` with `rule` (`lineflow classify`), by their support too when `sight` gives the cameras;
/// returns how many are texture.
pub fn classify_rows(rows: &mut [lineflow_formats::Line3Row], rule: &ClassRule, sight: Option<lineflow_linegeom::Sight>) -> usize {
    let segments = segments_of(rows);
    // A row without `n_images` (another tool's file) cannot be weighed: never weak.
    let shown: Vec<u32> = rows.iter().map(|r| r.n_images.unwrap_or(u32::MAX)).collect();
    let classes = lineflow_linegeom::classify_supported(&segments, &shown, sight, rule);
    for (r, class) in rows.iter_mut().zip(classes) {
        r.class = class;
    }
    rows.iter().filter(|r| r.class == LineClass::Texture).count()
}

/// The rows' segments, for the classing.
fn segments_of(rows: &[lineflow_formats::Line3Row]) -> Vec<[Vec3; 2]> {
    rows.iter().map(|r| [r.start, r.end]).collect()
}

/// The model's lines from `lines3d.csv` rows (or `Lines3D` elements through their rows), each with the endpoint
/// σ its statistics give and its class; when no row is classed (another tool's lines, an older run) and
/// `texture_lines` is not `keep`, they are classed here with `class`.
pub fn lines_from_rows(rows: &[lineflow_formats::Line3Row], params: &ModelParams) -> Vec<ModelLine> {
    let unclassed = rows.iter().all(|r| r.class == LineClass::Unknown);
    let classes: Vec<LineClass> = if unclassed && params.texture_lines != TextureLines::Keep {
        // No cameras here: by the lines' neighbours alone.
        lineflow_linegeom::classify(&segments_of(rows), &params.class)
    } else {
        rows.iter().map(|r| r.class).collect()
    };
    rows.iter()
        .zip(classes)
        .map(|(r, class)| {
            let fitted = params.fitted_sigma(r.rms_m, r.n_points);
            ModelLine {
                // Without statistics the endpoints themselves carry `sigma_m`, along the line too.
                sigma_end_m: fitted.is_none().then_some(params.sigma_m),
                texture: class == LineClass::Texture,
                ..ModelLine::new(r.start, r.end, fitted.unwrap_or(params.sigma_m))
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_sigma_comes_from_its_rms_and_points_and_a_zero_rms_says_nothing() {
        let p = ModelParams::default();
        // 2 · 1 cm / √16 = 5 mm.
        assert!((p.line_sigma(Some(0.01), Some(16)) - 0.005).abs() < 1e-12);
        assert_eq!(p.line_sigma(Some(0.001), Some(400)), p.min_sigma_m);
        // Points placed exactly on their line (an RMS of 1e-15), or as good as (3e-7 m, also written 0.000000 in
        // lines3d.csv): unknown, live and from the file alike.
        for rms in [None, Some(0.0), Some(1e-15), Some(3e-7), Some(f64::NAN)] {
            assert_eq!(p.line_sigma(rms, Some(12)), p.sigma_m, "{rms:?}");
        }
    }

    #[test]
    fn a_line_has_one_sigma_live_and_from_the_run_file() {
        // The live stage reads Lines3D elements, `lineflow model` the lines3d.csv written from them: every RMS, down
        // to those the file writes as 0.000000, gives one σ both ways.
        let p = ModelParams::default();
        let rms = [0.0, 1e-15, 1e-9, 3e-7, 4.9e-7, 5e-7, 7e-7, 1.6e-5, 0.0123456789, 0.003];
        let messages: Vec<lineflow_messages::Line3> = rms
            .iter()
            .enumerate()
            .map(|(k, &rms_m)| lineflow_messages::Line3 {
                id: k as u64,
                start_m: [k as f64, 0.0, 1.0],
                end_m: [k as f64, 0.0, 2.0],
                n_points: 2,
                n_images: 2,
                rms_m,
                class: 0,
                reserved: 0,
            })
            .collect();
        let live: Vec<lineflow_formats::Line3Row> = messages.iter().map(Into::into).collect();
        let file = std::env::temp_dir().join(format!("lineflow-model-sigma-{}.csv", std::process::id()));
        lineflow_formats::write_lines3d(&file, &live).unwrap();
        let read = lineflow_formats::read_lines3d(&file).unwrap();
        std::fs::remove_file(&file).ok();
        for ((a, b), r) in lines_from_rows(&live, &p).iter().zip(lines_from_rows(&read, &p)).zip(rms) {
            assert_eq!((a.sigma_m, a.sigma_end_m), (b.sigma_m, b.sigma_end_m), "RMS {r}");
        }
    }

    #[test]
    fn an_opening_size_range_must_be_a_range() {
        let set = |items: &[&str]| ModelParams::with_overrides(&items.iter().map(|s| s.to_string()).collect::<Vec<_>>());
        let p = set(&["opening_min_m = 0.5", "opening_max_m = 2.0"]).expect("a range");
        assert_eq!(p.opening_sizes().opening_m, (0.5, 2.0));
        for (lo, hi, name) in [
            ("opening_min_m = 2.0", "opening_max_m = 1.0", "opening_max_m"),
            ("recess_min_m = 0.2", "recess_max_m = 0.2", "recess_max_m"),
            ("frame_min_m = 0.1", "frame_max_m = 0.05", "frame_max_m"),
        ] {
            let e = set(&[lo, hi]).expect_err("an empty range").to_string();
            assert!(e.contains(name), "{e}");
        }
    }

    #[test]
    fn loose_lines_are_spelt_by_name_or_as_a_flag() {
        let parse = |v: &str| toml::from_str::<ModelParams>(&format!("loose_lines = {v}")).map(|p| p.loose_lines);
        assert_eq!(parse("true").unwrap(), LooseLines::Keep);
        assert_eq!(parse("false").unwrap(), LooseLines::Drop);
        assert_eq!(parse("\"openings\"").unwrap(), LooseLines::Openings);
        let err = parse("\"some\"").unwrap_err().to_string();
        assert!(err.contains("expected \"keep\", \"openings\" or \"drop\""), "{err}");
    }

    #[test]
    fn loose_lines_stay_when_asked_and_go_away_from_openings() {
        // A box's four edges meeting at corners, and a mortar course 2 m away that meets nothing.
        let sq = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let mut lines: Vec<ModelLine> = (0..4)
            .map(|i| {
                let (a, b) = (sq[i], sq[(i + 1) % 4]);
                ModelLine::new(Vec3::new(a[0], 0.0, a[1]), Vec3::new(b[0], 0.0, b[1]), 0.002)
            })
            .collect();
        lines.push(ModelLine::new(Vec3::new(3.0, 0.0, 0.5), Vec3::new(4.0, 0.0, 0.5), 0.002));
        let cameras = Cameras::from(Vec3::new(0.5, -10.0, 0.5));
        let with_mode = |loose_lines: LooseLines| {
            let params = ModelParams {
                loose_lines,
                ..ModelParams::default()
            };
            build(&lines, &params, &cameras)
        };
        let (with, without) = (with_mode(LooseLines::Keep), with_mode(LooseLines::Drop));
        assert_eq!(with.edges.len(), 5, "{:?}", with.edges);
        assert_eq!(without.edges.len(), 4, "{:?}", without.edges);
        assert_eq!(without.diagnostics.loose_dropped, 1);
        assert_eq!(without.vertices.len(), 4, "the loose line's ends went with it");
        assert!(without.edges.iter().all(|e| e.line < 4 && e.a < 4 && e.b < 4));
        assert_eq!(without.faces.len(), with.faces.len());
        assert!(without.faces.iter().flat_map(|f| &f.ring).all(|&v| v < without.vertices.len()));
        // No opening anywhere: the default leaves the course out too.
        let by_default = build(&lines, &ModelParams::default(), &cameras);
        assert_eq!(by_default.edges.len(), 4, "{:?}", by_default.edges);
    }
}
