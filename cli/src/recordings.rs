//! `lineflow replay`, `info`, `diff`, `export` and `recover`: working with recordings.
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use lineflow_formats::{Line2Row, Line3Row, PoseRow};
use lineflow_messages::schema::{decode, decode_view, read_elements, read_pod, Decoded};
use lineflow_messages::{parts, EdgeMapHeader, Encoding, ImageHeader, Line3, Lines2DHeader, MessageKind, Pose, Segment2};
use lineflow_recordings::replay::{playback_graph, recorded_programs, rerun_graph, Pace};
use lineflow_recordings::{tools, tools::Reading, Recording};
use lineflow_runtime::launch::Resolver;
use lineflow_runtime::run::Verbosity;

/// Options of `lineflow replay`.
pub struct ReplayArgs<'a> {
    /// The recording.
    pub recording: &'a Path,
    /// Re-run a graph on the recorded source topics.
    pub rerun: bool,
    /// Graph to re-run instead of the recorded one.
    pub graph: Option<&'a Path>,
    /// Parameter overrides.
    pub set: &'a [String],
    /// Output folder of a re-run.
    pub out: Option<PathBuf>,
    /// Start the programs the recorded launch file names without asking.
    pub yes: bool,
    /// Speed; 0 = as fast as possible.
    pub rate: f64,
    /// Loop (playback only).
    pub repeat: bool,
    /// Topics to play (playback only; default all).
    pub topics: &'a [String],
    /// What the terminal shows.
    pub verbosity: Verbosity,
}

/// `lineflow replay`.
pub fn replay(a: ReplayArgs<'_>) -> Result<ExitCode> {
    let rec = Recording::open(a.recording)?;
    if let Some(damage) = &rec.damage {
        eprintln!("warning: {}: {damage}; replaying what is readable", rec.path.display());
    }
    let resolver = Resolver::beside_current_exe();
    let pace = Pace {
        rate: a.rate,
        repeat: a.repeat,
    };
    if a.rerun {
        if a.repeat {
            bail!("--loop plays a recording for viewers; a --rerun runs the graph once");
        }
        let g = rerun_graph(&rec, a.graph, a.set, &resolver, pace)?;
        // A launch file of the user's own (--graph) starts what the user chose.
        let programs = if a.graph.is_none() {
            recorded_programs(&g, a.set)
        } else {
            Vec::new()
        };
        if !programs.is_empty() && !a.yes {
            confirm_programs(&rec, &programs)?;
        }
        let out = a.out.unwrap_or_else(|| rec.path.parent().unwrap_or(Path::new(".")).join("rerun"));
        eprintln!("re-running graph '{}' on {} -> {}", g.name, rec.path.display(), out.display());
        return lineflow_runtime::run::run_graph(&g, &out, None, a.verbosity);
    }
    if a.graph.is_some() || !a.set.is_empty() {
        bail!("--graph and --set apply to --rerun");
    }
    let g = playback_graph(&rec, a.topics, &resolver, pace)?;
    let out = a.out.unwrap_or_else(|| std::env::temp_dir().join("lineflow-replay"));
    eprintln!(
        "playing {} topics of {} (attach with `lineflow echo TOPIC` or `lineflow hz TOPIC`)",
        g.edges.len(),
        rec.path.display()
    );
    lineflow_runtime::run::run_graph(&g, &out, None, a.verbosity)
}

/// Shows the programs a recording's launch file would start and asks before starting them; without a terminal to
/// ask on, refuses.
fn confirm_programs(rec: &Recording, programs: &[(String, String)]) -> Result<()> {
    use std::io::{BufRead, IsTerminal, Write};
    let list: Vec<String> = programs.iter().map(|(n, c)| format!("  {n}: {c}")).collect();
    let list = list.join("\n");
    if !std::io::stdin().is_terminal() {
        bail!(
            "{}: the recorded launch file starts programs that are not lineflow stages:\n{list}\nnothing was started; \
             pass --yes to run them, or --graph with a launch file of your own",
            rec.path.display()
        );
    }
    eprintln!("The launch file stored in {}:\n", rec.path.display());
    eprintln!("{}\n", rec.run_meta("launch_text").unwrap_or_default());
    eprint!("It starts programs that are not lineflow stages:\n{list}\nStart them? [y/N] ");
    std::io::stderr().flush()?;
    let mut answer = String::new();
    std::io::stdin().lock().read_line(&mut answer)?;
    if !matches!(answer.trim(), "y" | "Y" | "yes") {
        bail!("not started");
    }
    Ok(())
}

/// `lineflow info`.
pub fn info(path: &Path, json: bool, verify: bool) -> Result<ExitCode> {
    let rec = Recording::open(path)?;
    let summary = tools::summarize(&rec, if verify { Reading::Messages } else { Reading::Index });
    match json {
        true => println!("{}", serde_json::to_string(&summary)?),
        false => print!("{}", tools::info(&summary)),
    }
    Ok(ExitCode::from(if summary.damaged { 2 } else { 0 }))
}

