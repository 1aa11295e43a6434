//! How a [`Renderer`] is built: from one height field and its settings, or from a scene
//! of several objects, and the host-side parts both constructors guard until assembly.

use super::*;

impl Renderer {
    /// Uploads `field` and builds what `settings` needs (no loaded mesh, no material
    /// maps: see [`Renderer::with_assets`]).
    pub fn new(ctx: &Arc<Context>, field: &HeightField, settings: RenderSettings) -> Result<Self> {
        Self::with_assets(ctx, field, settings, &SceneAssets::default())
    }

    /// [`Renderer::new`] with a scene's mesh and material maps. Builds only what the
    /// scene uses: vertex buffers only for mesh geometry, textures only for given maps.
    /// The map (and the maps) are staged here and copied by the first frame.
    pub fn with_assets(
        ctx: &Arc<Context>,
        field: &HeightField,
        settings: RenderSettings,
        assets: &SceneAssets,
    ) -> Result<Self> {
        if !assets.objects.is_empty() {
            let objects: Vec<_> = assets.objects.iter().map(ObjectAssets::as_object).collect();
            return Self::with_objects(ctx, settings, &objects);
        }
        settings.validate()?;
        let geometry = settings.scene.geometry;
        let mesh = match (geometry.generated_mesh(), &assets.mesh) {
            (Some(generated), _) => Some(std::borrow::Cow::Owned(generated)),
            (None, Some(loaded)) if geometry == crate::scene::Geometry::Mesh => {
                Some(std::borrow::Cow::Borrowed(loaded))
            }
            (None, None) if geometry == crate::scene::Geometry::Mesh => {
                return Err(Error::invalid(
                    "geometry",
                    "'mesh' needs a loaded mesh (a scene file's `mesh` key)",
                ));
            }
            _ => None,
        };
        // A one-sided convex mesh alone never shows itself behind a miss: its behind layer
        // is drawn empty (`Renderer::set_behind`).
        let convex = mesh.as_ref().is_some_and(|m| !m.two_sided && m.is_convex());
        let max = ctx.info().max_image_dimension_2d;
        if field.width() > max || field.height() > max {
            return Err(Error::invalid(
                field.label(),
                format!(
                    "{}x{} exceeds the device's maxImageDimension2D ({max})",
                    field.width(),
                    field.height()
                ),
            ));
        }
        let extent = settings.extent();
        let c = &**ctx;
        // Built in order; a failure destroys what the guards hold. The G-buffer gets its
        // curve image when a material is traced curved (`Renderer::set_curved`).
        let host = HostParts::new(c, extent)?;
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let gbuffer_pass = unsafe {
            Guard::new(
                c,
                GBufferPass::new_layer(
                    c,
                    mesh.is_some(),
                    mesh.as_ref().is_some_and(|m| m.two_sided),
                    false,
                    false,
                )?,
            )
        };
        let clusters = mesh
            .as_ref()
            .map(|m| super::behind_draws::clusters(m))
            .unwrap_or_default();
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let mesh_buffers = unsafe {
            Guard::new(
                c,
                mesh.as_ref()
                    .map(|m| MeshBuffers::upload(c, &host.shot, m))
                    .transpose()?,
            )
        };
        // What the curved `exact` trace walks, once curved tracing is on.
        let walked = mesh.map(std::borrow::Cow::into_owned);
        let mesh = mesh_buffers;
        // The renderer measures its methods: its frames always write the iteration counts.
        let mut pass = DisplacementPass::with_iterations(
            ctx.clone(),
            field,
            PassSettings {
                method: settings.method,
                params: settings.params,
                depth_scale: settings.scene.depth_scale,
                addressing: settings.scene.addressing(),
                extent,
                // A mesh can show itself behind a miss (a torus's far side behind the
                // carved top of its near tube): its frames may draw the behind layer
                // (`Renderer::set_behind`), whose record uses the pass's frame slot 1.
                frames_in_flight: if mesh.is_some() { 2 } else { 1 },
            },
            true,
        )?;
        let configured = pass
            .set_shadows(settings.shadows)
            .and_then(|()| pass.set_material(&assets.material));
        if let Err(e) = configured {
            // SAFETY: nothing was recorded with the pass.
            unsafe { pass.destroy() };
            return Err(e);
        }
        let mut renderer = host.keep(ctx, settings, gbuffer_pass.keep(), mesh.keep(), None, pass);
        renderer.convex_alone = convex;
        renderer.mesh_clusters = clusters;
        renderer.curved_meshes = walked.into_iter().collect();
        Ok(renderer)
    }

