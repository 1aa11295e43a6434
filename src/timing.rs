//! GPU timestamps: one pair of queries per pass, read back after the frame's fence.
//!
//! Timestamps are written with `ALL_COMMANDS` on both sides, so a pass's interval
//! covers exactly its own work (the passes are serialised by barriers anyway). Raw
//! values are masked to `timestampValidBits` and scaled by `timestampPeriod`.

use crate::context::Context;
use crate::error::{Error, Result, VkContext};
use ash::vk;

/// A query pool holding up to `capacity` named begin/end pairs per frame.
pub struct GpuTimer {
    pool: vk::QueryPool,
    capacity: u32,
    names: Vec<&'static str>,
    open: Option<u32>,
    period_ns: f64,
    mask: u64,
}

impl GpuTimer {
    /// Creates a timer for up to `capacity` scopes per frame.
    pub fn new(ctx: &Context, name: &str, capacity: u32) -> Result<Self> {
        let info = vk::QueryPoolCreateInfo::default()
            .query_type(vk::QueryType::TIMESTAMP)
            .query_count(capacity * 2);
        // SAFETY: valid device and create info.
        let pool =
            unsafe { ctx.device().create_query_pool(&info, None) }.vk("vkCreateQueryPool")?;
        ctx.set_name(pool, name);
        let bits = ctx.info().timestamp_valid_bits;
        Ok(GpuTimer {
            pool,
            capacity,
            names: Vec::new(),
            open: None,
            period_ns: ctx.info().timestamp_period_ns as f64,
            mask: if bits >= 64 {
                u64::MAX
            } else {
                (1u64 << bits) - 1
            },
        })
    }

    /// Resets the pool in `cmd`; call before the frame's first scope.
    pub fn reset(&mut self, ctx: &Context, cmd: vk::CommandBuffer) {
        // SAFETY: `cmd` is recording, outside a render pass; the pool is alive.
        unsafe {
            ctx.device()
                .cmd_reset_query_pool(cmd, self.pool, 0, self.capacity * 2)
        };
        self.names.clear();
        self.open = None;
    }

    /// Writes the begin timestamp of scope `name`.
    pub fn begin(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        name: &'static str,
    ) -> Result<()> {
        let index = self.names.len() as u32;
        if index >= self.capacity || self.open.is_some() {
            return Err(Error::invalid(
                "timer",
                format!(
                    "cannot open scope {name}: capacity {} or a scope still open",
                    self.capacity
                ),
            ));
        }
        self.names.push(name);
        self.open = Some(index);
        // SAFETY: `cmd` is recording; query `2 * index` was reset in this frame.
        unsafe {
            ctx.device().cmd_write_timestamp2(
                cmd,
                vk::PipelineStageFlags2::ALL_COMMANDS,
                self.pool,
                2 * index,
            )
        };
        Ok(())
    }

    /// Writes the end timestamp of the open scope.
    pub fn end(&mut self, ctx: &Context, cmd: vk::CommandBuffer) {
        if let Some(index) = self.open.take() {
            // SAFETY: `cmd` is recording; query `2 * index + 1` was reset in this frame.
            unsafe {
                ctx.device().cmd_write_timestamp2(
                    cmd,
                    vk::PipelineStageFlags2::ALL_COMMANDS,
                    self.pool,
                    2 * index + 1,
                )
            };
        }
    }

    /// Per-scope milliseconds of the last frame, in recording order. Call after the
    /// frame's fence has signalled.
    pub fn read(&self, ctx: &Context) -> Result<Vec<(&'static str, f64)>> {
        let count = self.names.len();
        if count == 0 {
            return Ok(Vec::new());
        }
        let mut raw = vec![0u64; count * 2];
        // SAFETY: the queries were written by a submission the caller waited for.
        unsafe {
            ctx.device().get_query_pool_results(
                self.pool,
                0,
                &mut raw,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .vk("vkGetQueryPoolResults")?;
        Ok(self
            .names
            .iter()
            .enumerate()
            .map(|(i, &name)| {
                let ticks =
                    (raw[2 * i + 1] & self.mask).wrapping_sub(raw[2 * i] & self.mask) & self.mask;
                (name, ticks as f64 * self.period_ns / 1e6)
            })
            .collect())
    }

    /// Destroys the pool. Nothing may be pending.
    pub fn destroy(&mut self, ctx: &Context) {
        // SAFETY: caller guarantees no pending use.
        unsafe { ctx.device().destroy_query_pool(self.pool, None) };
        self.pool = vk::QueryPool::null();
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
