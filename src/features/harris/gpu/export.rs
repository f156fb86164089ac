//! The export of a detection's corners to the next stages without a
//! readback (shaders/harris_export.wgsl).

use super::{ExportPlace, Harris, PendingCorners};
use crate::features::FeatureError;
use crate::features::gpu_data::ExportParams;
use crate::gpu::{PassChain, WORKGROUP_1D, workgroups};

impl Harris {
    /// Records into `enc` the export of `pending`'s corners (behind its
    /// detection; [`PendingCorners::slots`] slots): slot `i` of `points`
    /// gets corner `i` (its position in the detection's pixels, a
    /// gather's point; with `None`, a scratch buffer of the detector's)
    /// and slot `place.first + i` of `positions` the same placed as
    /// [`ExportPlace`] says (as NCC reads its positions); slots past the
    /// corners kept, or all where the host is to finish the selection, get
    /// a point far outside any image (a void NCC window, an empty sample).
    /// `shaders/harris_export.wgsl`.
    pub fn export_corners(
        &mut self,
        passes: &mut PassChain,
        pending: &PendingCorners,
        place: ExportPlace,
        positions: &wgpu::Buffer,
        points: Option<&wgpu::Buffer>,
    ) -> Result<(), FeatureError> {
        let n = pending.slots;
        let points = match points {
            Some(p) => p.clone(),
            None => {
                self.export_scratch.ensure(&self.ctx, (n.max(1) * 8) as u64);
                self.export_scratch.get().clone()
            }
        };
        let need = [((place.first + n) * 8) as u64, (n * 8) as u64];
        for ((what, b), need) in [("positions", positions), ("points", &points)]
            .into_iter()
            .zip(need)
        {
            if b.size() < need {
                return Err(FeatureError::Config(format!(
                    "the export's {what} buffer holds {} bytes, {need} needed",
                    b.size()
                )));
            }
        }
        let clip = place.clip.unwrap_or([0.0; 4]);
        let params = ExportParams {
            origin_x: place.origin[0],
            origin_y: place.origin[1],
            band_y0: place.band_y0,
            n: n as u32,
            first: place.first as u32,
            clip: place.clip.is_some() as u32,
            _pad0: 0,
            _pad1: 0,
            clip_x0: clip[0],
            clip_y0: clip[1],
            clip_x1: clip[2],
            clip_y1: clip[3],
        };
        self.export_params
            .write(&self.ctx, bytemuck::bytes_of(&params));
        let bufs = [
            self.counters.get().clone(),
            self.corners.get().clone(),
            positions.clone(),
            points,
        ];
        let (ctx, layout) = (&self.ctx, &self.export_layout);
        let (params, export_params) = (self.params.buffer(), self.export_params.buffer());
        let bind = self.export_bind.get(bufs, |b| {
            let at = [
                (0, params),
                (5, &b[0]),
                (7, &b[1]),
                (13, export_params),
                (14, &b[2]),
                (15, &b[3]),
            ];
            ctx.bind_buffers_at("harris export", layout, &at)
        })?;
        let pass = passes.stage("export", self.timer.as_mut());
        pass.set_pipeline(&self.export);
        pass.set_bind_group(0, bind, &[]);
        pass.dispatch_workgroups(workgroups(n as u32, WORKGROUP_1D), 1, 1);
        Ok(())
    }
}
