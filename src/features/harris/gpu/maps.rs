//! The map passes: grey levels, gradients, the structure tensor, the
//! response and the non-maximum suppression (shaders/harris_maps.wgsl).

use super::super::{gaussian_taps, pack_pixels, radius};
use super::passes::PASSES;
use super::{Harris, Input, capacity};
use crate::features::FeatureError;
use crate::features::gpu_data::{
    Counters, FUSED_HALO, HARRIS_BLOCK, HarrisParams, MAX_TAPS, MERGE_LINKS, SELECT_MAX,
};
use crate::gpu::{PassChain, WORKGROUP_2D, workgroups};

impl Harris {
    /// Whether the next detection's filter passes run as one.
    pub(super) fn maps_fused(&self) -> bool {
        let halo = radius(self.config.sigma_d) + radius(self.config.sigma_i);
        self.fused.is_some()
            && halo <= FUSED_HALO as usize
            && self.fuse.unwrap_or(!self.ctx.is_cpu())
    }

    pub(super) fn params(&self, w: usize, h: usize, n_corners: u32) -> HarrisParams {
        let c = &self.config;
        let (gd, dd) = gaussian_taps(c.sigma_d);
        let (gi, _) = gaussian_taps(c.sigma_i);
        let mut flat = [0f32; MAX_TAPS];
        for (slot, v) in flat.iter_mut().zip(gd.iter().chain(&dd).chain(&gi)) {
            *slot = *v;
        }
        let mut weights = [[0f32; 4]; MAX_TAPS / 4];
        for (i, v) in flat.iter().enumerate() {
            weights[i / 4][i % 4] = *v;
        }
        HarrisParams {
            width: w as u32,
            height: h as u32,
            rd: radius(c.sigma_d) as u32,
            ri: radius(c.sigma_i) as u32,
            k: c.k,
            rel_threshold: c.relative_threshold,
            min_response: c.min_response,
            capacity: capacity(w, h) as u32,
            refine_radius: c.refine_radius,
            refine_iterations: c.refine_iterations,
            refine_inv_2s2: c.refine_inv_2s2(),
            n_corners,
            max_shift: c.max_shift(),
            min_weight: c.min_valid_weight,
            max_corners: c.max_corners.min(u32::MAX as usize) as u32,
            grid_cell: c.grid_cell,
            merge_r2: c.merge_radius * c.merge_radius,
            refine: c.refine as u32,
            select_limit: self.select_limit_now() as u32,
            _pad2: 0,
            weights,
        }
    }

    /// Checks sizes against the device's limits and (re)allocates buffers.
    pub(super) fn prepare(&mut self, w: usize, h: usize) -> Result<(), FeatureError> {
        let limit = self
            .ctx
            .limits
            .max_storage_buffer_binding_size
            .min(self.ctx.limits.max_buffer_size);
        let too_large = |reason: String| FeatureError::TooLarge {
            width: w,
            height: h,
            reason,
        };
        let max_dim =
            self.ctx.limits.max_compute_workgroups_per_dimension as usize * WORKGROUP_2D as usize;
        if w > max_dim || h > max_dim {
            return Err(too_large(format!("a side exceeds {max_dim} pixels")));
        }
        // Shader indices are u32.
        if w * h >= 1 << 28 {
            return Err(too_large("more than 2^28 pixels".into()));
        }
        let big = (w * h * 16) as u64;
        if big > limit {
            return Err(too_large(format!(
                "needs {big}-byte buffers, limit {limit}"
            )));
        }
        let ctx = &self.ctx.clone();
        let mut changed = false;
        changed |= self.pixels.ensure(ctx, (w * h * 8) as u64);
        changed |= self.rgba.ensure(ctx, (w * h * 12) as u64);
        self.grey_out.ensure(ctx, (w * h * 4) as u64);
        // The fused filter pass keeps its lines in workgroup memory: no
        // `tmp` (its binding takes the smallest buffer).
        changed |= self
            .tmp
            .ensure(ctx, if self.maps_fused() { 16 } else { big });
        changed |= self.grad.ensure(ctx, big);
        changed |= self.response.ensure(ctx, (w * h * 4) as u64);
        changed |= self.counters.ensure(ctx, 16);
        changed |= self.candidates.ensure(ctx, (capacity(w, h) * 16) as u64);
        // The selected corners (by the GPU or the host).
        let cap = capacity(w, h);
        changed |= self
            .corners
            .ensure(ctx, (self.config.max_corners.min(cap).max(1) * 16) as u64);
        let max = SELECT_MAX as u64;
        let mut select_changed = changed;
        select_changed |= self
            .select_index
            .ensure(ctx, (1 + MERGE_LINKS as u64) * max * 4);
        select_changed |= self.select_state.ensure(ctx, max * 4);
        select_changed |= self.ordered.ensure(ctx, max * 16);
        select_changed |= self.select_args.ensure(ctx, 80);
        if select_changed || self.select_bind.is_none() {
            let bufs = [
                (0, self.params.buffer()),
                (3, self.grad.get()),
                (5, self.counters.get()),
                (6, self.candidates.get()),
                (7, self.corners.get()),
                (9, self.select_index.get()),
                (10, self.select_state.get()),
                (11, self.ordered.get()),
            ];
            self.select_bind =
                Some(ctx.bind_buffers_at("harris select", &self.select_layout, &bufs)?);
            let bufs = [
                (0, self.params.buffer()),
                (5, self.counters.get()),
                (12, self.select_args.get()),
            ];
            self.sizes_bind =
                Some(ctx.bind_buffers_at("harris select sizes", &self.sizes_layout, &bufs)?);
        }
        if changed || self.bind.is_none() {
            let bufs = [
                self.params.buffer(),
                self.pixels.get(),
                self.tmp.get(),
                self.grad.get(),
                self.response.get(),
                self.counters.get(),
                self.candidates.get(),
                self.corners.get(),
                self.rgba.get(),
            ];
            self.bind = Some(ctx.bind_buffers("harris", &self.layout, &bufs)?);
        }
        Ok(())
    }