    /// A renderer of several objects in one G-buffer: each object drawn with its own
    /// placement and, when it has a material, that material's index + 1 in the frame, depth
    /// scale and addressing (the per-draw push constants: `camera_pos.w` carries the
    /// material, see [`crate::abi::GBufferParams`]); objects without one are drawn flat
    /// (material 0 in the frame) and shaded by the background pass. Mesh vertices are placed on
    /// the CPU once here (positions transformed, frames rotated, surface ids shifted so
    /// that no two objects share one). Each displaced object is one material of the pass
    /// (maps with equal content and addressing are shared by the pass), except that
    /// objects given the very same `field` and `images` (the same references) and equal
    /// settings share one material: the first
    /// displaced object's is the pass's primary material, and `settings`' method,
    /// parameters, depth scale, addressing and geometry are replaced by its own (so
    /// [`Renderer::set_method`] and [`Renderer::set_scene`]'s depth scale act on it).
    /// `settings`' camera orbits the centre of the sphere around the objects at its
    /// [`crate::scene::Camera::distance`] or else the distance that frames the sphere, or, with a tiled plane among them, is the plane's camera (the eye
    /// `height` above the plane, looking at the origin). At least one object needs a
    /// material.
    pub fn with_objects(
        ctx: &Arc<Context>,
        settings: RenderSettings,
        objects: &[SceneObject<'_>],
    ) -> Result<Self> {
        if objects.is_empty() || objects.len() > MAX_OBJECTS {
            return Err(Error::invalid(
                "objects",
                format!(
                    "{} objects: a frame takes 1 to {MAX_OBJECTS}",
                    objects.len()
                ),
            ));
        }
        let Some((first, primary)) = objects
            .iter()
            .find_map(|o| o.material.map(|m| (o.geometry, m)))
        else {
            return Err(Error::invalid(
                "objects",
                "no object has a height map: at least one must be displaced",
            ));
        };
        let settings = objects_settings(settings, first, &primary.settings);
        settings.validate()?;
        let mut placed = Vec::with_capacity(objects.len());
        // The behind layer (a miss shows what is behind it): for several objects of which
        // a displaced one can miss, a mesh (curved tracing) or a clamp-addressed object (a
        // ray that leaves its decal). Its second record uses the pass's frame slot 1.
        let behind = objects.len() > 1
            && objects.iter().any(|o| {
                o.material.is_some_and(|m| {
                    o.geometry != Geometry::TiledPlane
                        || m.settings.addressing == crate::heightfield::Addressing::Clamp
                })
            });
        let mut convex = Vec::with_capacity(objects.len());
        let mut surface_offset = 0u32;
        for (i, o) in objects.iter().enumerate() {
            let name = |e: Error| match e {
                Error::InvalidInput { name, message } => {
                    Error::invalid(format!("object {} {name}", i + 1), message)
                }
                other => other,
            };
            o.placement.validate().map_err(name)?;
            let mesh = match o.geometry {
                Geometry::TiledPlane => {
                    if o.placement != Placement::default() {
                        return Err(name(Error::invalid(
                            "placement",
                            "the tiled plane has no position, scale or rotation",
                        )));
                    }
                    surface_offset += 1;
                    None
                }
                Geometry::Quad => Some(Mesh::quad()),
                Geometry::Mesh => Some(
                    o.mesh
                        .ok_or_else(|| {
                            name(Error::invalid(
                                "mesh",
                                "geometry 'mesh' needs a loaded mesh",
                            ))
                        })?
                        .clone(),
                ),
                g => g.generated_mesh(),
            };
            // Only a displaced object's pixels miss: only its convexity can spare a draw
            // of the behind layer (tested only when there is one). Tested before placing
            // (an affine map keeps it; the placed vertices' rounding can fail the test's
            // tolerance).
            convex.push(
                behind
                    && o.material.is_some()
                    && mesh.as_ref().is_some_and(|m| !m.two_sided && m.is_convex()),
            );
            placed.push(mesh.map(|m| {
                let m = m.placed(&o.placement, surface_offset);
                surface_offset += m.max_surface_id().max(1);
                m
            }));
            if let Some(m) = &o.material {
                let max = ctx.info().max_image_dimension_2d;
                if m.field.width() > max || m.field.height() > max {
                    return Err(name(Error::invalid(
                        m.field.label(),
                        format!("exceeds the device's maxImageDimension2D ({max})"),
                    )));
                }
            }
        }
        let framing = if objects.iter().any(|o| o.geometry == Geometry::TiledPlane) {
            None
        } else {
            let (centre, radius) = bounding_sphere(objects);
            Some((
                centre,
                crate::scene::framing_distance(radius, settings.scene.camera.fov_y_deg),
            ))
        };
        check_eye(&settings, framing, objects, &placed)?;
        let extent = settings.extent();
        let c = &**ctx;
        // The G-buffer gets its curve image, which every pipeline drawing into it then
        // writes, when a material is traced curved (`Renderer::set_curved`).
        let host = HostParts::new(c, extent)?;
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let gbuffer_pass = unsafe { Guard::new(c, GBufferPass::new(c)?) };
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let mut drawn = unsafe {
            Guard::new(
                c,
                Objects {
                    mesh_pass: None,
                    two_sided_pass: None,
                    meshes: Vec::new(),
                    clusters: Vec::new(),
                    one_normal: Vec::new(),
                    convex: Vec::new(),
                    materials: Vec::new(),
                    framing: None,
                },
            )
        };
        // Only the pipelines the objects need.
        if placed.iter().flatten().any(|m| !m.two_sided) {
            drawn.mesh_pass = Some(GBufferPass::new_mesh(c)?);
        }
        if placed.iter().flatten().any(|m| m.two_sided) {
            drawn.two_sided_pass = Some(GBufferPass::new_mesh_two_sided(c)?);
        }
        for mesh in &placed {
            let buffers = mesh
                .as_ref()
                .map(|m| MeshBuffers::upload(c, &host.shot, m))
                .transpose()?;
            drawn.meshes.push(buffers);
            drawn.clusters.push(
                mesh.as_ref()
                    .map(super::behind_draws::clusters)
                    .unwrap_or_default(),
            );
            drawn
                .one_normal
                .push(mesh.as_ref().is_some_and(|m| m.has_one_normal()));
        }
        drawn.convex = convex;
        drawn.framing = framing;
        // A material's refusal (its loop budget, its maps) names its object.
        let of_object = |i: usize| {
            move |e: Error| match e {
                Error::InvalidInput { name, message } => {
                    Error::invalid(format!("object {} {name}", i + 1), message)
                }
                other => other,
            }
        };
        let primary_index = objects
            .iter()
            .position(|o| o.material.is_some())
            .unwrap_or(0);
        // The renderer measures its methods: its frames always write the iteration counts.
        let mut pass = DisplacementPass::with_iterations(
            ctx.clone(),
            primary.field,
            PassSettings {
                method: primary.settings.method,
                params: primary.settings.params,
                depth_scale: primary.settings.depth_scale,
                addressing: primary.settings.addressing,
                extent,
                frames_in_flight: if behind { 2 } else { 1 },
            },
            true,
        )
        .map_err(of_object(primary_index))?;
        let mut first_material = true;
        let mut configure = |pass: &mut DisplacementPass| -> Result<()> {
            pass.set_shadows(settings.shadows)?;
            for (i, o) in objects.iter().enumerate() {
                // An object given the very same map, settings and maps as an earlier one
                // shares its material.
                let same = |a: &ObjectMaterial<'_>, b: &ObjectMaterial<'_>| {
                    std::ptr::eq(a.field, b.field)
                        && a.settings == b.settings
                        && std::ptr::eq(a.images, b.images)
                };
                let shared = o.material.as_ref().and_then(|m| {
                    objects[..i]
                        .iter()
                        .zip(&drawn.materials)
                        .find_map(|(e, id)| e.material.as_ref().filter(|e| same(e, m)).and(*id))
                });
                let id = match &o.material {
                    None => None,
                    Some(_) if shared.is_some() => shared,
                    Some(m) if first_material => {
                        first_material = false;
                        pass.set_material(m.images).map_err(of_object(i))?;
                        Some(pass.primary())
                    }
                    Some(m) => {
                        let id = pass
                            .add_material(m.field, m.settings)
                            .map_err(of_object(i))?;
                        pass.set_material_maps(id, m.images).map_err(of_object(i))?;
                        Some(id)
                    }
                };
                drawn.materials.push(id);
            }
            Ok(())
        };
        if let Err(e) = configure(&mut pass) {
            // SAFETY: nothing was recorded with the pass.
            unsafe { pass.destroy() };
            return Err(e);
        }
        let mut renderer = host.keep(
            ctx,
            settings,
            gbuffer_pass.keep(),
            None,
            Some(drawn.keep()),
            pass,
        );
        // What the curved `exact` trace walks, once curved tracing is on: the displaced
        // objects' meshes.
        renderer.curved_meshes = placed
            .iter()
            .zip(objects)
            .filter(|(_, o)| o.material.is_some())
            .filter_map(|(m, _)| m.clone())
            .collect();
        if behind {
            renderer.set_behind(true)?;
        }
        Ok(renderer)
    }
}

/// What both constructors build for the renderer as a host, each guarded until
/// [`HostParts::keep`] assembles the renderer: the one-shot, the timestamp pool, the
/// frame-sized images and the background pass.
struct HostParts<'c> {
    shot: Guard<'c, OneShot>,
    timestamps: Guard<'c, QueryPool>,
    gbuffer: Guard<'c, GBuffer>,
    hit: Guard<'c, Hits>,
    color: Guard<'c, Image>,
    background: Guard<'c, BackgroundPass>,
}

