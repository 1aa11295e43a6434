//! Where each side goes on screen, the frame composed on the CPU (heat map, overlay
//! marks) and what the panel is given to show.

use super::panel;
use super::panel::{OverlayState, SideInfo};
use super::present::{DIVIDER_PX, DIVIDER_RGBA, Layout, Part};
use super::state::{Compare, ViewState};
use super::viewer::Viewer;
use super::{ARTIFACT_RGBA, LOD_RGBA, MISS_RGBA, NOTICE_TIME};
use anyhow::Result;
use ash::vk;
use dispmap_cli::heatmap;
use std::sync::atomic::Ordering;

impl Viewer {
    /// What the panel shows.
    pub(super) fn panel_info(&self, state: &ViewState, layout: &Layout) -> panel::Info {
        let renderers = std::iter::once(&self.left).chain(self.right.as_ref());
        let sides = renderers
            .enumerate()
            .map(|(i, r)| SideInfo {
                method: r.settings().method,
                passes: self.stats.shown_passes[i].clone(),
                iterations: self.stats.shown_iterations[i],
                heat_scale: self.heat_scales[i],
                error: self
                    .overlay
                    .as_ref()
                    .and_then(|o| o.results.get(i).copied()),
            })
            .collect();
        let overlay = match (&self.job, &self.overlay) {
            (Some(j), _) => OverlayState::Computing(
                j.done.load(Ordering::Relaxed) as f32 / j.total.max(1) as f32,
            ),
            (None, Some(_)) => OverlayState::Shown,
            (None, None) => OverlayState::Off,
        };
        // Each side's label at the middle of its widest part on screen.
        let scale = self.presenter.extent().width as f32 / layout.frame.width.max(1) as f32;
        let mut label_columns: Vec<(usize, f32)> = Vec::new();
        for part in &layout.parts {
            let w = part.src_x1.saturating_sub(part.src_x0);
            if w == 0 {
                continue;
            }
            label_columns.push((part.side, (part.dst_x as f32 + w as f32 / 2.0) * scale));
        }
        let s = self.left.settings();
        panel::Info {
            sides,
            // Nothing measured yet: no numbers rather than zeros.
            fps: (self.stats.shown_fps > 0.0).then_some(self.stats.shown_fps),
            frame_ms: (self.stats.shown_fps > 0.0).then_some(self.stats.shown_frame_ms),
            history: [
                self.history[0].iter().copied().collect(),
                self.history[1].iter().copied().collect(),
            ],
            overlay,
            panel_ms: self.stats.last_ui,
            frame: [layout.frame.width, layout.frame.height],
            label_columns,
            maps: state.maps.iter().map(|(n, _)| n.clone()).collect(),
            geometry: s.scene.geometry.name().to_owned(),
            docked: (self.dock_px > 0).then(|| {
                let ppp = self.gui.as_ref().map_or(1.0, |g| g.egui.pixels_per_point());
                self.dock_px as f32 / ppp
            }),
            notice: self
                .notice
                .as_ref()
                .filter(|(_, at)| at.elapsed() < NOTICE_TIME)
                .map(|(line, _)| line.clone()),
        }
    }
}

impl Viewer {
    /// The frame composed on the CPU: each side's colour (or heat map) with the
    /// overlay's marks, put together by `layout` over the divider's colour. Also keeps
    /// the heat map's scale per side.
    pub(super) fn compose(&mut self, state: &ViewState, layout: &Layout) -> Result<Vec<u8>> {
        let mut sides = Vec::new();
        let mut scales = [None, None];
        // The heat map: one scale for both sides (the larger top count), so that one
        // colour means one count on either side of the divider.
        let mut heat = Vec::new();
        if state.heatmap {
            for r in std::iter::once(&self.left).chain(self.right.as_ref()) {
                let hits = r.read_hits()?;
                let covered = heatmap::coverage(&hits, None);
                heat.push((hits, covered));
            }
        }
        let top = heat
            .iter()
            .map(|(hits, covered)| heatmap::iteration_stats(hits, covered).max as f32)
            .fold(0.0f32, f32::max);
        for (i, r) in std::iter::once(&self.left)
            .chain(self.right.as_ref())
            .enumerate()
        {
            let mut rgba = match heat.get(i) {
                Some((hits, covered)) => {
                    scales[i] = Some(top);
                    heatmap::iteration_heatmap(hits, covered, (top > 0.0).then_some(top))?
                }
                None => r.read_color()?,
            };
            if let Some(marks) = self.overlay.as_ref().and_then(|o| o.marks.get(i)) {
                for (px, &m) in rgba.chunks_exact_mut(4).zip(marks) {
                    match m {
                        1 => px.copy_from_slice(&ARTIFACT_RGBA),
                        2 => px.copy_from_slice(&MISS_RGBA),
                        3 => px.copy_from_slice(&LOD_RGBA),
                        _ => {}
                    }
                }
            }
            sides.push((rgba, r.settings().width as usize));
        }
        self.heat_scales = scales;
        let (w, h) = (layout.frame.width as usize, layout.frame.height as usize);
        let mut out = DIVIDER_RGBA.repeat(w * h);
        for part in &layout.parts {
            let Some((rgba, side_w)) = sides.get(part.side) else {
                continue;
            };
            let (x0, x1) = (part.src_x0 as usize, (part.src_x1 as usize).min(*side_w));
            let dst = part.dst_x as usize;
            if x0 >= x1 || dst + (x1 - x0) > w {
                continue;
            }
            for (row_out, row_in) in out
                .chunks_exact_mut(4 * w)
                .zip(rgba.chunks_exact(4 * side_w))
            {
                row_out[4 * dst..4 * (dst + x1 - x0)].copy_from_slice(&row_in[4 * x0..4 * x1]);
            }
        }
        Ok(out)
    }
}

