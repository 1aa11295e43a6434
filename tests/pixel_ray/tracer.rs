//! An f64 trace of a pixel's centre ray against the tiled plane, written from
//! docs/design.md alone ("Height field", "Tangent-space ray and G-buffer", "Camera and
//! frame"): its own orbit camera, its own bilinear field over the map's texels with
//! repeat addressing, its own quadtree of per-cell maxima to skip space, and an exact
//! solve of the ray against each bilinear patch it reaches. Nothing here calls the
//! library's or the CLI's ray, camera or reference code; the library only supplies the
//! map's texels.

use dispmap::heightfield::{HeightField, Texels};

/// Documented constants (docs/design.md, "Camera and frame" and "Tangent-space ray and
/// G-buffer"); `tests/pixel_ray.rs` checks that the library still uses them.
/// The near plane: a point at forward distance `d` has depth `NEAR / d`.
pub const NEAR: f64 = 0.005;
/// The lower bound of `-V.z` in `P = depth_scale V.xy / max(-V.z, MIN_COS)`.
pub const MIN_COS: f64 = 1e-4;
/// The tiled plane covers this many tiles on each side of the eye's tile.
pub const PLANE_HALF_EXTENT: f64 = 4096.0;

/// A deliberately wrong reading of the conventions, for the checks that the comparison
/// is not vacuous (each must make many pixels disagree with `exact`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mistake {
    /// The conventions as documented.
    None,
    /// Pixel centres at `x`, `y` instead of `x + 0.5`, `y + 0.5`.
    PixelCorners,
    /// The map moved by half a texel along `v` (texel centres at `j` instead of `j + 0.5`).
    HalfTexelShift,
    /// Row 0 at `v = 1` instead of `v = 0`.
    FlippedRows,
    /// Heights read as depths (`1 - h`).
    FlippedConvention,
    /// The azimuth turning the other way (azimuth 90 putting the eye on `-x`).
    MirroredAzimuth,
}

/// The orbit camera of the tiled plane, in f64.
pub struct View {
    eye: [f64; 3],
    forward: [f64; 3],
    right: [f64; 3],
    up: [f64; 3],
    /// `tan(fov_y / 2)` times the aspect ratio, and `tan(fov_y / 2)`.
    tan_half: [f64; 2],
    size: [f64; 2],
    /// Where in the pixel its ray goes through (0.5: the centre).
    centre: f64,
    depth_scale: f64,
}

/// Where a pixel's centre ray meets the tiled plane's macro surface (`y = 0`).
#[derive(Clone, Copy, Debug)]
pub enum Entry {
    /// At or above the horizon, or beyond the plane's edge: no geometry.
    Sky,
    /// Within a tile of the plane's edge: whether the G-buffer covers it is left open.
    Edge,
    /// On the plane.
    Plane(PixelRay),
}

/// A pixel's ray in the tangent space of the plane: `uv(t) = entry + t P` at height
/// `h = 1 - t`, `t` in `[0, 1]`.
#[derive(Clone, Copy, Debug)]
pub struct PixelRay {
    /// `(u, v)` of the entry point: world `(x, z)`, not reduced to a tile.
    pub entry: [f64; 2],
    /// The parallax vector `P`, in tiles.
    pub parallax: [f64; 2],
    /// Whether `MIN_COS` clamps `P` (the ray is then not the view ray below the entry).
    pub clamped: bool,
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

impl View {
    /// The camera of the tiled plane: it orbits `(0, 0, 0)`, `eye = dist (cos e sin a,
    /// sin e, cos e cos a)` with `dist = height / sin e`, and looks at the target; right =
    /// forward x +y, up = right x forward.
    pub fn new(scene: &dispmap::scene::Scene, size: (u32, u32), mistake: Mistake) -> Self {
        let c = &scene.camera;
        let (e, mut a) = (
            f64::from(c.elevation_deg).to_radians(),
            f64::from(c.azimuth_deg).to_radians(),
        );
        if mistake == Mistake::MirroredAzimuth {
            a = -a;
        }
        let to_eye = [e.cos() * a.sin(), e.sin(), e.cos() * a.cos()];
        let dist = f64::from(c.height) / e.sin();
        let eye = to_eye.map(|x| x * dist);
        let forward = to_eye.map(|x| -x);
        let right = normalize(cross(forward, [0.0, 1.0, 0.0]));
        let up = cross(right, forward);
        let t = (f64::from(c.fov_y_deg).to_radians() / 2.0).tan();
        let size = [f64::from(size.0), f64::from(size.1)];
        View {
            eye,
            forward,
            right,
            up,
            tan_half: [t * size[0] / size[1], t],
            size,
            centre: if mistake == Mistake::PixelCorners {
                0.0
            } else {
                0.5
            },
            depth_scale: f64::from(scene.depth_scale),
        }
    }

