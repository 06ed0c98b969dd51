//! The layout's rules, checked on the sources (the README's "Layout"): `nodes/` holds stages only, a stage depends on the
//! base crates and not on another stage, no crate's modules import each other in a circle, and `cli/` keeps
//! only the user's commands.
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use lineflow_e2e::repo_file;

/// Crates no stage may build on: the front ends.
const FRONT_ENDS: [&str; 2] = ["lineflow-cli", "lineflow-bench"];

/// Stage-to-stage library dependencies still to go, each with the issue that removes it.
const KNOWN_SIDEWAYS: [(&str, &str, &str); 1] = [(
    "lineflow-modelfit",
    "lineflow-model",
    "#29 reworks model-image fitting on the model's types",
)];

fn workspace_crates() -> Vec<PathBuf> {
    let root = repo_file("");
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let doc: toml::Table = manifest.parse().unwrap();
    doc["workspace"]["members"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| root.join(m.as_str().unwrap()))
        .collect()
}

fn manifest(dir: &Path) -> toml::Table {
    std::fs::read_to_string(dir.join("Cargo.toml")).unwrap().parse().unwrap()
}

fn lineflow_dependencies(m: &toml::Table) -> BTreeSet<String> {
    m.get("dependencies")
        .and_then(toml::Value::as_table)
        .map(|d| d.keys().filter(|k| k.starts_with("lineflow-")).cloned().collect())
        .unwrap_or_default()
}

fn package_name(m: &toml::Table) -> String {
    m["package"]["name"].as_str().unwrap().to_owned()
}

#[test]
fn nodes_holds_stages_only_and_stages_do_not_import_each_other() {
    let mut manifests = Vec::new();
    for entry in std::fs::read_dir(repo_file("nodes")).unwrap().flatten() {
        let dir = entry.path();
        if dir.file_name().unwrap() == "python" {
            continue; // nodes in Python: scripts, no crate
        }
        let m = manifest(&dir);
        let bins = m.get("bin").and_then(toml::Value::as_array).map_or(0, Vec::len);
        assert!(
            bins >= 1,
            "{}: a crate under nodes/ is a stage with its process (a [[bin]])",
            dir.display()
        );
        manifests.push(m);
    }
    let stages: BTreeSet<String> = manifests.iter().map(package_name).collect();
    let mut sideways = Vec::new();
    for m in &manifests {
        let name = package_name(m);
        for dep in lineflow_dependencies(m) {
            assert!(!FRONT_ENDS.contains(&dep.as_str()), "{name} depends on the front end {dep}");
            if stages.contains(&dep) {
                sideways.push((name.clone(), dep));
            }
        }
    }
    let known: Vec<(String, String)> = KNOWN_SIDEWAYS.iter().map(|(a, b, _)| (a.to_string(), b.to_string())).collect();
    for s in &sideways {
        assert!(
            known.contains(s),
            "stage {} imports stage {}: move what they share into a base crate",
            s.0,
            s.1
        );
    }
    for k in &known {
        assert!(
            sideways.contains(k),
            "{} no longer imports {}: take it off KNOWN_SIDEWAYS",
            k.0,
            k.1
        );
    }
}

/// Every stage process dispatches its implementations through `run_stage` (parameters checked, an unknown `impl`
/// named with those available) and its library tests what the stage does without processes.
#[test]
fn every_stage_has_a_thin_shell_and_tested_library() {
    for entry in std::fs::read_dir(repo_file("nodes")).unwrap().flatten() {
        let dir = entry.path();
        let stage = dir.file_name().unwrap().to_string_lossy().into_owned();
        // python/: scripts; record/: the recorder and player the supervisor adds, not stages with implementations.
        if stage == "python" || stage == "record" {
            continue;
        }
        let main = std::fs::read_to_string(dir.join("src/main.rs")).unwrap();
        assert!(
            main.contains("run_stage("),
            "nodes/{stage}/src/main.rs does not dispatch through run_stage"
        );
        let tested = rust_files(&dir.join("src"))
            .iter()
            .filter(|f| f.file_name().unwrap() != "main.rs")
            .any(|f| std::fs::read_to_string(f).unwrap().contains("#[test]"));
        assert!(tested, "nodes/{stage}: no unit test in its library");
    }
}

#[test]
fn the_cli_keeps_the_users_commands_only() {
    let lines: usize = rust_files(&repo_file("cli/src"))
        .iter()
        .map(|f| std::fs::read_to_string(f).unwrap().lines().count())
        .sum();
    assert!(lines < 1500, "cli/ has {lines} lines; benchmarks and experiments belong in bench/");
}

#[test]
fn no_crate_has_an_import_circle_between_its_modules() {
    let mut circles = Vec::new();
    for dir in workspace_crates() {
        let src = dir.join("src");
        if !src.is_dir() {
            continue;
        }
        for c in module_circles(&src) {
            circles.push(format!(
                "{}: {}",
                dir.strip_prefix(repo_file("")).unwrap_or(&dir).display(),
                c.join(" -> ")
            ));
        }
    }
    assert!(
        circles.is_empty(),
        "modules that import each other in a circle:\n{}",
        circles.join("\n")
    );
}

fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(rust_files(&p));
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
    out.sort();
    out
}

/// The top-level module a file of `src/` belongs to (`None` for the crate root and binaries' roots).
fn top_module(src: &Path, file: &Path) -> Option<String> {
    let rel = file.strip_prefix(src).ok()?;
    let first = rel.components().next()?.as_os_str().to_str()?.trim_end_matches(".rs").to_owned();
    (!matches!(first.as_str(), "lib" | "main" | "bin")).then_some(first)
}

