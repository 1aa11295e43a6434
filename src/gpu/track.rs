//! The one place the pass's barriers are derived: each resource's last access, and the
//! barrier a newly declared access needs after it.
//!
//! A [`Tracker`] is keyed by whatever names the resources of one command buffer's work
//! (the orchestrator's frame graph uses its own enum). Each resource enters once with the
//! state its owner documents ([`Tracker::enter`]: a host image's entry state, or a
//! discarded per-slot image's last user). Every pass then *declares* what it reads and
//! writes and how ([`Tracker::declare`], an [`Access`] per binding, usually reflected
//! from the shader: [`binding_access`]); [`Tracker::flush`] turns the declarations of
//! one stage into the barriers they need, batched into one `vkCmdPipelineBarrier2`.
//! Nothing else writes a "before" state: the exit state of every resource is what the
//! declarations left ([`Tracker::exit`]).
//!
//! The rules (those of kajiya's render graph and wgpu-hal's usage-to-barrier mapping,
//! in synchronization2 terms):
//! * a layout change, any write, and a read that the last barrier did not make the last
//!   write visible to, get a barrier;
//! * a write right after a barrier whose destination covers it (e.g. the host's entry
//!   barrier) needs none, nor does a read the last barrier already covers, nor the first
//!   access of a resource nothing accessed that keeps its layout;
//! * the barrier waits for the last write and every read since (`src` = their stages,
//!   the write's accesses), and makes the write visible to the new access (`dst`);
//! * images with a `vk::Image` get image barriers; buffers and images known only by their
//!   view (the host's, which never change layout here) share one global memory barrier.

use super::sync::{self, Access};
use super::{Buffer, Image};
use crate::context::Context;
use crate::error::{Error, Result};
use crate::shaders::ShaderBinding;
use ash::vk;

/// What a barrier of a resource is recorded on.
#[derive(Clone, Copy, Debug)]
pub enum Target {
    /// An image with its subresource range: image barriers, layout transitions allowed.
    Image(vk::Image, vk::ImageSubresourceRange),
    /// A buffer, or an image known only by its view that keeps its layout: a global
    /// memory barrier.
    Memory,
}

/// One barrier the tracker derived: `key` from `src` (its last accesses and layout) to
/// `dst`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transition<K> {
    /// The resource.
    pub key: K,
    /// What the barrier waits for and its old layout.
    pub src: Access,
    /// What it makes the resource ready for and its new layout.
    pub dst: Access,
}

/// What the tracker knows of one resource.
#[derive(Clone, Copy, Debug)]
struct State {
    layout: vk::ImageLayout,
    /// The last write (or layout transition) and its stages.
    write_stage: vk::PipelineStageFlags2,
    write_access: vk::AccessFlags2,
    /// The reads since then.
    read_stage: vk::PipelineStageFlags2,
    read_access: vk::AccessFlags2,
    /// What the last barrier made the last write visible to.
    visible_stage: vk::PipelineStageFlags2,
    visible_access: vk::AccessFlags2,
    /// No access since that barrier.
    fresh: bool,
}

const WRITES: vk::AccessFlags2 = vk::AccessFlags2::from_raw(
    vk::AccessFlags2::SHADER_STORAGE_WRITE.as_raw()
        | vk::AccessFlags2::SHADER_WRITE.as_raw()
        | vk::AccessFlags2::TRANSFER_WRITE.as_raw()
        | vk::AccessFlags2::COLOR_ATTACHMENT_WRITE.as_raw()
        | vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_WRITE.as_raw()
        | vk::AccessFlags2::HOST_WRITE.as_raw()
        | vk::AccessFlags2::MEMORY_WRITE.as_raw(),
);

/// Whether `access` writes.
pub fn writes(access: vk::AccessFlags2) -> bool {
    access.intersects(WRITES)
}

impl State {
    fn entered(entry: Access) -> State {
        State {
            layout: entry.layout,
            write_stage: entry.stage,
            write_access: vk::AccessFlags2::NONE,
            read_stage: vk::PipelineStageFlags2::NONE,
            read_access: vk::AccessFlags2::NONE,
            visible_stage: entry.stage,
            visible_access: entry.access,
            fresh: true,
        }
    }

    /// The barrier `access` needs after this state, if any.
    fn barrier(&self, access: Access) -> Option<(Access, Access)> {
        let covered = self.visible_stage.contains(access.stage)
            && self.visible_access.contains(access.access)
            && (self.fresh || !writes(access.access));
        if access.layout == self.layout && covered {
            return None;
        }
        let src = Access {
            stage: self.write_stage | self.read_stage,
            access: self.write_access & WRITES,
            layout: self.layout,
        };
        if src.stage.is_empty() && access.layout == self.layout {
            // Nothing to wait for and no layout to change (a resource nothing accessed).
            return None;
        }
        Some((src, access))
    }