    /// Records the map passes and NMS over `input`, its uploads queued,
    /// and with `select` the selection behind them
    /// ([`Harris::encode_select`]), in one compute pass where untimed (two
    /// where a resolved view's grey levels are kept: a copy between), for
    /// the caller to submit: with a readback behind them, one
    /// submission.
    pub(super) fn encode_maps(
        &mut self,
        input: Input,
        mask: Option<&[bool]>,
        select: bool,
    ) -> Result<crate::gpu::Encoder, FeatureError> {
        let (w, h) = input.size();
        self.prepare(w, h)?;
        let ctx = &self.ctx.clone();
        let p = self.params(w, h, 0);
        self.params.write(ctx, bytemuck::bytes_of(&p));
        match input {
            Input::Grey(img) => ctx.write_buffer(
                self.pixels.get(),
                0,
                bytemuck::cast_slice(&pack_pixels(img, mask)),
            ),
            Input::Rgb(img) => {
                // RGBA8 with the mask in the alpha byte; little-endian, so
                // unpack4x8unorm reads red first.
                let packed: Vec<u32> = img
                    .pixels()
                    .enumerate()
                    .map(|(i, p)| {
                        let alpha = if mask.is_none_or(|m| m[i]) { 255 } else { 0 };
                        u32::from_le_bytes([p[0], p[1], p[2], alpha])
                    })
                    .collect();
                ctx.write_buffer(self.rgba.get(), 0, bytemuck::cast_slice(&packed));
            }
            // Already on the GPU (Harris::colour_target,
            // Harris::input_target).
            Input::Resolved { .. } | Input::Packed { .. } => {}
        }
        let bind = self.bind.as_ref().expect("prepared");
        let (gx, gy) = (
            workgroups(w as u32, WORKGROUP_2D),
            workgroups(h as u32, WORKGROUP_2D),
        );
        let mut enc = ctx.encoder();
        // The counters start at zero: cleared in the command stream (no
        // upload of its own, and in order with any earlier work of a
        // batch that still reads them).
        enc.clear_buffer(
            self.counters.get(),
            0,
            Some(std::mem::size_of::<Counters>() as u64),
        );
        let mut passes = PassChain::new(ctx, &mut enc);
        if let Input::Rgb(_) = input {
            let pass = passes.stage("grey", self.timer.as_mut());
            pass.set_pipeline(&self.grey);
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        if let Input::Resolved { keep_grey, .. } = input {
            let pass = passes.stage("grey", self.timer.as_mut());
            pass.set_pipeline(&self.grey_pack_f32);
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
            // The grey levels, before the integration passes reuse
            // `response`.
            if keep_grey {
                passes.encoder().copy_buffer_to_buffer(
                    self.response.get(),
                    0,
                    self.grey_out.get(),
                    0,
                    (w * h * 4) as u64,
                );
            }
        }
        // The filter passes run one invocation per HARRIS_BLOCK pixels
        // along their direction (x for *_h, y for *_v).
        let (bw, bh) = (
            workgroups((w as u32).div_ceil(HARRIS_BLOCK), WORKGROUP_2D),
            workgroups((h as u32).div_ceil(HARRIS_BLOCK), WORKGROUP_2D),
        );
        let groups = [(bw, gy), (gx, bh), (bw, gy), (gx, bh), (gx, gy)];
        let fused = self.maps_fused().then_some(self.fused.as_ref()).flatten();
        if let Some(pipeline) = fused {
            // A tile of WORKGROUP_2D^2 outputs a workgroup.
            let pass = passes.stage("maps", self.timer.as_mut());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        let skip = if fused.is_some() { 4 } else { 0 };
        for ((pipeline, label), (x, y)) in self.passes.iter().zip(PASSES).zip(groups).skip(skip) {
            let pass = passes.stage(label, self.timer.as_mut());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
        if select {
            self.encode_select(&mut passes);
        }
        drop(passes);
        Ok(enc)
    }
}