/// Each side's frame size and where the sides' columns go in a frame of `frame`
/// pixels, for the compare mode of `state`; the last `dock` columns are left to the
/// docked panel (no side is drawn there).
pub(super) fn frame_layout(state: &ViewState, frame: [u32; 2], dock: u32) -> ([u32; 2], Layout) {
    let extent = vk::Extent2D {
        width: frame[0],
        height: frame[1],
    };
    let (w, h) = (frame[0].saturating_sub(dock).max(1).min(frame[0]), frame[1]);
    let frame = [w, h];
    let part = |side, src_x0, src_x1, dst_x| Part {
        side,
        src_x0,
        src_x1,
        dst_x,
    };
    let (size, parts) = match (state.right, state.compare) {
        (None, _) => (frame, vec![part(0, 0, w, 0)]),
        (Some(_), Compare::Flip) => (frame, vec![part(usize::from(state.show_b), 0, w, 0)]),
        (Some(_), Compare::Wipe) => {
            let d = ((state.divider * w as f32).round() as u32).min(w);
            let d_end = (d + DIVIDER_PX).min(w);
            (frame, vec![part(0, 0, d, 0), part(1, d_end, w, d_end)])
        }
        (Some(_), Compare::SideBySide) => {
            let half = (w.saturating_sub(DIVIDER_PX) / 2).max(1);
            // The right half never overlaps the left one (two copies into one column
            // are a write-after-write hazard): on a window too narrow for both, it gets
            // the columns left over, or none.
            let right_x = w.saturating_sub(half).max(half);
            let mut parts = vec![part(0, 0, half.min(w), 0)];
            if right_x < w {
                parts.push(part(1, 0, (w - right_x).min(half), right_x));
            }
            ([half, h], parts)
        }
    };
    (
        size,
        Layout {
            frame: extent,
            parts,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use dispmap::method::{Method, MethodParams};
    use dispmap::passes::shadow::ShadowSettings;
    use dispmap::renderer::{RenderSettings, SceneAssets};
    use dispmap::scene::Scene;

    fn state(right: Option<Method>, compare: Compare) -> ViewState {
        let settings = RenderSettings {
            width: 100,
            height: 40,
            method: Method::Relief,
            params: MethodParams::default(),
            scene: Scene::default(),
            shadows: ShadowSettings::default(),
        };
        ViewState {
            bound: crate::view::budget::Bound {
                limit: None,
                given: false,
            },
            maps: Vec::new(),
            map: 0,
            assets: SceneAssets::default(),
            materials: Vec::new(),
            settings,
            steps: None,
            right,
            divider: 0.5,
            compare,
            show_b: true,
            heatmap: false,
            home: settings.scene.camera,
            panel: true,
            help: false,
        }
    }

    fn part(side: usize, src_x0: u32, src_x1: u32, dst_x: u32) -> Part {
        Part {
            side,
            src_x0,
            src_x1,
            dst_x,
        }
    }

    #[test]
    fn each_compare_mode_lays_out_its_sides() {
        let frame = [100, 40];
        let (size, l) = frame_layout(&state(None, Compare::Wipe), frame, 0);
        assert!(!l.has_gaps());
        assert_eq!((size, l.parts), (frame, vec![part(0, 0, 100, 0)]));
        let (size, l) = frame_layout(&state(Some(Method::Pom), Compare::Wipe), frame, 0);
        assert_eq!(size, frame);
        assert_eq!(l.parts, vec![part(0, 0, 50, 0), part(1, 52, 100, 52)]);
        assert!(l.has_gaps());
        // A/B: the shown side fills the frame, the same pixels as a frame of its own.
        let (size, l) = frame_layout(&state(Some(Method::Pom), Compare::Flip), frame, 0);
        assert_eq!((size, l.parts), (frame, vec![part(1, 0, 100, 0)]));
        // Side by side: each renderer at half the width less the divider.
        let (size, l) = frame_layout(&state(Some(Method::Pom), Compare::SideBySide), frame, 0);
        assert_eq!(size, [49, 40]);
        assert_eq!(l.parts, vec![part(0, 0, 49, 0), part(1, 0, 49, 51)]);
        // Windows too narrow for both halves: no column is written twice.
        for w in 1..8 {
            let (_, l) = frame_layout(&state(Some(Method::Pom), Compare::SideBySide), [w, 40], 0);
            let mut columns = vec![0; w as usize];
            for p in &l.parts {
                for x in p.dst_x..p.dst_x + (p.src_x1 - p.src_x0) {
                    columns[x as usize] += 1;
                }
            }
            assert!(columns.iter().all(|&c| c <= 1), "{w}: {:?}", l.parts);
        }
    }

    #[test]
    fn a_docked_panel_takes_columns_from_every_mode() {
        let frame = [100, 40];
        for compare in [Compare::Wipe, Compare::Flip, Compare::SideBySide] {
            let (size, l) = frame_layout(&state(Some(Method::Pom), compare), frame, 30);
            assert_eq!(l.frame.width, 100, "{compare:?}");
            assert!(size[0] <= 70, "{compare:?}: {size:?}");
            for p in &l.parts {
                assert!(p.dst_x + (p.src_x1 - p.src_x0) <= 70, "{compare:?}: {p:?}");
            }
            assert!(l.has_gaps(), "{compare:?}");
        }
        let (size, l) = frame_layout(&state(Some(Method::Pom), Compare::Wipe), frame, 30);
        assert_eq!(size, [70, 40]);
        assert_eq!(l.parts, vec![part(0, 0, 35, 0), part(1, 37, 70, 37)]);
    }
}
