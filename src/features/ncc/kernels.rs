//! The kernels' buffers, bind groups and passes.

use super::NccMatcher;
use super::pairs::{spatial_order, split_groups};
use super::shader::PASSES;
use crate::features::FeatureError;
use crate::features::gpu_data::{
    MatchOut, NCC_TILE, NccParams, REFINE_LOCAL_WINDOW, VECTORIZE_GROUP_WINDOW,
};
use crate::features::resident::Refinement;
use crate::gpu::{PassChain, WORKGROUP_1D, workgroups};

impl NccMatcher {
    /// Uploads the positions `pos` (A's first `na`, then B's) from slot
    /// `skip` on (the slots before are A's, written on the GPU) and B's
    /// [`spatial_order`] after the window flags in `ok`.
    pub(super) fn write_positions(&self, pos: &[[f32; 2]], na: usize, skip: usize) {
        let ctx = &self.ctx;
        ctx.write_buffer(
            self.positions.get(),
            (skip * 8) as u64,
            bytemuck::cast_slice(pos),
        );
        let order = spatial_order(&pos[na..], self.config.search_radius);
        ctx.write_buffer(
            self.ok.get(),
            ((skip + pos.len()) * 4) as u64,
            bytemuck::cast_slice(&order),
        );
    }

    /// Checks a problem of `na` and `nb` features in two images of
    /// `sizes` (width, height) against the device's limits, grows the
    /// buffers and writes the parameters.
    pub(super) fn prepare(
        &mut self,
        na: usize,
        nb: usize,
        sizes: [(usize, usize); 2],
        shift_b: [i32; 2],
        refine: Option<Refinement>,
        b_in_order: bool,
    ) -> Result<(), FeatureError> {
        let ctx = &self.ctx.clone();
        let lim = &ctx.limits;
        let max_groups = lim.max_compute_workgroups_per_dimension as usize;
        if na.max(nb) > max_groups {
            return Err(FeatureError::TooManyFeatures {
                n: na.max(nb),
                max: max_groups,
            });
        }
        let limit = lim.max_storage_buffer_binding_size.min(lim.max_buffer_size);
        if (na * nb * 4) as u64 > limit {
            return Err(FeatureError::TooManyFeatures {
                n: na.max(nb),
                max: ((limit / 4) as f64).sqrt() as usize,
            });
        }
        let [(wa, ha), (wb, hb)] = sizes;
        let n_pix = wa * ha + wb * hb;
        // Shader indices are u32.
        if (n_pix * 8) as u64 > limit || n_pix >= 1 << 28 {
            return Err(FeatureError::TooLarge {
                width: wa.max(wb),
                height: ha + hb,
                reason: format!("two images need {} bytes, limit {limit}", n_pix * 8),
            });
        }
        let stride = self.config.stride() as usize;
        let mut changed = self.pixels.ensure(ctx, (n_pix * 8) as u64);
        changed |= self.positions.ensure(ctx, ((na + nb) * 8) as u64);
        // Unit rows, then raw rows (windows with holes).
        changed |= self.desc.ensure(ctx, ((na + nb) * stride * 8) as u64);
        // The window flags, then B's spatial order.
        changed |= self.ok.ensure(ctx, ((na + 2 * nb) * 4) as u64);
        changed |= self.scores.ensure(ctx, (na * nb * 4) as u64);
        changed |= self.best.ensure(ctx, ((na + nb) * 8) as u64);
        changed |= self
            .matched
            .ensure(ctx, (na * std::mem::size_of::<MatchOut>()) as u64);
        if changed || self.bind.is_none() {
            let bufs = [
                self.params.buffer(),
                self.pixels.get(),
                self.positions.get(),
                self.desc.get(),
                self.ok.get(),
                self.scores.get(),
                self.best.get(),
                self.matched.get(),
            ];
            self.bind = Some(ctx.bind_buffers("ncc", &self.layout, &bufs)?);
        }
        self.refine_wide = refine.is_some_and(|r| 2 * (r.patch / 2) + 1 > REFINE_LOCAL_WINDOW);
        let c = &self.config;
        let r = refine.unwrap_or(Refinement {
            patch: 1,
            max_shift: 0,
            min_score: 0.0,
        });
        let params = NccParams {
            na: na as u32,
            nb: nb as u32,
            stride: stride as u32,
            window: c.patch,
            wa: wa as u32,
            ha: ha as u32,
            wb: wb as u32,
            hb: hb as u32,
            offset_b: (wa * ha) as u32,
            radius2: c.search_radius.map_or(-1.0, |r| r * r),
            min_std: c.min_std,
            min_valid: c.min_valid,
            min_score: c.min_score,
            refine_on: refine.is_some() as u32,
            refine_half: r.patch / 2,
            max_shift: r.max_shift,
            refine_min: r.min_score,
            shift_bx: shift_b[0] as f32,
            shift_by: shift_b[1] as f32,
            b_in_order: b_in_order as u32,
        };
        self.params.write(ctx, bytemuck::bytes_of(&params));
        Ok(())
    }

    /// Records the stages (vectorize, scores, bests; with `mutual`, the
    /// mutual check and refinement) into `passes`.
    pub(super) fn encode(&mut self, passes: &mut PassChain, na: usize, nb: usize, mutual: bool) {
        // The bests: a workgroup a line (rows, then columns), or on CPU
        // adapters a thread a line, in rows of at most 65535 workgroups.
        let lines = (na + nb) as u32;
        let groups = [
            (workgroups(lines, WORKGROUP_1D), 1),
            (
                workgroups(nb as u32, NCC_TILE),
                workgroups(na as u32, NCC_TILE),
            ),
            split_groups(lines),
        ];
        let bind = self.bind.as_ref().expect("bind group built in prepare");
        for ((pipeline, label), (gx, gy)) in self.passes.iter().zip(PASSES).zip(groups) {
            let pass = passes.stage(label, self.timer.as_mut());
            pass.set_bind_group(0, bind, &[]);
            if label == "vectorize" && self.tiled && self.config.patch <= VECTORIZE_GROUP_WINDOW {
                pass.set_pipeline(&self.vectorize_group);
                // A workgroup a window (they stride over any beyond).
                pass.dispatch_workgroups(((na + nb) as u32).clamp(1, 65535), 1, 1);
            } else if label == "score" && !self.tiled {
                pass.set_pipeline(&self.score_direct);
                // Four columns per thread.
                pass.dispatch_workgroups(workgroups(nb as u32, 4 * NCC_TILE), gy, 1);
            } else if label == "bests" && !self.tiled {
                pass.set_pipeline(&self.bests_direct);
                let (x, y) = split_groups(workgroups(lines, WORKGROUP_1D));
                pass.dispatch_workgroups(x, y, 1);
            } else {
                pass.set_pipeline(pipeline);
                pass.dispatch_workgroups(gx, gy, 1);
            }
        }
        if mutual {
            let pass = passes.stage("mutual_refine", self.timer.as_mut());
            pass.set_bind_group(0, bind, &[]);
            pass.set_pipeline(if self.refine_wide || !self.tiled {
                &self.mutual_refine_wide
            } else {
                &self.mutual_refine
            });
            // One workgroup per feature of A.
            pass.dispatch_workgroups(na as u32, 1, 1);
        }
        if let Some(t) = self.timer.as_mut() {
            // The timestamps come with this matching's readback.
            match t.resolve_later(&self.ctx, passes.encoder()) {
                Ok(read) => self.timings.append(read),
                Err(e) => log::warn!("GPU timer: {e}"),
            }
        }
    }
}
