//! Preparations of a height map as entries of the displacement pass's keyed table: what
//! one is ([`MapPreparation`]: a constructor, a pipeline and a record) and the list of
//! them ([`super::MAP_PREPARATIONS`]). The table ([`crate::embed::DisplacementPass::set_map_preparation`])
//! keys each entry by (map, kind), builds it in the first record or preparation after a
//! host asked for it, retires it with its map and hands out the built value
//! ([`crate::embed::DisplacementPass::map_preparation`]). A new preparation pass is its
//! type implementing [`MapPreparation`] beside its shader, and a [`PassName`] and a line
//! in [`super::MAP_PREPARATIONS`] (`passes/mod.rs`).

use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::HeightTexture;
use crate::gpu::owned::Destroy;
use crate::passes::PassName;
use ash::vk;
use std::any::{Any, TypeId};
use std::marker::PhantomData;

/// A preparation of one height map: built once per map, after its upload, by one compute
/// pass, and read by frames or by the host.
pub trait MapPreparation: Destroy + Send + Sync + Sized + 'static {
    /// Its scope: the timestamps and debug label of its builds (a one-off pass).
    const NAME: PassName;
    /// Its pipelines, shared by every map.
    type Pass: Destroy + Send + Sync + 'static;

    /// Builds the pipelines.
    fn new_pass(ctx: &Context) -> Result<Self::Pass>;

    /// Its resources for a map read through `texture` (nothing recorded).
    fn new(ctx: &Context, texture: &HeightTexture) -> Result<Self>;

    /// Records the build from `texture`, leaving what it wrote readable by its readers
    /// (its own barriers: the table declares nothing for it).
    ///
    /// # Safety
    /// `cmd` is recording outside a render pass on the context's queue family; the
    /// texture's level 0 is sampled-readable by compute shaders (as every fill leaves
    /// it); `prepared` was made by [`MapPreparation::new`] for this texture and no command
    /// has used it yet; `pass`, `texture` and `prepared` live until `cmd` has executed.
    unsafe fn record(
        pass: &Self::Pass,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        texture: &HeightTexture,
        prepared: &Self,
    ) -> Result<()>;
}

/// A value of the table, its type erased ([`Kind`] restores it).
pub trait Erased: Destroy + Send + Sync {
    /// The value, for a downcast.
    fn as_any(&self) -> &dyn Any;
}

impl<T: Destroy + Send + Sync + 'static> Erased for T {
    fn as_any(&self) -> &dyn Any {
        self
    }
}

/// One [`MapPreparation`] as the table handles it: its constructors and its record on
/// erased values.
pub trait Kind: Sync {
    /// Its scope.
    fn name(&self) -> PassName;
    /// The preparation's type.
    fn prepared_type(&self) -> TypeId;
    /// [`MapPreparation::new_pass`].
    fn new_pass(&self, ctx: &Context) -> Result<Box<dyn Erased>>;
    /// [`MapPreparation::new`].
    fn new_prepared(&self, ctx: &Context, texture: &HeightTexture) -> Result<Box<dyn Erased>>;
    /// [`MapPreparation::record`] (an [`Error::Internal`] if the values are of another
    /// kind).
    ///
    /// # Safety
    /// As [`MapPreparation::record`].
    unsafe fn record(
        &self,
        pass: &dyn Erased,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        texture: &HeightTexture,
        prepared: &dyn Erased,
    ) -> Result<()>;
}

/// The [`Kind`] of `P`.
pub struct KindOf<P>(PhantomData<fn() -> P>);

impl<P> KindOf<P> {
    /// The kind.
    pub const NEW: Self = KindOf(PhantomData);
}

impl<P: MapPreparation> Kind for KindOf<P> {
    fn name(&self) -> PassName {
        P::NAME
    }

    fn prepared_type(&self) -> TypeId {
        TypeId::of::<P>()
    }

    fn new_pass(&self, ctx: &Context) -> Result<Box<dyn Erased>> {
        Ok(Box::new(P::new_pass(ctx)?))
    }

    fn new_prepared(&self, ctx: &Context, texture: &HeightTexture) -> Result<Box<dyn Erased>> {
        Ok(Box::new(P::new(ctx, texture)?))
    }

    unsafe fn record(
        &self,
        pass: &dyn Erased,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        texture: &HeightTexture,
        prepared: &dyn Erased,
    ) -> Result<()> {
        let mismatch = || Error::Internal(format!("{}: a value of another kind", P::NAME));
        let pass = pass
            .as_any()
            .downcast_ref::<P::Pass>()
            .ok_or_else(mismatch)?;
        let prepared = prepared.as_any().downcast_ref::<P>().ok_or_else(mismatch)?;
        // SAFETY: this function's contract is `P::record`'s.
        unsafe { P::record(pass, ctx, cmd, texture, prepared) }
    }
}

/// Every map preparation ([`super::MAP_PREPARATIONS`], listed beside the pass names).
pub use super::MAP_PREPARATIONS as KINDS;

/// The index of `P` in [`KINDS`] (an [`Error::InvalidInput`] naming it when it is not
/// listed there).
pub fn kind_of<P: MapPreparation>() -> Result<usize> {
    KINDS
        .iter()
        .position(|k| k.prepared_type() == TypeId::of::<P>())
        .ok_or_else(|| {
            Error::invalid(
                "map preparation",
                format!("{} is not listed in passes::MAP_PREPARATIONS", P::NAME),
            )
        })
}
