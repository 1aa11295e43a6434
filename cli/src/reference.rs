//! The CPU reference: the exact first intersection of each pixel's ray with the
//! bilinearly interpolated height field, in `f64`.
//!
//! # Problem
//!
//! The G-buffer gives, per pixel, the entry point `uv0` and the parallax vector `P`; the
//! ray is `uv(h) = uv0 + (1 - h) P`. With the ray parameter `t = 1 - h` in `[0, 1]` the
//! answer is the smallest `t` with
//!
//! ```text
//! f(t) = H(uv0 + t P) - (1 - t) >= 0,
//! ```
//!
//! `H` being the height field interpolated bilinearly between texel centres. The hit is
//! `uv = uv0 + t P`, `height = 1 - t`.
//!
//! # Texel space and cells
//!
//! In texel space `x = u W - 0.5`, `y = v H - 0.5`, so texel `(i, j)` sits at the integer
//! point `(i, j)` and the bilinear *cell* `(i, j) = (floor x, floor y)` is the square
//! `[i, i + 1] x [j, j + 1]` with corner texels `(i, j)`, `(i + 1, j)`, `(i, j + 1)`,
//! `(i + 1, j + 1)`. Indices are wrapped modulo `W`/`H` (`Repeat`) or clamped to the map
//! (`Clamp`) only when a texel is read; the traversal itself runs in unbounded cell
//! coordinates, so a long grazing ray in `Repeat` mode simply crosses many tiles.
//!
//! * `Repeat`: a tile holds `W x H` cells (cell `W - 1` wraps to texel 0). There is
//!   always a hit, since `f(1) = H >= 0`.
//! * `Clamp`: the decal `[0, 1]²` is `[-0.5, W - 0.5] x [-0.5, H - 0.5]` in texel space,
//!   covered by the cells `-1 ..= W - 1` (the half cells at the borders have clamped,
//!   hence equal, corners). A ray whose `uv0` is outside `[0, 1]²`, or that leaves it
//!   (strictly) before its first hit, is a miss (`None`); a hit exactly on the border
//!   counts.
//!
//! # Algorithm
//!
//! 1. **Start high.** Nothing can be hit above the highest texel, so the walk starts at
//!    `t0 = max(0, 1 - max H)`; for grazing rays this skips most of the ray.
//! 2. **Max pyramid.** Level 0 holds, per cell, the maximum of its 4 corner texels (an
//!    exact bound of the bilinear patch). Level `L` node `n` covers the level-0 cells
//!    `[n 2^L, (n + 1) 2^L)` of one tile (clamped to the tile, so odd sizes are exact, not
//!    just conservative); the top level is one node per tile. Nodes never straddle a
//!    tile.
//! 3. **Traversal** (maximum-mipmap style, Tevs et al. 2008). The state is `t`, the
//!    integer cell containing `uv(t)` and a level. The node of the current level that
//!    contains the cell is tested: the ray's height decreases along the ray, so its
//!    lowest height inside the node is `1 - t_exit` at the node's exit. If that is above
//!    the node's maximum the whole node is skipped (`t = t_exit`, the cell steps across
//!    the exit face, the level goes up by one); otherwise the level goes down; at level
//!    0 the cell is solved exactly and, without a hit, skipped the same way.
//! 4. **Cell solve.** Along the ray inside a cell the bilinear patch is a quadratic in
//!    `s = t - t_in`: `f = A s² + B s + C` on `[0, t_out - t_in]`. If `C >= 0` the hit is
//!    `t_in`. Otherwise the interval is split at the parabola's vertex into monotone
//!    pieces; the first piece whose end has `f >= 0` holds exactly one (increasing)
//!    crossing, given by the stable form of `(-B + sqrt(B² - 4AC)) / 2A` (the
//!    "citardauq" form `2C / (-B - sqrt(..))` when `B >= 0`, which also covers the
//!    linear case `A = 0`). If rounding puts that root outside the piece (or the
//!    discriminant is negative by rounding) the bracketed root is found by bisection.
//!
//! # Termination and cost
//!
//! Each skip moves the cell index by at least one cell along an axis, in the direction
//! of the ray only, so there are at most `|Δx| + |Δy| + 4` skips (`Δ` the ray's extent in
//! texels), each preceded by at most `levels` descents. The loop is capped at twice that
//! bound; the cap can only be reached through a bug and then yields `None`. Cost grows
//! with the number of cells the ray crosses *below* the local maxima, so it stays small
//! for grazing rays. Rays with non-finite components, or that span more than `2^40`
//! texels (far beyond any G-buffer's bounded `P`), are rejected with `None`.

