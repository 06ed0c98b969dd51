//! The lines2d stage between frames, as a state machine the process shell feeds: the `trace` implementation
//! joins the latched camera with each edge map and, when the images are wired, with the frame's grey image; edge
//! maps that arrive before what they need wait, in order. Both implementations lay out their segments the same
//! way ([`FrameLines::assemble`]).
use std::collections::{BTreeMap, VecDeque};

use lineflow_formats::Line2Row;
use lineflow_imaging::{ColourEdges, Planes};
use lineflow_messages::{EdgeMapHeader, EdgePixel, Segment2, Stamp};
use lineflow_photogrammetry::Camera;

use crate::TraceParams;

/// One frame's result: segments numbered in order with their chains laid out one after the other (the two parts
/// of a `Lines2D` message), and their `lines2d.csv` rows.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameLines {
    /// The stamp of the edge map (or image) the lines come from.
    pub stamp: Stamp,
    /// The image's name, as in the message header.
    pub name: [u8; 64],
    /// The segments.
    pub segments: Vec<Segment2>,
    /// Their pixel chains, concatenated.
    pub chain: Vec<[u16; 2]>,
    /// Their rows of `lines2d.csv`.
    pub rows: Vec<Line2Row>,
}

impl FrameLines {
    /// Numbers the segments `found` (endpoints in measured pixels, and the chain each was fitted to) in order.
    pub fn assemble<'a>(stamp: Stamp, name: [u8; 64], found: impl Iterator<Item = ([f64; 2], [f64; 2], &'a [[u16; 2]])>) -> FrameLines {
        let image = lineflow_messages::str_from_fixed(&name).to_owned();
        let mut out = FrameLines {
            stamp,
            name,
            segments: Vec::new(),
            chain: Vec::new(),
            rows: Vec::new(),
        };
        for (id, (a, b, pixels)) in found.enumerate() {
            out.segments.push(Segment2 {
                id: id as u32,
                chain_start: out.chain.len() as u32,
                chain_len: pixels.len() as u32,
                reserved: 0,
                start_px: a,
                end_px: b,
            });
            out.chain.extend_from_slice(pixels);
            out.rows.push(Line2Row {
                image: image.clone(),
                id: id as u64,
                start_px: a,
                end_px: b,
                n_pixels: Some(pixels.len() as u32),
            });
        }
        out
    }
}

/// Why the `trace` stage cannot go on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TraceError {
    /// An edge map whose size is not the camera's.
    #[error("frame {frame} ({image}): edge map is {width}x{height} but the camera is {camera_width}x{camera_height}")]
    SizeMismatch {
        /// The frame.
        frame: u64,
        /// Its image.
        image: String,
        /// The edge map's size.
        width: u32,
        /// The edge map's size.
        height: u32,
        /// The camera's size.
        camera_width: u32,
        /// The camera's size.
        camera_height: u32,
    },
    /// The edge maps ended before any camera model arrived.
    #[error("the edge maps ended but no camera model arrived")]
    NoCamera,
}

/// The `trace` implementation's state.
pub struct TraceStage {
    params: TraceParams,
    camera: Option<Camera>,
    /// Whether images are wired: then each edge map waits for its frame's image (sub-pixel positions).
    images_wired: bool,
    waiting: VecDeque<(EdgeMapHeader, Vec<EdgePixel>)>,
    /// Each frame's image as the planes its gradient is taken over (one grey plane, or grey and three colour
    /// channels) and how the channels take part.
    images: BTreeMap<u64, (Vec<Vec<u8>>, ColourEdges)>,
}

impl TraceStage {
    /// A stage tracing with `params`; `images_wired`: the grey images arrive too, and lines are fitted to the
    /// edges' sub-pixel positions.
    pub fn new(params: TraceParams, images_wired: bool) -> Self {
        Self {
            params,
            camera: None,
            images_wired,
            waiting: VecDeque::new(),
            images: BTreeMap::new(),
        }
    }

    /// The camera model (latched; the newest one counts).
    pub fn on_camera(&mut self, camera: Camera) {
        self.camera = Some(camera);
    }

    /// A frame's grey image.
    pub fn on_gray(&mut self, frame: u64, gray: &[u8]) {
        self.on_image(frame, &Planes::gray(gray));
    }

    /// A frame's image as the planes of its gradient: sub-pixel positions then follow the gradient the edges
    /// stage's `color` finds the edges on.
    pub fn on_image(&mut self, frame: u64, planes: &Planes) {
        self.images
            .insert(frame, (planes.iter().map(<[u8]>::to_vec).collect(), planes.mode()));
    }

    /// A frame's edge map.
    pub fn on_edges(&mut self, header: EdgeMapHeader, pixels: &[EdgePixel]) {
        self.waiting.push_back((header, pixels.to_vec()));
    }

    /// Whether edge maps are still waiting.
    pub fn has_waiting(&self) -> bool {
        !self.waiting.is_empty()
    }

