//! The module layering of ARCHITECTURE.md, checked on the source: every `crate::` path in
//! a module names itself or a module below it, so there are no circles and nothing imports
//! upward; every module is placed in a layer; and ARCHITECTURE.md's module table names
//! every layer. This reads the files as text (no compiler), so it also catches paths in
//! code that a feature switches off.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The layers, bottom first. A module may use modules earlier in this list, never later.
const LAYERS: &[&str] = &[
    "geometry",
    "cancel",
    "files",
    "accel",
    "scene",
    "light",
    "mesh",
    "solver",
    "reference",
    "exposure",
    "export",
    "pipeline",
    "analytic",
    "worker",
    "view",
    "cli",
];

/// Files at the crate root that only declare or start things.
const ROOT_FILES: &[&str] = &["lib.rs", "main.rs"];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The module path of a file under `src`: `mesh/display.rs` → [mesh, display],
/// `mesh/mod.rs` → [mesh], `files.rs` → [files].
fn module_path(relative: &Path) -> Vec<String> {
    let mut parts: Vec<String> = relative
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap();
    let stem = last.trim_end_matches(".rs");
    if stem != "mod" {
        parts.push(stem.to_string());
    }
    parts
}

/// The code of a line without its `//` comment (doc comments included: a comment may name
/// any module).
fn code(line: &str) -> &str {
    match line.find("//") {
        Some(i) => &line[..i],
        None => line,
    }
}

/// The top-level modules a source text names through `crate::`: `crate::mesh::Mesh`,
/// `use crate::{mesh::Mesh, scene}`.
fn crate_paths(text: &str) -> BTreeSet<String> {
    let code: String = text.lines().map(|l| format!("{}\n", code(l))).collect();
    let mut found = BTreeSet::new();
    let mut rest = code.as_str();
    while let Some(i) = rest.find("crate::") {
        // `crate` as a whole word (not `mycrate::`).
        let before = rest[..i].chars().last();
        rest = &rest[i + "crate::".len()..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let rest_trim = rest.trim_start();
        if let Some(group) = rest_trim.strip_prefix('{') {
            // A use group: the first name of each item at depth 1.
            let mut depth = 1;
            let mut item = String::new();
            let mut items = Vec::new();
            for c in group.chars() {
                match c {
                    '{' => depth += 1,
                    '}' => {
                        depth -= 1;
                        if depth == 0 {
                            break;
                        }
                    }
                    ',' if depth == 1 => items.push(std::mem::take(&mut item)),
                    _ if depth == 1 => item.push(c),
                    _ => {}
                }
            }
            items.push(item);
            for it in items {
                let name: String = it
                    .trim()
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    found.insert(name);
                }
            }
        } else {
            let name: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() {
                found.insert(name);
            }
        }
    }
    found
}

/// How many `super::` a path of the file's own module climbs at most in `text` (inline
/// modules, such as `mod tests { use super::*; }`, are one level deeper and not counted).
fn deepest_super(text: &str) -> usize {
    text.lines()
        .take_while(|l| {
            let l = l.trim_start();
            !(l.starts_with("mod ") && l.trim_end().ends_with('{'))
        })
        .map(code)
        .flat_map(|l| {
            l.match_indices("super::").map(move |(i, _)| {
                let mut k = 0;
                let mut at = &l[i..];
                while let Some(r) = at.strip_prefix("super::") {
                    k += 1;
                    at = r;
                }
                k
            })
        })
        .max()
        .unwrap_or(0)
}

fn rank(module: &str) -> Option<usize> {
    LAYERS.iter().position(|m| *m == module)
}

#[test]
fn the_parsing_sees_plain_paths_groups_and_skips_comments() {
    let text = "use crate::mesh::Mesh;\nuse crate::{scene::Scene, light};\n// crate::view\nlet x = crate::files::write_atomic;\nuse mycrate::worker;";
    let found: Vec<String> = crate_paths(text).into_iter().collect();
    assert_eq!(found, ["files", "light", "mesh", "scene"]);
    assert_eq!(deepest_super("use super::super::X; use super::Y;"), 2);
    assert_eq!(
        deepest_super("use super::X;\nmod tests {\n    use super::super::Y;\n}"),
        1
    );
}

#[test]
fn no_module_imports_a_module_above_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();
    let mut problems = Vec::new();
    for file in &files {
        let relative = file.strip_prefix(&src).unwrap();
        if ROOT_FILES.iter().any(|r| Path::new(r) == relative) {
            continue;
        }
        let path = module_path(relative);
        let top = &path[0];
        let Some(own) = rank(top) else {
            problems.push(format!(
                "{}: module `{top}` is in no layer (add it to LAYERS here and to ARCHITECTURE.md)",
                relative.display()
            ));
            continue;
        };
        let text = std::fs::read_to_string(file).unwrap();
        for used in crate_paths(&text) {
            match rank(&used) {
                Some(r) if r > own => problems.push(format!(
                    "{}: `{top}` uses `crate::{used}`, a layer above it",
                    relative.display()
                )),
                Some(_) => {}
                None => problems.push(format!(
                    "{}: `crate::{used}` is in no layer",
                    relative.display()
                )),
            }
        }
        if deepest_super(&text) >= path.len() {
            problems.push(format!(
                "{}: `super::` climbs out of module `{top}` to the crate root (use `crate::`)",
                relative.display()
            ));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn the_architecture_document_names_every_layer() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let doc = std::fs::read_to_string(root.join("ARCHITECTURE.md")).unwrap();
    let missing: Vec<&&str> = LAYERS
        .iter()
        .filter(|m| !doc.contains(&format!("`{m}`")))
        .collect();
    assert!(
        missing.is_empty(),
        "ARCHITECTURE.md does not name {missing:?}"
    );
}