/// The source without `#[cfg(test)]` modules (tests may use anything) and without comments; nothing of a file
/// that is a test module itself (`#![cfg(test)]`).
fn production_code(text: &str) -> String {
    if text.contains("#![cfg(test)]") {
        return String::new();
    }
    let text = match text.find("#[cfg(test)]") {
        Some(i) => &text[..i],
        None => text,
    };
    text.lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Names the crate root re-exports from a module (`pub use module::{A, B}` / `pub use module::A`).
fn root_reexports(root: &str) -> BTreeMap<String, String> {
    let mut map = BTreeMap::new();
    for stmt in root.split(';') {
        let stmt = stmt.trim();
        let Some(rest) = stmt.strip_prefix("pub use ") else { continue };
        let Some((module, names)) = rest.split_once("::") else { continue };
        let names = names.trim_start_matches('{').trim_end_matches('}');
        for n in names.split(',') {
            let n = n.trim().rsplit("::").next().unwrap_or("").trim();
            let n = n.split(" as ").last().unwrap_or(n).trim();
            if !n.is_empty() && n != "self" {
                map.insert(n.to_owned(), module.trim().to_owned());
            }
        }
    }
    map
}

/// Every `crate::…` path in `code`, as the path's segments after `crate` (a `use crate::{a::X, b}` group gives
/// one path per member).
fn crate_paths(code: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let mut rest = code;
    while let Some(i) = rest.find("crate::") {
        let before = rest[..i].chars().last();
        rest = &rest[i + "crate::".len()..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == '$') {
            continue; // `lineflow_crate::`, `$crate::`
        }
        if let Some(group) = rest.strip_prefix('{') {
            let end = matching_brace(group);
            for member in split_top_level(&group[..end]) {
                out.push(segments(&member));
            }
        } else {
            out.push(segments(rest));
        }
    }
    out
}

fn matching_brace(s: &str) -> usize {
    let mut depth = 0;
    for (i, c) in s.char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth == 0 => return i,
            '}' => depth -= 1,
            _ => {}
        }
    }
    s.len()
}

fn split_top_level(s: &str) -> Vec<String> {
    let (mut out, mut cur, mut depth) = (Vec::new(), String::new(), 0);
    for c in s.chars() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                out.push(std::mem::take(&mut cur));
                continue;
            }
            _ => {}
        }
        cur.push(c);
    }
    out.push(cur);
    out.into_iter().map(|m| m.trim().to_owned()).filter(|m| !m.is_empty()).collect()
}

fn segments(path: &str) -> Vec<String> {
    let mut segs = Vec::new();
    let mut rest = path;
    loop {
        let end = rest.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(rest.len());
        if end == 0 {
            break;
        }
        segs.push(rest[..end].to_owned());
        match rest[end..].strip_prefix("::") {
            Some(r) if !r.starts_with('{') => rest = r,
            _ => break,
        }
    }
    segs
}

fn module_circles(src: &Path) -> Vec<Vec<String>> {
    let files = rust_files(src);
    let modules: BTreeSet<String> = files.iter().filter_map(|f| top_module(src, f)).collect();
    let root = ["lib.rs", "main.rs"]
        .iter()
        .map(|r| src.join(r))
        .find(|p| p.is_file())
        .map(|p| std::fs::read_to_string(p).unwrap())
        .unwrap_or_default();
    let reexports = root_reexports(&production_code(&root));
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for f in &files {
        let Some(from) = top_module(src, f) else { continue };
        let code = production_code(&std::fs::read_to_string(f).unwrap());
        for path in crate_paths(&code) {
            let Some(first) = path.first() else { continue };
            let to = if modules.contains(first) {
                Some(first.clone())
            } else {
                reexports.get(first).filter(|m| modules.contains(*m)).cloned()
            };
            if let Some(to) = to.filter(|t| *t != from) {
                edges.entry(from.clone()).or_default().insert(to);
            }
        }
    }
    strongly_connected(&modules, &edges).into_iter().filter(|c| c.len() > 1).collect()
}

/// Tarjan's strongly connected components.
fn strongly_connected(nodes: &BTreeSet<String>, edges: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct State<'a> {
        edges: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on_stack: BTreeSet<&'a str>,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        let i = s.index.len();
        s.index.insert(v, i);
        s.low.insert(v, i);
        s.stack.push(v);
        s.on_stack.insert(v);
        if let Some(next) = s.edges.get(v) {
            for w in next {
                if !s.index.contains_key(w.as_str()) {
                    visit(s, w);
                    let lw = s.low[w.as_str()];
                    let lv = s.low.get_mut(v).unwrap();
                    *lv = (*lv).min(lw);
                } else if s.on_stack.contains(w.as_str()) {
                    let iw = s.index[w.as_str()];
                    let lv = s.low.get_mut(v).unwrap();
                    *lv = (*lv).min(iw);
                }
            }
        }
        if s.low[v] == s.index[v] {
            let mut component = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on_stack.remove(w);
                component.push(w.to_owned());
                if w == v {
                    break;
                }
            }
            component.sort();
            s.out.push(component);
        }
    }
    let mut s = State {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        out: Vec::new(),
    };
    for n in nodes {
        if !s.index.contains_key(n.as_str()) {
            visit(&mut s, n);
        }
    }
    s.out
}
