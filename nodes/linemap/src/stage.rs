//! What the linemap process keeps between messages, and when it maps: the camera, the search region from the site
//! model, every frame's segments and the newest poses. The map is recomputed from every oriented frame (the poses
//! of earlier frames move as the orientation adjusts them) whenever their number has grown by `remap_growth`, and
//! once more at the end with the final poses. The schedule depends on frame counts only, so a replay publishes the
//! same sets.
use std::collections::BTreeMap;
use std::sync::Arc;

use lineflow_messages::Segment2;
use lineflow_photogrammetry::{Camera, Pose, Vec3};

use crate::guide::Guide;
use crate::line::MappedLine;
use crate::tracks::map_lines;
use crate::views::View;
use crate::MapParams;
use lineflow_linegeom::Photo;

/// The stage's state.
#[derive(Debug, Clone)]
pub struct MapStage {
    params: MapParams,
    camera: Option<Camera>,
    guide: Guide,
    segments: BTreeMap<u64, Vec<Segment2>>,
    poses: BTreeMap<u64, Pose>,
    photos: BTreeMap<u64, Arc<Photo>>,
    /// Whether a frame waits for its image before it is mapped (the images are an input of the graph).
    needs_photos: bool,
    /// Frames with both segments and a pose when the map was last computed.
    mapped_frames: usize,
    lines: Vec<MappedLine>,
}

impl MapStage {
    /// An empty stage.
    pub fn new(params: MapParams) -> Self {
        MapStage {
            params,
            camera: None,
            guide: Guide::default(),
            segments: BTreeMap::new(),
            poses: BTreeMap::new(),
            photos: BTreeMap::new(),
            needs_photos: false,
            mapped_frames: 0,
            lines: Vec::new(),
        }
    }

    /// The camera model.
    pub fn set_camera(&mut self, camera: Camera) {
        self.camera = Some(camera);
    }

    /// The site model's walls (corner lists): lines are sought within `site_margin_m` of them and may take their
    /// directions. No walls: anywhere, and only the vertical.
    pub fn set_walls(&mut self, walls: &[Vec<Vec3>]) {
        self.guide = if walls.is_empty() {
            Guide::default()
        } else {
            Guide::from_walls(walls, self.params.site_margin_m)
        };
    }

    /// One frame's 2-D segments.
    pub fn add_segments(&mut self, frame: u64, segments: Vec<Segment2>) {
        self.segments.insert(frame, segments);
    }

    /// Frames are mapped only once their image is in, so that the appearance test sees the same images whatever
    /// the order the topics arrive in (a replay maps the same lines).
    pub fn wait_for_photos(&mut self) {
        self.needs_photos = true;
    }

    /// One frame's grey image, for the appearance test.
    pub fn add_photo(&mut self, frame: u64, photo: Photo) {
        self.photos.insert(frame, Arc::new(photo));
    }

    /// The newest poses of every oriented frame.
    pub fn set_poses(&mut self, poses: BTreeMap<u64, Pose>) {
        self.poses = poses;
    }

    /// Frames with both segments and a pose (and their image, when waited for).
    pub fn ready_frames(&self) -> usize {
        self.segments.keys().filter(|f| self.is_ready(f)).count()
    }

    fn is_ready(&self, frame: &u64) -> bool {
        self.poses.contains_key(frame) && (!self.needs_photos || self.photos.contains_key(frame))
    }

    /// Whether the ready frames have grown by `remap_growth` since the last map (and by one at least), so that
    /// [`MapStage::remap`] is due.
    pub fn remap_due(&self) -> bool {
        let due = ((self.mapped_frames as f64 * self.params.remap_growth).ceil() as usize).max(self.mapped_frames + 1);
        self.camera.is_some() && self.ready_frames() >= due.max(2)
    }

    /// Recomputes the map from the ready frames.
    pub fn remap(&mut self) {
        self.compute();
    }

    /// [`MapStage::remap`] when it is due; true when it ran.
    pub fn update(&mut self) -> bool {
        let due = self.remap_due();
        if due {
            self.remap();
        }
        due
    }

    /// The final map from every frame with segments and a pose.
    pub fn finish(&mut self) -> &[MappedLine] {
        // Every input has ended: an image still missing is not coming, and its frame is mapped without it.
        self.needs_photos = false;
        if self.camera.is_some() {
            self.compute();
        }
        &self.lines
    }

    /// The current lines.
    pub fn lines(&self) -> &[MappedLine] {
        &self.lines
    }

    /// Whether the camera model has arrived.
    pub fn has_camera(&self) -> bool {
        self.camera.is_some()
    }

    fn compute(&mut self) {
        let Some(camera) = self.camera else { return };
        let views: Vec<View> = self
            .segments
            .iter()
            .filter(|(f, _)| self.is_ready(f))
            .map(|(f, s)| {
                let view = View::new(&camera, *f, self.poses[f], s, self.params.min_length_px);
                match self.photos.get(f) {
                    Some(photo) => view.with_photo(Arc::clone(photo)),
                    None => view,
                }
            })
            .collect();
        self.mapped_frames = views.len();
        self.lines = map_lines(&camera, &views, &self.guide, &self.params);
    }
}