    /// The state after `barrier` (if any) and then `access`.
    fn apply(&mut self, barrier: bool, access: Access) {
        if barrier {
            if access.layout != self.layout {
                // The transition is a write ordered before `access`'s stages.
                self.write_stage = access.stage;
                self.write_access = vk::AccessFlags2::NONE;
            }
            self.layout = access.layout;
            self.read_stage = vk::PipelineStageFlags2::NONE;
            self.read_access = vk::AccessFlags2::NONE;
            self.visible_stage = access.stage;
            self.visible_access = access.access;
        }
        if writes(access.access) {
            self.write_stage = access.stage;
            self.write_access = access.access;
            self.read_stage = vk::PipelineStageFlags2::NONE;
            self.read_access = vk::AccessFlags2::NONE;
            self.visible_stage = vk::PipelineStageFlags2::NONE;
            self.visible_access = vk::AccessFlags2::NONE;
        } else {
            self.read_stage |= access.stage;
            self.read_access |= access.access;
        }
        self.fresh = false;
    }

    /// The last accesses: what a barrier after them waits for, and the layout.
    fn exit(&self) -> Access {
        Access {
            stage: self.write_stage | self.read_stage,
            access: self.write_access | self.read_access,
            layout: self.layout,
        }
    }
}

/// Each resource's last access, and the declarations of the stage being recorded.
#[derive(Debug)]
pub struct Tracker<K> {
    states: Vec<(K, State)>,
    pending: Vec<(K, Access)>,
}

impl<K: Copy + Eq + std::fmt::Debug> Default for Tracker<K> {
    fn default() -> Self {
        Tracker {
            states: Vec::new(),
            pending: Vec::new(),
        }
    }
}

impl<K: Copy + Eq + std::fmt::Debug> Tracker<K> {
    /// An empty tracker.
    pub fn new() -> Self {
        Self::default()
    }

    /// `key` enters in `entry`: its layout, and the stages and accesses its earlier
    /// accesses were made visible to (a host image's documented entry state; for a
    /// resource whose contents are discarded, `UNDEFINED` with no access after the
    /// stages of its last user). Replaces what was known of `key`.
    pub fn enter(&mut self, key: K, entry: Access) {
        let state = State::entered(entry);
        match self.states.iter_mut().find(|(k, _)| *k == key) {
            Some((_, s)) => *s = state,
            None => self.states.push((key, state)),
        }
    }

    /// Declares that the stage being recorded accesses `key` as `access`. Declarations
    /// of one key in one stage are one access (their stages and accesses joined; several
    /// dispatches of one stage over disjoint pixels need no barrier between them).
    pub fn declare(&mut self, key: K, access: Access) -> Result<()> {
        match self.pending.iter_mut().find(|(k, _)| *k == key) {
            Some((_, a)) if a.layout != access.layout => Err(Error::Internal(format!(
                "{key:?} declared in {:?} and {:?} by one stage",
                a.layout, access.layout
            ))),
            Some((_, a)) => {
                a.stage |= access.stage;
                a.access |= access.access;
                Ok(())
            }
            None => {
                self.pending.push((key, access));
                Ok(())
            }
        }
    }

    /// The barriers the declarations since the last call need, in declaration order;
    /// the tracker then knows the declared accesses as each resource's last. An error for
    /// a key that never entered.
    pub fn resolve(&mut self) -> Result<Vec<Transition<K>>> {
        let mut out = Vec::new();
        for (key, access) in std::mem::take(&mut self.pending) {
            let Some((_, state)) = self.states.iter_mut().find(|(k, _)| *k == key) else {
                return Err(Error::Internal(format!("{key:?} used before it entered")));
            };
            let barrier = state.barrier(access);
            if let Some((src, dst)) = barrier {
                out.push(Transition { key, src, dst });
            }
            state.apply(barrier.is_some(), access);
        }
        Ok(out)
    }

