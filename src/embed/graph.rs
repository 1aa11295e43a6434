//! The frame as a declared graph: the resources a record touches, the state each enters
//! in, and what each stage reads and writes, taken from its shader's reflected bindings
//! (one GLSL binding name is one resource in every shader of the pass). One
//! [`Tracker`] per record derives every barrier between the stages from these
//! declarations, and the host contract's exit states are what the same declarations
//! leave ([`host_table`], checked against docs/embedding.md).

use crate::error::{Error, Result};
use crate::gpu::Image;
use crate::gpu::sync::Access;
use crate::gpu::track::{Target, Tracker, binding_access};
use crate::passes::PassName;
use crate::shaders::ShaderBinding;
use ash::vk;

/// A resource of a record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Res {
    /// The host's G-buffer images.
    Ray,
    /// The G-buffer's frame (normal, tangent, material, surface id).
    GFrame,
    Depth,
    /// The G-buffer's curve image (materials traced curved).
    Curve,
    /// The host's hit uv image.
    HitUv,
    /// The host's hit height image.
    HitHeight,
    /// The host's colour image (with a [`super::ShadeTarget`]).
    Color,
    /// The host's motion image (the motion output on).
    Motion,
    /// The light visibility: the slot's, or the host's given to `record_shading`.
    Visibility,
    /// The slot's corrected depth.
    HitDepth,
    /// The slot's iteration counts.
    Iterations,
    /// The slot's DIG corner grid of a material (by index).
    Corners(u32),
    /// The slot's tile lists.
    Tiles,
    /// The slot's per-material dispatch arguments of the lists.
    Args,
    /// The host's list of tiles a listed record classifies (the standalone renderer's
    /// behind layer), written and made visible to compute reads and indirect reads by
    /// the host.
    Listed,
    /// What frames only read: height textures, pyramids, cone maps, albedo and normal
    /// maps (filled and left sampled-readable by the builds before the stages).
    Maps,
    /// The mesh walk buffer (`DisplacementPass::set_curved_meshes`): written through
    /// its mapping before the submission that first reads it, then only read.
    Walk,
    /// The slot's mesh walk list: reset by a transfer; its first list appended to by the
    /// walk's first trace and read (and its dispatch arguments) by the triage, its second
    /// appended to by the triage and read (and its arguments) by the walk.
    WalkList,
}

/// The resource the binding `name` of a shader is, for a dispatch of `material`.
fn resource(name: &str, material: u32) -> Option<Res> {
    Some(match name {
        "u_ray" => Res::Ray,
        "u_frame" => Res::GFrame,
        "u_depth" => Res::Depth,
        "u_curve" => Res::Curve,
        "u_hit_uv" => Res::HitUv,
        "u_hit_height" => Res::HitHeight,
        "u_iterations" => Res::Iterations,
        "u_color" => Res::Color,
        "u_motion" => Res::Motion,
        "u_visibility" => Res::Visibility,
        "u_hit_depth" => Res::HitDepth,
        "u_corners" => Res::Corners(material),
        "u_tiles" => Res::Tiles,
        "u_args" => Res::Args,
        "u_listed" => Res::Listed,
        "u_height" | "u_pyramid" | "u_cone" | "u_albedo" | "u_normal_map" => Res::Maps,
        "u_walk" => Res::Walk,
        "u_walk_list" => Res::WalkList,
        _ => return None,
    })
}

/// The stages of a record in their order; a stage declared out of it is an error.
pub(super) const ORDER: [PassName; 7] = [
    PassName::Classify,
    PassName::DigCorners,
    PassName::Trace,
    PassName::Shadow,
    PassName::Shade,
    PassName::HitDepth,
    PassName::Motion,
];

/// Which entry point records: the hit images enter differently.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Entry {
    /// `record` / `record_with_camera`: the hit images' contents are discarded.
    Frame,
    /// `record_shading`: the hit images (and a given visibility) hold the host's values.
    Shading,
}

