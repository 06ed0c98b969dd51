//! `lineflow export`: one topic of a recording into the project's file formats (`conventions.md`), streamed: an
//! image or edge map is written as its message is read, 3-D lines keep only the latest message, poses the latest
//! revision of each frame, so that memory does not grow with the recording.
use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{bail, Context, Result};
use lineflow_formats::{Line2Row, Line3Row, PoseRow};
use lineflow_messages::schema::{decode, decode_view, read_elements, read_pod, Decoded};
use lineflow_messages::{parts, EdgeMapHeader, Encoding, ImageHeader, Line3, Lines2DHeader, MessageKind, Pose, Segment2};

use super::{RecordedMessage, Recording};

/// What an export keeps between messages.
enum Sink {
    Images(usize),
    EdgeMasks(usize),
    Lines2D(Vec<Line2Row>),
    Lines3D(Vec<Line3>),
    Poses(BTreeMap<u64, Pose>),
}

fn name_of(frame: u64, name: &str) -> String {
    if name.is_empty() {
        format!("frame_{frame:06}")
    } else {
        name.to_owned()
    }
}

/// Writes topic `topic` of `rec` into `out`: `Image` → one PNG per message (named as the source image), `EdgeMap`
/// → PNG masks, `Lines2D` → `lines2d.csv`, `Lines3D` → `lines3d.csv` + `lines3d.ply` (latest message), `Poses` →
/// `poses.csv` (latest revision of each frame). Returns what was written, in words. A recording that ends early
/// exports what it holds, with a warning.
///
/// # Errors
/// An unknown or viewer topic, a kind that has no file format, a damaged message, a file that cannot be written.
pub fn export(rec: &Recording, topic: &str, out: &Path) -> Result<String> {
    let channels = rec.channels();
    let Some(channel) = channels.iter().find(|c| c.topic == topic) else {
        let names: Vec<_> = channels.iter().filter(|c| !c.view).map(|c| c.topic.as_str()).collect();
        bail!("{}: no topic '{topic}' (topics: {})", rec.path.display(), names.join(", "));
    };
    let Some(kind) = channel.kind else {
        bail!(
            "topic '{topic}' is a viewer channel ({}); export the topic it renders",
            channel.schema
        );
    };
    let mut sink = match kind {
        MessageKind::Image => Sink::Images(0),
        MessageKind::EdgeMap => Sink::EdgeMasks(0),
        MessageKind::Lines2D => Sink::Lines2D(Vec::new()),
        MessageKind::Lines3D => Sink::Lines3D(Vec::new()),
        MessageKind::Poses => Sink::Poses(BTreeMap::new()),
        other => bail!(
            "topic '{topic}' carries {}; export handles Image, EdgeMap, Lines2D, Lines3D and Poses",
            other.name()
        ),
    };
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    // Poses name their images by frame number: take the names from the image headers (pixels not copied).
    let mut frame_names = BTreeMap::new();
    let mut scratch = Decoded::default();
    let read = rec.for_each_message(|mut m: RecordedMessage| {
        // A compressed image's header is the plain one: its pixels are not needed here.
        if kind == MessageKind::Poses && m.kind == Some(MessageKind::Image) {
            if let Ok((h, _)) = decode_view(MessageKind::Image, &m.data, &mut scratch) {
                let h: ImageHeader = read_pod(h);
                frame_names.insert(h.stamp.frame, h.name().to_owned());
            }
        }
        if m.topic != topic {
            return Ok(());
        }
        m.restore(&mut scratch)?;
        let d = decode(kind, &m.data).with_context(|| format!("'{topic}' message {}", m.sequence))?;
        take(&mut sink, &d, out)
    });
    if let Err(e) = read {
        eprintln!("warning: {e:#}");
    }
    finish(sink, out, &frame_names)
}

