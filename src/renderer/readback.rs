//! Reading the standalone renderer's images and results back to the CPU (hits, colour,
//! depth, rays, the pass's preparation images) and shading hits a caller gives.

use super::*;
use crate::gpu::track::{Handle, Tracker};

impl Renderer {
    /// The last frame's light visibility (1 = lit), row by row; `None` when
    /// self-shadowing is off.
    pub fn read_visibility(&self) -> Result<Option<Vec<f32>>> {
        let Some(image) = self.pass.visibility(0) else {
            return Ok(None);
        };
        let bytes = read_image(&self.ctx, &self.shot, image, Access::COMPUTE_STORAGE_READ)?;
        Ok(Some(
            bytes
                .chunks_exact(2)
                .map(|b| crate::passes::shadow::f16_to_f32(u16::from_le_bytes([b[0], b[1]])))
                .collect(),
        ))
    }

    /// The last frame's DIG corner grid (`None` unless the method is a DIG): the grid size
    /// in corners and the corners row by row.
    pub fn read_corners(&self) -> Result<Option<([u32; 2], Vec<Corner>)>> {
        match self.pass.corner_grid(0) {
            Some(c) => Ok(Some((
                c.size(),
                c.read(&self.ctx, &self.shot, Access::COMPUTE_SAMPLED)?,
            ))),
            None => Ok(None),
        }
    }

    /// The pyramid's levels (logical sizes, row by row); `None` unless the method uses
    /// one and a frame has built it.
    pub fn read_pyramid(&self) -> Result<Option<Vec<Vec<f32>>>> {
        self.pass
            .pyramid()
            .map(|p| p.read_levels(&self.ctx, &self.shot))
            .transpose()
    }

    /// The cone map, `(M, w)` per cell row by row (see [`crate::passes::cone`]); `None`
    /// unless the method uses one and a frame has built it.
    pub fn read_cone_map(&self) -> Result<Option<Vec<[f32; 2]>>> {
        self.pass
            .cone_map()
            .map(|c| c.read(&self.ctx, &self.shot))
            .transpose()
    }

    /// The corrected-depth image (`R32_SFLOAT`, reverse-Z clip depth of each pixel's hit,
    /// 0 without one; see [`crate::passes::hit_depth`]) once a frame has been rendered
    /// with the output on. It is in `GENERAL`, last written by a compute-shader storage
    /// write; a caller that reads it in its own submission (e.g.
    /// [`crate::passes::depth_resolve`]) places the barrier from that state and returns
    /// it there.
    pub fn hit_depth(&self) -> Option<&Image> {
        self.pass.hit_depth(0).filter(|_| self.depth_written)
    }

    /// The corrected depth of the last [`Renderer::render`]'s hits, row by row (`None`
    /// when the output is off; an error when no frame has been rendered since it was
    /// turned on). [`Renderer::shade_hits`] does not update it.
    pub fn read_depth(&self) -> Result<Option<Vec<f32>>> {
        if !self.pass.depth_output() {
            return Ok(None);
        }
        let image = self.hit_depth().ok_or_else(|| {
            Error::invalid(
                "depth output",
                "no frame has been rendered since the depth output was turned on",
            )
        })?;
        let bytes = read_image(&self.ctx, &self.shot, image, Access::COMPUTE_STORAGE_WRITE)?;
        Ok(Some(bytemuck::cast_slice::<u8, f32>(&bytes).to_vec()))
    }

    /// Each pixel's ray from the last frame's G-buffer (`None` where there is no
    /// geometry). An error after a forward frame ([`Renderer::render_forward`] writes no
    /// rays) or before the first frame.
    pub fn read_rays(&self) -> Result<Vec<Option<Ray>>> {
        if self.rays_frame.is_none() {
            return Err(Error::invalid(
                "rays",
                "the last frame wrote no rays (none rendered yet, or a forward frame): \
                 render a frame with Renderer::render first",
            ));
        }
        let ray = read_image(
            &self.ctx,
            &self.shot,
            &self.gbuffer.ray,
            Access::COMPUTE_SAMPLED,
        )?;
        let depth = self.read_macro_depth()?;
        let ray: &[[f32; 4]] = bytemuck::cast_slice(&ray);
        Ok(ray
            .iter()
            .zip(depth)
            .map(|(r, d)| {
                (d > 0.0).then(|| Ray {
                    uv0: [r[0] as f64, r[1] as f64],
                    parallax: [r[2] as f64, r[3] as f64],
                })
            })
            .collect())
    }