    /// Traces the next edge map if it has what it needs (edge maps are traced in the order they came), `None`
    /// when none has. `images_ended`: no more grey images will come, so an edge map without its image is traced
    /// on its pixels.
    ///
    /// # Errors
    /// An edge map of another size than the camera's.
    pub fn next_frame(&mut self, images_ended: bool) -> Option<Result<FrameLines, TraceError>> {
        let c = self.camera.as_ref()?;
        let frame = self.waiting.front()?.0.stamp.frame;
        if !self.images.contains_key(&frame) && self.images_wired && !images_ended {
            return None;
        }
        let (h, px) = self.waiting.pop_front()?;
        let planes = self.images.get(&frame).map(|(p, mode)| match p.as_slice() {
            [gray, r, g, b] => Planes::colour(gray, r, g, b, *mode),
            planes => Planes::gray(planes.first().map_or(&[][..], Vec::as_slice)),
        });
        let lines = trace_frame(c, &h, &px, planes.as_ref(), &self.params);
        // Images of frames without an edge map are not kept either.
        self.images.retain(|&f, _| f > frame);
        Some(lines)
    }

    /// Checks that the stage can finish its stream. `edges_ended`: no more edge maps will come.
    ///
    /// # Errors
    /// The edge maps ended without a camera model.
    pub fn check_camera(&self, edges_ended: bool) -> Result<(), TraceError> {
        if edges_ended && self.camera.is_none() {
            return Err(TraceError::NoCamera);
        }
        Ok(())
    }
}

/// The segments of one edge map; with the frame's image (its grey plane or colour channels) the lines are fitted to
/// the edges' sub-pixel positions.
///
/// # Errors
/// An edge map of another size than the camera's.
pub fn trace_frame(
    cam: &Camera,
    h: &EdgeMapHeader,
    px: &[EdgePixel],
    image: Option<&Planes>,
    p: &TraceParams,
) -> Result<FrameLines, TraceError> {
    if (h.width, h.height) != (cam.width, cam.height) {
        return Err(TraceError::SizeMismatch {
            frame: h.stamp.frame,
            image: h.name().to_owned(),
            width: h.width,
            height: h.height,
            camera_width: cam.width,
            camera_height: cam.height,
        });
    }
    let pixels: Vec<[u16; 2]> = px.iter().map(|e| [e.col, e.row]).collect();
    let (w, ht) = (cam.width as usize, cam.height as usize);
    let traced = match image {
        Some(planes) if planes.iter().all(|g| g.len() == w * ht) => {
            let positions = lineflow_imaging::subpixel_positions_in(planes, w, ht, px);
            crate::trace_measured_at(cam, &pixels, &positions, p)
        }
        _ => crate::trace_measured(cam, &pixels, p),
    };
    Ok(FrameLines::assemble(
        h.stamp,
        h.name,
        traced.iter().map(|(a, b, chain)| (*a, *b, chain.as_slice())),
    ))
}

#[cfg(test)]
mod tests {
    use lineflow_messages::fixed_str;

    use super::*;

    const W: u32 = 80;
    const H: u32 = 60;

    fn camera() -> Camera {
        Camera::pinhole(W, H, 0.01, 8.0)
    }

    /// An edge map of frame `frame` holding one horizontal edge 50 pixels long at row 30.
    fn edge_map(frame: u64, width: u32) -> (EdgeMapHeader, Vec<EdgePixel>) {
        let header = EdgeMapHeader {
            stamp: Stamp { frame, ..Stamp::default() },
            width,
            height: H,
            detector: fixed_str("canny"),
            name: fixed_str(&format!("IMG_{frame}.png")),
        };
        let pixels = (10..60)
            .map(|col| EdgePixel {
                col,
                row: 30,
                magnitude: 200.0,
                direction_rad: std::f32::consts::FRAC_PI_2,
            })
            .collect();
        (header, pixels)
    }

    /// A grey image dark above row 30 and bright from it on.
    fn gray() -> Vec<u8> {
        (0..W * H).map(|i| if i / W < 30 { 20 } else { 220 }).collect()
    }

    fn drain(stage: &mut TraceStage, images_ended: bool) -> Vec<FrameLines> {
        std::iter::from_fn(|| stage.next_frame(images_ended)).map(Result::unwrap).collect()
    }