    /// Records the barriers of the declarations since the last call ([`Tracker::resolve`])
    /// in one `vkCmdPipelineBarrier2` (nothing when none is needed): an image barrier for
    /// each resource `target` names an [`Target::Image`], one global memory barrier
    /// joining the others.
    ///
    /// # Safety
    /// As [`sync::record`]: `cmd` is a command buffer of `ctx`'s device in the recording
    /// state, outside a render pass instance; every image `target` names is alive until
    /// the command buffer has executed and, when it executes, in the state the tracker
    /// knows (each resource's entry state as given to [`Tracker::enter`], then the
    /// declared accesses, recorded in this order in this command buffer).
    pub unsafe fn flush(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        target: impl Fn(K) -> Target,
    ) -> Result<()> {
        let transitions = self.resolve()?;
        let mut images = Vec::new();
        let mut memory: Option<vk::MemoryBarrier2> = None;
        for t in transitions {
            match target(t.key) {
                Target::Image(image, range) => {
                    images.push(sync::image_barrier(image, range, t.src, t.dst));
                }
                Target::Memory if t.src.layout != t.dst.layout => {
                    return Err(Error::Internal(format!(
                        "{:?} changes layout ({:?} -> {:?}) without an image",
                        t.key, t.src.layout, t.dst.layout
                    )));
                }
                Target::Memory => {
                    let m = memory.get_or_insert_with(vk::MemoryBarrier2::default);
                    m.src_stage_mask |= t.src.stage;
                    m.src_access_mask |= t.src.access;
                    m.dst_stage_mask |= t.dst.stage;
                    m.dst_access_mask |= t.dst.access;
                }
            }
        }
        if images.is_empty() && memory.is_none() {
            return Ok(());
        }
        let memory: Vec<_> = memory.into_iter().collect();
        let dep = vk::DependencyInfo::default()
            .image_memory_barriers(&images)
            .memory_barriers(&memory);
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the images are alive and in the old layouts the tracker derived.
        unsafe { ctx.device().cmd_pipeline_barrier2(cmd, &dep) };
        Ok(())
    }

    /// `key`'s last accesses (what a barrier after them waits for: their stages and
    /// accesses) and its layout; `None` if it never entered.
    pub fn exit(&self, key: K) -> Option<Access> {
        let (_, s) = self.states.iter().find(|(k, _)| *k == key)?;
        Some(s.exit())
    }
}

/// A resource known by its Vulkan handle: what the standalone renderer and one-off
/// recordings (uploads, read-backs, builds) track with a `Tracker<Handle>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Handle {
    /// Mip levels `base .. base + count` of an image (its format's aspect, one layer).
    Image {
        /// The image.
        image: vk::Image,
        /// Its format's aspect.
        aspect: vk::ImageAspectFlags,
        /// The first level.
        base: u32,
        /// The number of levels.
        count: u32,
    },
    /// A buffer (its barriers are global memory barriers).
    Buffer(vk::Buffer),
}

impl Handle {
    /// Every level of `image`.
    pub fn image(image: &Image) -> Handle {
        let range = image.range();
        Handle::Image {
            image: image.raw,
            aspect: range.aspect_mask,
            base: 0,
            count: range.level_count,
        }
    }

    /// Level `level` of `image`.
    pub fn level(image: &Image, level: u32) -> Handle {
        Handle::Image {
            image: image.raw,
            aspect: image.range().aspect_mask,
            base: level,
            count: 1,
        }
    }

    /// `buffer`.
    pub fn buffer(buffer: &Buffer) -> Handle {
        Handle::Buffer(buffer.raw)
    }

    /// What its barriers are recorded on.
    pub fn target(self) -> Target {
        match self {
            Handle::Image {
                image,
                aspect,
                base,
                count,
            } => Target::Image(
                image,
                vk::ImageSubresourceRange {
                    aspect_mask: aspect,
                    base_mip_level: base,
                    level_count: count,
                    base_array_layer: 0,
                    layer_count: 1,
                },
            ),
            Handle::Buffer(_) => Target::Memory,
        }
    }
}

impl Tracker<Handle> {
    /// [`Tracker::flush`] with each handle's own [`Handle::target`].
    ///
    /// # Safety
    /// As [`Tracker::flush`]: `cmd` is a command buffer of `ctx`'s device in the recording
    /// state, outside a render pass instance; every handle declared is alive until the
    /// command buffer has executed and, when it executes, in the state the tracker knows
    /// (its entry state, then the declared accesses, recorded in this order).
    pub unsafe fn record(&mut self, ctx: &Context, cmd: vk::CommandBuffer) -> Result<()> {
        // SAFETY: this function's contract is the flush's.
        unsafe { self.flush(ctx, cmd, Handle::target) }
    }
}

