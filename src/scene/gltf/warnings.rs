//! Warning lines for one file: deduplicated, capped, and per-kind counters that become one
//! line each at the end (so 10,000 dropped triangles are one warning, not 10,000).

use super::{material, one_line};

/// Largest number of distinct warning lines kept per file; the rest are counted.
const MAX_WARNING_LINES: usize = 40;

/// Warning lines for one file, deduplicated and capped, plus per-kind counters.
pub(super) struct Warnings {
    path: String,
    lines: Vec<String>,
    dropped_lines: usize,
    /// Names of materials whose base colour exceeded 1 (reported in one line).
    pub clamped_reflectance: Vec<String>,
    /// Emission factors above 1 (allowed here as HDR; the spec says [0, 1]).
    pub hdr_emission: Vec<String>,
    /// Primitives of mode 0–3 (points, lines).
    pub skipped_points_lines: usize,
    /// Triangles dropped because an index is ≥ the vertex count.
    pub out_of_range: usize,
    /// Triangles dropped because a vertex is NaN or infinite (locally or after transform).
    pub non_finite: usize,
    /// Triangles dropped because their world-space area is zero.
    pub degenerate: usize,
    /// Nodes reached a second time (a cycle or a node with two parents).
    pub revisited_nodes: usize,
    /// Nodes with a skin (drawn unskinned).
    pub skinned: usize,
}

impl Warnings {
    /// Empty warnings for the file shown as `path`.
    pub fn new(path: &str) -> Self {
        Warnings {
            path: path.to_string(),
            lines: Vec::new(),
            dropped_lines: 0,
            clamped_reflectance: Vec::new(),
            hdr_emission: Vec::new(),
            skipped_points_lines: 0,
            out_of_range: 0,
            non_finite: 0,
            degenerate: 0,
            revisited_nodes: 0,
            skinned: 0,
        }
    }

    /// Records one warning (the file path is prefixed here).
    pub fn line(&mut self, message: String) {
        let line = format!("{}: {}", self.path, one_line(&message));
        if self.lines.contains(&line) {
            return;
        }
        if self.lines.len() < MAX_WARNING_LINES {
            self.lines.push(line);
        } else {
            self.dropped_lines += 1;
        }
    }

    /// All lines, the counted kinds last.
    pub fn finish(mut self) -> Vec<String> {
        let list = |names: &[String]| {
            let mut s = names
                .iter()
                .take(5)
                .map(|n| format!("'{n}'"))
                .collect::<Vec<_>>()
                .join(", ");
            if names.len() > 5 {
                s += &format!(" and {} more", names.len() - 5);
            }
            s
        };
        let mut tail = Vec::new();
        if !self.clamped_reflectance.is_empty() {
            tail.push(format!(
                "baseColorFactor above 1 clamped to {} (reflectance must stay below 1) in {} material(s): {}",
                material::MAX_REFLECTANCE,
                self.clamped_reflectance.len(),
                list(&self.clamped_reflectance)
            ));
        }
        if !self.hdr_emission.is_empty() {
            tail.push(format!(
                "emissiveFactor above 1 (outside the spec's [0, 1]) used as given in: {}",
                list(&self.hdr_emission)
            ));
        }
        let counted = [
            (
                self.skipped_points_lines,
                "point/line primitive(s) skipped (only triangles are used)",
            ),
            (
                self.out_of_range,
                "triangle(s) with vertex indices out of range dropped",
            ),
            (
                self.non_finite,
                "triangle(s) with NaN or infinite vertex positions dropped",
            ),
            (self.degenerate, "zero-area triangle(s) dropped"),
            (
                self.revisited_nodes,
                "node(s) reached more than once (a cycle or two parents) visited only once",
            ),
            (
                self.skinned,
                "skinned node(s) drawn in their bind pose (skinning is ignored)",
            ),
        ];
        for (n, what) in counted {
            if n > 0 {
                tail.push(format!("{n} {what}"));
            }
        }
        for t in tail {
            self.lines.push(format!("{}: {}", self.path, t));
        }
        if self.dropped_lines > 0 {
            self.lines.push(format!(
                "{}: … and {} more warnings",
                self.path, self.dropped_lines
            ));
        }
        self.lines
    }
}
