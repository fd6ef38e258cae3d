//! The 2-D image panel: its tabs, the image shown with zoom and pan, the
//! overlays on the input, the mask tools' gestures and the hover text.

use eframe::egui;

use super::{Action, Gesture, Panel2d, Panels, UiContext};
use crate::app::document::KnownDistance;
use crate::app::images;
use crate::app::session::Session;
use crate::app::settings::Tool;
use crate::mask_edit::{Brush, ImagePoint, OverlayStyle};

impl Panels {
    pub(super) fn image_panel_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let set_names = cx.set_names();
        let mut rows = vec![vec![
            (Panel2d::Input, "input + mask"),
            (Panel2d::Reprojection, "reprojection"),
            (Panel2d::Difference, "residual I − R"),
            (Panel2d::Depth, "depth"),
            (Panel2d::DepthError, "depth error"),
        ]];
        if set_names.is_none()
            && cx
                .session
                .solve
                .finished()
                .is_some_and(|s| s.albedo_fit.is_some())
        {
            // On a row of its own: a sixth tab does not fit the first.
            rows.push(vec![(Panel2d::Albedo, "albedo")]);
        }
        if set_names.is_some() {
            // A set's own panels on a row of their own: nine tabs do not
            // fit one row of the image panel.
            rows[0].retain(|(p, _)| *p != Panel2d::DepthError);
            rows.push(vec![
                (Panel2d::Albedo, "albedo"),
                (Panel2d::Normals, "normals"),
                (Panel2d::PhotoResidual, "photo residual"),
                (Panel2d::SingleDifference, "alone − set"),
            ]);
        }
        for panels in rows {
            ui.horizontal_wrapped(|ui| {
                for (panel, name) in panels {
                    let enabled = panel != Panel2d::DepthError
                        || cx
                            .session
                            .document
                            .as_ref()
                            .is_some_and(|d| d.ground_truth.is_some());
                    ui.add_enabled_ui(enabled, |ui| {
                        ui.selectable_value(&mut self.panel, panel, name);
                    });
                }
            });
        }
        ui.horizontal_wrapped(|ui| {
            if self.panel == Panel2d::PhotoResidual
                && let Some(names) = &set_names
            {
                self.set.residual_selector_ui(ui, names);
            }
            if let Some(caption) = self.set.caption(self.panel, cx.session) {
                ui.weak(caption);
            }
            if matches!(self.panel, Panel2d::Input | Panel2d::Reprojection)
                && cx.session.document.is_some()
            {
                let display = cx.session.display;
                ui.weak(display.describe()).on_hover_text(format!(
                    "For viewing only: the linear values times {:.3}, so that the {:.0}th \
                     percentile of the object's pixels is white, then the sRGB transfer \
                     function (display gamma). The solver gets the linear values, and \
                     hovering shows them (I).",
                    display.exposure,
                    100.0 * images::WHITE_QUANTILE
                ));
            }
        });
        let Some((w, h)) = cx.session.document.as_ref().map(|d| d.size()) else {
            ui.label("Open an image (File > Open or drop a file here).");
            return;
        };
        let (texture, range) = match self.panel {
            Panel2d::Input => (self.input_texture(ui.ctx(), cx.session), None),
            Panel2d::Reprojection => (self.textures.reprojection.clone(), None),
            Panel2d::Difference => split(&self.textures.difference),
            Panel2d::Depth => split(&self.textures.depth),
            Panel2d::DepthError => split(&self.textures.depth_error),
            Panel2d::Albedo
            | Panel2d::Normals
            | Panel2d::PhotoResidual
            | Panel2d::SingleDifference => {
                match self.set.texture(ui.ctx(), self.panel, cx.session) {
                    // Albedo is grey and normals are colours: no colour bar.
                    Some((texture, range)) => {
                        let bar = matches!(
                            self.panel,
                            Panel2d::PhotoResidual | Panel2d::SingleDifference
                        );
                        (Some(texture), bar.then_some(range))
                    }
                    None => (None, None),
                }
            }
        };
        let bar_width = if range.is_some() { 90.0 } else { 0.0 };
        let available = ui.available_size() - egui::vec2(bar_width, 0.0);
        let (rect, response) = ui.allocate_exact_size(
            available.max(egui::vec2(32.0, 32.0)),
            egui::Sense::click_and_drag(),
        );
        // image -> screen: fit, then the user's zoom and pan.
        let fit = (rect.width() / w as f32).min(rect.height() / h as f32);
        let scale = fit * self.zoom;
        let origin = rect.center() - egui::vec2(w as f32, h as f32) * scale / 2.0 + self.pan;
        let to_image = |p: egui::Pos2| -> ImagePoint {
            let q = (p - origin) / scale;
            [q.x, q.y]
        };
        // Zoom about the cursor, pan with the right or middle button.
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0
                && let Some(cursor) = response.hover_pos()
            {
                let factor = (scroll * 0.002).exp();
                let before = to_image(cursor);
                self.zoom = (self.zoom * factor).clamp(0.1, 64.0);
                let new_scale = fit * self.zoom;
                let new_origin = rect.center() - egui::vec2(w as f32, h as f32) * new_scale / 2.0;
                self.pan = cursor - new_origin - egui::vec2(before[0], before[1]) * new_scale;
            }
        }
        if response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
        {
            self.pan += response.drag_delta();
        }
        if response.double_clicked_by(egui::PointerButton::Secondary) {
            self.zoom = 1.0;
            self.pan = egui::Vec2::ZERO;
        }
        let image_rect = egui::Rect::from_min_size(origin, egui::vec2(w as f32, h as f32) * scale);
        let painter = ui.painter_at(rect);
        let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        if let Some(texture) = &texture {
            painter.image(texture.id(), image_rect, uv, egui::Color32::WHITE);
        } else {
            painter.text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "waiting for the first level",
                egui::FontId::proportional(14.0),
                ui.visuals().weak_text_color(),
            );
        }
        if self.panel == Panel2d::Input {
            self.update_overlay(ui.ctx(), cx);
            if let Some((_, overlay)) = &self.textures.overlay {
                painter.image(overlay.id(), image_rect, uv, egui::Color32::WHITE);
            }
            let solve = &cx.session.solve;
            let key = solve.completed_jobs;
            let alpha = (cx.settings.brush.overlay_opacity.clamp(0.0, 1.0) * 255.0) as u8;
            // Draws `mask` over the image in `colour` through `texture`.
            let overlay = |texture: &mut Option<(usize, egui::TextureHandle)>,
                           name: &str,
                           mask: Option<&sfs_core::grid::Grid<bool>>,
                           colour: [u8; 4]| {
                update_mask_texture(ui.ctx(), texture, name, mask, colour, key);
                if let Some((_, texture)) = texture {
                    painter.image(texture.id(), image_rect, uv, egui::Color32::WHITE);
                }
            };
            if cx.settings.brush.show_shadows {
                let shadow = solve.finished().and_then(|s| s.shadow.as_ref());
                let violet = [150, 60, 220, alpha];
                overlay(&mut self.textures.shadows, "shadows", shadow, violet);
            }
            if cx.settings.brush.show_contours {
                let orange = [255, 150, 0, alpha.max(160)];
                let contours = solve.occlusion_edges();
                overlay(&mut self.textures.contours, "contours", contours, orange);
            }
            self.draw_known_distances(&painter, cx, scale, origin);
            self.paint_input(ui, cx, &response, &to_image, scale, origin);
        }
        if let Some(range) = range {
            let bar = egui::Rect::from_min_size(
                egui::pos2(rect.right() + 8.0, rect.top() + 10.0),
                egui::vec2(80.0, (rect.height() - 20.0).max(20.0)),
            );
            images::scale_bar(ui, bar, range);
        }
        self.hover = response.hover_pos().and_then(|p| {
            let [x, y] = to_image(p);
            (x >= 0.0 && y >= 0.0 && (x as usize) < w && (y as usize) < h)
                .then(|| describe_pixel(cx.session, x as usize, y as usize))
        });
    }

    fn update_overlay(&mut self, ctx: &egui::Context, cx: &UiContext<'_>) {
        let Some(doc) = &cx.session.document else {
            return;
        };
        // A set's photograph's own layer, when the tools paint it.
        let masks = match (self.set.paint_photo, &doc.set) {
            (Some(k), Some(set)) => set.photo_masks.get(k).unwrap_or(&doc.masks),
            _ => &doc.masks,
        };
        let key = (masks.revision() ^ (cx.settings.brush.overlay_opacity.to_bits() as u64) << 32)
            .wrapping_add(self.set.paint_photo.map_or(0, |k| k as u64 + 1) << 56);
        if self
            .textures
            .overlay
            .as_ref()
            .is_some_and(|(k, _)| *k == key)
        {
            return;
        }
        let style = OverlayStyle {
            opacity: cx.settings.brush.overlay_opacity,
            ..OverlayStyle::default()
        };
        let rgba = masks.overlay_rgba(&style);
        let (w, h) = doc.size();
        let image = egui::ColorImage::from_rgba_unmultiplied([w, h], &rgba);
        self.textures.overlay = Some((
            key,
            images::load_texture(ctx, "overlay", image, egui::TextureOptions::NEAREST),
        ));
    }

    /// Mask tools on the input panel.
    fn paint_input(
        &mut self,
        ui: &egui::Ui,
        cx: &mut UiContext<'_>,
        response: &egui::Response,
        to_image: &dyn Fn(egui::Pos2) -> ImagePoint,
        scale: f32,
        origin: egui::Pos2,
    ) {
        let b = cx.settings.brush.clone();
        let paint_photo = self.set.paint_photo;
        let Some(doc) = &mut cx.session.document else {
            return;
        };
        let pointer = response.interact_pointer_pos().or(response.hover_pos());
        let primary = egui::PointerButton::Primary;
        if self.known.picking {
            // "Set distance": a click picks the pixel; no mask tool.
            if response.hovered() {
                ui.ctx().set_cursor_icon(egui::CursorIcon::Crosshair);
            }
            if response.clicked_by(primary)
                && let Some(p) = pointer
            {
                let picked = doc
                    .photo_pixel(to_image(p))
                    .ok_or_else(|| "that is outside the image: click a pixel of the object".into())
                    .and_then(|(x, y)| {
                        let probe = KnownDistance {
                            column_px: x as f64,
                            row_px: y as f64,
                            depth: 1.0,
                        };
                        doc.check_known_depth(&probe).map(|_| (x, y))
                    });
                match picked {
                    Ok(pixel) => {
                        self.known.pending = Some(pixel);
                        self.known.picking = false;
                        self.known.refused = None;
                    }
                    Err(reason) => {
                        cx.actions.push(Action::Notice(reason.clone()));
                        self.known.refused = Some(reason);
                    }
                }
            }
            return;
        }
        let (masks, image) = doc.paint_target(paint_photo);
        let brush = Brush {
            radius_px: b.radius_px,
            hardness: b.hardness,
            mode: b.mode,
        };
        match b.tool {
            Tool::Brush => {
                if response.drag_started_by(primary)
                    && let Some(p) = pointer
                {
                    match masks.begin_stroke(b.layer, brush, to_image(p)) {
                        Ok(()) => self.gesture = Some(Gesture::Stroke),
                        Err(e) => cx.actions.push(Action::Notice(e.to_string())),
                    }
                }
                if response.dragged_by(primary)
                    && matches!(self.gesture, Some(Gesture::Stroke))
                    && let Some(p) = pointer
                {
                    let d = response.drag_delta();
                    masks.stroke_segment(to_image(p - d), to_image(p));
                }
                if response.clicked_by(primary)
                    && let Some(p) = pointer
                {
                    // A click is a single dab.
                    if masks.begin_stroke(b.layer, brush, to_image(p)).is_ok() {
                        masks.end_stroke();
                    }
                }
                if let Some(p) = response.hover_pos() {
                    ui.painter().circle_stroke(
                        p,
                        b.radius_px * scale,
                        egui::Stroke::new(1.0, egui::Color32::YELLOW),
                    );
                }
            }
            Tool::Rectangle => {
                if response.drag_started_by(primary)
                    && let Some(p) = pointer
                {
                    self.gesture = Some(Gesture::Rectangle(to_image(p)));
                }
                if let (Some(Gesture::Rectangle(start)), Some(p)) = (&self.gesture, pointer) {
                    let a = origin + egui::vec2(start[0], start[1]) * scale;
                    ui.painter().rect_stroke(
                        egui::Rect::from_two_pos(a, p),
                        0.0,
                        egui::Stroke::new(1.0, egui::Color32::YELLOW),
                        egui::StrokeKind::Middle,
                    );
                }
            }
            Tool::Lasso => {
                if response.drag_started_by(primary)
                    && let Some(p) = pointer
                {
                    self.gesture = Some(Gesture::Lasso(vec![to_image(p)]));
                }
                if let (Some(Gesture::Lasso(points)), Some(p)) = (&mut self.gesture, pointer) {
                    if response.dragged_by(primary) {
                        points.push(to_image(p));
                    }
                    let screen: Vec<egui::Pos2> = points
                        .iter()
                        .map(|q| origin + egui::vec2(q[0], q[1]) * scale)
                        .collect();
                    ui.painter().add(egui::Shape::line(
                        screen,
                        egui::Stroke::new(1.0, egui::Color32::YELLOW),
                    ));
                }
            }
            Tool::FloodFill => {
                if response.clicked_by(primary)
                    && let Some(p) = pointer
                    && let Err(e) =
                        masks.flood_fill(b.layer, b.mode, image, to_image(p), b.flood_tolerance)
                {
                    cx.actions.push(Action::Notice(e.to_string()));
                }
            }
        }
        if response.drag_stopped_by(primary) {
            match self.gesture.take() {
                Some(Gesture::Stroke) => {
                    masks.end_stroke();
                }
                Some(Gesture::Rectangle(start)) => {
                    if let Some(p) = pointer {
                        masks.fill_rect(b.layer, b.mode, start, to_image(p));
                    }
                }
                Some(Gesture::Lasso(points)) => {
                    masks.fill_lasso(b.layer, b.mode, &points);
                }
                None => {}
            }
        }
    }
}

