//! GPU timestamps: one begin/end pair of queries per pass, read back after the frame's
//! fence. The one timestamp writer of the crate: [`crate::embed::DisplacementPass`]
//! writes its passes with it, and the standalone renderer its G-buffer pass.
//!
//! Timestamps are written with `ALL_COMMANDS` on both sides, so a pass's interval
//! covers exactly its own work (the passes are serialised by barriers anyway). Raw
//! values are masked to `timestampValidBits` and scaled by `timestampPeriod`.

use crate::context::Context;
use crate::error::{Result, VkContext};
use crate::gpu::owned::Destroy;
use crate::passes::PassName;
use ash::vk;

/// One timed pass of a recorded frame: its name and its begin/end queries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TimestampScope {
    /// The pass.
    pub name: PassName,
    /// The pool holding the queries.
    pub pool: vk::QueryPool,
    /// Query written before the pass.
    pub begin_query: u32,
    /// Query written after the pass.
    pub end_query: u32,
}

/// Records passes between debug labels and, with a pool, timestamps: the queries
/// `first .. first + capacity` of `pool`, reset by [`ScopeWriter::reset`], two per
/// scope in recording order.
pub(crate) struct ScopeWriter {
    pool: Option<vk::QueryPool>,
    first: u32,
    capacity: u32,
    /// The scopes written so far.
    pub(crate) scopes: Vec<TimestampScope>,
    /// Every pass recorded, timed or not.
    pub(crate) passes: Vec<PassName>,
}

impl ScopeWriter {
    /// A writer of the queries `first .. first + capacity` of `pool` (`None`: labels
    /// only).
    pub(crate) fn new(pool: Option<vk::QueryPool>, first: u32, capacity: u32) -> Self {
        ScopeWriter {
            pool,
            first,
            capacity,
            scopes: Vec::new(),
            passes: Vec::new(),
        }
    }

    /// Resets the writer's queries in `cmd`; recorded before the first scope.
    ///
    /// # Safety
    /// `cmd` is recording outside a render pass; the pool (if any) is alive, belongs to
    /// `ctx`'s device and holds the writer's range.
    pub(crate) unsafe fn reset(&self, ctx: &Context, cmd: vk::CommandBuffer) {
        if let Some(pool) = self.pool {
            // SAFETY: the caller's contract; the frame writes these queries after it.
            unsafe {
                ctx.device()
                    .cmd_reset_query_pool(cmd, pool, self.first, self.capacity)
            };
        }
    }

    /// Records `body` between a debug label and, with a pool, two timestamps. A scope
    /// beyond the range is labelled but not timed.
    ///
    /// # Safety
    /// As [`ScopeWriter::reset`], which was recorded earlier into the same frame.
    pub(crate) unsafe fn scope<R>(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        name: PassName,
        body: impl FnOnce(vk::CommandBuffer) -> R,
    ) -> R {
        // SAFETY: `cmd` is recording (this function's # Safety contract); the label is
        // closed by `end_label` below, in the same command buffer.
        unsafe { ctx.begin_label(cmd, name.as_str()) };
        let used = 2 * self.scopes.len() as u32;
        let queries = self
            .pool
            .filter(|_| used + 2 <= self.capacity)
            .map(|pool| (pool, self.first + used));
        if let Some((pool, begin)) = queries {
            // SAFETY: `cmd` is recording (the caller's contract); the query was reset in
            // this frame.
            unsafe {
                ctx.device().cmd_write_timestamp2(
                    cmd,
                    vk::PipelineStageFlags2::ALL_COMMANDS,
                    pool,
                    begin,
                )
            };
        }
        let result = body(cmd);
        if let Some((pool, begin)) = queries {
            // SAFETY: as above.
            unsafe {
                ctx.device().cmd_write_timestamp2(
                    cmd,
                    vk::PipelineStageFlags2::ALL_COMMANDS,
                    pool,
                    begin + 1,
                )
            };
            self.scopes.push(TimestampScope {
                name,
                pool,
                begin_query: begin,
                end_query: begin + 1,
            });
        }
        // SAFETY: `cmd` is recording (this function's # Safety contract); `begin_label`
        // above opened the region (the bodies, dispmap's passes, open none of their own).
        unsafe { ctx.end_label(cmd) };
        self.passes.push(name);
        result
    }
}

/// Per-pass milliseconds of a frame's timestamps, in recording order.
///
/// # Safety
/// The pools in `scopes` must be alive and belong to `ctx`'s device, and the frame that
/// wrote them must have completed (its fence signalled) and not been re-recorded since.
pub unsafe fn read_timestamps(
    ctx: &Context,
    scopes: &[TimestampScope],
) -> Result<Vec<(PassName, f64)>> {
    let bits = ctx.info().timestamp_valid_bits;
    let mask = if bits >= 64 {
        u64::MAX
    } else {
        (1u64 << bits) - 1
    };
    let period = ctx.info().timestamp_period_ns as f64;
    scopes
        .iter()
        .map(|s| {
            let mut begin = [0u64; 1];
            let mut end = [0u64; 1];
            // SAFETY: the caller guarantees the pool and that the frame completed; without
            // WAIT an unavailable query is reported (NOT_READY), never waited for.
            unsafe {
                let dev = ctx.device();
                dev.get_query_pool_results(
                    s.pool,
                    s.begin_query,
                    &mut begin,
                    vk::QueryResultFlags::TYPE_64,
                )
                .vk("vkGetQueryPoolResults")?;
                dev.get_query_pool_results(
                    s.pool,
                    s.end_query,
                    &mut end,
                    vk::QueryResultFlags::TYPE_64,
                )
                .vk("vkGetQueryPoolResults")?;
            }
            let ticks = (end[0] & mask).wrapping_sub(begin[0] & mask) & mask;
            Ok((s.name, ticks as f64 * period / 1e6))
        })
        .collect()
}

/// A `TIMESTAMP` query pool of `count` queries named `name`.
pub(crate) fn timestamp_pool(ctx: &Context, name: &str, count: u32) -> Result<vk::QueryPool> {
    if ctx.info().timestamp_valid_bits == 0 {
        return Err(crate::error::Error::Unsupported {
            device: ctx.info().name.clone(),
            what: "timestamps on the queue family in use (timestampValidBits = 0)".into(),
        });
    }
    let info = vk::QueryPoolCreateInfo::default()
        .query_type(vk::QueryType::TIMESTAMP)
        .query_count(count);
    // SAFETY: valid device and create info.
    let pool = unsafe { ctx.device().create_query_pool(&info, None) }.vk("vkCreateQueryPool")?;
    ctx.set_name(pool, name);
    Ok(pool)
}

/// A `TIMESTAMP` query pool owned by the standalone renderer.
pub(crate) struct QueryPool(pub(crate) vk::QueryPool);

impl Destroy for QueryPool {
    /// Destroys the pool. Nothing may be pending.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            if self.0 != vk::QueryPool::null() {
                ctx.device().destroy_query_pool(self.0, None);
                self.0 = vk::QueryPool::null();
            }
        }
    }
}

/// The median of `values` (mean of the two middle values for an even count); 0 if empty.
pub fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn median_of_odd_and_even() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        assert_eq!(median(&[]), 0.0);
    }
}
