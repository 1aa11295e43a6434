//! The pass's material table: adding, removing and changing displaced materials, their
//! height maps and material maps (each change is "change the settings, then sync").

use super::*;

impl DisplacementPass {
    /// Adds a displaced material: `field` as its height map (shared with a material that
    /// already has the same map and addressing: one texture, one pyramid, one cone map),
    /// its method, parameters and depth scale. Returns its handle; its
    /// [`MaterialId::index`] (the lowest free one) is what the host's G-buffer writes
    /// for its pixels. The next record uploads the map and builds what the method needs.
    /// Needs no GPU idle. On error the pass is unchanged.
    pub fn add_material(
        &mut self,
        field: &HeightField,
        settings: MaterialSettings,
    ) -> Result<MaterialId> {
        self.check_alive()?;
        validate_material(self.context()?, &settings)?;
        let index = self.free_index()?;
        let (map, new_map) = self.map_for(field, &settings)?;
        self.insert_material(index, settings, map, new_map)
    }

    /// The table index a new material gets: the lowest free one.
    pub(super) fn free_index(&self) -> Result<usize> {
        match self.materials.iter().position(Option::is_none) {
            Some(i) => Ok(i),
            None if self.materials.len() < MAX_MATERIALS as usize => Ok(self.materials.len()),
            None => Err(Error::invalid(
                "material",
                format!("the table is full ({MAX_MATERIALS} materials)"),
            )),
        }
    }

    /// Puts a material with `settings` on map `map` (`new_map`: made for it, destroyed
    /// if the sync fails) at `index` ([`DisplacementPass::free_index`]) and syncs.
    pub(super) fn insert_material(
        &mut self,
        index: usize,
        settings: MaterialSettings,
        map: usize,
        new_map: bool,
    ) -> Result<MaterialId> {
        let generation = self.next_generation;
        self.next_generation += 1;
        let entry = plan::MaterialEntry {
            generation,
            settings,
            map,
            shading: None,
            pending_shading: None,
            curved: false,
        };
        if index == self.materials.len() {
            self.materials.push(Some(entry));
        } else {
            self.materials[index] = Some(entry);
        }
        if let Err(e) = self.sync() {
            // Never recorded: destroyed at once.
            let unused = self.materials[index].take();
            // SAFETY: the failed sync recorded nothing with the new entry.
            unsafe { self.destroy_unused(unused) };
            if index + 1 == self.materials.len() {
                self.materials.pop();
            }
            if new_map {
                let unused = self.maps[map].take();
                // SAFETY: the failed sync recorded nothing with the new map.
                unsafe { self.destroy_unused(unused) };
            }
            return Err(e);
        }
        Ok(MaterialId {
            index: index as u32,
            generation,
        })
    }

    /// Removes a material: its pixels are treated as not displaced from the next record
    /// on. What only it used (its map when no other material shares it, pipelines, grids)
    /// is retired like a replaced method's resources. Needs no GPU idle.
    pub fn remove_material(&mut self, id: MaterialId) -> Result<()> {
        self.check_alive()?;
        let i = self.entry_index(id)?;
        let entry = self.materials[i].take();
        // The plan without it only drops resources: nothing is built, so the sync cannot
        // fail for lack of memory (the tile lists keep their size).
        let result = self.sync();
        self.retired.retire(entry);
        result
    }

    /// The handles of the live materials, by index.
    pub fn materials(&self) -> Vec<MaterialId> {
        self.materials
            .iter()
            .enumerate()
            .filter_map(|(i, m)| {
                m.as_ref().map(|m| MaterialId {
                    index: i as u32,
                    generation: m.generation,
                })
            })
            .collect()
    }

    /// A material's method pyramid once a record or preparation has built it (`None`
    /// for methods without one, or before the build; as [`DisplacementPass::pyramid`]).
    pub fn material_pyramid(&self, id: MaterialId) -> Option<&Pyramid> {
        let m = self.entry(id).ok()?;
        let kind = m.settings.method.needs().pyramid?;
        self.maps[m.map].as_ref()?.pyramid(kind)
    }

    /// A material's settings.
    pub fn material_settings(&self, id: MaterialId) -> Result<MaterialSettings> {
        Ok(self.entry(id)?.settings)
    }

    /// Changes a material's method, parameters and depth scale (not its addressing),
    /// building only what the new settings need that the pass lacks (a `trace` pipeline,
    /// a pyramid or cone map of its map, DIG grids; the height texture's mip chain when
    /// level of detail is switched, filled on the GPU from the old texture by the next
    /// record) and retiring what nothing uses any more.
    ///
    /// GPU-use contract: needs no GPU idle; what is replaced may still be read by frames
    /// in flight, so it is retired: destroyed once every slot has been recorded again (by
    /// the slot contract, every frame that could use it has completed), or by
    /// [`DisplacementPass::destroy`]. Frames recorded before the call keep the old
    /// settings. On error (invalid settings, an allocation or pipeline failure) the pass
    /// is unchanged.
    pub fn set_material_settings(
        &mut self,
        id: MaterialId,
        settings: MaterialSettings,
    ) -> Result<()> {
        self.check_alive()?;
        let i = self.entry_index(id)?;
        validate_material(self.context()?, &settings)?;
        let old = self.materials[i]
            .as_ref()
            .map(|m| m.settings)
            .unwrap_or(settings);
        if settings.addressing != old.addressing {
            return Err(Error::invalid(
                "addressing",
                "a material's addressing is fixed: remove it and add it again",
            ));
        }
        self.with_material_settings(i, settings);
        if let Err(e) = self.sync() {
            self.with_material_settings(i, old);
            return Err(e);
        }
        Ok(())
    }