    /// The rays a CPU reference traces for the last frame: each pixel's own f64 centre
    /// ray where the macro surface is analytic (the tiled plane or the quad, drawn
    /// alone: [`crate::scene::Scene::analytic_rays`]), else the G-buffer's
    /// ([`Renderer::read_rays`]: meshes and scenes of several objects interpolate their
    /// entry). Pixels where the G-buffer and the centre ray disagree on coverage are
    /// listed: see [`ReferenceRays`].
    pub fn reference_rays(&self) -> Result<ReferenceRays> {
        let drawn = self.read_rays()?;
        let analytic = match (&self.rays_frame, &self.objects, &self.mesh) {
            (Some((scene, camera)), None, None) => scene.analytic_rays(camera),
            _ => None,
        };
        let Some(rays) = analytic else {
            return Ok(ReferenceRays {
                rays: drawn,
                analytic: false,
                drawn_only: Vec::new(),
                ray_only: Vec::new(),
            });
        };
        let (mut drawn_only, mut ray_only) = (Vec::new(), Vec::new());
        for (i, (d, r)) in drawn.iter().zip(&rays).enumerate() {
            match (d.is_some(), r.is_some()) {
                (true, false) => drawn_only.push(i),
                (false, true) => ray_only.push(i),
                _ => {}
            }
        }
        Ok(ReferenceRays {
            rays,
            analytic: true,
            drawn_only,
            ray_only,
        })
    }

    /// The last frame's G-buffer depth (reverse-Z depth of the macro surface, 0 where
    /// there is no geometry), row by row.
    pub fn read_macro_depth(&self) -> Result<Vec<f32>> {
        let depth = read_image(
            &self.ctx,
            &self.shot,
            &self.gbuffer.depth,
            Access::COMPUTE_SAMPLED,
        )?;
        Ok(bytemuck::cast_slice::<u8, f32>(&depth).to_vec())
    }

    /// Each pixel's material index from the last frame's G-buffer (its frame's material
    /// field, which [`Renderer::read_frames`] decodes into `tangent.w`, the handedness
    /// times the index plus one): `None` where there is no geometry or the geometry is
    /// flat (not displaced).
    pub fn read_materials(&self) -> Result<Vec<Option<u32>>> {
        let (_, tangent) = self.read_frames()?;
        let depth = self.read_macro_depth()?;
        Ok(tangent
            .iter()
            .zip(depth)
            .map(|(t, d)| {
                let m = t[3].abs().round();
                (d > 0.0 && m >= 1.0).then(|| m as u32 - 1)
            })
            .collect())
    }

    /// The last frame's G-buffer frame texels decoded ([`crate::passes::gbuffer::frame`])
    /// into `normal` (`N`, surface id) and `tangent` (`T`, handedness * (material + 1); 0
    /// for flat geometry) texels, row by row; zeros where nothing was drawn.
    pub fn read_frames(&self) -> Result<TangentFrames> {
        let bytes = read_image(
            &self.ctx,
            &self.shot,
            &self.gbuffer.frame,
            Access::COMPUTE_SAMPLED,
        )?;
        Ok(bytes
            .chunks_exact(8)
            .map(|c| {
                let word = |i: usize| u32::from_le_bytes([c[i], c[i + 1], c[i + 2], c[i + 3]]);
                let bits = [word(0), word(4)];
                if bits == [0, 0] {
                    return ([0.0; 4], [0.0; 4]);
                }
                let f = crate::passes::gbuffer::frame::unpack(bits);
                (
                    f.normal.extend(f.surface_id as f32).to_array(),
                    f.tangent
                        .extend(f.handedness * f.material_plus_one as f32)
                        .to_array(),
                )
            })
            .unzip())
    }

    /// The last frame's hits: its hit images and iteration counts, one texel per pixel
    /// (`u`, `v`, height, iterations).
    pub fn read_hits(&self) -> Result<Vec<HitTexel>> {
        let iterations = match (&self.forward, self.forward_frame) {
            (Some(f), true) => f.iterations(),
            _ => self
                .pass
                .iterations(0)
                .map(|i| (i, Access::COMPUTE_STORAGE_WRITE)),
        };
        self.read_layer_hits(&self.hit, iterations, Access::COMPUTE_STORAGE_READ)
    }