use dispmap::heightfield::{Addressing, HeightField};
use rayon::prelude::*;

/// Rays longer than this (in texels, per axis, including the start offset) are rejected:
/// cell indices and positions must stay exactly representable.
const MAX_TEXEL_EXTENT: f64 = (1u64 << 40) as f64;

pub use dispmap::passes::shadow::{SHADOW_BIAS, SHADOW_MIN_COS};

pub use dispmap::passes::gbuffer::Ray;

/// The exact first intersection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Hit point in UV units (`uv0 + t P`, not wrapped).
    pub uv: [f64; 2],
    /// Hit height `1 - t` in `[0, 1]`.
    pub height: f64,
}

/// One level of the max pyramid: the maximum height per node of one tile.
#[derive(Clone, Debug)]
struct Level {
    /// Nodes per row.
    width: usize,
    /// Node values, row by row (`f32`: each is one texel's value, which `f32` holds
    /// exactly; widened to `f64` where read).
    max: Vec<f32>,
}

/// Exact CPU intersection of rays with one height field under one addressing mode.
///
/// Built once per (height field, addressing): holds a copy of the texels and the cell max
/// pyramid described in the [module documentation](self), both stored as `f32` (the
/// height field's own precision, so every stored value is exact) and widened to `f64`
/// where read: all arithmetic is `f64`, and the results are those of `f64` storage bit
/// for bit, in about half its memory (see [`Reference::memory_bytes`]).
#[derive(Clone)]
pub struct Reference {
    /// Texels per row / column.
    size: [usize; 2],
    /// Texels, row by row.
    texels: Vec<f32>,
    addressing: Addressing,
    /// Cells per tile and axis at level 0: `W, H` (repeat) or `W + 1, H + 1` (clamp).
    cells: [i64; 2],
    /// Index of the first cell of tile 0: `0` (repeat) or `-1` (clamp).
    first_cell: i64,
    /// Level 0 (cells) up to the top level (one node per tile).
    levels: Vec<Level>,
    /// The highest texel.
    global_max: f64,
}

impl std::fmt::Debug for Reference {
    /// A summary: the texels and the pyramid are not printed.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Reference")
            .field("size", &self.size)
            .field("addressing", &self.addressing)
            .field("levels", &self.levels.len())
            .field("global_max", &self.global_max)
            .finish_non_exhaustive()
    }
}

impl Reference {
    /// Copies the texels of `field` and builds the max pyramid.
    pub fn new(field: &HeightField, addressing: Addressing) -> Self {
        let (w, h) = (field.width() as usize, field.height() as usize);
        let texels: Vec<f32> = (0..field.height())
            .flat_map(|j| (0..field.width()).map(move |i| (i, j)))
            .map(|(i, j)| field.texel(i, j))
            .collect();
        let (cells, first_cell) = match addressing {
            Addressing::Repeat => ([w as i64, h as i64], 0),
            Addressing::Clamp => ([w as i64 + 1, h as i64 + 1], -1),
        };
        let mut reference = Reference {
            size: [w, h],
            texels,
            addressing,
            cells,
            first_cell,
            levels: Vec::new(),
            global_max: 0.0,
        };
        reference.global_max = reference
            .texels
            .iter()
            .map(|&t| f64::from(t))
            .fold(0.0, f64::max);
        reference.build_pyramid();
        reference
    }