    /// Swaps in a new height map for a material (any size; its addressing). The next
    /// [`DisplacementPass::record`] uploads it and rebuilds what its method needs (timed
    /// as `upload`, `pyramid`, `cone`). The old texture and what was derived from it stay
    /// alive for frames in flight (unless another material still uses them) and are
    /// retired. Needs no GPU idle. On error the pass is unchanged.
    pub fn set_material_height_map(&mut self, id: MaterialId, field: &HeightField) -> Result<()> {
        self.check_alive()?;
        let i = self.entry_index(id)?;
        let settings = self.entry(id)?.settings;
        let (map, new_map) = self.map_for(field, &settings)?;
        self.swap_material_map(i, map, new_map)
    }

    /// Points material `i` at map `map` (`new_map`: made for it, destroyed if the sync
    /// fails) and syncs; on error the material keeps its old map.
    pub(super) fn swap_material_map(&mut self, i: usize, map: usize, new_map: bool) -> Result<()> {
        let old = self.materials[i].as_ref().map_or(map, |m| m.map);
        if let Some(m) = &mut self.materials[i] {
            m.map = map;
        }
        if let Err(e) = self.sync() {
            if let Some(m) = &mut self.materials[i] {
                m.map = old;
            }
            if new_map {
                let unused = self.maps[map].take();
                // SAFETY: the failed sync recorded nothing with the new map.
                unsafe { self.destroy_unused(unused) };
            }
            return Err(e);
        }
        Ok(())
    }

    /// Sets a material's maps for `shade` (an albedo and a tangent-space normal map,
    /// addressed like its height map; [`crate::material`] has their conventions); empty
    /// [`MaterialImages`] remove them. The next record uploads them (in its `upload`
    /// scope); replaced maps are retired. A map with the same texels as one another
    /// material already has shares its image (one GPU copy). On error the material keeps
    /// its old maps.
    pub fn set_material_maps(&mut self, id: MaterialId, images: &MaterialImages) -> Result<()> {
        self.check_alive()?;
        let i = self.entry_index(id)?;
        let ctx = self.context()?.clone();
        let addressing = self.entry(id)?.settings.addressing;
        let others = (self.materials.iter().flatten())
            .filter_map(|m| Some((m.shading.as_ref()?, m.pending_shading.as_ref())));
        let created = MaterialTextures::create_sharing(&ctx, images, addressing, others)?;
        let (shading, staging) = created.unzip();
        if let Some(m) = &mut self.materials[i] {
            if let Some(old) = std::mem::replace(&mut m.shading, shading) {
                self.retired.retire(old);
            }
            // Staging never recorded: no frame reads it.
            // SAFETY: staging buffers are only read by the next record's upload, which has not happened.
            unsafe { std::mem::replace(&mut m.pending_shading, staging).destroy(&ctx) };
        }
        Ok(())
    }

    /// Traces the material's pixels as curved macro geometry (`on`) or as their tangent
    /// planes (the default). Curved: each pixel's ray follows the curvature of the base
    /// surface under it, which the host's G-buffer writes into its curve image
    /// ([`crate::passes::gbuffer::GBufferViews::curve`], `dispmap_gbuffer_curve` in
    /// `glsl/include/dispmap_gbuffer.glsl`; a frame without it fails naming
    /// `gbuffer.curve`), and a ray that crosses the shell between the base surface and its inward offset
    /// without meeting the relief is a miss (no hit: what lies behind shows), so carved
    /// outlines appear on curved meshes (docs/methods.md, "Curved surfaces"). It needs the
    /// frame's camera ([`DisplacementPass::record`] with a [`crate::embed::ShadeTarget`],
    /// or [`DisplacementPass::record_with_camera`]); without one the material is traced
    /// flat. Only methods with [`crate::method::Method::traces_curved`] (`exact`, `relief`,
    /// `pom`) follow it. Turn it on for materials drawn on curved meshes; on a plane it
    /// changes nothing but costs the curve image's reads. Takes effect from the next record;
    /// builds the method's curved pipeline variant (the flat one is compiled without the
    /// curved path) and retires the flat one if no material uses it. On error the pass is
    /// unchanged.
    pub fn set_material_curved(&mut self, id: MaterialId, on: bool) -> Result<()> {
        let i = self.entry_index(id)?;
        let set = |pass: &mut Self, on| {
            if let Some(m) = &mut pass.materials[i] {
                std::mem::replace(&mut m.curved, on)
            } else {
                on
            }
        };
        let old = set(self, on);
        if let Err(e) = self.sync() {
            set(self, old);
            return Err(e);
        }
        Ok(())
    }