    /// The unit direction of pixel `(x, y)`'s ray: NDC `((x + 0.5) / W * 2 - 1,
    /// (y + 0.5) / H * 2 - 1)`, Vulkan's y down (row 0 at the top: the far side).
    pub fn direction(&self, x: u32, y: u32) -> [f64; 3] {
        let ndc = [
            (f64::from(x) + self.centre) / self.size[0] * 2.0 - 1.0,
            (f64::from(y) + self.centre) / self.size[1] * 2.0 - 1.0,
        ];
        let (sx, sy) = (ndc[0] * self.tan_half[0], -ndc[1] * self.tan_half[1]);
        normalize([0, 1, 2].map(|k| self.forward[k] + sx * self.right[k] + sy * self.up[k]))
    }

    /// Pixel `(x, y)`'s centre ray on the plane.
    pub fn entry(&self, x: u32, y: u32) -> Entry {
        let d = self.direction(x, y);
        if d[1] >= 0.0 {
            return Entry::Sky;
        }
        let s = self.eye[1] / -d[1];
        let entry = [self.eye[0] + s * d[0], self.eye[2] + s * d[2]];
        // The plane spans PLANE_HALF_EXTENT tiles on each side of the eye's tile.
        let beyond = [(entry[0], self.eye[0]), (entry[1], self.eye[2])]
            .iter()
            .map(|&(p, e)| (p - e.floor()).abs() - PLANE_HALF_EXTENT)
            .fold(f64::NEG_INFINITY, f64::max);
        if beyond > 1.0 {
            return Entry::Sky;
        }
        if beyond > -1.0 {
            return Entry::Edge;
        }
        // Tangent frame: T = +x (u), B = +z (v), N = +y; V_ts = (d.x, d.z, d.y).
        let down = (-d[1]).max(MIN_COS);
        Entry::Plane(PixelRay {
            entry,
            parallax: [
                self.depth_scale * d[0] / down,
                self.depth_scale * d[2] / down,
            ],
            clamped: -d[1] < MIN_COS,
        })
    }

    /// The world point at `uv`, height `h` (the macro surface at `y = 0`, depth
    /// `(1 - h) depth_scale` below it).
    pub fn world(&self, uv: [f64; 2], h: f64) -> [f64; 3] {
        [uv[0], -(1.0 - h) * self.depth_scale, uv[1]]
    }

    /// The forward distance of a world point from the eye (depth = `NEAR / distance`).
    pub fn forward_distance(&self, p: [f64; 3]) -> f64 {
        dot([0, 1, 2].map(|k| p[k] - self.eye[k]), self.forward)
    }
}

/// The bilinear height field of a map with repeat addressing, and its max quadtree.
pub struct Surface {
    size: [usize; 2],
    /// Heights in `[0, 1]`, row by row from row 0 (`v = 0`).
    texels: Vec<f64>,
    /// `levels[0]`: each bilinear cell's maximum (its 4 corner texels); level `L`: the
    /// maximum of the cells `[n 2^L, min((n + 1) 2^L, W))` (and likewise in `y`).
    levels: Vec<Grid>,
    /// Added to texel-space coordinates (the half-texel-shift mistake).
    shift: [f64; 2],
}

struct Grid {
    size: [usize; 2],
    max: Vec<f64>,
}

/// A ray in the map's texel space: `p(t) = p0 + t d`, height `1 - t`.
#[derive(Clone, Copy)]
struct TexRay {
    p0: [f64; 2],
    d: [f64; 2],
}

/// The ray against one bilinear cell from `t = a`: with `s = t - a` in `[0, len]`,
/// `H(p(t)) - (1 - t) = c0 + c1 s + c2 s²` (the ray is at or below the surface where it
/// is `>= 0`).
struct Patch {
    a: f64,
    len: f64,
    c: [f64; 3],
}

impl Patch {
    fn at(&self, s: f64) -> f64 {
        self.c[0] + s * (self.c[1] + s * self.c[2])
    }