/// Hover text: image, reprojection and depth at an image pixel.
fn describe_pixel(session: &Session, c: usize, r: usize) -> String {
    let mut text = format!("({c}, {r})");
    let Some(doc) = &session.document else {
        return text;
    };
    let (w, h) = doc.size();
    text.push_str(&format!(" I {:.4}", doc.image.at(c, r)));
    if let Some(level) = &session.solve.latest {
        let (lw, lh) = level.depth.size();
        let (lc, lr) = ((c * lw / w).min(lw - 1), (r * lh / h).min(lh - 1));
        // Off the object the solver's depth is no surface (the views hide it).
        let z = if *doc.masks.object().at(c, r) {
            *level.depth.at(lc, lr)
        } else {
            f64::NAN
        };
        text.push_str(&format!(
            "  R {:.4}  z {:.4}",
            level.reprojection.at(lc, lr),
            z
        ));
    }
    if let Some(gt) = &doc.ground_truth {
        text.push_str(&format!("  z_gt {:.4}", gt.at(c, r)));
    }
    text.push_str(&format!("  c {:.2}", doc.masks.confidence().at(c, r)));
    text
}

fn split(
    entry: &Option<(egui::TextureHandle, [f64; 2])>,
) -> (Option<egui::TextureHandle>, Option<[f64; 2]>) {
    match entry {
        Some((t, r)) => (Some(t.clone()), Some(*r)),
        None => (None, None),
    }
}

/// Keeps `texture` the RGBA of `mask` (`colour` where set, clear elsewhere)
/// for the result `key`: rebuilt once per result, dropped without a mask.
fn update_mask_texture(
    ctx: &egui::Context,
    texture: &mut Option<(usize, egui::TextureHandle)>,
    name: &str,
    mask: Option<&sfs_core::grid::Grid<bool>>,
    colour: [u8; 4],
    key: usize,
) {
    let Some(mask) = mask else {
        *texture = None;
        return;
    };
    if texture.as_ref().is_some_and(|(k, _)| *k == key) {
        return;
    }
    let (w, h) = mask.size();
    let rgba: Vec<u8> = mask
        .as_slice()
        .iter()
        .flat_map(|&on| if on { colour } else { [0, 0, 0, 0] })
        .collect();
    let image = egui::ColorImage::from_rgba_unmultiplied([w, h], &rgba);
    *texture = Some((
        key,
        images::load_texture(ctx, name, image, egui::TextureOptions::NEAREST),
    ));
}
