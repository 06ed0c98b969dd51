//! `lineflow bench fuzz`: every parser a user's file reaches, fed mutated copies of valid files (bytes flipped,
//! set, inserted, deleted, repeated, truncated, and tokens of the formats spliced in), counting panics and the
//! slowest call. Not coverage-guided (cargo-fuzz needs nightly, which these machines lack): a mutation fuzzer from
//! seeds of every format, deterministic from its seed so that a panic it finds is found again.
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::Result;
use lineflow_messages::MessageKind;
use lineflow_photogrammetry::random::Rng;

/// A parser and the valid file its mutations start from.
pub struct Target {
    /// Name (the format).
    pub name: &'static str,
    /// File name the mutated bytes are written under (some readers go by the extension).
    pub file: &'static str,
    /// A valid file.
    pub seed: Vec<u8>,
    /// Reads the file; an error is the right answer to bad bytes, a panic is a defect.
    pub parse: fn(&Path),
}

/// What one target's run found.
#[derive(Debug, Clone)]
pub struct Found {
    /// The target's name.
    pub name: &'static str,
    /// Calls made.
    pub executions: u64,
    /// Calls that panicked.
    pub panics: u64,
    /// The first input that panicked and the panic's message.
    pub first_panic: Option<(Vec<u8>, String)>,
    /// The slowest call.
    pub slowest: Duration,
    /// All calls, with writing their inputs.
    pub elapsed: Duration,
}

static PANIC_AT: std::sync::Mutex<String> = std::sync::Mutex::new(String::new());

/// Tokens the formats are made of, spliced into the inputs.
const TOKENS: &[&[u8]] = &[
    b",",
    b"\n",
    b"\r\n",
    b"=",
    b"\"",
    b"[",
    b"]",
    b"[[",
    b"{",
    b"}",
    b"nan",
    b"inf",
    b"-inf",
    b"-1e308",
    b"1e308",
    b"0",
    b"-0",
    b"18446744073709551615",
    b"-1",
    b"4294967295",
    b"v ",
    b"l ",
    b"f ",
    b"#",
    b"\0",
    b"\xff\xff\xff\xff",
];

/// A mutated copy of `seed`: one to four mutations.
pub fn mutate(seed: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut b = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        let n = b.len();
        let at = if n == 0 { 0 } else { rng.below(n) };
        match rng.below(8) {
            0 if n > 0 => b[at] ^= 1 << rng.below(8),
            1 if n > 0 => b[at] = rng.below(256) as u8,
            2 => b.insert(at, rng.below(256) as u8),
            3 if n > 0 => {
                let len = 1 + rng.below((n - at).min(64));
                b.drain(at..at + len);
            }
            4 if n > 0 => {
                let len = 1 + rng.below((n - at).min(64));
                let piece = b[at..at + len].to_vec();
                b.splice(at..at, piece);
            }
            5 => b.truncate(at),
            _ => {
                let t = TOKENS[rng.below(TOKENS.len())];
                b.splice(at..at, t.iter().copied());
            }
        }
    }
    b
}

/// Runs `executions` mutated inputs through each target (one thread; files in `dir`).
pub fn fuzz(targets: &[Target], executions: u64, seed: u64, dir: &Path) -> Result<Vec<Found>> {
    let hook = std::panic::take_hook();
    // Where the last panic happened: the message alone rarely names the parser at fault.
    std::panic::set_hook(Box::new(|info| {
        if let Some(l) = info.location() {
            *PANIC_AT.lock().unwrap_or_else(|e| e.into_inner()) = format!("{}:{}", l.file(), l.line());
        }
    }));
    let result = targets
        .iter()
        .enumerate()
        .map(|(k, t)| {
            let mut rng = Rng::new(seed, k as u64);
            let path = dir.join(t.file);
            let mut found = Found {
                name: t.name,
                executions: 0,
                panics: 0,
                first_panic: None,
                slowest: Duration::ZERO,
                elapsed: Duration::ZERO,
            };
            let started = Instant::now();
            for e in 0..executions {
                // The seed itself first, then mutations.
                let input = if e == 0 { t.seed.clone() } else { mutate(&t.seed, &mut rng) };
                std::fs::write(&path, &input)?;
                let start = Instant::now();
                let outcome = catch_unwind(AssertUnwindSafe(|| (t.parse)(&path)));
                found.slowest = found.slowest.max(start.elapsed());
                found.executions += 1;
                if let Err(panic) = outcome {
                    found.panics += 1;
                    if found.first_panic.is_none() {
                        let message = panic
                            .downcast_ref::<String>()
                            .cloned()
                            .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                            .unwrap_or_default();
                        let at = PANIC_AT.lock().map(|s| s.clone()).unwrap_or_default();
                        found.first_panic = Some((input, format!("{message} at {at}")));
                    }
                }
            }
            found.elapsed = started.elapsed();
            Ok(found)
        })
        .collect();
    std::panic::set_hook(hook);
    result
}