/// The host's images and the state each enters in (the module docs' entry column): what
/// the host's barrier made the image's earlier writes visible to, and its layout.
pub(super) fn host_entry(entry: Entry) -> [(Res, Access); 8] {
    let hit = match entry {
        // Discarded by the host's barrier (UNDEFINED -> GENERAL) and ordered before the
        // pass's writes.
        Entry::Frame => Access::COMPUTE_STORAGE_WRITE,
        Entry::Shading => Access::COMPUTE_STORAGE_READ,
    };
    [
        (Res::Ray, Access::COMPUTE_SAMPLED),
        (Res::GFrame, Access::COMPUTE_SAMPLED),
        (Res::Depth, Access::COMPUTE_SAMPLED),
        (Res::Curve, Access::COMPUTE_SAMPLED),
        (Res::HitUv, hit),
        (Res::HitHeight, hit),
        (Res::Color, Access::COMPUTE_STORAGE_WRITE),
        (Res::Motion, Access::COMPUTE_STORAGE_READ_WRITE),
    ]
}

/// A list of tiles the host gives a listed record: its writes visible to compute-shader
/// storage reads and indirect reads.
pub(super) const LISTED_ENTRY: Access = Access::INDIRECT_READ;

/// A visibility the host gives `record_shading`: its writes visible to storage reads.
pub(super) const HOST_VISIBILITY: Access = Access::COMPUTE_STORAGE_READ;

/// The state of a pass-owned resource when a record starts.
pub(super) fn owned_entry(res: Res) -> Access {
    let after = |stage| Access {
        stage,
        ..Access::UNDEFINED
    };
    match res {
        // The host may have read it in any stage and left it in any layout: discarded
        // after every earlier access.
        Res::HitDepth | Res::Iterations => after(vk::PipelineStageFlags2::ALL_COMMANDS),
        // The slot's previous frame (its last reader) has completed: discarded.
        Res::Visibility | Res::Corners(_) => after(vk::PipelineStageFlags2::COMPUTE_SHADER),
        // Last read by the slot's previous frame's indirect dispatches.
        Res::Tiles | Res::Args | Res::WalkList => Access {
            stage: vk::PipelineStageFlags2::DRAW_INDIRECT | vk::PipelineStageFlags2::COMPUTE_SHADER,
            ..Access::UNDEFINED
        },
        // Host-written before any submission (made visible by the submission itself),
        // then only read by compute shaders (a texel buffer).
        Res::Walk => Access {
            stage: vk::PipelineStageFlags2::COMPUTE_SHADER,
            access: vk::AccessFlags2::SHADER_SAMPLED_READ,
            layout: vk::ImageLayout::UNDEFINED,
        },
        _ => Access::COMPUTE_SAMPLED,
    }
}

/// The reset of the lists' arguments: a transfer write of a buffer.
pub(super) const ARGS_RESET: Access = Access {
    layout: vk::ImageLayout::UNDEFINED,
    ..Access::TRANSFER_WRITE
};

/// An indirect dispatch reads its arguments.
pub(super) const INDIRECT: Access = Access {
    stage: vk::PipelineStageFlags2::DRAW_INDIRECT,
    access: vk::AccessFlags2::INDIRECT_COMMAND_READ,
    layout: vk::ImageLayout::UNDEFINED,
};

/// One record's tracker and the images its barriers are recorded on.
pub(super) struct FrameGraph {
    tracker: Tracker<Res>,
    images: Vec<(Res, Target)>,
    stage: usize,
}

impl FrameGraph {
    /// A graph whose host images entered as `entry` says (the colour and motion images
    /// only if `color` / `motion`), the maps sampled-readable and the slot's lists last
    /// read by its previous frame.
    pub(super) fn new(entry: Entry, color: bool, motion: bool) -> Self {
        let mut tracker = Tracker::new();
        for (res, access) in host_entry(entry) {
            let given = match res {
                Res::Color => color,
                Res::Motion => motion,
                _ => true,
            };
            if given {
                tracker.enter(res, access);
            }
        }
        for res in [Res::Maps, Res::Walk, Res::Tiles, Res::Args, Res::WalkList] {
            tracker.enter(res, owned_entry(res));
        }
        FrameGraph {
            tracker,
            images: Vec::new(),
            stage: 0,
        }
    }