    /// The smallest `s` in `[0, len]` where the ray is at or below the surface.
    fn first_contact(&self) -> Option<f64> {
        let [c0, c1, c2] = self.c;
        if c0 >= 0.0 {
            return Some(0.0);
        }
        let in_range = |s: f64| (0.0..=self.len).contains(&s);
        let root = if c2 == 0.0 {
            (c1 > 0.0).then(|| -c0 / c1).filter(|&s| in_range(s))
        } else {
            let disc = c1 * c1 - 4.0 * c2 * c0;
            if disc < 0.0 {
                None
            } else {
                // The two roots without cancellation.
                let q = -0.5 * (c1 + c1.signum() * disc.sqrt());
                let r = [q / c2, if q != 0.0 { c0 / q } else { q / c2 }];
                r.into_iter()
                    .filter(|&s| in_range(s))
                    .min_by(|x, y| x.total_cmp(y))
            }
        };
        match root {
            Some(s) => Some(s),
            // Rounding put the root just outside: f(0) < 0 <= f(len) brackets one crossing.
            None if self.at(self.len) >= 0.0 => {
                let (mut lo, mut hi) = (0.0, self.len);
                for _ in 0..200 {
                    let mid = 0.5 * (lo + hi);
                    if mid <= lo || mid >= hi {
                        break;
                    }
                    if self.at(mid) >= 0.0 {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                Some(hi)
            }
            None => None,
        }
    }

    /// The largest `H - (1 - t)` over the cell's segment (a quadratic: its ends and
    /// its vertex).
    fn max_penetration(&self) -> f64 {
        let mut m = self.at(0.0).max(self.at(self.len));
        if self.c[2] < 0.0 {
            let s = -self.c[1] / (2.0 * self.c[2]);
            if (0.0..=self.len).contains(&s) {
                m = m.max(self.at(s));
            }
        }
        m
    }
}

/// What a walk along the ray does in each node and cell it reaches.
trait Visit {
    /// The part of `[a, b]` worth descending into a node of maximum height `max`.
    fn node(&mut self, max: f64, a: f64, b: f64) -> Option<(f64, f64)>;
    /// A cell's segment; `true` stops the walk.
    fn cell(&mut self, patch: Patch) -> bool;
}

/// The first contact.
struct FirstHit(Option<f64>);

impl Visit for FirstHit {
    fn node(&mut self, max: f64, a: f64, b: f64) -> Option<(f64, f64)> {
        // The ray is lowest at b: above the node's maximum there, it misses the node; it
        // cannot touch it before it comes down to that maximum.
        let a = a.max(1.0 - max);
        (1.0 - b <= max && a <= b).then_some((a, b))
    }

    fn cell(&mut self, patch: Patch) -> bool {
        self.0 = patch.first_contact().map(|s| patch.a + s);
        self.0.is_some()
    }
}

/// The deepest the ray goes below the surface.
struct Deepest(f64);

impl Visit for Deepest {
    fn node(&mut self, max: f64, a: f64, b: f64) -> Option<(f64, f64)> {
        (max - (1.0 - b) > self.0).then_some((a, b))
    }

    fn cell(&mut self, patch: Patch) -> bool {
        self.0 = self.0.max(patch.max_penetration());
        false
    }
}

impl Surface {
    /// The map's texels as documented: 8-bit and 16-bit UNORM (`v / 255`, `v / 65535`),
    /// floats as they are; row 0 is `v = 0`.
    pub fn new(field: &HeightField, mistake: Mistake) -> Self {
        let (w, h) = (field.width() as usize, field.height() as usize);
        let mut texels: Vec<f64> = match field.texels() {
            Texels::R8(v) => v.iter().map(|&x| f64::from(x) / 255.0).collect(),
            Texels::R16(v) => v.iter().map(|&x| f64::from(x) / 65535.0).collect(),
            Texels::R32F(v) => v.iter().map(|&x| f64::from(x)).collect(),
        };
        match mistake {
            Mistake::FlippedRows => {
                texels = (0..h)
                    .rev()
                    .flat_map(|j| texels[j * w..(j + 1) * w].to_vec())
                    .collect();
            }
            Mistake::FlippedConvention => texels.iter_mut().for_each(|x| *x = 1.0 - *x),
            _ => {}
        }
        let shift = match mistake {
            Mistake::HalfTexelShift => [0.0, 0.5],
            _ => [0.0, 0.0],
        };
        let cells = Grid {
            size: [w, h],
            max: (0..h)
                .flat_map(|j| (0..w).map(move |i| (i, j)))
                .map(|(i, j)| {
                    let (i1, j1) = ((i + 1) % w, (j + 1) % h);
                    [(i, j), (i1, j), (i, j1), (i1, j1)]
                        .iter()
                        .map(|&(x, y)| texels[y * w + x])
                        .fold(f64::NEG_INFINITY, f64::max)
                })
                .collect(),
        };
        let mut levels = vec![cells];
        while levels.last().is_some_and(|g| g.size != [1, 1]) {
            let below = levels.last().unwrap();
            let size = below.size.map(|n| n.div_ceil(2));
            let max = (0..size[1])
                .flat_map(|m| (0..size[0]).map(move |n| (n, m)))
                .map(|(n, m)| {
                    let xs = (2 * n..(2 * n + 2).min(below.size[0])).collect::<Vec<_>>();
                    (2 * m..(2 * m + 2).min(below.size[1]))
                        .flat_map(|y| xs.iter().map(move |&x| below.max[y * below.size[0] + x]))
                        .fold(f64::NEG_INFINITY, f64::max)
                })
                .collect();
            levels.push(Grid { size, max });
        }
        Surface {
            size: [w, h],
            texels,
            levels,
            shift,
        }
    }

    fn texel(&self, i: usize, j: usize) -> f64 {
        self.texels[j * self.size[0] + i]
    }

    /// Texel space: texel `(i, j)`'s centre, at `uv = ((i + 0.5) / W, (j + 0.5) / H)`,
    /// is at `(i, j)`; bilinear cell `(i, j)` is `[i, i + 1] x [j, j + 1]`.
    fn texel_space(&self, uv: [f64; 2]) -> [f64; 2] {
        [0, 1].map(|k| uv[k] * self.size[k] as f64 - 0.5 + self.shift[k])
    }

    fn tex_ray(&self, ray: &PixelRay) -> TexRay {
        TexRay {
            p0: self.texel_space(ray.entry),
            d: [0, 1].map(|k| ray.parallax[k] * self.size[k] as f64),
        }
    }

    /// `H` at a texel-space point (repeat addressing).
    fn height(&self, p: [f64; 2]) -> f64 {
        let [w, h] = self.size;
        let (fx, fy) = (p[0].floor(), p[1].floor());
        let (i, j) = (
            (fx as i64).rem_euclid(w as i64) as usize,
            (fy as i64).rem_euclid(h as i64) as usize,
        );
        let (i1, j1) = ((i + 1) % w, (j + 1) % h);
        let (x, y) = (p[0] - fx, p[1] - fy);
        let (h00, h10, h01, h11) = (
            self.texel(i, j),
            self.texel(i1, j),
            self.texel(i, j1),
            self.texel(i1, j1),
        );
        h00 * (1.0 - x) * (1.0 - y) + h10 * x * (1.0 - y) + h01 * (1.0 - x) * y + h11 * x * y
    }

    /// `H - (1 - t)` at `t` along the ray: > 0 below the surface, < 0 its clearance.
    pub fn penetration(&self, ray: &PixelRay, t: f64) -> f64 {
        let r = self.tex_ray(ray);
        self.height([0, 1].map(|k| r.p0[k] + t * r.d[k])) - (1.0 - t)
    }

    /// The ray against cell `cell` (tile-local indices) of the tile at `origin`, from `a`
    /// to `b`.
    fn patch(&self, r: &TexRay, origin: [f64; 2], cell: [usize; 2], a: f64, b: f64) -> Patch {
        let [w, h] = self.size;
        let [i, j] = cell;
        let (i1, j1) = ((i + 1) % w, (j + 1) % h);
        let h00 = self.texel(i, j);
        let bx = self.texel(i1, j) - h00;
        let cy = self.texel(i, j1) - h00;
        let e = h00 - self.texel(i1, j) - self.texel(i, j1) + self.texel(i1, j1);
        // The ray's position in the cell at a (in [0, 1]² up to rounding).
        let f = [0, 1].map(|k| r.p0[k] + a * r.d[k] - (origin[k] + cell[k] as f64));
        let [dx, dy] = r.d;
        Patch {
            a,
            len: b - a,
            c: [
                h00 + bx * f[0] + cy * f[1] + e * f[0] * f[1] - (1.0 - a),
                bx * dx + cy * dy + e * (f[0] * dy + f[1] * dx) + 1.0,
                e * dx * dy,
            ],
        }
    }

    /// Node `n` of `level` in the tile at `origin`, for the ray's `[a, b]` inside it:
    /// the segment is cut where the ray crosses the node's midlines, and each piece goes
    /// to the child it lies in, in order along the ray.
    fn walk_node(
        &self,
        r: &TexRay,
        origin: [f64; 2],
        (level, n): (usize, [usize; 2]),
        (a, b): (f64, f64),
        v: &mut impl Visit,
    ) -> bool {
        let grid = &self.levels[level];
        let Some((a, b)) = v.node(grid.max[n[1] * grid.size[0] + n[0]], a, b) else {
            return false;
        };
        if level == 0 {
            return v.cell(self.patch(r, origin, n, a, b));
        }
        let half = 1usize << (level - 1);
        // The midlines (tile-local texel space), where the node has a second child.
        let mid: [Option<f64>; 2] = [0, 1].map(|k| {
            let m = (2 * n[k] + 1) * half;
            (m < self.size[k]).then_some(m as f64)
        });
        let mut cuts = [a, b, b, b];
        let mut count = 1;
        for k in 0..2 {
            let Some(m) = mid[k] else { continue };
            if r.d[k] != 0.0 {
                let t = (origin[k] + m - r.p0[k]) / r.d[k];
                if t > a && t < b {
                    cuts[count] = t;
                    count += 1;
                }
            }
        }
        cuts[count] = b;
        cuts[..=count].sort_by(|x, y| x.total_cmp(y));
        for piece in cuts[..=count].windows(2) {
            let (c0, c1) = (piece[0], piece[1]);
            if c1 <= c0 && a < b {
                continue;
            }
            let t = 0.5 * (c0 + c1);
            let child = [0, 1].map(|k| {
                let p = r.p0[k] + t * r.d[k] - origin[k];
                2 * n[k] + usize::from(mid[k].is_some_and(|m| p >= m))
            });
            if self.walk_node(r, origin, (level - 1, child), (c0, c1), v) {
                return true;
            }
        }
        false
    }

    /// Walks the ray over `[a, b]` tile by tile (each tile the whole quadtree, repeat
    /// addressing); `true` when the visitor stopped it.
    fn walk(&self, r: &TexRay, a: f64, b: f64, v: &mut impl Visit) -> bool {
        let size = self.size.map(|n| n as f64);
        let mut tile = [0, 1].map(|k| {
            let p = (r.p0[k] + a * r.d[k]) / size[k];
            let f = p.floor();
            // On a tile border, the tile the ray goes into.
            f as i64 - i64::from(p == f && r.d[k] < 0.0)
        });
        let mut t = a;
        let top = self.levels.len() - 1;
        loop {
            let next = [0, 1].map(|k| {
                let d = r.d[k];
                if d > 0.0 {
                    ((tile[k] + 1) as f64 * size[k] - r.p0[k]) / d
                } else if d < 0.0 {
                    (tile[k] as f64 * size[k] - r.p0[k]) / d
                } else {
                    f64::INFINITY
                }
            });
            let end = next[0].min(next[1]).min(b).max(t);
            let origin = [0, 1].map(|k| tile[k] as f64 * size[k]);
            if self.walk_node(r, origin, (top, [0, 0]), (t, end), v) {
                return true;
            }
            if end >= b {
                return false;
            }
            for k in 0..2 {
                if next[k] <= next[1 - k] {
                    tile[k] += if r.d[k] > 0.0 { 1 } else { -1 };
                }
            }
            t = end;
        }
    }

    /// The first `t` where the ray is at or below the surface. The ray always meets it by
    /// `t = 1` (`h = 0`).
    pub fn trace(&self, ray: &PixelRay) -> f64 {
        let r = self.tex_ray(ray);
        let top = &self.levels[self.levels.len() - 1];
        let start = (1.0 - top.max[0]).clamp(0.0, 1.0);
        let mut hit = FirstHit(None);
        self.walk(&r, start, 1.0, &mut hit);
        hit.0.unwrap_or(1.0)
    }

    /// The deepest the ray goes below the surface over `[a, b]` (heights; negative: it
    /// stays above by that much).
    pub fn deepest(&self, ray: &PixelRay, a: f64, b: f64) -> f64 {
        let r = self.tex_ray(ray);
        let mut deepest = Deepest(f64::NEG_INFINITY);
        self.walk(&r, a, b, &mut deepest);
        deepest.0
    }

    /// The map's size in texels.
    pub fn size(&self) -> [f64; 2] {
        self.size.map(|n| n as f64)
    }
}