    /// The bytes a reference for a `width` x `height` map holds: the texels and the max
    /// pyramid (level 0 has one node per cell, `(W + 1) (H + 1)` at most; each coarser
    /// level a quarter of the one below, so 4/3 of level 0 in all, plus one node per
    /// level for rounding up), 4 bytes each.
    pub fn memory_bytes(width: u32, height: u32) -> u64 {
        let (w, h) = (u64::from(width), u64::from(height));
        let cells = (w + 1) * (h + 1);
        let levels = 2 + u64::from(32 - width.max(height).leading_zeros());
        4 * (w * h + cells * 4 / 3 + levels * (w + h + 2))
    }

    /// Level 0 = max of each cell's corners; each coarser level the max of its (up to)
    /// 2x2 children, until one node covers the tile.
    fn build_pyramid(&mut self) {
        let (cw, ch) = (self.cells[0] as usize, self.cells[1] as usize);
        let mut max = Vec::with_capacity(cw * ch);
        for ly in 0..ch {
            for lx in 0..cw {
                let (ci, cj) = (lx as i64 + self.first_cell, ly as i64 + self.first_cell);
                let corners = self.corners(ci, cj);
                // The max of exact f32 values is one of them: exact in f32.
                max.push(corners.iter().copied().fold(f64::MIN, f64::max) as f32);
            }
        }
        let mut levels = vec![Level { width: cw, max }];
        let (mut w, mut h) = (cw, ch);
        while w > 1 || h > 1 {
            let (pw, ph) = (w.div_ceil(2), h.div_ceil(2));
            let child = &levels[levels.len() - 1];
            let mut max = Vec::with_capacity(pw * ph);
            for py in 0..ph {
                for px in 0..pw {
                    let mut m = f32::MIN;
                    for y in (2 * py)..(2 * py + 2).min(h) {
                        for x in (2 * px)..(2 * px + 2).min(w) {
                            m = m.max(child.max[y * w + x]);
                        }
                    }
                    max.push(m);
                }
            }
            levels.push(Level { width: pw, max });
            (w, h) = (pw, ph);
        }
        self.levels = levels;
    }

    /// The texel at unbounded indices, wrapped or clamped by the addressing mode.
    #[inline]
    fn texel(&self, i: i64, j: i64) -> f64 {
        let (w, h) = (self.size[0] as i64, self.size[1] as i64);
        let (i, j) = match self.addressing {
            Addressing::Repeat => (i.rem_euclid(w), j.rem_euclid(h)),
            Addressing::Clamp => (i.clamp(0, w - 1), j.clamp(0, h - 1)),
        };
        f64::from(self.texels[j as usize * self.size[0] + i as usize])
    }

    /// Corner texels `[h00, h10, h01, h11]` of cell `(ci, cj)`.
    #[inline]
    fn corners(&self, ci: i64, cj: i64) -> [f64; 4] {
        [
            self.texel(ci, cj),
            self.texel(ci + 1, cj),
            self.texel(ci, cj + 1),
            self.texel(ci + 1, cj + 1),
        ]
    }

    /// The bilinear height at `uv` (unbounded UV, the reference's addressing), in `f64`.
    pub fn height(&self, uv: [f64; 2]) -> f64 {
        let x = uv[0] * self.size[0] as f64 - 0.5;
        let y = uv[1] * self.size[1] as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let [h00, h10, h01, h11] = self.corners(x0 as i64, y0 as i64);
        let top = h00 + (h10 - h00) * fx;
        let bottom = h01 + (h11 - h01) * fx;
        top + (bottom - top) * fy
    }