/// How a compute shader accesses a binding, from its reflection: sampled images are read
/// in `SHADER_READ_ONLY_OPTIMAL`, storage images in `GENERAL` (read, written or both as
/// the GLSL's `readonly` / `writeonly` say), buffers with no layout.
pub fn binding_access(b: &ShaderBinding) -> Access {
    let stage = vk::PipelineStageFlags2::COMPUTE_SHADER;
    let storage = |layout| {
        let mut access = vk::AccessFlags2::NONE;
        if b.reads {
            access |= vk::AccessFlags2::SHADER_STORAGE_READ;
        }
        if b.writes {
            access |= vk::AccessFlags2::SHADER_STORAGE_WRITE;
        }
        Access {
            stage,
            access,
            layout,
        }
    };
    match b.ty {
        vk::DescriptorType::STORAGE_IMAGE => storage(vk::ImageLayout::GENERAL),
        vk::DescriptorType::STORAGE_BUFFER => storage(vk::ImageLayout::UNDEFINED),
        vk::DescriptorType::UNIFORM_BUFFER => Access {
            stage,
            access: vk::AccessFlags2::UNIFORM_READ,
            layout: vk::ImageLayout::UNDEFINED,
        },
        vk::DescriptorType::UNIFORM_TEXEL_BUFFER => Access {
            stage,
            access: vk::AccessFlags2::SHADER_SAMPLED_READ,
            layout: vk::ImageLayout::UNDEFINED,
        },
        _ => Access::COMPUTE_SAMPLED,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_share_a_barrier_and_writes_wait_for_every_reader() {
        let mut t = Tracker::new();
        t.enter("hit", Access::COMPUTE_STORAGE_WRITE);
        // The entry barrier covers the first write.
        t.declare("hit", Access::COMPUTE_STORAGE_WRITE).unwrap();
        assert_eq!(t.resolve().unwrap(), vec![]);
        // A second writer waits for the first.
        t.declare("hit", Access::COMPUTE_STORAGE_WRITE).unwrap();
        let w = t.resolve().unwrap();
        assert_eq!(w.len(), 1);
        assert_eq!(w[0].src.access, vk::AccessFlags2::SHADER_STORAGE_WRITE);
        // The first reader gets the write made visible; the second needs nothing.
        t.declare("hit", Access::COMPUTE_STORAGE_READ).unwrap();
        assert_eq!(t.resolve().unwrap().len(), 1);
        t.declare("hit", Access::COMPUTE_STORAGE_READ).unwrap();
        assert_eq!(t.resolve().unwrap(), vec![]);
        let exit = t.exit("hit").unwrap();
        assert_eq!(
            exit.access,
            vk::AccessFlags2::SHADER_STORAGE_WRITE | vk::AccessFlags2::SHADER_STORAGE_READ
        );
        // A writer after readers waits for them (write-after-read).
        t.declare("hit", Access::COMPUTE_STORAGE_WRITE).unwrap();
        let war = t.resolve().unwrap();
        assert_eq!(war.len(), 1);
        assert_eq!(war[0].src.stage, vk::PipelineStageFlags2::COMPUTE_SHADER);
    }

    #[test]
    fn a_layout_change_is_a_barrier_and_a_discard_starts_undefined() {
        let mut t = Tracker::new();
        let discard = Access {
            stage: vk::PipelineStageFlags2::COMPUTE_SHADER,
            ..Access::UNDEFINED
        };
        t.enter(1u32, discard);
        t.declare(1, Access::COMPUTE_STORAGE_WRITE).unwrap();
        let first = t.resolve().unwrap();
        assert_eq!(first[0].src, discard);
        t.declare(1, Access::COMPUTE_SAMPLED).unwrap();
        let to_read = t.resolve().unwrap();
        assert_eq!(to_read[0].src, Access::COMPUTE_STORAGE_WRITE);
        assert_eq!(to_read[0].dst, Access::COMPUTE_SAMPLED);
        // Already sampled-readable: no barrier.
        t.declare(1, Access::COMPUTE_SAMPLED).unwrap();
        assert!(t.resolve().unwrap().is_empty());
        // Used before it entered: an error, not a guess.
        t.declare(2, Access::COMPUTE_SAMPLED).unwrap();
        assert!(t.resolve().is_err());
    }

    #[test]
    fn one_stage_joins_its_declarations_of_a_key() {
        let mut t = Tracker::new();
        t.enter('m', Access::COMPUTE_STORAGE_READ_WRITE);
        t.declare('m', Access::COMPUTE_STORAGE_READ_WRITE).unwrap();
        t.declare('m', Access::COMPUTE_STORAGE_READ_WRITE).unwrap();
        assert!(t.resolve().unwrap().is_empty());
        t.declare('m', Access::COMPUTE_SAMPLED).unwrap();
        assert!(t.declare('m', Access::COMPUTE_STORAGE_READ).is_err());
    }
}