    /// The hits of a layer: `hit` last accessed as `hit_access`, `iterations` (the pass's
    /// or the forward path's) with its last access.
    pub(super) fn read_layer_hits(
        &self,
        hit: &Hits,
        iterations: Option<(&Image, Access)>,
        hit_access: Access,
    ) -> Result<Vec<HitTexel>> {
        let read = |image: &Image, access| read_image(&self.ctx, &self.shot, image, access);
        let uv = read(&hit.uv, hit_access)?;
        let height = read(&hit.height, hit_access)?;
        let counts = iterations.map(|(i, access)| read(i, access)).transpose()?;
        Ok(crate::passes::trace::join_hits(
            &uv,
            &height,
            counts.as_deref(),
        ))
    }

    /// The last frame's colour image (RGBA8, sRGB-encoded).
    pub fn read_color(&self) -> Result<Vec<u8>> {
        read_image(
            &self.ctx,
            &self.shot,
            &self.color,
            Access::COMPUTE_STORAGE_WRITE,
        )
    }

    /// Shades `hits` (one texel per pixel) with the current G-buffer and returns the
    /// colour. Overwrites the hit images. With self-shadowing on, the `shadow` pass runs
    /// on `hits` first.
    pub fn shade_hits(&mut self, hits: &[HitTexel]) -> Result<Vec<u8>> {
        self.shade_hits_with(hits, None)
    }

    /// [`Renderer::shade_hits`] with the light visibility given (one value per pixel;
    /// self-shadowing must be on) instead of computed by the `shadow` pass
    /// ([`DisplacementPass::record_shading`]).
    pub fn shade_hits_with(
        &mut self,
        hits: &[HitTexel],
        visibility: Option<&[f32]>,
    ) -> Result<Vec<u8>> {
        let ctx = &*self.ctx;
        if visibility.is_some() && !self.settings.shadows.is_on() {
            return Err(Error::invalid(
                "visibility",
                "self-shadowing is off: nothing to shade with",
            ));
        }
        let given = visibility
            .map(|values| -> Result<Image> {
                // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
                let image = unsafe {
                    Guard::new(
                        ctx,
                        Image::new(
                            ctx,
                            "given_visibility",
                            VISIBILITY_FORMAT,
                            self.settings.extent(),
                            1,
                            vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_DST,
                        )?,
                    )
                };
                upload_image(
                    ctx,
                    &self.shot,
                    &image,
                    &crate::passes::shadow::encode_visibility(values),
                    Access::COMPUTE_STORAGE_READ,
                )?;
                Ok(image.keep())
            })
            .transpose()?;
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let mut given = unsafe { Guard::new(ctx, given) };
        let (uv, height) = crate::passes::trace::split_hits(hits);
        for (image, bytes) in [(&self.hit.uv, &uv), (&self.hit.height, &height)] {
            upload_image(ctx, &self.shot, image, bytes, Access::COMPUTE_STORAGE_READ)?;
        }
        let (_, target) = self.frame_target();
        let inputs = self.frame_inputs(Some(target));
        let cmd = self.shot.begin(ctx)?;
        let color = &self.color;
        // SAFETY: `cmd` was begun by `shot.begin` above (outside a render pass, on the
        // context's queue family) and is submitted and waited for below; the colour image
        // is the renderer's, alive, and its previous frame was waited for, so it may be
        // discarded; the G-buffer is sampled-readable since the frame that drew it.
        let mut t = Tracker::new();
        t.enter(Handle::image(color), DISCARD);
        t.declare(Handle::image(color), Access::COMPUTE_STORAGE_WRITE)?;
        unsafe {
            t.record(ctx, cmd)?;
            self.record_background(cmd, &target, &mut t)?;
        }
        // SAFETY: `cmd` is recording and submitted below; the hits (and the given
        // visibility) were uploaded and made visible to storage reads; one slot, whose
        // previous frame was waited for.
        unsafe {
            self.pass.record_shading(
                cmd,
                &inputs,
                given.as_ref().map(|v| v.view),
                Timestamps::Off,
            )?
        };
        self.shot.submit_and_wait(ctx)?;
        // SAFETY: the submission that read it was waited for just above.
        unsafe { given.destroy(ctx) };
        self.read_color()
    }
}