    /// How far the surface rises above `ray` at its parameter `t` (`t = 1 - h`):
    /// `H(uv0 + t P) - (1 - t)`; `>= 0` on or below the surface.
    pub fn penetration(&self, ray: &Ray, t: f64) -> f64 {
        let uv = [
            ray.uv0[0] + t * ray.parallax[0],
            ray.uv0[1] + t * ray.parallax[1],
        ];
        self.height(uv) - (1.0 - t)
    }

    /// The exact first intersection of `ray`, or `None` for a clamp-mode miss (and for
    /// rays with non-finite components or an absurd extent, see the module docs).
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let t = self.first_hit(ray)?;
        Some(Hit {
            uv: [
                ray.uv0[0] + t * ray.parallax[0],
                ray.uv0[1] + t * ray.parallax[1],
            ],
            height: 1.0 - t,
        })
    }

    /// [`Reference::intersect`] for every pixel, in parallel (rayon); a pixel without a
    /// ray (no geometry) gives `None`.
    pub fn trace(&self, rays: &[Option<Ray>]) -> Vec<Option<Hit>> {
        rays.par_iter()
            .map(|ray| ray.as_ref().and_then(|r| self.intersect(r)))
            .collect()
    }

    /// Self-shadowing: whether the surface point `(uv, height)` is hidden from a
    /// directional light whose tangent-space direction (towards the light) is `light_ts`
    /// (`z` along the macro normal), the displacement being `depth_scale` tiles deep.
    ///
    /// * `light_ts.z <= 0` (the macro surface faces away from the light): occluded.
    /// * Otherwise the light ray climbs from the point to the macro surface: going up by
    ///   `dh` (heights, depth 1) moves it by `dh * depth_scale * L.xy / L.z` in UV (one
    ///   UV unit is one tile, the depth of height `h` is `(1 - h) * depth_scale` tiles),
    ///   `L.z` taken at least [`SHADOW_MIN_COS`]. The point is occluded when the bilinear
    ///   surface reaches the ray anywhere on its part from `height + SHADOW_BIAS` up to
    ///   `h = 1` (clamp mode: the part inside the decal; outside it there is no surface).
    ///
    /// Reversed, the light ray is a view ray entering the macro surface at
    /// `uv + (1 - height) C` with parallax `-C` (`C` the climb per unit height), so this
    /// is the exact first-hit search of [`Reference::intersect`] over `t` in
    /// `[0, 1 - height - SHADOW_BIAS]`. The GPU's `shadow` pass (hard mode with the
    /// pyramid methods) answers the same question in `f32`.
    pub fn occluded(
        &self,
        uv: [f64; 2],
        height: f64,
        light_ts: [f64; 3],
        depth_scale: f64,
    ) -> bool {
        // Facing away, or a NaN component: in shadow.
        if light_ts[2].partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return true;
        }
        let cos = light_ts[2].max(SHADOW_MIN_COS);
        let climb = [
            depth_scale * light_ts[0] / cos,
            depth_scale * light_ts[1] / cos,
        ];
        let rise = 1.0 - height;
        let t_stop = rise - SHADOW_BIAS;
        // Within the bias of the macro surface (or a NaN height): nothing above it.
        if t_stop.is_nan() || t_stop < 0.0 {
            return false;
        }
        let ray = Ray {
            uv0: [uv[0] + rise * climb[0], uv[1] + rise * climb[1]],
            parallax: [-climb[0], -climb[1]],
        };
        self.segment_hit(&ray, t_stop).is_some()
    }

    /// The ray parameter `t` of the first hit.
    fn first_hit(&self, ray: &Ray) -> Option<f64> {
        if self.addressing == Addressing::Clamp && !ray.uv0.iter().all(|u| (0.0..=1.0).contains(u))
        {
            return None;
        }
        self.segment_hit(ray, 1.0)
    }

    /// The first `t` in `[0, t_stop]` where `ray` meets the surface, over the part of the
    /// ray that crosses the height field: in clamp mode a ray starting outside the decal
    /// enters it further on (the light rays of [`Reference::occluded`]); for a ray
    /// starting inside the clip changes nothing.
    fn segment_hit(&self, ray: &Ray, t_stop: f64) -> Option<f64> {
        let dims = [self.size[0] as f64, self.size[1] as f64];
        // Texel space: x(t) = origin + t dir.
        let origin = [ray.uv0[0] * dims[0] - 0.5, ray.uv0[1] * dims[1] - 0.5];
        let dir = [ray.parallax[0] * dims[0], ray.parallax[1] * dims[1]];
        // Non-finite values fail this test too (NaN compares false, inf is too long).
        let bounded = (0..2).all(|a| origin[a].abs() + dir[a].abs() <= MAX_TEXEL_EXTENT);
        if !bounded {
            return None;
        }

        // Where the ray starts and ends: [0, t_stop], clipped to the decal.
        let mut t_begin: f64 = 0.0;
        let mut t_end: f64 = t_stop;
        if self.addressing == Addressing::Clamp {
            for a in 0..2 {
                let (lo, hi) = (-0.5, dims[a] - 0.5);
                if dir[a] > 0.0 {
                    t_begin = t_begin.max((lo - origin[a]) / dir[a]);
                    t_end = t_end.min((hi - origin[a]) / dir[a]);
                } else if dir[a] < 0.0 {
                    t_begin = t_begin.max((hi - origin[a]) / dir[a]);
                    t_end = t_end.min((lo - origin[a]) / dir[a]);
                } else if !(lo..=hi).contains(&origin[a]) {
                    return None;
                }
            }
            t_end = t_end.max(0.0);
        }
        // Nothing can be hit above the highest texel.
        let t0 = (1.0 - self.global_max).max(t_begin);
        if t0 > t_end {
            return None;
        }

        let top = self.levels.len() - 1;
        let mut t = t0;
        let mut cell = [0i64; 2];
        for a in 0..2 {
            cell[a] = self.clamp_cell(a, cell_at(origin[a] + t * dir[a], dir[a]));
        }
        let mut level = top;

        // Each skip advances a cell index by >= 1 in the ray's direction; each skip is
        // preceded by at most `top` descents (see the module docs).
        let span = dir[0].abs() + dir[1].abs() + 4.0;
        let cap = 2.0 * (top as f64 + 2.0) * span + 16.0;
        let mut steps = 0.0;
        while steps < cap {
            steps += 1.0;
            let mut range = [(0i64, 0i64); 2];
            let mut node = [0usize; 2];
            for a in 0..2 {
                let (lo, hi, n) = self.node_range(a, cell[a], level);
                range[a] = (lo, hi);
                node[a] = n;
            }
            let lv = &self.levels[level];
            let node_max = f64::from(lv.max[node[1] * lv.width + node[0]]);

            // Exit of the node along each axis.
            let mut exit = [f64::INFINITY; 2];
            for a in 0..2 {
                if dir[a] > 0.0 {
                    exit[a] = (range[a].1 as f64 - origin[a]) / dir[a];
                } else if dir[a] < 0.0 {
                    exit[a] = (range[a].0 as f64 - origin[a]) / dir[a];
                }
            }
            let t_exit = exit[0].min(exit[1]).min(t_end).max(t);

            if 1.0 - t_exit > node_max {
                // The ray stays above everything in the node: skip it.
            } else if level > 0 {
                level -= 1;
                continue;
            } else if let Some(hit) = self.cell_hit(cell, origin, dir, t, t_exit) {
                return Some(hit);
            }

            if t_exit >= t_end {
                // At t = 1 the ray is at h = 0 <= H: it always hits there (rounding may
                // have hidden the root in the last cell).
                return (t_end >= 1.0).then_some(1.0);
            }
            // Step into the next node: across the exit face(s), and recompute the other
            // axis inside the node's range (it may have moved within the node).
            for a in 0..2 {
                let other = exit[1 - a];
                cell[a] = if exit[a] <= other {
                    if dir[a] > 0.0 {
                        range[a].1
                    } else {
                        range[a].0 - 1
                    }
                } else {
                    cell_at(origin[a] + t_exit * dir[a], dir[a]).clamp(range[a].0, range[a].1 - 1)
                };
            }
            if self.addressing == Addressing::Clamp
                && (0..2).any(|a| {
                    cell[a] < self.first_cell || cell[a] >= self.first_cell + self.cells[a]
                })
            {
                // Left the decal (only reachable through rounding at the border).
                return None;
            }
            t = t_exit;
            level = (level + 1).min(top);
        }
        None
    }

    /// Clamp mode: keeps a start cell inside the decal's cells.
    fn clamp_cell(&self, axis: usize, cell: i64) -> i64 {
        match self.addressing {
            Addressing::Repeat => cell,
            Addressing::Clamp => {
                cell.clamp(self.first_cell, self.first_cell + self.cells[axis] - 1)
            }
        }
    }

    /// The cells `[lo, hi)` along `axis` covered by the level-`level` node containing
    /// `cell`, and that node's index within its level.
    #[inline]
    fn node_range(&self, axis: usize, cell: i64, level: usize) -> (i64, i64, usize) {
        let n_cells = self.cells[axis];
        let (base, local) = match self.addressing {
            Addressing::Repeat => (cell.div_euclid(n_cells) * n_cells, cell.rem_euclid(n_cells)),
            Addressing::Clamp => (
                self.first_cell,
                (cell - self.first_cell).clamp(0, n_cells - 1),
            ),
        };
        let node = local >> level;
        let lo = base + (node << level);
        let hi = base + ((node + 1) << level).min(n_cells);
        (lo, hi, node as usize)
    }

    /// The first `t` in `[t_in, t_out]` where the ray meets the bilinear patch of `cell`.
    fn cell_hit(
        &self,
        cell: [i64; 2],
        origin: [f64; 2],
        dir: [f64; 2],
        t_in: f64,
        t_out: f64,
    ) -> Option<f64> {
        let [h00, h10, h01, h11] = self.corners(cell[0], cell[1]);
        // Local coordinates of the entry point in the cell.
        let fx = origin[0] + t_in * dir[0] - cell[0] as f64;
        let fy = origin[1] + t_in * dir[1] - cell[1] as f64;
        // H = h00 + a fx + b fy + c fx fy, with fx = fx_in + dx s, fy = fy_in + dy s.
        let a = h10 - h00;
        let b = h01 - h00;
        let c = h00 - h10 - h01 + h11;
        let qa = c * dir[0] * dir[1];
        let qb = a * dir[0] + b * dir[1] + c * (fx * dir[1] + fy * dir[0]) + 1.0;
        // The height at the entry in nested-lerp form, which is exact at texel centres,
        // along edges between equal texels and on plateaus (so ties `f = 0` are kept).
        let top = h00 + (h10 - h00) * fx;
        let bottom = h01 + (h11 - h01) * fx;
        let qc = top + (bottom - top) * fy - (1.0 - t_in);
        first_root(qa, qb, qc, t_out - t_in).map(|s| (t_in + s).min(t_out))
    }
}

