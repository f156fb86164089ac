//! GPU time per pass for `track --profile`: with
//! timing on, every splat pass, Harris pass and NCC pass of a frame is
//! timed by GPU timestamp queries and reported by stage in
//! [`super::StageTimes::gpu`]. Off by default. The timestamps of a
//! frame's passes are copied behind them and mapped by the frame's own
//! readbacks ([`crate::gpu::GpuTimer::resolve_later`]), so timing adds
//! no wait for the GPU: the readbacks `--profile` counts are the loop's.

use super::result::add;
use super::state::Tracker;
use crate::geometry::{Intrinsics, Pose};
use crate::gpu::{GpuTimer, TimerReport, Timings};
use crate::splat::{Attributes, SplatError};

/// Which model a render splats.
#[derive(Debug, Clone, Copy)]
pub(super) enum Texture {
    /// The geometry only (colours of the model, if any).
    None,
    /// Coloured by keyframe `k`.
    Keyframe(usize),
}

impl Tracker {
    /// Times every GPU pass of every frame from now on (where the adapter
    /// supports timestamp queries): [`super::StageTimes::gpu`]
    /// ([`super::Execution::gpu_timing`]).
    pub(super) fn enable_gpu_timing(&mut self) {
        let Some(ctx) = self.device.gpu() else {
            return;
        };
        self.gpu_timer = Some(GpuTimer::new(ctx, 2));
        self.harris.enable_timing();
        if let Some(c) = self.check.as_mut() {
            c.enable_timing();
        }
        if let Some(o) = self.outline.as_mut() {
            o.enable_timing();
        }
        for m in [
            &mut self.it_matcher,
            &mut self.kf_matcher,
            &mut self.recover_matcher,
        ] {
            m.enable_timing();
        }
    }

    /// Splats the model at `pose` into the current targets (sized by
    /// [`Tracker::use_window`], whose camera `cam` is), timing its passes
    /// under `stage` when timing is on.
    pub(super) fn splat(
        &mut self,
        texture: Texture,
        cam: &Intrinsics,
        pose: &Pose,
        attrs: Attributes,
        stage: &str,
    ) -> Result<(), SplatError> {
        self.splat_with(texture, cam, pose, attrs, stage, false)
    }

    /// [`Tracker::splat`]; with `keep_depth` (the CPU device only) the
    /// render keeps its visibility depth too
    /// ([`crate::splat::Splatter::render_keeping_depth`]).
    pub(super) fn splat_with(
        &mut self,
        texture: Texture,
        cam: &Intrinsics,
        pose: &Pose,
        attrs: Attributes,
        stage: &str,
        keep_depth: bool,
    ) -> Result<(), SplatError> {
        let gm = match (texture, self.store.as_ref()) {
            (Texture::Keyframe(k), Some(store)) => {
                self.textured.get(&self.device, store, &self.geometry, k)?
            }
            _ => &self.geometry,
        };
        if keep_depth {
            self.splatter.render_keeping_depth(
                &self.device,
                gm,
                cam,
                pose,
                attrs,
                &mut self.targets,
            )?;
        } else {
            self.splatter.render_timed(
                &self.device,
                gm,
                cam,
                pose,
                attrs,
                &mut self.targets,
                self.gpu_timer.as_mut(),
            )?;
        }
        self.note_splat(&format!("{stage} splat"));
        Ok(())
    }

    /// Notes the splat just recorded (counted in
    /// [`super::StageTimes::renders`]), its passes as `label`.
    pub(super) fn note_splat(&mut self, label: &str) {
        self.stages.renders += 1.0;
        self.view_made = None;
        if let (Some(t), Some(ctx)) = (self.gpu_timer.as_mut(), self.device.gpu()) {
            match t.read_later(ctx) {
                Ok(r) => self.pending_gpu.push((label.to_owned(), r)),
                Err(e) => log::warn!("GPU timer: {e}"),
            }
        }
    }

    /// Notes the last Harris run's passes under `stage`.
    pub(super) fn note_harris(&mut self, stage: &str) {
        if self.gpu_timer.is_some() {
            let t = self.harris.take_timings();
            self.pending_gpu.push((format!("{stage} harris"), t));
        }
    }

    /// Notes passes taken from a module (`t`) as `label`.
    pub(super) fn note_timings(&mut self, label: &str, t: Timings) {
        if self.gpu_timer.is_some() {
            self.pending_gpu.push((label.to_owned(), t));
        }
    }

    /// Reads the frame's noted passes into its stage times: their
    /// timestamps came with the frame's readbacks (those noted after the
    /// last, if any, in one wait of their own).
    pub(super) fn collect_gpu_times(&mut self) {
        let mut spans = Vec::new();
        let Some(ctx) = self.device.gpu() else {
            return;
        };
        for (label, t) in std::mem::take(&mut self.pending_gpu) {
            let r = t.wait(ctx);
            note(&mut self.stages.gpu, &label, &r);
            spans.extend(r.spans);
        }
        self.stages.gpu_timeline = crate::gpu::GpuTimeline::of(&spans);
    }
}

/// Adds the passes of `r` to `acc` as "`prefix` pass" (summing repeats).
pub(super) fn note(acc: &mut Vec<(String, f64)>, prefix: &str, r: &TimerReport) {
    for (label, ms) in &r.passes {
        add(acc, &format!("{prefix} {label}"), *ms);
    }
}
