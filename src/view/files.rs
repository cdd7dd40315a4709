//! The viewer's files: the open, export and screenshot dialogs (with a typed path when no
//! dialog service answers), dropped scene files, the recent-files list, screenshots (asked
//! for in the menu or timed by `view --screenshot`) and the `--frame-stats` file.

use super::app::App;
use super::percentile;
use crate::worker::Command;
use eframe::egui;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};
use std::time::{Duration, Instant};

/// What a chosen path is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum PathAction {
    Open,
    Export,
    Screenshot,
}

/// Screenshots of the window: egui delivers one a frame or more after it is asked for.
pub(super) struct Shots {
    /// The timed screenshot of `view --screenshot`: its file, and the seconds of solving
    /// before it is taken.
    pub(super) timed: Option<(PathBuf, f64)>,
    /// Close the window once a screenshot is saved (there was a timed one).
    close_after: bool,
    /// A screenshot to ask egui for this frame.
    pending: Option<Sender<Arc<egui::ColorImage>>>,
    /// A screenshot asked for and not yet delivered, and the file it goes to.
    pub(super) awaited: Option<(PathBuf, Receiver<Arc<egui::ColorImage>>)>,
}

impl Shots {
    /// With the timed screenshot `timed` (file, seconds of solving), if any.
    pub(super) fn new(timed: Option<(PathBuf, f64)>) -> Shots {
        Shots {
            close_after: timed.is_some(),
            timed,
            pending: None,
            awaited: None,
        }
    }
}

/// `$XDG_CONFIG_HOME/radiosity/recent.txt` (or under `~/.config`).
fn recent_path() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")))?;
    Some(base.join("radiosity").join("recent.txt"))
}

/// The recent-files list, newest first; empty when there is none or it cannot be read.
pub(super) fn load_recent() -> Vec<String> {
    recent_path()
        .and_then(|p| std::fs::read_to_string(p).ok())
        .map(|s| {
            s.lines()
                .map(str::to_owned)
                .filter(|l| !l.is_empty())
                .collect()
        })
        .unwrap_or_default()
}

impl App {
    /// Puts `source` first in the recent-files list (ten at most) and saves the list.
    pub(super) fn remember_recent(&mut self, source: String) {
        self.recent.retain(|r| *r != source);
        self.recent.insert(0, source);
        self.recent.truncate(10);
        // Best effort: the list is a convenience nobody asked to have written, and a
        // read-only or missing configuration directory must not stop a scene from opening.
        if let Some(p) = recent_path() {
            let _ = std::fs::create_dir_all(p.parent().unwrap_or(Path::new(".")));
            let _ = crate::files::write_atomic(&p, self.recent.join("\n").as_bytes());
        }
    }

    /// A file dialog, or the path field when no dialog service answers. rfd's portal
    /// backend returns `None` within milliseconds when no portal runs; a person cannot
    /// cancel that fast, so a quick `None` means "no dialog available".
    pub(super) fn ask_path(&mut self, action: PathAction) {
        let start = Instant::now();
        let dialog = rfd::FileDialog::new();
        let picked = match action {
            PathAction::Open => dialog.add_filter("glTF", &["gltf", "glb"]).pick_file(),
            PathAction::Export => dialog
                .add_filter("binary glTF", &["glb"])
                .set_file_name("baked.glb")
                .save_file(),
            PathAction::Screenshot => dialog
                .add_filter("PNG", &["png"])
                .set_file_name("screenshot.png")
                .save_file(),
        };
        match picked {
            Some(p) => self.path_chosen(action, p),
            None if start.elapsed() < Duration::from_millis(250) => {
                self.prompt = Some((action, String::new()));
            }
            None => {}
        }
    }

    fn path_chosen(&mut self, action: PathAction, path: PathBuf) {
        match action {
            PathAction::Open => self.open(path.to_string_lossy().into_owned()),
            PathAction::Export => self.worker.send(Command::Export {
                path,
                ev: Some(self.display.ev),
                tonemap: Some(self.display.tonemap),
            }),
            PathAction::Screenshot => self.request_screenshot(path),
        }
    }

