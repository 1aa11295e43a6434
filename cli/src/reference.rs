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
mod tests {
    use super::*;

    /// SplitMix64: a small deterministic generator for test data.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }

        /// Uniform in `[lo, hi)`.
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * ((self.next() >> 11) as f64 / (1u64 << 53) as f64)
        }
    }

    fn random_field(w: u32, h: u32, lo: f32, hi: f32, rng: &mut Rng) -> HeightField {
        let values = (0..w * h)
            .map(|_| rng.range(lo as f64, hi as f64) as f32)
            .collect();
        HeightField::from_heights(w, h, values, "random").unwrap()
    }

    /// Independent bilinear evaluation at `uv` (no cells, no pyramid).
    fn bilinear(field: &HeightField, addressing: Addressing, uv: [f64; 2]) -> f64 {
        let (w, h) = (field.width() as i64, field.height() as i64);
        let x = uv[0] * w as f64 - 0.5;
        let y = uv[1] * h as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let fetch = |i: i64, j: i64| {
            let (i, j) = match addressing {
                Addressing::Repeat => (i.rem_euclid(w), j.rem_euclid(h)),
                Addressing::Clamp => (i.clamp(0, w - 1), j.clamp(0, h - 1)),
            };
            field.texel(i as u32, j as u32) as f64
        };
        let (i, j) = (x0 as i64, y0 as i64);
        let top = fetch(i, j) * (1.0 - fx) + fetch(i + 1, j) * fx;
        let bottom = fetch(i, j + 1) * (1.0 - fx) + fetch(i + 1, j + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// Brute force: dense sampling of `f(t)` from `t = 0`, then bisection of the first
    /// sign change. Returns `t`.
    fn brute_force(field: &HeightField, addressing: Addressing, ray: &Ray) -> Option<f64> {
        let uv = |t: f64| {
            [
                ray.uv0[0] + t * ray.parallax[0],
                ray.uv0[1] + t * ray.parallax[1],
            ]
        };
        let f = |t: f64| bilinear(field, addressing, uv(t)) - (1.0 - t);
        let mut t_end: f64 = 1.0;
        if addressing == Addressing::Clamp {
            if ray.uv0.iter().any(|u| !(0.0..=1.0).contains(u)) {
                return None;
            }
            for a in 0..2 {
                let p = ray.parallax[a];
                if p > 0.0 {
                    t_end = t_end.min((1.0 - ray.uv0[a]) / p);
                } else if p < 0.0 {
                    t_end = t_end.min(-ray.uv0[a] / p);
                }
            }
        }
        if f(0.0) >= 0.0 {
            return Some(0.0);
        }
        let n = 100_000;
        let mut prev = 0.0;
        for k in 1..=n {
            let t = t_end * k as f64 / n as f64;
            if f(t) >= 0.0 {
                let (mut lo, mut hi) = (prev, t);
                for _ in 0..100 {
                    let mid = 0.5 * (lo + hi);
                    if f(mid) >= 0.0 {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                return Some(hi);
            }
            prev = t;
        }
        None
    }

    fn t_of(hit: &Hit) -> f64 {
        1.0 - hit.height
    }

    fn assert_hit(hit: Option<Hit>, ray: &Ray, t: f64, tol: f64) {
        let hit = hit.unwrap_or_else(|| panic!("no hit for {ray:?}, expected t = {t}"));
        assert!(
            (t_of(&hit) - t).abs() <= tol,
            "{ray:?}: t = {} expected {t}",
            t_of(&hit)
        );
        for a in 0..2 {
            let u = ray.uv0[a] + t * ray.parallax[a];
            assert!(
                (hit.uv[a] - u).abs() <= tol * (1.0 + ray.parallax[a].abs()),
                "{ray:?}: uv {:?}, expected {u} on axis {a}",
                hit.uv
            );
        }
    }

    #[test]
    fn flat_map_hits_at_its_height() {
        let h0 = 0.37f32;
        let field = HeightField::from_heights(8, 6, vec![h0; 48], "flat").unwrap();
        let h0 = h0 as f64;
        let repeat = Reference::new(&field, Addressing::Repeat);
        let clamp = Reference::new(&field, Addressing::Clamp);
        let parallaxes = [
            [0.0, 0.0],
            [0.3, 0.1],
            [-0.2, 0.45],
            [1.0, -1.0],
            [37.5, -12.25],
            [1e3, -7e2],
            [-6e3, 8e3],
        ];
        let starts = [[0.5, 0.5], [0.0, 0.0], [1.0, 0.25], [0.123, 0.987]];
        for p in parallaxes {
            for uv0 in starts {
                let ray = Ray { uv0, parallax: p };
                let hit = repeat.intersect(&ray).unwrap();
                assert!((hit.height - h0).abs() < 1e-12, "{ray:?}: {hit:?}");
                assert_hit(Some(hit), &ray, 1.0 - h0, 1e-12);
                let end = [uv0[0] + (1.0 - h0) * p[0], uv0[1] + (1.0 - h0) * p[1]];
                let inside = end.iter().all(|u| (0.0..=1.0).contains(u));
                match clamp.intersect(&ray) {
                    Some(hit) => {
                        assert!(inside, "{ray:?} should leave the decal");
                        assert!((hit.height - h0).abs() < 1e-12, "{ray:?}: {hit:?}");
                    }
                    None => assert!(!inside, "{ray:?} should hit"),
                }
            }
        }
    }

    #[test]
    fn linear_ramp_has_the_closed_form_hit() {
        // h_i = (1 + i) / 32 (exact in f32): between the first and last texel centres the
        // bilinear surface is exactly H(x) = (1 + x) / 32.
        let (w, h) = (16u32, 4u32);
        let values = (0..w * h).map(|k| (1 + k % w) as f32 / 32.0).collect();
        let field = HeightField::from_heights(w, h, values, "ramp").unwrap();
        let reference = Reference::new(&field, Addressing::Clamp);
        let rays = [
            Ray {
                uv0: [0.5, 0.5],
                parallax: [-0.3, 0.05],
            },
            Ray {
                uv0: [0.5, 0.3],
                parallax: [0.2, 0.1],
            },
            Ray {
                uv0: [0.8, 0.6],
                parallax: [-0.45, -0.2],
            },
            Ray {
                uv0: [0.2, 0.4],
                parallax: [0.6, 0.0],
            },
        ];
        for ray in rays {
            let x0 = ray.uv0[0] * w as f64 - 0.5;
            let dx = ray.parallax[0] * w as f64;
            // (1 + x0 + t dx) / 32 = 1 - t.
            let t = (31.0 - x0) / (32.0 + dx);
            let x = x0 + t * dx;
            assert!(
                (0.0..=(w - 1) as f64).contains(&x),
                "{ray:?} leaves the ramp"
            );
            assert_hit(reference.intersect(&ray), &ray, t, 1e-12);
        }
    }

    #[test]
    fn step_edge_is_hit_on_the_wall() {
        // Left half 0.25, right half 0.75: between the texel centres x = 3 and x = 4 the
        // surface is the wall H(x) = 0.25 + 0.5 (x - 3).
        let (w, h) = (8u32, 2u32);
        let values = (0..w * h)
            .map(|k| if k % w < w / 2 { 0.25 } else { 0.75 })
            .collect();
        let field = HeightField::from_heights(w, h, values, "step").unwrap();
        for addressing in [Addressing::Clamp, Addressing::Repeat] {
            let reference = Reference::new(&field, addressing);
            for (x0, dx) in [(1.0, 5.0), (0.5, 4.0), (0.0, 4.5)] {
                let ray = Ray {
                    uv0: [(x0 + 0.5) / w as f64, 0.5],
                    parallax: [dx / w as f64, 0.0],
                };
                // 0.25 + 0.5 (x0 + t dx - 3) = 1 - t.
                let t = (0.75 + 0.5 * (3.0 - x0)) / (1.0 + 0.5 * dx);
                let x = x0 + t * dx;
                assert!((3.0..=4.0).contains(&x), "{ray:?}: x = {x} not on the wall");
                assert!(
                    1.0 - t > 0.25 + 1e-3,
                    "the plateau must not be reached first"
                );
                assert_hit(reference.intersect(&ray), &ray, t, 1e-12);
            }
        }
    }

    #[test]
    fn vertical_ray_hits_below_its_entry() {
        let mut rng = Rng(7);
        let field = random_field(9, 7, 0.0, 1.0, &mut rng);
        for addressing in [Addressing::Repeat, Addressing::Clamp] {
            let reference = Reference::new(&field, addressing);
            for _ in 0..200 {
                let uv0 = [rng.range(0.0, 1.0), rng.range(0.0, 1.0)];
                let ray = Ray {
                    uv0,
                    parallax: [0.0, 0.0],
                };
                let expected = bilinear(&field, addressing, uv0);
                let hit = reference.intersect(&ray).unwrap();
                assert!(
                    (hit.height - expected).abs() < 1e-12,
                    "{ray:?}: {hit:?} vs {expected}"
                );
                assert_eq!(hit.uv, uv0);
            }
        }
    }

    #[test]
    fn clamp_discards_a_ray_that_leaves_and_repeat_wraps_it() {
        let field = HeightField::from_heights(4, 4, vec![0.25; 16], "flat").unwrap();
        let clamp = Reference::new(&field, Addressing::Clamp);
        let repeat = Reference::new(&field, Addressing::Repeat);
        let ray = Ray {
            uv0: [0.875, 0.5],
            parallax: [1.0, 0.0],
        };
        assert_eq!(clamp.intersect(&ray), None);
        let hit = repeat.intersect(&ray).unwrap();
        assert_eq!(
            hit,
            Hit {
                uv: [1.625, 0.5],
                height: 0.25
            }
        );
        // An entry outside the decal is a miss in clamp mode only.
        let outside = Ray {
            uv0: [1.2, 0.5],
            parallax: [0.0, 0.0],
        };
        assert_eq!(clamp.intersect(&outside), None);
        assert!(repeat.intersect(&outside).is_some());
        // A hit exactly on the border counts.
        let border = Ray {
            uv0: [0.25, 0.5],
            parallax: [1.0, 0.0],
        };
        assert_eq!(
            clamp.intersect(&border),
            Some(Hit {
                uv: [1.0, 0.5],
                height: 0.25
            })
        );
    }

    #[test]
    fn agrees_with_brute_force_on_random_maps() {
        let mut rng = Rng(42);
        for (w, h) in [(7u32, 5u32), (16, 16), (1, 3), (1, 1)] {
            let field = random_field(w, h, 0.0, 1.0, &mut rng);
            for addressing in [Addressing::Repeat, Addressing::Clamp] {
                let reference = Reference::new(&field, addressing);
                let mut hits = 0;
                for k in 0..150 {
                    let scale = [0.05, 0.5, 3.0][k % 3];
                    let ray = Ray {
                        uv0: [rng.range(0.0, 1.0), rng.range(0.0, 1.0)],
                        parallax: [rng.range(-scale, scale), rng.range(-scale, scale)],
                    };
                    let exact = reference.intersect(&ray);
                    let brute = brute_force(&field, addressing, &ray);
                    match (exact, brute) {
                        (Some(hit), Some(t)) => {
                            hits += 1;
                            assert_hit(Some(hit), &ray, t, 1e-9);
                            let surface = bilinear(&field, addressing, hit.uv);
                            assert!((surface - hit.height).abs() < 1e-9 || t == 0.0);
                        }
                        (None, None) => {}
                        other => panic!("{w}x{h} {addressing:?} {ray:?}: {other:?}"),
                    }
                }
                assert!(hits > 30, "{w}x{h} {addressing:?}: only {hits} hits");
            }
        }
    }

    #[test]
    fn grazing_rays_stay_finite() {
        let mut rng = Rng(3);
        let field = random_field(16, 16, 0.0, 0.9, &mut rng);
        // Mostly flat at 0 with a single spike: the ray descends through many tiles.
        let mut spike = vec![0.0f32; 256];
        spike[5 * 16 + 9] = 0.9;
        let spike = HeightField::from_heights(16, 16, spike, "spike").unwrap();
        for field in [field, spike] {
            let reference = Reference::new(&field, Addressing::Repeat);
            for parallax in [[8e3, 6e3], [-1e4, 0.0], [0.0, 1e4], [-7071.0, -7071.0]] {
                let ray = Ray {
                    uv0: [0.25, 0.75],
                    parallax,
                };
                let hit = reference.intersect(&ray).unwrap();
                assert!(hit.height.is_finite() && hit.uv.iter().all(|u| u.is_finite()));
                assert!((0.0..=0.9).contains(&hit.height), "{hit:?}");
                // The hit lies on the surface (or at the very bottom).
                let surface = bilinear(&field, Addressing::Repeat, hit.uv);
                assert!(surface >= hit.height - 1e-6, "{hit:?} below {surface}");
            }
            let clamp = Reference::new(&field, Addressing::Clamp);
            let ray = Ray {
                uv0: [0.5, 0.5],
                parallax: [1e4, 3.0],
            };
            assert_eq!(clamp.intersect(&ray), None);
        }
    }

    #[test]
    fn non_finite_rays_are_rejected() {
        let field = HeightField::from_heights(2, 2, vec![0.5; 4], "flat").unwrap();
        let reference = Reference::new(&field, Addressing::Repeat);
        for ray in [
            Ray {
                uv0: [f64::NAN, 0.0],
                parallax: [0.0, 0.0],
            },
            Ray {
                uv0: [0.0, 0.0],
                parallax: [f64::INFINITY, 0.0],
            },
            Ray {
                uv0: [0.0, 0.0],
                parallax: [1e300, 0.0],
            },
        ] {
            assert_eq!(reference.intersect(&ray), None);
        }
        let traced = reference.trace(&[
            None,
            Some(Ray {
                uv0: [0.5, 0.5],
                parallax: [0.0, 0.0],
            }),
        ]);
        assert_eq!(traced[0], None);
        assert!((traced[1].unwrap().height - 0.5).abs() < 1e-12);
    }

    /// Unit light direction (towards the light) from `(x, y, z)`.
    fn light(x: f64, y: f64, z: f64) -> [f64; 3] {
        let n = (x * x + y * y + z * z).sqrt();
        [x / n, y / n, z / n]
    }

    #[test]
    fn a_flat_map_never_shadows_itself() {
        let mut rng = Rng(11);
        let field = HeightField::from_heights(8, 8, vec![0.4; 64], "flat").unwrap();
        for addressing in [Addressing::Repeat, Addressing::Clamp] {
            let reference = Reference::new(&field, addressing);
            for _ in 0..300 {
                let uv = [rng.range(0.0, 1.0), rng.range(0.0, 1.0)];
                let l = light(
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(1e-3, 1.0),
                );
                assert!(!reference.occluded(uv, 0.4, l, 0.1), "{uv:?} {l:?}");
                // The macro surface facing away from the light: shadowed.
                assert!(reference.occluded(uv, 0.4, [l[0], l[1], -l[2]], 0.1));
            }
            assert!(reference.occluded([0.5, 0.5], 0.4, [1.0, 0.0, 0.0], 0.1));
        }
    }

    /// Left half 0.25, right half 0.75 (16 x 2): the wall rises between the texel
    /// centres x = 7 and x = 8.
    fn wall() -> HeightField {
        let values = (0..32)
            .map(|k| if k % 16 < 8 { 0.25 } else { 0.75 })
            .collect();
        HeightField::from_heights(16, 2, values, "wall").unwrap()
    }

    #[test]
    fn a_wall_shadows_the_side_behind_it_only() {
        // Light towards +x with L.z / L.x = 0.2 and depth 0.1: the climb is 0.5 uv =
        // 8 texels per unit height. From (x_p, 0.25) the ray reaches 0.75 at x_p + 4, so
        // it is blocked by the wall exactly when x_p > 4 (x_p = 4 grazes its top edge).
        let field = wall();
        let towards_wall = light(1.0, 0.0, 0.2);
        let away = light(-1.0, 0.0, 0.2);
        for addressing in [Addressing::Repeat, Addressing::Clamp] {
            let reference = Reference::new(&field, addressing);
            let uv = |x: f64| [(x + 0.5) / 16.0, 0.5];
            for x in [1.0, 2.0, 3.0, 3.9] {
                assert!(
                    !reference.occluded(uv(x), 0.25, towards_wall, 0.1),
                    "{addressing:?} x = {x} is lit over the wall"
                );
            }
            for x in [4.1, 5.0, 6.0, 6.9] {
                assert!(
                    reference.occluded(uv(x), 0.25, towards_wall, 0.1),
                    "{addressing:?} x = {x} is behind the wall"
                );
            }
            // The top plateau is lit from both sides.
            for x in [8.5, 10.0, 14.0] {
                assert!(!reference.occluded(uv(x), 0.75, towards_wall, 0.1));
                assert!(!reference.occluded(uv(x), 0.75, away, 0.1));
            }
        }
        // Light from the other side over the low plateau (clamp: no wrap to the wall
        // of the next tile): lit; the wall's face towards the light: lit.
        let clamp = Reference::new(&field, Addressing::Clamp);
        for x in [1.0, 4.0, 6.9] {
            assert!(!clamp.occluded([(x + 0.5) / 16.0, 0.5], 0.25, away, 0.1));
        }
        let face = 0.25 + 0.5 * 0.5; // x = 7.5, on the wall
        assert!(!clamp.occluded([8.0 / 16.0, 0.5], face, away, 0.1));
        // Its back, seen from the light on the +x side: in its own shadow.
        assert!(clamp.occluded([8.0 / 16.0, 0.5], face, towards_wall, 0.1));
    }

    #[test]
    fn a_clamp_light_ray_enters_the_decal_from_outside() {
        // A low light: the ray reaches h = 1 far beyond the decal (u + 0.75 * 2 > 1); the
        // part inside the decal still meets the wall.
        let reference = Reference::new(&wall(), Addressing::Clamp);
        let low = light(1.0, 0.0, 0.05);
        for x in [2.0, 5.0] {
            let uv = [(x + 0.5) / 16.0, 0.5];
            assert!(reference.occluded(uv, 0.25, low, 0.1), "x = {x}");
        }
        // The top plateau: its ray leaves the decal without meeting anything.
        assert!(!reference.occluded([0.75, 0.5], 0.75, low, 0.1));
    }

    /// Brute force: dense samples of the light ray from `h + SHADOW_BIAS` to 1 (clamp:
    /// inside the decal). Returns the largest `H - h_ray` seen.
    fn brute_occlusion(
        field: &HeightField,
        addressing: Addressing,
        uv: [f64; 2],
        h: f64,
        climb: [f64; 2],
    ) -> f64 {
        let n = 20_000;
        let start = h + SHADOW_BIAS;
        let mut worst = f64::NEG_INFINITY;
        for k in 0..=n {
            let hr = start + (1.0 - start) * f64::from(k) / f64::from(n);
            let p = [uv[0] + (hr - h) * climb[0], uv[1] + (hr - h) * climb[1]];
            if addressing == Addressing::Clamp && p.iter().any(|u| !(0.0..=1.0).contains(u)) {
                continue;
            }
            worst = worst.max(bilinear(field, addressing, p) - hr);
        }
        worst
    }

    #[test]
    fn occlusion_agrees_with_brute_force_on_random_maps() {
        let mut rng = Rng(5);
        for (w, h) in [(9u32, 7u32), (16, 16)] {
            let field = random_field(w, h, 0.0, 1.0, &mut rng);
            for addressing in [Addressing::Repeat, Addressing::Clamp] {
                let reference = Reference::new(&field, addressing);
                let (mut shadowed, mut lit) = (0, 0);
                for _ in 0..300 {
                    let uv = [rng.range(0.0, 1.0), rng.range(0.0, 1.0)];
                    let height = bilinear(&field, addressing, uv);
                    let l = light(
                        rng.range(-1.0, 1.0),
                        rng.range(-1.0, 1.0),
                        rng.range(0.05, 1.0),
                    );
                    let depth = [0.05, 0.1, 0.3][rng.next() as usize % 3];
                    let climb = [depth * l[0] / l[2], depth * l[1] / l[2]];
                    let worst = brute_occlusion(&field, addressing, uv, height, climb);
                    if worst.abs() < 1e-4 {
                        continue; // a graze: the sampling cannot decide it
                    }
                    let exact = reference.occluded(uv, height, l, depth);
                    assert_eq!(
                        exact,
                        worst > 0.0,
                        "{w}x{h} {addressing:?} uv {uv:?} h {height} L {l:?}: brute {worst}"
                    );
                    if exact {
                        shadowed += 1;
                    } else {
                        lit += 1;
                    }
                }
                assert!(shadowed > 30 && lit > 30, "{shadowed} shadowed, {lit} lit");
            }
        }
    }

    #[test]
    fn first_root_handles_degenerate_quadratics() {
        // Linear: s + c.
        assert_eq!(first_root(0.0, 1.0, -0.25, 1.0), Some(0.25));
        // Constant below zero: never.
        assert_eq!(first_root(0.0, 0.0, -0.25, 1.0), None);
        // Already above.
        assert_eq!(first_root(1.0, -5.0, 0.0, 1.0), Some(0.0));
        // Concave, touching later: -(s - 0.5)^2 + 0.01 -> roots 0.4, 0.6.
        let s = first_root(-1.0, 1.0, -0.24, 1.0).unwrap();
        assert!((s - 0.4).abs() < 1e-12, "{s}");
        // Convex, first falling then rising through zero at the larger root.
        let s = first_root(1.0, -0.9, 0.14 - 0.2, 1.0).unwrap();
        let expected = (0.9 + (0.81f64 - 4.0 * (0.14 - 0.2)).sqrt()) / 2.0;
        assert!((s - expected).abs() < 1e-12, "{s} vs {expected}");
        // Root beyond the interval.
        assert_eq!(first_root(0.0, 1.0, -2.0, 1.0), None);
    }
}