fn take(sink: &mut Sink, d: &Decoded, out: &Path) -> Result<()> {
    match sink {
        Sink::Images(n) => {
            let h: ImageHeader = read_pod(&d.header);
            let file = out.join(Path::new(&name_of(h.stamp.frame, h.name())).with_extension("png"));
            save_image(&h, &d.payload, &file)?;
            *n += 1;
        }
        Sink::EdgeMasks(n) => {
            let h: EdgeMapHeader = read_pod(&d.header);
            let mut mask = image::GrayImage::new(h.width, h.height);
            for p in read_elements::<lineflow_messages::EdgePixel>(&d.payload) {
                if (p.col as u32) < h.width && (p.row as u32) < h.height {
                    mask.put_pixel(p.col as u32, p.row as u32, image::Luma([255]));
                }
            }
            let file = out.join(format!("{}.edges.png", name_of(h.stamp.frame, h.name())));
            mask.save(&file).with_context(|| format!("cannot write {}", file.display()))?;
            *n += 1;
        }
        Sink::Lines2D(rows) => {
            let h: Lines2DHeader = read_pod(&d.header);
            let off = parts::align8(h.n_segments as usize * size_of::<Segment2>());
            for s in read_elements::<Segment2>(&d.payload[..off.min(d.payload.len())])
                .iter()
                .take(h.n_segments as usize)
            {
                rows.push(Line2Row {
                    image: name_of(h.stamp.frame, h.name()),
                    id: s.id as u64,
                    start_px: s.start_px,
                    end_px: s.end_px,
                    n_pixels: Some(s.chain_len),
                });
            }
        }
        // The latest message holds the current estimate of every line.
        Sink::Lines3D(latest) => *latest = read_elements::<Line3>(&d.payload),
        Sink::Poses(latest) => {
            for p in read_elements::<Pose>(&d.payload) {
                if latest.get(&p.frame).is_none_or(|q| q.revision <= p.revision) {
                    latest.insert(p.frame, p);
                }
            }
        }
    }
    Ok(())
}

fn finish(sink: Sink, out: &Path, frame_names: &BTreeMap<u64, String>) -> Result<String> {
    Ok(match sink {
        Sink::Images(n) => format!("{n} PNG images"),
        Sink::EdgeMasks(n) => format!("{n} edge masks (PNG)"),
        Sink::Lines2D(rows) => {
            lineflow_formats::write_lines2d(&out.join("lines2d.csv"), &rows)?;
            format!("{} segments to lines2d.csv", rows.len())
        }
        Sink::Lines3D(lines) => {
            let rows: Vec<Line3Row> = lines
                .iter()
                .map(|l| Line3Row {
                    id: l.id.to_string(),
                    ..Line3Row::from(l)
                })
                .collect();
            lineflow_formats::write_lines3d_results(out, &rows)?;
            format!("{} lines to lines3d.csv and lines3d.ply", rows.len())
        }
        Sink::Poses(latest) => {
            let finite = |v: [f64; 3]| v.iter().all(|x| x.is_finite()).then_some(v);
            let rows: Vec<PoseRow> = latest
                .values()
                .map(|p| PoseRow {
                    image: name_of(p.frame, frame_names.get(&p.frame).map(String::as_str).unwrap_or("")),
                    pose: p.exterior(),
                    sigma_center_m: finite(p.sigma_center_m),
                    sigma_angles_deg: finite(p.sigma_angles_rad).map(|v| v.map(f64::to_degrees)),
                })
                .collect();
            lineflow_formats::write_poses(&out.join("poses.csv"), &rows)?;
            format!("{} poses to poses.csv", rows.len())
        }
    })
}

fn save_image(h: &ImageHeader, payload: &[u8], file: &Path) -> Result<()> {
    let (w, ht) = (h.width, h.height);
    let row = |bpp: usize| -> Result<Vec<u8>> {
        let (step, len) = (h.step as usize, w as usize * bpp);
        if step < len || payload.len() < step * ht as usize {
            bail!("{}: payload too short for {w}x{ht}", file.display());
        }
        Ok(payload.chunks(step).take(ht as usize).flat_map(|r| &r[..len]).copied().collect())
    };
    let wide = |bytes: Vec<u8>| -> Vec<u16> { bytes.chunks_exact(2).map(|c| u16::from_ne_bytes([c[0], c[1]])).collect() };
    let result = match h.encoding() {
        Some(Encoding::Mono8) => image::GrayImage::from_raw(w, ht, row(1)?).map(|i| i.save(file)),
        Some(Encoding::Rgb8) => image::RgbImage::from_raw(w, ht, row(3)?).map(|i| i.save(file)),
        Some(Encoding::Mono16) => image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, ht, wide(row(2)?)).map(|i| i.save(file)),
        Some(Encoding::Rgb16) => image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(w, ht, wide(row(6)?)).map(|i| i.save(file)),
        None => bail!("{}: unknown encoding {}", file.display(), h.encoding),
    };
    result
        .with_context(|| format!("{}: size mismatch", file.display()))?
        .with_context(|| format!("cannot write {}", file.display()))
}