    /// The path field that stands in for a file dialog, while one is asked for.
    pub(super) fn prompt_ui(&mut self, ctx: &egui::Context) {
        let Some((action, mut text)) = self.prompt.take() else {
            return;
        };
        let mut keep = true;
        let mut chosen = None;
        egui::Window::new("Path")
            .collapsible(false)
            .show(ctx, |ui| {
                ui.label(match action {
                    PathAction::Open => {
                        "No file dialog is available. Scene to open (.gltf / .glb):"
                    }
                    PathAction::Export => "No file dialog is available. Export to (.glb):",
                    PathAction::Screenshot => {
                        "No file dialog is available. Save screenshot to (.png):"
                    }
                });
                let r = ui.text_edit_singleline(&mut text);
                ui.horizontal(|ui| {
                    if ui.button("OK").clicked()
                        || (r.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter)))
                    {
                        chosen = Some(PathBuf::from(text.trim()));
                    }
                    if ui.button("Cancel").clicked() {
                        keep = false;
                    }
                });
            });
        match chosen {
            Some(p) if !p.as_os_str().is_empty() => self.path_chosen(action, p),
            _ if keep => self.prompt = Some((action, text)),
            _ => {}
        }
    }

    /// Opens the first `.gltf` or `.glb` file dropped on the window this frame.
    pub(super) fn files_dropped(&mut self, ctx: &egui::Context) {
        let dropped: Vec<PathBuf> = ctx.input(|i| {
            i.raw
                .dropped_files
                .iter()
                .map(|f| f.path().to_path_buf())
                .filter(|p| !p.as_os_str().is_empty())
                .collect()
        });
        if let Some(p) = dropped.into_iter().next() {
            let ext = p
                .extension()
                .map(|e| e.to_string_lossy().to_lowercase())
                .unwrap_or_default();
            if ext == "gltf" || ext == "glb" {
                self.open(p.to_string_lossy().into_owned());
            } else {
                self.session.error = Some(format!("{}: not a .gltf or .glb file", p.display()));
            }
        }
    }

    /// Asks for a screenshot of the window, saved to `path` once egui delivers it.
    fn request_screenshot(&mut self, path: PathBuf) {
        let (tx, rx) = channel();
        self.shots.awaited = Some((path, rx));
        self.shots.pending = Some(tx);
    }

    /// Takes the timed screenshot when due, asks egui for a requested one, and saves a
    /// delivered one (then, for `view --screenshot`, writes the frame statistics and
    /// closes the window).
    pub(super) fn screenshots(&mut self, ctx: &egui::Context) {
        // The timed screenshot of `view --screenshot`: after the delay, once a snapshot is
        // on screen.
        let s = &self.session;
        if let Some((path, after)) = &self.shots.timed
            && s.uploads.uploaded > 0
            && s.solve_started
                .is_some_and(|t| t.elapsed().as_secs_f64() >= *after)
        {
            let path = path.clone();
            self.shots.timed = None;
            self.request_screenshot(path);
        } else if let Some((_, after)) = &self.shots.timed
            && let Some(started) = s.solve_started
            && s.error.is_none()
        {
            // Not due yet: wake up when it is, as a converged solve sends nothing more
            // that would repaint the window.
            let left = (*after - started.elapsed().as_secs_f64()).max(0.0);
            ctx.request_repaint_after(std::time::Duration::from_secs_f64(left.min(1.0)));
        } else if let Some((_, after)) = &self.shots.timed
            && s.error.is_some()
            && s.solve_started
                .is_none_or(|t| t.elapsed().as_secs_f64() >= *after)
        {
            // Failed before any snapshot: still take the shot (it shows the error).
            let path = self.shots.timed.take().map(|s| s.0).unwrap_or_default();
            self.request_screenshot(path);
        }
        if let Some(tx) = self.shots.pending.take() {
            ctx.request_screenshot(move |image| {
                let _ = tx.send(image);
            });
        }
        if let Some((path, rx)) = self.shots.awaited.take() {
            match rx.try_recv() {
                Ok(image) => {
                    self.save_screenshot(&path, &image);
                    if self.shots.close_after {
                        self.write_frame_stats();
                        if let Some(e) = &self.session.error {
                            eprintln!("radiosity view: {e}");
                        }
                        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                    }
                }
                Err(TryRecvError::Empty) => self.shots.awaited = Some((path, rx)),
                Err(TryRecvError::Disconnected) => {
                    self.session.error = Some("the screenshot was not delivered".into());
                }
            }
        }
    }

    fn save_screenshot(&mut self, path: &Path, image: &egui::ColorImage) {
        let [w, h] = image.size;
        let bytes: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
        let result = image::RgbaImage::from_raw(w as u32, h as u32, bytes)
            .ok_or_else(|| anyhow::anyhow!("screenshot has the wrong size"))
            .and_then(|img| super::write_png(path, &img));
        match result {
            Ok(()) => self.status = format!("screenshot saved to {}", path.display()),
            Err(e) => self.session.error = Some(format!("{e:#}")),
        }
    }

    /// Writes the frame-time statistics (JSON) to the `--frame-stats` file, when one was
    /// asked for. Under [`super::app::run`] the outcome goes to it (the last write's
    /// failure becomes the command's error); otherwise a failure is printed to stderr as
    /// `error: PATH: cannot write: …`.
    pub(super) fn write_frame_stats(&self) {
        let Some(path) = &self.frame_stats else {
            return;
        };
        let mut t: Vec<f32> = self.frame_times.clone();
        let n = t.len();
        let p50 = percentile(&mut t, 0.5);
        let p99 = percentile(&mut t, 0.99);
        let max = percentile(&mut t, 1.0);
        let adapter = self.gpu.as_ref().map(|g| g.adapter()).unwrap_or_default();
        let s = &self.session;
        let json = serde_json::json!({
            "scene": s.source,
            "frames": n,
            "p50_ms": p50 * 1e3,
            "p99_ms": p99 * 1e3,
            "max_ms": max * 1e3,
            "elements": s.stats.elements,
            "adapter": adapter,
            "solver_seconds": s.stats.seconds,
            "iterations": s.stats.iterations,
        });
        let written = crate::files::write_atomic(path, json.to_string().as_bytes());
        let unreceived = match &self.frame_stats_written {
            Some(to) => to.send(written).err().map(|e| e.0),
            None => Some(written),
        };
        if let Some(Err(e)) = unreceived {
            eprintln!("error: {e}");
        }
    }
}