    /// A pass-owned image of the slot (visibility, corrected depth, iteration counts, a
    /// corner grid): it
    /// enters as [`owned_entry`] says, and its barriers are image barriers on `image`.
    pub(super) fn own(&mut self, res: Res, image: &Image) {
        self.tracker.enter(res, owned_entry(res));
        self.images
            .push((res, Target::Image(image.raw, image.range())));
    }

    /// A resource the host gives, known by its view, entering in `entry`.
    pub(super) fn enter_host(&mut self, res: Res, entry: Access) {
        self.tracker.enter(res, entry);
    }

    /// Declares `res` accessed as `access` by the stage being recorded.
    pub(super) fn declare(&mut self, res: Res, access: Access) -> Result<()> {
        self.tracker.declare(res, access)
    }

    /// Declares a dispatch of a shader with `bindings` for `material`: each binding's
    /// resource accessed as the shader declares it ([`binding_access`]), except those in
    /// `skip` (bound but not accessed by this dispatch); a shader that reads the tile
    /// lists is dispatched indirectly, so its arguments are read too, and so is one that
    /// binds the walk list without the tile lists (the triage and the walk run the
    /// pixels of a walk list, dispatched from its own arguments).
    pub(super) fn dispatch(
        &mut self,
        bindings: &[ShaderBinding],
        material: u32,
        skip: &[Res],
    ) -> Result<()> {
        let tiled = bindings
            .iter()
            .any(|b| b.name == crate::passes::classify::TILES.0);
        for b in bindings {
            let res = resource(b.name, material).ok_or_else(|| {
                Error::Internal(format!("binding {} names no resource of the frame", b.name))
            })?;
            if skip.contains(&res) {
                continue;
            }
            self.tracker.declare(res, binding_access(b))?;
            if res == Res::Tiles && !b.writes {
                self.tracker.declare(Res::Args, INDIRECT)?;
            }
            if res == Res::WalkList && !tiled {
                self.tracker.declare(Res::WalkList, INDIRECT)?;
            }
        }
        Ok(())
    }

    /// Records the barriers the declarations of `stage` need (one command), in the order
    /// of [`ORDER`] (an error otherwise).
    ///
    /// # Safety
    /// As [`Tracker::flush`]: `cmd` is recording outside a render pass; every image given
    /// to [`FrameGraph::own`] is alive until the command buffer has executed; the host's
    /// images enter as [`host_entry`] says (the host's barriers) and the slot's as
    /// [`owned_entry`] says (the slot contract).
    pub(super) unsafe fn flush(
        &mut self,
        ctx: &crate::context::Context,
        cmd: vk::CommandBuffer,
        stage: PassName,
    ) -> Result<()> {
        let at = ORDER
            .iter()
            .position(|&s| s == stage)
            .filter(|&i| i >= self.stage)
            .ok_or_else(|| Error::Internal(format!("stage {stage:?} recorded out of order")))?;
        self.stage = at;
        let images = &self.images;
        let target = |res: Res| {
            images
                .iter()
                .find(|(r, _)| *r == res)
                .map_or(Target::Memory, |(_, t)| *t)
        };
        // SAFETY: this function's contract is the tracker's.
        unsafe { self.tracker.flush(ctx, cmd, target) }
    }

    #[cfg(test)]
    /// Resolves the declarations without recording (what [`host_table`] runs).
    fn resolve(&mut self) -> Result<()> {
        self.tracker.resolve().map(|_| ())
    }

    #[cfg(test)]
    /// `res`'s last accesses and layout.
    fn exit(&self, res: Res) -> Option<Access> {
        self.tracker.exit(res)
    }
}

