//! Ownership of Vulkan objects without hand-written rollback: one trait for what can be
//! destroyed ([`Destroy`]), one guard for half-built state ([`Guard`]) and one queue for
//! what frames in flight may still read ([`RetireQueue`], after rafx's
//! `ResourceDropSink`: destruction deferred until every frame slot has been recorded
//! again).
//!
//! Every GPU object of the crate is destroyed explicitly with the [`Context`] that made
//! it, by its own `impl Destroy` beside its type; these types only decide *when*.

use crate::context::Context;

/// A GPU object (or a group of them) destroyed explicitly with its context. After
/// `destroy` the value owns nothing (every handle it freed is null); destroying it again
/// does nothing.
pub trait Destroy {
    /// Destroys the Vulkan objects and frees the memory.
    ///
    /// # Safety
    /// The GPU is done with them: no command buffer that may still be pending uses them
    /// (the owner's contract: a [`Guard`] holds objects no command has used yet, a
    /// [`RetireQueue`] holds them until the frames that could use them have completed).
    /// `ctx` is the context (device and allocator) they were made with.
    unsafe fn destroy(&mut self, ctx: &Context);

    /// The bytes of device memory the value holds (its allocations' sizes; 0 for objects
    /// without memory of their own, such as pipelines, samplers and views of another's
    /// image): what [`crate::embed::MemoryReport`] sums.
    fn bytes(&self) -> u64 {
        0
    }
}

impl<T: Destroy> Destroy for Option<T> {
    unsafe fn destroy(&mut self, ctx: &Context) {
        if let Some(mut v) = self.take() {
            // SAFETY: this function's contract, passed on.
            unsafe { v.destroy(ctx) };
        }
    }

    fn bytes(&self) -> u64 {
        self.as_ref().map_or(0, T::bytes)
    }
}

impl<T: Destroy> Destroy for Vec<T> {
    unsafe fn destroy(&mut self, ctx: &Context) {
        for mut v in self.drain(..) {
            // SAFETY: this function's contract, passed on.
            unsafe { v.destroy(ctx) };
        }
    }

    fn bytes(&self) -> u64 {
        self.iter().map(T::bytes).sum()
    }
}

impl<T: Destroy + ?Sized> Destroy for Box<T> {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: this function's contract, passed on.
        unsafe { (**self).destroy(ctx) };
    }

    fn bytes(&self) -> u64 {
        (**self).bytes()
    }
}

impl<A: Destroy, B: Destroy> Destroy for (A, B) {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: this function's contract, passed on.
        unsafe {
            self.0.destroy(ctx);
            self.1.destroy(ctx);
        }
    }

    fn bytes(&self) -> u64 {
        self.0.bytes() + self.1.bytes()
    }
}

/// A value being built that is destroyed when dropped unless [`Guard::keep`] takes it
/// out: an early `?` in a constructor destroys exactly what was built so far.
pub struct Guard<'c, T: Destroy> {
    ctx: &'c Context,
    value: Option<T>,
}

impl<'c, T: Destroy> Guard<'c, T> {
    /// Guards `value`, built with `ctx`.
    ///
    /// # Safety
    /// Until [`Guard::keep`] takes it out, no command buffer that may be pending when the
    /// guard drops uses `value` (a constructor records nothing with it, or submits and
    /// waits): dropping the guard destroys it.
    pub unsafe fn new(ctx: &'c Context, value: T) -> Self {
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
        // SAFETY: `Guard::new`'s contract: nothing pending uses the value yet.
        unsafe { self.value.destroy(self.ctx) };
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
    ///
    /// # Safety
    /// Every frame recorded earlier in `slot` has completed on the GPU (the slot
    /// contract), and `ctx` made the resources.
    pub unsafe fn release(&mut self, ctx: &Context, slot: u32) {
        self.waiting.retain_mut(|(pending, resource)| {
            *pending &= !(1u64 << slot);
            if *pending == 0 {
                // SAFETY: every slot it waited for has completed its frames (this
                // function's contract for `slot`, earlier calls' for the others).
                unsafe { resource.destroy(ctx) };
                false
            } else {
                true
            }
        });
    }

    /// The number of waiting resources: a mark for [`RetireQueue::release_holding`].
    pub fn mark(&self) -> usize {
        self.waiting.len()
    }

    /// [`RetireQueue::release`], except that what was retired since `mark` (taken with
    /// no release in between) is not released: it waits for every slot again. For work
    /// recorded outside the frame slots (a host's preparation command buffer), which is
    /// submitted before the frame now recorded in `slot`, so that frame's completion is
    /// the first that implies the work's: what the work used and was retired after it
    /// was recorded stays until every slot has been recorded after this frame.
    ///
    /// # Safety
    /// As [`RetireQueue::release`].
    pub unsafe fn release_holding(&mut self, ctx: &Context, slot: u32, mark: usize) {
        let held = self.waiting.split_off(mark.min(self.waiting.len()));
        // SAFETY: this function's contract.
        unsafe { self.release(ctx, slot) };
        let all = self.all_slots;
        self.waiting
            .extend(held.into_iter().map(|(_, resource)| (all, resource)));
    }

    /// Destroys everything now.
    ///
    /// # Safety
    /// No frame that could use a waiting resource is still pending (e.g. the device is
    /// idle), and `ctx` made the resources.
    pub unsafe fn destroy_all(&mut self, ctx: &Context) {
        for (_, mut resource) in self.waiting.drain(..) {
            // SAFETY: this function's contract.
            unsafe { resource.destroy(ctx) };
        }
    }

    /// The bytes the waiting resources hold ([`Destroy::bytes`]).
    pub fn bytes(&self) -> u64 {
        self.waiting.iter().map(|(_, r)| r.bytes()).sum()
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