/// The cell containing coordinate `x` for a ray moving with `dir` along that axis: on an
/// exact boundary a ray moving backwards is in the cell behind it.
#[inline]
fn cell_at(x: f64, dir: f64) -> i64 {
    let f = x.floor();
    if dir < 0.0 && f == x {
        f as i64 - 1
    } else {
        f as i64
    }
}

/// The smallest `s` in `[0, len]` with `q(s) = a s² + b s + c >= 0`, if any.
fn first_root(a: f64, b: f64, c: f64, len: f64) -> Option<f64> {
    if c >= 0.0 {
        return Some(0.0);
    }
    if len.is_nan() || len <= 0.0 || !(a.is_finite() && b.is_finite() && c.is_finite()) {
        return None;
    }
    let q = |s: f64| (a * s + b) * s + c;
    // Split [0, len] at the vertex into pieces where q is monotone.
    let vertex = if a != 0.0 { -b / (2.0 * a) } else { f64::NAN };
    let mut ends = [len, len];
    if vertex > 0.0 && vertex < len {
        ends[0] = vertex;
    }
    let mut start = 0.0;
    for &end in &ends {
        if end > start && q(end) >= 0.0 {
            // q(start) < 0 <= q(end) and q is monotone: exactly one increasing crossing.
            return Some(increasing_root(a, b, c, start, end));
        }
        start = end;
    }
    None
}