impl<'c> HostParts<'c> {
    /// Builds them in order; a failure destroys what was built.
    fn new(c: &'c Context, extent: vk::Extent2D) -> Result<Self> {
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let shot = unsafe { Guard::new(c, OneShot::new(c, "renderer")?) };
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let timestamps = unsafe {
            Guard::new(
                c,
                QueryPool(crate::timing::timestamp_pool(
                    c,
                    "renderer.timestamps",
                    GBUFFER_QUERIES + MAX_QUERIES + behind::BEHIND_QUERIES,
                )?),
            )
        };
        let (gbuffer, hit, color) = frame_images(c, extent, false)?;
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let background = unsafe { Guard::new(c, BackgroundPass::new(c)?) };
        Ok(HostParts {
            shot,
            timestamps,
            gbuffer,
            hit,
            color,
            background,
        })
    }

    /// The renderer of these parts and the rest.
    fn keep(
        self,
        ctx: &Arc<Context>,
        settings: RenderSettings,
        gbuffer_pass: GBufferPass,
        mesh: Option<MeshBuffers>,
        objects: Option<Objects>,
        pass: DisplacementPass,
    ) -> Renderer {
        Renderer {
            ctx: ctx.clone(),
            settings,
            shot: self.shot.keep(),
            timestamps: self.timestamps.keep(),
            gbuffer: self.gbuffer.keep(),
            hit: self.hit.keep(),
            color: self.color.keep(),
            gbuffer_pass,
            background: self.background.keep(),
            mesh,
            mesh_clusters: Vec::new(),
            objects,
            pass,
            depth_written: false,
            motion: None,
            builds: Vec::new(),
            forward: None,
            rays_frame: None,
            behind: None,
            behind_empty: false,
            convex_alone: false,
            convex_skip: true,
            forward_frame: false,
            curved_meshes: Vec::new(),
        }
    }
}