    #[test]
    fn edge_maps_wait_for_the_camera_and_are_traced_in_order() {
        let mut s = TraceStage::new(TraceParams::default(), false);
        for f in [0, 1] {
            let (h, px) = edge_map(f, W);
            s.on_edges(h, &px);
        }
        assert!(s.next_frame(true).is_none(), "no camera yet");
        assert!(s.has_waiting());
        s.on_camera(camera());
        let out = drain(&mut s, false);
        assert_eq!(out.iter().map(|l| l.stamp.frame).collect::<Vec<_>>(), [0, 1]);
        for l in &out {
            assert_eq!(l.segments.len(), 1, "one straight edge, one segment");
            let seg = l.segments[0];
            assert_eq!((seg.chain_start, seg.chain_len as usize), (0, l.chain.len()));
            assert!((seg.start_px[0] - seg.end_px[0]).abs() >= 45.0, "{seg:?}");
            assert_eq!(l.rows[0].image, format!("IMG_{}.png", l.stamp.frame));
            assert_eq!(l.rows[0].n_pixels, Some(seg.chain_len));
        }
        assert!(!s.has_waiting());
        s.check_camera(true).unwrap();
    }

    #[test]
    fn with_images_wired_an_edge_map_waits_for_its_image_until_the_images_end() {
        let mut s = TraceStage::new(TraceParams::default(), true);
        s.on_camera(camera());
        let (h, px) = edge_map(0, W);
        s.on_edges(h, &px);
        assert!(s.next_frame(false).is_none(), "frame 0's image has not come");
        s.on_gray(0, &gray());
        let with_image = drain(&mut s, false);
        assert_eq!(with_image.len(), 1);
        // Sub-pixel positions put the step between rows 29 and 30, where the pixel grid alone keeps row 30.
        let y = with_image[0].segments[0].start_px[1];
        assert!(y < 30.0 && y > 29.0, "sub-pixel row {y}");

        let (h, px) = edge_map(1, W);
        s.on_edges(h, &px);
        assert!(s.next_frame(false).is_none());
        let without = drain(&mut s, true);
        assert_eq!(without.len(), 1, "traced on its pixels once no image can come");
        assert_eq!(without[0].segments[0].start_px[1], 30.0);
    }

    #[test]
    fn on_colour_images_sub_pixel_positions_follow_the_colour_channels() {
        // A plumb step between columns 39 and 40 in red and green that keeps the grey value (BT.601 luma 111 on
        // both sides): no grey gradient at all, a strong one in the channels.
        let rgb: Vec<u8> = (0..W * H)
            .flat_map(|i| if i % W < 40 { [40, 150, 100] } else { [200, 68, 100] })
            .collect();
        let mut gray = vec![0u8; (W * H) as usize];
        lineflow_imaging::gray_into(
            lineflow_messages::Encoding::Rgb8,
            W as usize,
            H as usize,
            W as usize * 3,
            &rgb,
            &mut gray,
        )
        .unwrap();
        assert!(gray.iter().all(|&g| g == gray[0]), "the step is invisible in grey");
        let [r, g, b] = lineflow_imaging::rgb_planes(&rgb, W as usize, H as usize, W as usize * 3);
        let header = EdgeMapHeader {
            stamp: Stamp::default(),
            width: W,
            height: H,
            detector: fixed_str("canny"),
            name: fixed_str("IMG_0.png"),
        };
        let plumb: Vec<EdgePixel> = (10..50)
            .map(|row| EdgePixel {
                col: 40,
                row,
                magnitude: 200.0,
                direction_rad: 0.0,
            })
            .collect();
        let column = |planes: &Planes| {
            let mut s = TraceStage::new(TraceParams::default(), true);
            s.on_camera(camera());
            s.on_edges(header, &plumb);
            s.on_image(0, planes);
            drain(&mut s, false)[0].segments[0].start_px[0]
        };
        // The grey image leaves the pixel grid's column; the channels put the line between the two columns.
        assert_eq!(column(&Planes::gray(&gray)), 40.0);
        let x = column(&Planes::colour(&gray, &r, &g, &b, ColourEdges::Plumb));
        assert!((x - 39.5).abs() < 0.05, "sub-pixel column {x}");
    }

    #[test]
    fn an_edge_map_of_another_size_and_a_stream_without_a_camera_are_named_errors() {
        let mut s = TraceStage::new(TraceParams::default(), false);
        assert_eq!(s.check_camera(false), Ok(()));
        assert_eq!(s.check_camera(true), Err(TraceError::NoCamera));
        s.on_camera(camera());
        let (h, px) = edge_map(3, W + 1);
        s.on_edges(h, &px);
        let e = s.next_frame(true).unwrap().unwrap_err();
        assert_eq!(e.to_string(), "frame 3 (IMG_3.png): edge map is 81x60 but the camera is 80x60");
    }

    #[test]
    fn parameters_out_of_range_are_named_with_their_value() {
        use lineflow_runtime::StageParams;
        assert_eq!(TraceParams::default().validate(), Ok(()));
        let bad = TraceParams {
            max_jump_px: 40.0,
            ..TraceParams::default()
        };
        assert_eq!(bad.validate().unwrap_err().to_string(), "max_jump_px must be in [0, 32], got 40");
        let nan = TraceParams {
            max_distance_px: f64::NAN,
            ..TraceParams::default()
        };
        assert!(nan.validate().unwrap_err().to_string().starts_with("max_distance_px must be > 0"));
    }
}
