//! Ownership of Vulkan objects without hand-written rollback: one trait for what can be
//! destroyed ([`Destroy`]), one guard for half-built state ([`Guard`]) and one queue for
//! what frames in flight may still read ([`RetireQueue`], after rafx's
//! `ResourceDropSink`: destruction deferred until every frame slot has been recorded
//! again).
//!
//! Every GPU object of the crate is destroyed explicitly with the [`Context`] that made
//! it; these types only decide *when*.

use crate::context::Context;

/// A GPU object (or a group of them) destroyed explicitly with its context. After
/// `destroy` the value owns nothing; destroying it again does nothing.
pub trait Destroy {
    /// Destroys the Vulkan objects and frees the memory. The GPU must be done with them:
    /// no pending command buffer may use them (the owner's contract: a [`Guard`] holds
    /// objects no command has used yet, a [`RetireQueue`] holds them until the frames
    /// that could use them have completed).
    fn destroy(&mut self, ctx: &Context);
}

impl<T: Destroy> Destroy for Option<T> {
    fn destroy(&mut self, ctx: &Context) {
        if let Some(mut v) = self.take() {
            v.destroy(ctx);
        }
    }
}

impl<T: Destroy> Destroy for Vec<T> {
    fn destroy(&mut self, ctx: &Context) {
        for mut v in self.drain(..) {
            v.destroy(ctx);
        }
    }
}

impl<A: Destroy, B: Destroy> Destroy for (A, B) {
    fn destroy(&mut self, ctx: &Context) {
        self.0.destroy(ctx);
        self.1.destroy(ctx);
    }
}

/// Implements [`Destroy`] by the type's own `destroy(&mut self, &Context)`.
macro_rules! destroy_by_method {
    ($($t:ty),* $(,)?) => {
        $(impl $crate::gpu::owned::Destroy for $t {
            fn destroy(&mut self, ctx: &$crate::context::Context) {
                <$t>::destroy(self, ctx)
            }
        })*
    };
}

/// A value being built that is destroyed when dropped unless [`Guard::keep`] takes it
/// out: an early `?` in a constructor destroys exactly what was built so far.
pub struct Guard<'c, T: Destroy> {
    ctx: &'c Context,
    value: Option<T>,
}

impl<'c, T: Destroy> Guard<'c, T> {
    /// Guards `value`, built with `ctx`.
    pub fn new(ctx: &'c Context, value: T) -> Self {
        Guard {
            ctx,
            value: Some(value),
        }
    }

    /// Takes the value out: the build succeeded and someone else owns it now.
    pub fn keep(mut self) -> T {
        self.value
            .take()
            .expect("a guard holds its value until kept")
    }
}

impl<T: Destroy> std::ops::Deref for Guard<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.value
            .as_ref()
            .expect("a guard holds its value until kept")
    }
}

impl<T: Destroy> std::ops::DerefMut for Guard<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        self.value
            .as_mut()
            .expect("a guard holds its value until kept")
    }
}

impl<T: Destroy> Drop for Guard<'_, T> {
    fn drop(&mut self) {
        self.value.destroy(self.ctx);
    }
}

/// Resources replaced while frames in flight may still read them. Each waits for a set
/// of frame slots; when every slot of its set has been recorded again (by the slot
/// contract, the frames that could read it have completed) it is destroyed.
pub struct RetireQueue {
    all_slots: u64,
    waiting: Vec<(u64, Box<dyn Destroy + Send>)>,
}

impl RetireQueue {
    /// A queue for `slots` frame slots (1..=64).
    pub fn new(slots: u32) -> Self {
        debug_assert!((1..=64).contains(&slots));
        RetireQueue {
            all_slots: if slots >= 64 {
                u64::MAX
            } else {
                (1u64 << slots) - 1
            },
            waiting: Vec::new(),
        }
    }

    /// Retires `resource` until every slot has been recorded again.
    pub fn retire(&mut self, resource: impl Destroy + Send + 'static) {
        self.waiting.push((self.all_slots, Box::new(resource)));
    }

    /// Retires `resource` until `slot` has been recorded again (only that slot's frame
    /// reads it).
    pub fn retire_for_slot(&mut self, slot: u32, resource: impl Destroy + Send + 'static) {
        self.waiting.push((1u64 << slot, Box::new(resource)));
    }

    /// Slot `slot` is being recorded again: its previous frame has completed. Destroys
    /// what no other slot still waits for.
    pub fn release(&mut self, ctx: &Context, slot: u32) {
        self.waiting.retain_mut(|(pending, resource)| {
            *pending &= !(1u64 << slot);
            if *pending == 0 {
                resource.destroy(ctx);
                false
            } else {
                true
            }
        });
    }

    /// Destroys everything now (the GPU must be idle).
    pub fn destroy_all(&mut self, ctx: &Context) {
        for (_, mut resource) in self.waiting.drain(..) {
            resource.destroy(ctx);
        }
    }

    /// How many resources wait.
    pub fn len(&self) -> usize {
        self.waiting.len()
    }

    /// Whether nothing waits.
    pub fn is_empty(&self) -> bool {
        self.waiting.is_empty()
    }
}

destroy_by_method!(
    crate::gpu::Buffer,
    crate::gpu::Image,
    crate::gpu::HeightTexture,
    crate::gpu::OneShot,
    crate::gpu::ComputePipeline,
    crate::gpu::pipeline::FetchPipeline,
    crate::material::MaterialTextures,
    crate::material::MaterialStaging,
    crate::mesh::MeshBuffers,
    crate::passes::background::BackgroundPass,
    crate::passes::classify::ClassifyPass,
    crate::passes::classify::TileLists,
    crate::passes::cone::ConeMap,
    crate::passes::cone::ConePass,
    crate::passes::dig::CornerGrid,
    crate::passes::dig::DigCornerPass,
    crate::passes::forward::ForwardPass,
    crate::passes::gbuffer::GBuffer,
    crate::passes::gbuffer::GBufferPass,
    crate::passes::hit_depth::HitDepthPass,
    crate::passes::motion::MotionPass,
    crate::passes::pixel_ray_buffer::PixelRayBuffer,
    crate::passes::camera_motion::CameraMotionPass,
    crate::passes::camera_motion::CameraMotion,
    crate::passes::pyramid::Pyramid,
    crate::passes::pyramid::PyramidPass,
    crate::passes::shade::ShadePass,
    crate::passes::shadow::ShadowPass,
    crate::passes::trace::TracePass,
    crate::timing::QueryPool,
);
