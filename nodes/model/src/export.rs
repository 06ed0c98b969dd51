//! The model as files: `model.obj` (vertices, faces grouped by kind, every edge as a polyline element) and
//! `model.city.json` (CityJSON 2.0: one Building with an LOD 3 MultiSurface and semantic surfaces).
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use serde_json::json;

use crate::{EdgeOrigin, Model, SurfaceKind};

fn write(path: &Path, text: &str) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create folder", dir.display()))?;
    }
    std::fs::write(path, text).with_context(|| format!("{}: cannot write", path.display()))
}

/// Wavefront OBJ: `v` per vertex (metres, object coordinates), `f` per face outer ring grouped by kind (OBJ has no
/// holes: openings are their own faces), `l` per edge (group `edges` for the observed ones, `inferred_edges` for
/// those the model's rules placed, `completed_edges` for the occluded ones, and `surface_lines` for the lines inside
/// a wall's surface, which are no edges of the model).
pub fn obj_text(model: &Model) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# lineflow wire-frame model: {} vertices, {} edges, {} faces (object coordinates, metres)",
        model.vertices.len(),
        model.edges.len(),
        model.faces.len()
    );
    for v in &model.vertices {
        let _ = writeln!(s, "v {:.6} {:.6} {:.6}", v.point.x, v.point.y, v.point.z);
    }
    let mut by_kind: BTreeMap<SurfaceKind, Vec<&Vec<usize>>> = BTreeMap::new();
    for f in &model.faces {
        by_kind.entry(f.kind).or_default().push(&f.ring);
    }
    for (kind, rings) in by_kind {
        let _ = writeln!(s, "g {}", kind.cityjson());
        for ring in rings {
            let idx: Vec<String> = ring.iter().map(|v| (v + 1).to_string()).collect();
            let _ = writeln!(s, "f {}", idx.join(" "));
        }
    }
    // Hidden edges in their own group, as the seed flags them; inferred ones apart from the observed, as a reader
    // may want to tell them, though both are edges a camera sees.
    for (group, origin) in [
        ("edges", EdgeOrigin::Observed),
        ("inferred_edges", EdgeOrigin::Inferred),
        ("completed_edges", EdgeOrigin::Hidden),
    ] {
        let mut group_edges = model.edges.iter().filter(|e| e.origin == origin).peekable();
        if group_edges.peek().is_some() {
            let _ = writeln!(s, "g {group}");
        }
        for e in group_edges {
            let _ = writeln!(s, "l {} {}", e.a + 1, e.b + 1);
        }
    }
    if !model.surface_lines.is_empty() {
        let _ = writeln!(s, "g surface_lines");
    }
    for [a, b] in &model.surface_lines {
        let _ = writeln!(s, "l {} {}", a + 1, b + 1);
    }
    s
}

pub fn write_obj(path: &Path, model: &Model) -> Result<()> {
    write(path, &obj_text(model))
}

/// CityJSON 2.0 with integer vertices at 0.1 mm and only the vertices that faces use.
pub fn cityjson(model: &Model) -> serde_json::Value {
    let mut used: Vec<usize> = model
        .faces
        .iter()
        .flat_map(|f| f.ring.iter().chain(f.holes.iter().flatten()))
        .copied()
        .collect();
    used.sort_unstable();
    used.dedup();
    let index: BTreeMap<usize, usize> = used.iter().enumerate().map(|(i, &v)| (v, i)).collect();
    let scale = 1e-4;
    let mut origin = [f64::INFINITY; 3];
    for &v in &used {
        for (k, o) in origin.iter_mut().enumerate() {
            *o = o.min(model.vertices[v].point[k]);
        }
    }
    if used.is_empty() {
        origin = [0.0; 3];
    }
    let vertices: Vec<[i64; 3]> = used
        .iter()
        .map(|&v| {
            let p = model.vertices[v].point;
            [0, 1, 2].map(|k| ((p[k] - origin[k]) / scale).round() as i64)
        })
        .collect();
    let kinds: Vec<SurfaceKind> = {
        let mut k: Vec<SurfaceKind> = model.faces.iter().map(|f| f.kind).collect();
        k.sort_unstable();
        k.dedup();
        k
    };
    let ring = |r: &Vec<usize>| r.iter().map(|v| index[v]).collect::<Vec<usize>>();
    let boundaries: Vec<Vec<Vec<usize>>> = model
        .faces
        .iter()
        .map(|f| std::iter::once(ring(&f.ring)).chain(f.holes.iter().map(ring)).collect())
        .collect();
    let values: Vec<usize> = model.faces.iter().map(|f| kinds.binary_search(&f.kind).unwrap_or(0)).collect();
    let surfaces: Vec<serde_json::Value> = kinds.iter().map(|k| json!({ "type": k.cityjson() })).collect();
    let mut objects = serde_json::Map::new();
    if !model.faces.is_empty() {
        objects.insert(
            "building".into(),
            json!({
                "type": "Building",
                "geometry": [{
                    "type": "MultiSurface",
                    "lod": "3",
                    "boundaries": boundaries,
                    "semantics": { "surfaces": surfaces, "values": values },
                }],
            }),
        );
    }
    json!({
        "type": "CityJSON",
        "version": "2.0",
        "transform": { "scale": [scale, scale, scale], "translate": origin },
        "metadata": { "title": "lineflow wire-frame model (local object coordinates, metres)" },
        "CityObjects": objects,
        "vertices": vertices,
    })
}

pub fn write_cityjson(path: &Path, model: &Model) -> Result<()> {
    let text = serde_json::to_string(&cityjson(model)).context("CityJSON serialisation")?;
    write(path, &text)
}
