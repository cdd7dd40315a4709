//! The panels around the 3D view: the menu bar, the status bar, and the side panel with
//! its sections (statistics and solve control, display, the selection with its material
//! and placement, solver settings, the convergence plot).

use super::app::App;
use super::colour::{linear_to_srgb, srgb_to_linear, turbo};
use super::edits::Placement;
use super::files::PathAction;
use super::percentile;
use super::render::ToneMap;
use crate::mesh::Reconstruction;
use crate::solver::Method;
use crate::worker::{Command, Stage};
use eframe::egui;
use glam::Vec3;

impl App {
    /// The menu bar: File (open, recent and built-in scenes, export, screenshot, quit),
    /// Edit (undo, redo), View (wireframe, frame all).
    pub(super) fn menu_ui(&mut self, ui: &mut egui::Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("Open…").clicked() {
                    ui.close();
                    self.ask_path(PathAction::Open);
                }
                ui.menu_button("Open Recent", |ui| {
                    if self.recent.is_empty() {
                        ui.label("(none)");
                    }
                    let mut chosen = None;
                    for r in &self.recent {
                        if ui.button(r).clicked() {
                            chosen = Some(r.clone());
                        }
                    }
                    ui.separator();
                    for name in crate::scene::builtin::NAMES {
                        let spec = format!("builtin:{name}");
                        if ui.button(&spec).clicked() {
                            chosen = Some(spec);
                        }
                    }
                    if let Some(c) = chosen {
                        ui.close();
                        self.open(c);
                    }
                });
                if ui.button("Export baked glTF…").clicked() {
                    ui.close();
                    self.ask_path(PathAction::Export);
                }
                if ui.button("Save Screenshot…").clicked() {
                    ui.close();
                    self.ask_path(PathAction::Screenshot);
                }
                ui.separator();
                if ui.button("Quit").clicked() {
                    ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
                }
            });
            ui.menu_button("Edit", |ui| {
                if ui
                    .add_enabled(
                        !self.session.edits.undo.is_empty(),
                        egui::Button::new("Undo move (Ctrl+Z)"),
                    )
                    .clicked()
                {
                    self.undo();
                }
                if ui
                    .add_enabled(
                        !self.session.edits.redo.is_empty(),
                        egui::Button::new("Redo move (Ctrl+Shift+Z)"),
                    )
                    .clicked()
                {
                    self.redo();
                }
            });
            ui.menu_button("View", |ui| {
                ui.checkbox(&mut self.display.wireframe, "Wireframe (W)");
                if ui.button("Frame all (F)").clicked() {
                    self.frame_all();
                }
            });
        });
    }

    /// The status bar: scene and stage, progress towards the tolerance, the last message.
    pub(super) fn status_bar_ui(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let stage = match (
                self.session.stage,
                self.session.converged,
                self.session.paused,
            ) {
                (_, true, _) => "converged".to_string(),
                (_, _, true) => "paused".to_string(),
                (Some(Stage::Loading), ..) => "loading…".to_string(),
                (Some(Stage::Meshing), ..) => "meshing and building the BVH…".to_string(),
                (Some(Stage::Solving), ..) => "solving".to_string(),
                (None, ..) => "idle".to_string(),
            };
            ui.label(format!("{}: {stage}", self.session.source));
            let s = &mut self.session;
            let progress = s
                .progress
                .update(&s.stats, s.converged, self.solver_settings.tolerance);
            ui.add(
                egui::ProgressBar::new(progress)
                    .desired_width(200.0)
                    .show_percentage(),
            );
            if !self.status.is_empty() {
                ui.label(&self.status);
            }
        });
    }

    /// The side panel: the error and warnings, then statistics, display, selection,
    /// solver and convergence sections.
    pub(super) fn side_panel_ui(&mut self, ui: &mut egui::Ui) {
        if let Some(e) = self.session.error.clone() {
            ui.horizontal_wrapped(|ui| {
                ui.colored_label(egui::Color32::from_rgb(230, 80, 60), format!("Error: {e}"));
                if ui.small_button("dismiss").clicked() {
                    self.session.error = None;
                }
            });
            ui.separator();
        }
        if !self.session.warnings.is_empty() {
            egui::CollapsingHeader::new(format!("Warnings ({})", self.session.warnings.len()))
                .show(ui, |ui| {
                    for w in &self.session.warnings {
                        ui.label(w);
                    }
                });
        }
        egui::CollapsingHeader::new("Statistics")
            .default_open(true)
            .show(ui, |ui| self.stats_ui(ui));
        egui::CollapsingHeader::new("Display")
            .default_open(true)
            .show(ui, |ui| self.display_ui(ui));
        egui::CollapsingHeader::new("Selection")
            .default_open(true)
            .show(ui, |ui| self.selection_ui(ui));
        egui::CollapsingHeader::new("Solver")
            .default_open(true)
            .show(ui, |ui| self.solver_ui(ui));
        egui::CollapsingHeader::new("Convergence")
            .default_open(true)
            .show(ui, |ui| self.plot_ui(ui));
    }

    fn stats_ui(&mut self, ui: &mut egui::Ui) {
        let s = &self.session.stats;
        let secs = s.seconds.max(1e-9);
        egui::Grid::new("stats").num_columns(2).show(ui, |ui| {
            let mut row = |k: &str, v: String| {
                ui.label(k);
                ui.label(v);
                ui.end_row();
            };
            row("elements", s.elements.to_string());
            row("patches", s.patches.to_string());
            row("shots / sweeps", s.iterations.to_string());
            row("rays/s", format!("{:.2} M", s.rays as f64 / secs / 1e6));
            row(
                "unshot fraction",
                s.unshot_fraction.map_or("–".into(), |u| format!("{u:.2e}")),
            );
            row(
                "residual",
                s.residual.map_or("–".into(), |u| format!("{u:.2e}")),
            );
            row("elapsed", format!("{:.2} s", s.seconds));
            if let (Some(links), Some(bytes)) = (s.links, s.link_bytes) {
                row("links", links.to_string());
                let memory = match s.link_index_bytes.filter(|b| *b > 0) {
                    Some(index) => format!(
                        "{:.1} MB + {:.1} MB indexed by source (for edits)",
                        bytes as f64 / 1e6,
                        index as f64 / 1e6
                    ),
                    None => format!("{:.1} MB", bytes as f64 / 1e6),
                };
                row("link memory", memory);
                let eps = self.solver_settings.hierarchy.link_error;
                row(
                    "oracle ε",
                    if s.link_budget_reached == Some(true) {
                        format!("{eps} (refinement stopped at the link budget)")
                    } else {
                        format!("{eps}")
                    },
                );
            }
            if let Some(share) = s.cluster_light_share {
                // The part of the light a leaf's 16 rays estimate (see `Stats`): where it
                // is large, the picture's mottling is their noise.
                row(
                    "light along rays",
                    format!("{:.1} % (from clusters)", 100.0 * share),
                );
            }
            if let Some(t) = s.first_solution_seconds {
                // A small scene's first preview comes within milliseconds.
                let shown = if t < 0.1 {
                    format!("{:.1} ms", t * 1e3)
                } else {
                    format!("{t:.2} s")
                };
                row("first solution", shown);
            }
            if let Some(m) = self.texture_memory()
                && m.images > 0
            {
                let smaller = if m.downscaled > 0 {
                    format!(", {} shown smaller to fit", m.downscaled)
                } else {
                    String::new()
                };
                row(
                    "textures",
                    format!(
                        "{} images, {:.1} MB on the GPU{smaller}",
                        m.images,
                        m.bytes as f64 / 1e6
                    ),
                );
            }
            if let Some(l) = self.session.edits.edit_latency {
                row(
                    "last edit to frame",
                    format!("{:.0} ms", l.as_secs_f64() * 1e3),
                );
            }
            if !self.frame_times.is_empty() {
                let mut t: Vec<f32> = self.frame_times.iter().rev().take(600).copied().collect();
                let p50 = percentile(&mut t, 0.5);
                let p99 = percentile(&mut t, 0.99);
                row(
                    "frame p50 / p99",
                    format!("{:.1} / {:.1} ms", p50 * 1e3, p99 * 1e3),
                );
            }
        });
        ui.horizontal(|ui| {
            let label = if self.session.paused {
                "Resume"
            } else {
                "Pause"
            };
            if ui.button(label).clicked() {
                self.toggle_pause();
            }
            if ui.button("Reset").clicked() {
                self.worker.send(Command::Reset);
                self.session.history.clear();
                self.session.converged = false;
                self.session.stage = Some(Stage::Solving);
            }
        });
    }

    fn display_ui(&mut self, ui: &mut egui::Ui) {
        let d = &mut self.display;
        ui.checkbox(&mut d.wireframe, "Wireframe (W)");
        ui.checkbox(&mut d.textures, "Textures (T)").on_hover_text(
            "Show each surface's base-colour and emissive textures under the solved light; \
             off, each element shows the mean colour the solver used (the solution alone)",
        );
        ui.horizontal(|ui| {
            ui.label("Shading");
            ui.selectable_value(&mut d.reconstruction, Reconstruction::Flat, "flat");
            ui.selectable_value(&mut d.reconstruction, Reconstruction::Gouraud, "Gouraud");
            ui.selectable_value(&mut d.reconstruction, Reconstruction::Hermite, "Hermite");
        });
        ui.checkbox(&mut d.false_colour, "False colour (log radiosity)");
        ui.checkbox(&mut self.final_gather, "Final gather")
            .on_hover_text(
                "While the camera rests on a converged solution, fill the view with the light \
                 gathered at each pixel's point (what probe reports), coarse to fine",
            );
        let d = &mut self.display;
        let r = ui.add(egui::Slider::new(&mut d.ev, -20.0..=20.0).text("Exposure (EV)"));
        // Only a person's change turns auto exposure off (not the slider's own clamping).
        if r.changed() && (r.dragged() || r.clicked() || r.has_focus()) {
            self.auto_exposure = false;
        }
        ui.checkbox(&mut self.auto_exposure, "Auto exposure");
        egui::ComboBox::from_label("Tone mapping")
            .selected_text(d.tonemap.name())
            .show_ui(ui, |ui| {
                for t in ToneMap::ALL {
                    ui.selectable_value(&mut d.tonemap, t, t.name());
                }
            });
        if d.false_colour {
            // The legend: the shader's colour map from the low to the high end.
            let (rect, _) = ui.allocate_exact_size(egui::vec2(220.0, 12.0), egui::Sense::hover());
            let n = 64;
            for k in 0..n {
                let t0 = k as f32 / n as f32;
                let x0 = rect.left() + rect.width() * t0;
                let x1 = rect.left() + rect.width() * (k + 1) as f32 / n as f32;
                let [r, g, b] = turbo(t0 + 0.5 / n as f32);
                ui.painter().rect_filled(
                    egui::Rect::from_min_max(
                        egui::pos2(x0, rect.top()),
                        egui::pos2(x1, rect.bottom()),
                    ),
                    0.0,
                    egui::Color32::from_rgb(
                        (r * 255.0) as u8,
                        (g * 255.0) as u8,
                        (b * 255.0) as u8,
                    ),
                );
            }
            ui.label(format!(
                "radiosity 10^{:.1} to 10^{:.1} W/m² (log scale)",
                d.log_range.0, d.log_range.1
            ));
        }
        if ui
            .checkbox(&mut self.ambient, "Ambient term preview")
            .changed()
        {
            self.worker.send(Command::SetAmbient(self.ambient));
        }
    }

    fn selection_ui(&mut self, ui: &mut egui::Ui) {
        let Some(object) = self.session.selected else {
            ui.label("Click an object in the view to select it.");
            return;
        };
        self.links_summary_ui(ui);
        let name = self
            .session
            .objects
            .get(object as usize)
            .map(|o| o.name.clone())
            .unwrap_or_default();
        ui.label(format!("Object {object}: {name}"));
        if let Some(mi) = self.session.material
            && let Some(m) = self.session.materials.get(mi as usize).cloned()
        {
            ui.label(format!("Material {mi}: {}", m.name));
            let mut rho = m.reflectance;
            let mut srgb = rho.to_array().map(linear_to_srgb);
            let mut changed = false;
            ui.horizontal(|ui| {
                let label = ui.label("Reflectance");
                if ui
                    .color_edit_button_rgb(&mut srgb)
                    .labelled_by(label.id)
                    .changed()
                {
                    rho = Vec3::from_array(srgb.map(srgb_to_linear));
                    changed = true;
                }
            });
            ui.horizontal(|ui| {
                let label = ui.label("ρ (linear)");
                for c in 0..3 {
                    changed |= ui
                        .add(
                            egui::DragValue::new(&mut rho[c])
                                .range(0.0..=0.999)
                                .speed(0.002)
                                .max_decimals(3),
                        )
                        .labelled_by(label.id)
                        .changed();
                }
            });
            let mut strength = m.emission.max_element();
            let mut colour = if strength > 0.0 {
                (m.emission / strength).to_array().map(linear_to_srgb)
            } else {
                [1.0; 3]
            };
            ui.horizontal(|ui| {
                let label = ui.label("Emission");
                changed |= ui
                    .color_edit_button_rgb(&mut colour)
                    .labelled_by(label.id)
                    .changed();
                let label = ui.label("strength");
                changed |= ui
                    .add(
                        egui::DragValue::new(&mut strength)
                            .range(0.0..=1e9)
                            .speed(0.05)
                            .suffix(" W/(m²·sr)"),
                    )
                    .labelled_by(label.id)
                    .changed();
            });
            if changed {
                let emission = Vec3::from_array(colour.map(srgb_to_linear)) * strength;
                self.edit_material(mi, rho.clamp(Vec3::ZERO, Vec3::splat(0.999)), emission);
            }
        }
        ui.separator();
        ui.label("Move (about the object's centre; Ctrl+Z undoes)");
        let committed = self
            .session
            .edits
            .placements
            .get(&object)
            .map(|e| e.0)
            .unwrap_or_default();
        let mut p = match self.session.edits.draft {
            Some((o, d)) if o == object => d,
            _ => committed,
        };
        let mut commit = false;
        let mut field = |ui: &mut egui::Ui, label: &str, v: &mut [f64; 3], speed: f64| {
            ui.horizontal(|ui| {
                let label = ui.label(label);
                for x in v.iter_mut() {
                    let r = ui
                        .add(egui::DragValue::new(x).speed(speed).max_decimals(3))
                        .labelled_by(label.id);
                    // Mesh again when a drag ends or a typed value is entered, not on
                    // every pixel of a drag.
                    if r.drag_stopped() || (r.changed() && !r.dragged()) {
                        commit = true;
                    }
                }
            });
        };
        let speed = (self.camera.scene_radius as f64 * 0.005).max(1e-6);
        field(ui, "translate", &mut p.translate, speed);
        field(ui, "rotate °", &mut p.rotate_deg, 0.5);
        field(ui, "scale", &mut p.scale, 0.005);
        p.scale = p.scale.map(|s| if s.abs() < 1e-6 { 1e-6 } else { s });
        self.session.edits.draft = Some((object, p));
        if commit && p != committed {
            self.place(object, p);
        }
        ui.horizontal(|ui| {
            if ui.button("Reset placement").clicked() {
                self.place(object, Placement::default());
            }
        });
    }

    /// The clicked element as the hierarchy sees it (the link inspector; its links are
    /// drawn over the view): its level, how many links light it and what they carry, and
    /// the link whose error estimate is nearest its threshold.
    fn links_summary_ui(&self, ui: &mut egui::Ui) {
        let Some(e) = &self.session.inspected else {
            return;
        };
        ui.label(format!("Element {} (level {})", e.element, e.level));
        if e.links.is_empty() {
            ui.label("links: being refined");
            return;
        }
        let carried = e
            .links
            .iter()
            .fold(glam::Vec3::ZERO, |s, l| s + l.irradiance);
        let clusters = e.links.iter().filter(|l| l.from_cluster).count();
        ui.label(format!(
            "{} links ({clusters} from clusters), H = {:.3} {:.3} {:.3} W/m²",
            e.links.len(),
            carried.x,
            carried.y,
            carried.z
        ));
        let worst = e
            .links
            .iter()
            .map(|l| (l.error / l.threshold, l))
            .filter(|(r, _)| r.is_finite())
            .max_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((ratio, l)) = worst {
            ui.label(format!(
                "largest link error {:.2e} W/m² ({:.0} % of its threshold)",
                l.error,
                ratio * 100.0
            ));
        }
    }

    fn solver_ui(&mut self, ui: &mut egui::Ui) {
        let mut s = self.solver_settings.clone();
        egui::ComboBox::from_label("Method")
            .selected_text(s.method.name())
            .show_ui(ui, |ui| {
                for m in Method::ALL {
                    ui.selectable_value(&mut s.method, m, m.name());
                }
            });
        ui.horizontal(|ui| {
            let label = ui.label("Tolerance");
            let speed = s.tolerance * 0.05;
            ui.add(
                egui::DragValue::new(&mut s.tolerance)
                    .range(1e-8..=0.5)
                    .speed(speed)
                    .custom_formatter(|v, _| format!("{v:.1e}")),
            )
            .labelled_by(label.id);
        });
        if s.method == Method::Hierarchical {
            let h = &mut s.hierarchy;
            ui.horizontal(|ui| {
                let label = ui.label("link error ε");
                let speed = h.link_error * 0.05;
                ui.add(
                    egui::DragValue::new(&mut h.link_error)
                        .range(1e-4..=1.0)
                        .speed(speed)
                        .max_decimals(4),
                )
                .labelled_by(label.id);
            });
            min_size_ui(ui, &mut h.min_size);
            ui.checkbox(&mut h.clustering, "Clustering");
        }
        let mut adaptive = s.adaptive.is_some();
        ui.checkbox(&mut adaptive, "Adaptive subdivision (flat methods)");
        if adaptive != s.adaptive.is_some() {
            s.adaptive = adaptive.then(crate::mesh::AdaptiveSettings::default);
        }
        if let Some(a) = &mut s.adaptive {
            ui.horizontal(|ui| {
                let label = ui.label("contrast threshold (ln)");
                ui.add(
                    egui::DragValue::new(&mut a.threshold)
                        .range(0.01..=5.0)
                        .speed(0.01),
                )
                .labelled_by(label.id);
            });
            min_size_ui(ui, &mut a.min_size);
        }
        if s != self.solver_settings {
            self.solver_settings = s.clone();
            self.worker.send(Command::SetSettings(s));
            self.session.history.clear();
            self.session.converged = false;
            self.session.stage = Some(Stage::Solving);
        }
        ui.horizontal(|ui| {
            let label = ui.label("Element size (m, 0 = auto)");
            ui.add(
                egui::DragValue::new(&mut self.element_size)
                    .range(0.0..=1e6)
                    .speed(0.002)
                    .max_decimals(4),
            )
            .labelled_by(label.id);
        });
        let current = self
            .session
            .mesh
            .as_ref()
            .map(|m| m.element_size)
            .unwrap_or(0.0);
        ui.label(format!("in use: {current:.4} m"));
        let toggled = ui
            .checkbox(
                &mut self.mesh_settings.contact_lines,
                "Split at contact lines",
            )
            .on_hover_text(
                "Cut surfaces where others touch or pierce them (a box's base on a floor), \
                 so light and shadow do not leak across; meshes again",
            )
            .changed();
        if ui.button("Mesh again with this size").clicked() || toggled {
            let source = self.session.source.clone();
            self.open(source);
        }
    }

    fn plot_ui(&mut self, ui: &mut egui::Ui) {
        use egui_plot::{Line, Plot, PlotPoints};
        let log = |i: usize| -> PlotPoints<'static> {
            self.session
                .history
                .iter()
                .filter(|h| h[i].is_finite() && h[i] > 0.0)
                .map(|h| [h[0], h[i].log10()])
                .collect()
        };
        Plot::new("convergence")
            .height(160.0)
            .x_axis_label("solver time (s)")
            // Values are log10; label whole decades only.
            .y_axis_formatter(|m, _| {
                if (m.value - m.value.round()).abs() < 1e-6 {
                    format!("1e{:.0}", m.value)
                } else {
                    String::new()
                }
            })
            .legend(egui_plot::Legend::default())
            .show(ui, |p| {
                p.line(Line::new("unshot fraction", log(1)));
                p.line(Line::new("residual", log(2)));
            });
    }
}

/// The "min element size" field (0 = the automatic size) of the hierarchy and of adaptive
/// subdivision.
fn min_size_ui(ui: &mut egui::Ui, min_size: &mut Option<f64>) {
    ui.horizontal(|ui| {
        let label = ui.label("min element size (m, 0 = auto)");
        let mut m = min_size.unwrap_or(0.0);
        ui.add(
            egui::DragValue::new(&mut m)
                .range(0.0..=1e6)
                .speed(0.001)
                .max_decimals(4),
        )
        .labelled_by(label.id);
        *min_size = (m > 0.0).then_some(m);
    });
}