/// `lineflow bench fuzz`: a table of every target; exit status 1 when any panicked or took more than a second.
pub fn bench_fuzz(executions: u64, seed: u64) -> Result<std::process::ExitCode> {
    let dir = scratch()?;
    let targets = targets()?;
    println!("{executions} mutated inputs per parser (seed {seed}), one thread:\n");
    println!("| parser | executions | per second | panics | slowest (ms) |");
    println!("|---|---|---|---|---|");
    let mut bad = false;
    for (t, found) in targets.iter().zip(fuzz(&targets, executions, seed, dir.path())?) {
        let rate = found.executions as f64 / found.elapsed.as_secs_f64();
        println!(
            "| {} | {} | {rate:.0} | {} | {:.2} |",
            found.name,
            found.executions,
            found.panics,
            found.slowest.as_secs_f64() * 1e3
        );
        if let Some((input, message)) = &found.first_panic {
            let kept = dir.path().join(format!("panic-{}", t.file));
            std::fs::write(&kept, input)?;
            eprintln!("{}: {message}", t.name);
        }
        bad |= found.panics > 0 || found.slowest > Duration::from_secs(1);
    }
    Ok(if bad {
        std::process::ExitCode::FAILURE
    } else {
        std::process::ExitCode::SUCCESS
    })
}

/// A folder for the inputs in memory where there is one: a disk makes the writes, not the parsers, the cost.
fn scratch() -> Result<tempfile::TempDir> {
    let shm = Path::new("/dev/shm");
    Ok(if shm.is_dir() {
        tempfile::tempdir_in(shm)?
    } else {
        tempfile::tempdir()?
    })
}

/// Every parser a user's file or recording reaches, each with a valid seed.
pub fn targets() -> Result<Vec<Target>> {
    use lineflow_formats as f;
    let text = |s: &str| s.as_bytes().to_vec();
    Ok(vec![
        Target {
            name: "launch TOML",
            file: "graph.toml",
            seed: text(LAUNCH),
            parse: |p| {
                let text = std::fs::read_to_string(p).unwrap_or_default();
                let _ = lineflow_runtime::launch::parse(p, &text, &[], &lineflow_runtime::launch::Resolver::beside_current_exe());
            },
        },
        Target {
            name: "camera.toml",
            file: "camera.toml",
            seed: text(CAMERA),
            parse: |p| {
                let _ = f::project::read_camera(p);
            },
        },
        Target {
            name: "site.toml",
            file: "site.toml",
            seed: text(SITE),
            parse: |p| {
                let _ = f::project::read_site(p);
            },
        },
        Target {
            name: "control_points.csv",
            file: "control_points.csv",
            seed: text("id,X,Y,Z,sx,sy,sz,role\nC1,2.0,0.0,1.56,0.005,0.005,0.005,control\nK1,5.0,0.1,2.0,,,,check\n"),
            parse: |p| {
                let _ = f::project::read_control_points(p);
            },
        },
        Target {
            name: "observations.csv",
            file: "observations.csv",
            seed: text("image,point_id,col,row\nIMG_0001.png,C1,276.107,757.581\nIMG_0002.png,C1,1458.8,766.2\n"),
            parse: |p| {
                let images = [Path::new("IMG_0001.png").to_owned(), Path::new("IMG_0002.png").to_owned()];
                let _ = f::project::read_observations(p, &images);
            },
        },
        Target {
            name: "poses.csv",
            file: "poses.csv",
            seed: text(
                "image,X,Y,Z,omega_deg,phi_deg,kappa_deg,sX,sY,sZ,s_omega_deg,s_phi_deg,s_kappa_deg\n\
                 IMG_0001.png,12.17,-25.07,1.46,104.37,0.93,0.40,,,,,,\n\
                 IMG_0002.png,12.95,-25.09,1.56,103.44,-0.04,-0.44,0.01,0.01,0.01,0.001,0.001,0.001\n",
            ),
            parse: |p| {
                let _ = f::read_poses(p);
            },
        },
        Target {
            name: "checkpoints.csv",
            file: "checkpoints.csv",
            seed: text("id,dX,dY,dZ\nK1,0.001,-0.002,0.0005\nK2,0.0,0.001,-0.001\n"),
            parse: |p| {
                let _ = f::read_checkpoints(p);
            },
        },
        Target {
            name: "lines2d.csv",
            file: "lines2d.csv",
            seed: text("image,id,col1,row1,col2,row2,n_pixels\nIMG_0001.png,0,1046.194,1303.458,4538.001,1326.375,3493\n"),
            parse: |p| {
                let _ = f::read_lines2d(p);
            },
        },
        Target {
            name: "lines3d.csv",
            file: "lines3d.csv",
            seed: text(
                "id,X1,Y1,Z1,X2,Y2,Z2,n_points,n_images,rms_m,class\nL1,-0.19,-0.25,7.47,30.19,-0.25,7.47,24,18,0.0004,structure\n\
                 L2,0.1,0.0,1.2,4.0,0.0,1.2,12,9,0.002,texture\nG1,0.53,0.0,0.60,1.46,0.0,0.60,,,,\n",
            ),
            parse: |p| {
                let _ = f::read_lines3d(p);
            },
        },
        Target {
            name: "OBJ model",
            file: "model.obj",
            seed: text(OBJ),
            parse: |p| {
                let _ = f::read_obj(p);
                let _ = f::read_obj_wireframe(p);
            },
        },
        Target {
            name: "PNG",
            file: "image.png",
            seed: encoded_image(image::ImageFormat::Png)?,
            parse: decode_image,
        },
        Target {
            name: "JPEG",
            file: "image.jpg",
            seed: encoded_image(image::ImageFormat::Jpeg)?,
            parse: decode_image,
        },
        Target {
            name: "TIFF",
            file: "image.tif",
            seed: encoded_image(image::ImageFormat::Tiff)?,
            parse: decode_image,
        },
        Target {
            name: "MCAP recording",
            file: "recording.mcap",
            seed: recording_seed()?,
            parse: |p| {
                let Ok(rec) = lineflow_recordings::Recording::open(p) else { return };
                for reading in [
                    lineflow_recordings::tools::Reading::Index,
                    lineflow_recordings::tools::Reading::Messages,
                ] {
                    let _ = lineflow_recordings::tools::summarize(&rec, reading);
                }
                let _ = rec.for_each_message(|m| {
                    if let Some(kind) = m.kind {
                        let _ = lineflow_messages::schema::decode(kind, &m.data);
                    }
                    Ok(())
                });
                let out = p.with_extension("recovered.mcap");
                let _ = lineflow_recordings::tools::recover(&rec, &out);
            },
        },
    ])
}