#[cfg(test)]
/// The exit state of every image the host gives or may read, computed by running the
/// declarations of a frame with every output on (shade with self-shadowing, corrected
/// depth, motion, iteration counts; one DIG material) and of `record_shading`:
/// `(image, entry, exit)`.
/// With fewer outputs the layouts are the same and the accesses a subset.
pub(super) fn host_exits() -> Result<Vec<(&'static str, Access, Access)>> {
    use crate::shaders;
    let mut g = FrameGraph::new(Entry::Frame, true, true);
    for res in [
        Res::Visibility,
        Res::HitDepth,
        Res::Iterations,
        Res::Corners(0),
    ] {
        g.tracker.enter(res, owned_entry(res));
    }
    let stages: [(&[ShaderBinding], &[Res]); 11] = [
        (shaders::CLASSIFY_COMP_DEPTH_ITERATIONS.bindings, &[]),
        (shaders::CLASSIFY_OFFSETS_COMP.bindings, &[]),
        (shaders::CLASSIFY_SCATTER_COMP.bindings, &[]),
        (shaders::CLASSIFY_MIXED_COMP.bindings, &[]),
        (shaders::DIG_CORNERS_COMP.bindings, &[]),
        (shaders::TRACE_DIG_COMP_ITERATIONS.bindings, &[]),
        (shaders::TRACE_EXACT_COMP_CURVED_ITERATIONS.bindings, &[]),
        (shaders::SHADOW_COMP.bindings, &[]),
        (shaders::SHADE_COMP_SHADOWS.bindings, &[]),
        (shaders::HIT_DEPTH_COMP.bindings, &[]),
        (shaders::MOTION_COMP.bindings, &[]),
    ];
    g.declare(Res::Args, ARGS_RESET)?;
    g.resolve()?;
    for (bindings, skip) in stages {
        g.dispatch(bindings, 0, skip)?;
        g.resolve()?;
    }
    let mut s = FrameGraph::new(Entry::Shading, true, false);
    s.enter_host(Res::Visibility, HOST_VISIBILITY);
    s.declare(Res::Args, ARGS_RESET)?;
    s.resolve()?;
    for (bindings, skip) in [
        (
            shaders::CLASSIFY_COMP.bindings,
            &[Res::HitUv, Res::HitHeight][..],
        ),
        (shaders::CLASSIFY_OFFSETS_COMP.bindings, &[]),
        (shaders::CLASSIFY_SCATTER_COMP.bindings, &[]),
        (shaders::CLASSIFY_MIXED_COMP.bindings, &[]),
        (shaders::SHADE_COMP_SHADOWS.bindings, &[]),
    ] {
        s.dispatch(bindings, 0, skip)?;
        s.resolve()?;
    }
    let entry = |e: Entry, r: Res| {
        host_entry(e)
            .into_iter()
            .find(|(res, _)| *res == r)
            .map(|(_, a)| a)
    };
    let rows = [
        (
            "gbuffer.ray",
            entry(Entry::Frame, Res::Ray),
            g.exit(Res::Ray),
        ),
        (
            "gbuffer.frame",
            entry(Entry::Frame, Res::GFrame),
            g.exit(Res::GFrame),
        ),
        (
            "gbuffer.depth",
            entry(Entry::Frame, Res::Depth),
            g.exit(Res::Depth),
        ),
        (
            "gbuffer.curve (curved tracing)",
            entry(Entry::Frame, Res::Curve),
            g.exit(Res::Curve),
        ),
        (
            "hit uv",
            entry(Entry::Frame, Res::HitUv),
            g.exit(Res::HitUv),
        ),
        (
            "hit height",
            entry(Entry::Frame, Res::HitHeight),
            g.exit(Res::HitHeight),
        ),
        ("color", entry(Entry::Frame, Res::Color), g.exit(Res::Color)),
        (
            "motion",
            entry(Entry::Frame, Res::Motion),
            g.exit(Res::Motion),
        ),
        (
            "visibility (the pass's)",
            Some(owned_entry(Res::Visibility)),
            g.exit(Res::Visibility),
        ),
        (
            "corrected depth (the pass's)",
            Some(owned_entry(Res::HitDepth)),
            g.exit(Res::HitDepth),
        ),
        (
            "iterations (the pass's)",
            Some(owned_entry(Res::Iterations)),
            g.exit(Res::Iterations),
        ),
        (
            "hit uv (record_shading)",
            entry(Entry::Shading, Res::HitUv),
            s.exit(Res::HitUv),
        ),
        (
            "hit height (record_shading)",
            entry(Entry::Shading, Res::HitHeight),
            s.exit(Res::HitHeight),
        ),
        (
            "visibility (record_shading, the host's)",
            Some(HOST_VISIBILITY),
            s.exit(Res::Visibility),
        ),
    ];
    rows.into_iter()
        .map(|(name, entry, exit)| match (entry, exit) {
            (Some(e), Some(x)) => Ok((name, e, x)),
            _ => Err(Error::Internal(format!("{name} has no state"))),
        })
        .collect()
}