/// The hit images of one layer: the renderer's as a host of the pass
/// ([`crate::embed::HitImages`]).
pub(super) struct Hits {
    /// The hit's `u`, `v` ([`HIT_UV_FORMAT`]).
    pub uv: Image,
    /// The hit's height ([`HIT_HEIGHT_FORMAT`]).
    pub height: Image,
}

impl Hits {
    /// Both images of `extent`, named `{name}.uv` and `{name}.height`, with `STORAGE`,
    /// `TRANSFER_SRC`, `TRANSFER_DST` (the shading of given hits uploads them) and
    /// `usage`.
    pub(super) fn new(
        c: &Context,
        name: &str,
        extent: vk::Extent2D,
        usage: vk::ImageUsageFlags,
    ) -> Result<Self> {
        let usage = usage
            | vk::ImageUsageFlags::STORAGE
            | vk::ImageUsageFlags::TRANSFER_SRC
            | vk::ImageUsageFlags::TRANSFER_DST;
        let image =
            |part: &str, format| Image::new(c, &format!("{name}.{part}"), format, extent, 1, usage);
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let uv = unsafe { Guard::new(c, image("uv", HIT_UV_FORMAT)?) };
        let height = image("height", HIT_HEIGHT_FORMAT)?;
        Ok(Hits {
            uv: uv.keep(),
            height,
        })
    }

    /// The images as the pass takes them.
    pub(super) fn host(&self) -> HitImages {
        HitImages {
            uv: self.uv.host_view(),
            height: self.height.host_view(),
        }
    }
}

impl Destroy for Hits {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.uv.destroy(ctx);
            self.height.destroy(ctx);
        }
    }

    fn bytes(&self) -> u64 {
        self.uv.bytes() + self.height.bytes()
    }
}

/// The images sized by the frame: the G-buffer (with the curve image when `curve`), the
/// hit images and the colour image, each guarded until the caller keeps it (creation and
/// `resize`).
pub(super) fn frame_images(
    c: &Context,
    extent: vk::Extent2D,
    curve: bool,
) -> Result<(Guard<'_, GBuffer>, Guard<'_, Hits>, Guard<'_, Image>)> {
    let gbuffer = if curve {
        GBuffer::new_curved(c, extent)?
    } else {
        GBuffer::new(c, extent)?
    };
    // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
    let gbuffer = unsafe { Guard::new(c, gbuffer) };
    // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
    let hit = unsafe {
        Guard::new(
            c,
            // COLOR_ATTACHMENT: the forward path writes them from its fragment shader.
            Hits::new(c, "hits", extent, vk::ImageUsageFlags::COLOR_ATTACHMENT)?,
        )
    };
    // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
    let color = unsafe {
        Guard::new(
            c,
            Image::new(
                c,
                "color",
                COLOR_FORMAT,
                extent,
                1,
                vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
            )?,
        )
    };
    Ok((gbuffer, hit, color))
}