fn decode_image(p: &Path) {
    let _ = lineflow_capture::decode::decode_file(p);
}

/// A small grey-and-colour image in `format`.
fn encoded_image(format: image::ImageFormat) -> Result<Vec<u8>> {
    let img = image::RgbImage::from_fn(16, 12, |x, y| image::Rgb([(x * 16) as u8, (y * 20) as u8, ((x + y) * 8) as u8]));
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, format)?;
    Ok(bytes.into_inner())
}

/// A finished recording of two topics with a few messages each.
fn recording_seed() -> Result<Vec<u8>> {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("seed.mcap");
    let mut w = lineflow_recordings::McapWriter::create(&path, lineflow_recordings::Compression::None)?;
    for (topic, kind) in [("poses", MessageKind::Poses), ("lines3d", MessageKind::Lines3D)] {
        w.add_topic(topic, kind)?;
        for t in 0..3u64 {
            let mut cdr = Vec::new();
            let header = vec![0u8; kind.header_size()];
            lineflow_messages::schema::encode(kind, &header, &[], &mut cdr);
            w.write(topic, t * 1000, t * 1000, &cdr)?;
        }
    }
    w.finish()?;
    Ok(std::fs::read(&path)?)
}

const LAUNCH: &str = r#"[graph]
name = "fuzz"

[[node]]
name = "capture"
stage = "capture"
impl = "synthetic"
params = { preset = "d2x-strip", scale = 0.1, seed = 1, fps = 0 }

[[node]]
name = "gray"
stage = "convert"
impl = "gray"
restart = "on-failure"

[[edge]]
topic = "images"
type = "Image"
from = "capture"
to = ["gray"]
"#;

const CAMERA: &str = "width = 1474\nheight = 979\npixel_size_mm = 0.016\nfocal_mm = 18.007\n\
principal_point_mm = [-0.229, 0.1067]\nradial = [0.000174, 0.0, 0.0]\ndecentering = [0.000007, -0.000005]\n";

const SITE: &str = "[[wall]]\nname = \"facade\"\n\
corners = [[-0.02, -0.03, 0.0], [29.99, -0.03, 0.01], [30.0, -0.03, 8.23], [0.01, -0.03, 8.24]]\n";

const OBJ: &str = "# model\no facade\nv 0 0 0\nv 30 0 0\nv 30 0 8\nv 0 0 8\nf 1 2 3 4\nl 1 2\nl 2 3\ng completed_edges\nl 3 4\n";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mutations_are_deterministic_and_change_the_input() {
        let seed = b"id,X,Y\n1,2,3\n";
        let a: Vec<Vec<u8>> = (0..50).scan(Rng::new(1, 0), |r, _| Some(mutate(seed, r))).collect();
        let b: Vec<Vec<u8>> = (0..50).scan(Rng::new(1, 0), |r, _| Some(mutate(seed, r))).collect();
        assert_eq!(a, b);
        assert!(a.iter().filter(|m| m.as_slice() != seed).count() > 40);
    }

    /// With seed 2026 this found the mcap crate's unchecked chunk arithmetic (`recordings`' `Guarded`): it stays
    /// as that panic's regression test.
    #[test]
    fn every_parser_survives_mutated_files_without_a_panic() {
        let dir = scratch().unwrap();
        let targets = targets().unwrap();
        for found in fuzz(&targets, 300, 2026, dir.path()).unwrap() {
            assert_eq!(found.executions, 300);
            assert!(
                found.panics == 0,
                "{} panicked {} times, first on {} bytes: {:?}",
                found.name,
                found.panics,
                found.first_panic.as_ref().map_or(0, |(input, _)| input.len()),
                found.first_panic.as_ref().map(|(_, message)| message)
            );
        }
    }
}
