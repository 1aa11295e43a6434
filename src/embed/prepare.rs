//! Preparation the host schedules: the uploads and builds a change left pending (a new or
//! changed height map's upload, pyramid and cone map, material maps) recorded into a
//! command buffer of the host's choosing before the frame that first uses them, so that
//! frame records none of it (by default the next record builds them).

use super::*;
use crate::timing::ScopeWriter;

impl DisplacementPass {
    /// Whether a preparation is pending: what [`DisplacementPass::record_preparation`]
    /// would record (and otherwise the next record records).
    pub fn preparation_pending(&self) -> bool {
        self.rebuild_pending()
            || self
                .materials
                .iter()
                .flatten()
                .any(|m| m.pending_shading.is_some())
    }

    /// Records every pending preparation into the host's `cmd` (the `upload`, `pyramid`
    /// and `cone` scopes a record would otherwise begin with) and returns what it
    /// recorded; with nothing pending it records nothing. Every record after it finds the
    /// preparation done, so a frame's timings hold none of it. Changes made after this
    /// call (a new map, new settings) are pending again.
    ///
    /// Timestamps: [`Timestamps::Off`] or [`Timestamps::Host`] (the pass's own pool has
    /// one range per frame slot; a preparation has no slot, so [`Timestamps::Owned`] is
    /// refused).
    ///
    /// # Safety
    /// * `cmd` is a primary command buffer of the context's device in the recording
    ///   state, outside a render pass, for a queue of the context's queue family.
    /// * It is submitted to the context's queue after every command buffer recorded
    ///   earlier with this pass and before any recorded later (in the same command buffer
    ///   before the next record, or in an earlier submission): the next frame's fence
    ///   then covers it, and the pass keeps what it reads until that frame and every
    ///   slot after it have completed.
    /// * The host images of the materials it prepares ([`HostHeightMap`]) are in
    ///   `SHADER_READ_ONLY_OPTIMAL` with their writes visible to `COMPUTE_SHADER`
    ///   `SHADER_SAMPLED_READ` when it executes.
    /// * With [`Timestamps::Host`], `pool` is a live timestamp pool of the device with at
    ///   least `first_query + MAX_QUERIES` queries, not used by other commands until the
    ///   host has read them.
    pub unsafe fn record_preparation(
        &mut self,
        cmd: vk::CommandBuffer,
        timestamps: Timestamps,
    ) -> Result<RecordedFrame> {
        self.check_alive()?;
        let (pool, first) = match timestamps {
            Timestamps::Off => (None, 0),
            Timestamps::Host { pool, first_query } => (Some(pool), first_query),
            Timestamps::Owned => {
                return Err(Error::invalid(
                    "timestamps",
                    "a preparation has no frame slot: use Timestamps::Host or Off",
                ));
            }
        };
        if !self.preparation_pending() {
            return Ok(RecordedFrame::default());
        }
        // What the preparation uses and is retired from now on waits for the next
        // frame too (`begin`).
        let mark = self.retired.mark();
        self.prepared_mark.get_or_insert(mark);
        let mut w = ScopeWriter::new(pool, first, MAX_QUERIES);
        // SAFETY: this function's contract: `cmd` is recording outside a render pass on
        // the context's queue family, `pool` (when given) has the range; the writer's
        // queries are reset before its scopes; what the builds read is alive and
        // sampled-readable (the host images by this contract, dispmap's by their fills),
        // and what they retire waits past the next frame (the mark above).
        unsafe {
            w.reset(&self.context()?.clone(), cmd);
            self.record_builds(cmd, &mut w, None)?;
        }
        Ok(RecordedFrame {
            passes: w.passes,
            timestamps: w.scopes,
        })
    }
}