    /// Whether the material is traced as curved geometry
    /// ([`DisplacementPass::set_material_curved`]).
    pub fn material_curved(&self, id: MaterialId) -> Result<bool> {
        Ok(self.entry(id)?.curved)
    }

    /// Gives the curved trace the meshes the frame draws, in world space as its G-buffer
    /// draws them (`meshes`; none: the default). A method with
    /// [`crate::method::Method::walks_meshes`] (`exact`) then follows a curved pixel's ray
    /// through the shell of the mesh's own triangles (`glsl/common/walk.glsl`: each
    /// sample's foot solved on its triangle, neighbours across edges matched by position),
    /// which is exact against the displaced mesh; a pixel on none of them (or every
    /// pixel, with no meshes) keeps the per-pixel circle model of the curve image. The
    /// meshes are copied into one buffer (36 words a triangle, the planes of the faces
    /// around it, and a start grid); moved meshes need another call. Takes effect from the next record; the old buffer is
    /// retired. Needs no GPU idle. On error the pass is unchanged.
    pub fn set_curved_meshes(&mut self, meshes: &[&crate::mesh::Mesh]) -> Result<()> {
        self.check_alive()?;
        let walk = crate::mesh::walk::WalkMeshes::new(self.context()?, meshes)?;
        self.replace_walk(walk)
    }

    /// [`DisplacementPass::set_curved_meshes`] without the walk buffer's flat regions
    /// ([`crate::mesh::walk::WalkMeshes::without_regions`]).
    #[cfg(test)]
    pub(crate) fn set_curved_meshes_without_regions(
        &mut self,
        meshes: &[&crate::mesh::Mesh],
    ) -> Result<()> {
        self.check_alive()?;
        let walk = crate::mesh::walk::WalkMeshes::without_regions(self.context()?, meshes)?;
        self.replace_walk(walk)
    }

    /// Makes `walk` the pass's walk buffer, the old one retired (restored on failure).
    fn replace_walk(&mut self, walk: crate::mesh::walk::WalkMeshes) -> Result<()> {
        let old = std::mem::replace(&mut self.walk, walk);
        // The slots' walk lists follow whether there is anything to walk.
        if let Err(e) = self.sync() {
            let new = std::mem::replace(&mut self.walk, old);
            self.retired.retire(new);
            return Err(e);
        }
        self.retired.retire(old);
        Ok(())
    }

    /// How many triangles the curved trace walks ([`DisplacementPass::set_curved_meshes`];
    /// 0: none).
    pub fn curved_mesh_triangles(&self) -> u32 {
        self.walk.triangles
    }

    /// The table index of a live material's handle.
    pub(super) fn entry_index(&self, id: MaterialId) -> Result<usize> {
        self.check_alive()?;
        match self.materials.get(id.index as usize) {
            Some(Some(m)) if m.generation == id.generation => Ok(id.index as usize),
            _ => Err(Error::invalid(
                "material",
                format!("{id:?} is not a material of this pass (removed, or of another pass)"),
            )),
        }
    }

    pub(super) fn entry(&self, id: MaterialId) -> Result<&plan::MaterialEntry> {
        let i = self.entry_index(id)?;
        self.materials[i]
            .as_ref()
            .ok_or_else(|| Error::Internal("a checked material entry is empty".into()))
    }

    /// Sets entry `i`'s settings, keeping [`DisplacementPass::settings`] in step.
    pub(super) fn with_material_settings(&mut self, i: usize, settings: MaterialSettings) {
        if let Some(m) = &mut self.materials[i] {
            m.settings = settings;
        }
        if i == self.primary.index as usize {
            self.primary_settings = PassSettings {
                method: settings.method,
                params: settings.params,
                depth_scale: settings.depth_scale,
                addressing: settings.addressing,
                ..self.primary_settings
            };
        }
    }

    /// The map table entry for `field` with `settings`' addressing: an existing one with
    /// the same content, or a new one with its upload staged (`true`).
    pub(super) fn map_for(
        &mut self,
        field: &HeightField,
        settings: &MaterialSettings,
    ) -> Result<(usize, bool)> {
        let key = plan::MapKey::of(field, settings.addressing);
        if let Some(i) = self
            .maps
            .iter()
            .position(|m| m.as_ref().is_some_and(|m| m.key == key))
        {
            return Ok((i, false));
        }
        let chain = settings.params.lod_threshold.is_some();
        let entry = plan::MapEntry::new(&self.context()?.clone(), field, key, chain)?;
        Ok((self.push_map(entry), true))
    }

    /// Puts `entry` in the map table's first free place; its index.
    pub(super) fn push_map(&mut self, entry: plan::MapEntry) -> usize {
        match self.maps.iter().position(Option::is_none) {
            Some(i) => {
                self.maps[i] = Some(entry);
                i
            }
            None => {
                self.maps.push(Some(entry));
                self.maps.len() - 1
            }
        }
    }
}