#[cfg(test)]
/// Flags as `A, B` (`none` when empty), from ash's names.
fn flags(debug: String) -> String {
    if debug.is_empty() || debug == "NONE" || debug == "(empty)" || debug == "0" {
        return "none".into();
    }
    debug.replace(" | ", ", ")
}

#[cfg(test)]
/// The markdown rows of [`host_exits`]: image, entry layout, what the entry made the
/// image's earlier writes visible to, exit layout, the last accesses on exit (what the
/// host's next barrier waits for).
pub(super) fn host_table() -> Result<Vec<String>> {
    let side = |a: Access| {
        (
            format!("`{:?}`", a.layout),
            format!(
                "`{}` / `{}`",
                flags(format!("{:?}", a.stage)),
                flags(format!("{:?}", a.access))
            ),
        )
    };
    Ok(host_exits()?
        .into_iter()
        .map(|(name, entry, exit)| {
            let (el, ea) = side(entry);
            let (xl, xa) = side(exit);
            format!("| {name} | {el} | {ea} | {xl} | {xa} |")
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// docs/embedding.md's table of entry and exit states is the one the declarations
    /// compute.
    #[test]
    fn the_documented_exit_states_are_the_declared_ones() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/embedding.md");
        let doc = std::fs::read_to_string(path).unwrap();
        let start = doc
            .find("<!-- host-states:begin -->")
            .expect("docs/embedding.md has the host-states table");
        let end = doc.find("<!-- host-states:end -->").unwrap();
        let documented: Vec<&str> = doc[start..end]
            .lines()
            .filter(|l| l.starts_with("| ") && !l.starts_with("| image "))
            .collect();
        let computed = host_table().unwrap();
        assert_eq!(
            documented,
            computed.iter().map(String::as_str).collect::<Vec<_>>(),
            "docs/embedding.md's host-states table differs from the declarations; \
             computed:\n{}",
            computed.join("\n")
        );
    }

    /// Every binding of every compute shader a record dispatches names a resource.
    #[test]
    fn every_binding_of_the_frame_names_a_resource() {
        use crate::shaders;
        let mut all = vec![
            shaders::CLASSIFY_COMP,
            shaders::CLASSIFY_COMP_DEPTH,
            shaders::CLASSIFY_COMP_ITERATIONS,
            shaders::CLASSIFY_COMP_DEPTH_ITERATIONS,
            shaders::CLASSIFY_OFFSETS_COMP,
            shaders::CLASSIFY_SCATTER_COMP,
            shaders::CLASSIFY_MIXED_COMP,
            shaders::DIG_CORNERS_COMP,
            shaders::SHADOW_COMP,
            shaders::SHADOW_COMP_PYRAMID,
            shaders::SHADE_COMP,
            shaders::SHADE_COMP_SHADOWS,
            shaders::HIT_DEPTH_COMP,
            shaders::MOTION_COMP,
            shaders::MOTION_COMP_WIDE,
        ];
        all.extend(crate::method::Method::ALL.iter().map(|m| m.shader()));
        all.extend(
            crate::method::Method::ALL
                .iter()
                .map(|m| m.iterations_shader()),
        );
        for iterations in [false, true] {
            all.extend(
                crate::method::Method::ALL
                    .iter()
                    .filter_map(|m| m.curved_shader(iterations)),
            );
        }
        for s in all {
            for b in s.bindings {
                assert!(
                    resource(b.name, 0).is_some(),
                    "{}: binding {} ({}) names no resource",
                    s.name,
                    b.binding,
                    b.name
                );
            }
        }
    }
}