/// The root of `q` in `[l, r]` where it increases through 0, given `q(l) < 0 <= q(r)`.
fn increasing_root(a: f64, b: f64, c: f64, l: f64, r: f64) -> f64 {
    let disc = b * b - 4.0 * a * c;
    if disc >= 0.0 {
        let sq = disc.sqrt();
        // (-b + sq) / 2a without cancellation.
        let root = if b >= 0.0 {
            2.0 * c / (-b - sq)
        } else {
            (-b + sq) / (2.0 * a)
        };
        let tol = 1e-9 * (r - l);
        if root.is_finite() && root >= l - tol && root <= r + tol {
            return root.clamp(l, r);
        }
    }
    // Rounding made the closed form unusable: bisect the bracket.
    let q = |s: f64| (a * s + b) * s + c;
    let (mut lo, mut hi) = (l, r);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if q(mid) >= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// The exact hard-shadow visibility (1 = lit, 0 = shadowed) of reference hits:
/// [`Reference::occluded`] per pixel, with `L_ts` from the G-buffer's `normal` and
/// `tangent` texels (as the pass forms it: `B = w cross(N, T)`) and the frame's world
/// light direction. Pixels without a hit get 1. This is what the renderer shades the
/// reference colour with when hard shadows are on, whatever the method.
pub fn reference_visibility(
    reference: &Reference,
    hits: &[Option<Hit>],
    normal: &[[f32; 4]],
    tangent: &[[f32; 4]],
    light_dir: [f32; 3],
    depth_scale: f32,
) -> Vec<f32> {
    use rayon::prelude::*;
    let l = light_dir.map(f64::from);
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let unit = |v: [f32; 4]| {
        let v = [f64::from(v[0]), f64::from(v[1]), f64::from(v[2])];
        let n = dot(v, v).sqrt();
        v.map(|c| c / n)
    };
    hits.par_iter()
        .zip(normal.par_iter().zip(tangent.par_iter()))
        .map(|(hit, (n4, t4))| {
            let Some(hit) = hit else { return 1.0 };
            if n4[3] == 0.0 {
                // No geometry drawn (a centre-ray hit the rasteriser left empty,
                // `Renderer::reference_rays`): no shading frame, nothing the method shades.
                return 1.0;
            }
            let (n, t) = (unit(*n4), unit(*t4));
            // tangent.w = handedness * (material + 1): its sign is the handedness.
            let w = f64::from(t4[3]).signum();
            let b = [
                w * (n[1] * t[2] - n[2] * t[1]),
                w * (n[2] * t[0] - n[0] * t[2]),
                w * (n[0] * t[1] - n[1] * t[0]),
            ];
            let l_ts = [dot(l, t), dot(l, b), dot(l, n)];
            // The receiver as the pass takes it: the surface under the hit's uv.
            let h = reference.height(hit.uv);
            if reference.occluded(hit.uv, h, l_ts, f64::from(depth_scale)) {
                0.0
            } else {
                1.0
            }
        })
        .collect()
}

#[cfg(test)]
mod tests;