/// `lineflow diff`: exit status 0 when equal, 1 when they differ.
pub fn diff(a: &Path, b: &Path) -> Result<ExitCode> {
    let (ra, rb) = (Recording::open(a)?, Recording::open(b)?);
    let report = tools::diff(&ra, &rb)?;
    for t in &report.equal {
        println!("equal    {t}");
    }
    for d in &report.differ {
        println!("DIFFERS  {}: {}", d.topic, d.what);
    }
    if report.differ.is_empty() {
        println!("recordings are equal on all {} topics", report.equal.len());
        Ok(ExitCode::SUCCESS)
    } else {
        println!(
            "{} of {} topics differ",
            report.differ.len(),
            report.differ.len() + report.equal.len()
        );
        Ok(ExitCode::FAILURE)
    }
}

/// `lineflow recover`.
pub fn recover(path: &Path, out: &Path) -> Result<ExitCode> {
    let rec = Recording::open(path)?;
    let r = tools::recover(&rec, out)?;
    match &r.lost {
        Some(why) => eprintln!("recovered {} messages into {}; the rest is lost: {why}", r.messages, out.display()),
        None => eprintln!("recovered all {} messages into {}", r.messages, out.display()),
    }
    Ok(ExitCode::SUCCESS)
}

/// `lineflow export`: images (and edge maps) as PNG, 2-D lines as `lines2d.csv`, 3-D lines as `lines3d.csv` and
/// `.ply`, poses as `poses.csv` (formats of `conventions.md`).
pub fn export(path: &Path, topic: &str, out: &Path) -> Result<ExitCode> {
    let rec = Recording::open(path)?;
    let channels = rec.channels();
    let Some(channel) = channels.iter().find(|c| c.topic == topic) else {
        let names: Vec<_> = channels.iter().filter(|c| !c.view).map(|c| c.topic.as_str()).collect();
        bail!("{}: no topic '{topic}' (topics: {})", path.display(), names.join(", "));
    };
    let Some(kind) = channel.kind else {
        bail!(
            "topic '{topic}' is a viewer channel ({}); export the topic it renders",
            channel.schema
        );
    };
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    // Poses name their images by frame number: take the names from the image headers (pixels not copied).
    let mut frame_names = BTreeMap::new();
    let mut scratch = Decoded::default();
    let mut decoded = Vec::new();
    let read = rec.for_each_message(|m| {
        if kind == MessageKind::Poses && m.kind == Some(MessageKind::Image) {
            if let Ok((h, _)) = decode_view(MessageKind::Image, &m.data, &mut scratch) {
                let h: ImageHeader = read_pod(h);
                frame_names.insert(h.stamp.frame, h.name().to_owned());
            }
        }
        if m.topic == topic {
            decoded.push(decode(kind, &m.data).with_context(|| format!("'{topic}' message {}", m.sequence))?);
        }
        Ok(())
    });
    if let Err(e) = read {
        eprintln!("warning: {e:#}");
    }
    let name_of = |frame: u64, name: &str| {
        if name.is_empty() {
            format!("frame_{frame:06}")
        } else {
            name.to_owned()
        }
    };
    let written = match kind {
        MessageKind::Image => {
            for d in &decoded {
                let h: ImageHeader = read_pod(&d.header);
                let file = out.join(Path::new(&name_of(h.stamp.frame, h.name())).with_extension("png"));
                save_image(&h, &d.payload, &file)?;
            }
            format!("{} PNG images", decoded.len())
        }
        MessageKind::EdgeMap => {
            for d in &decoded {
                let h: EdgeMapHeader = read_pod(&d.header);
                let mut mask = image::GrayImage::new(h.width, h.height);
                for p in read_elements::<lineflow_messages::EdgePixel>(&d.payload) {
                    if (p.col as u32) < h.width && (p.row as u32) < h.height {
                        mask.put_pixel(p.col as u32, p.row as u32, image::Luma([255]));
                    }
                }
                let file = out.join(format!("{}.edges.png", name_of(h.stamp.frame, h.name())));
                mask.save(&file).with_context(|| format!("cannot write {}", file.display()))?;
            }
            format!("{} edge masks (PNG)", decoded.len())
        }
        MessageKind::Lines2D => {
            let mut rows = Vec::new();
            for d in &decoded {
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
            lineflow_formats::write_lines2d(&out.join("lines2d.csv"), &rows)?;
            format!("{} segments to lines2d.csv", rows.len())
        }
        MessageKind::Lines3D => {
            // The latest message holds the current estimate of every line.
            let rows: Vec<Line3Row> = decoded
                .last()
                .map(|d| read_elements::<Line3>(&d.payload))
                .unwrap_or_default()
                .iter()
                .map(|l| Line3Row {
                    id: l.id.to_string(),
                    ..Line3Row::from(l)
                })
                .collect();
            lineflow_formats::write_lines3d_results(out, &rows)?;
            format!("{} lines to lines3d.csv and lines3d.ply", rows.len())
        }
        MessageKind::Poses => {
            // The highest revision of each frame.
            let mut latest: BTreeMap<u64, Pose> = BTreeMap::new();
            for d in &decoded {
                for p in read_elements::<Pose>(&d.payload) {
                    if latest.get(&p.frame).is_none_or(|q| q.revision <= p.revision) {
                        latest.insert(p.frame, p);
                    }
                }
            }
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
        other => bail!(
            "topic '{topic}' carries {}; export handles Image, EdgeMap, Lines2D, Lines3D and Poses",
            other.name()
        ),
    };
    eprintln!("exported {written} into {}", out.display());
    Ok(ExitCode::SUCCESS)
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
