//! The matchings of images resident on the GPU: bands copied on the GPU,
//! features uploaded or exported by a detection, the gate by a gather,
//! the mutual bests refined on the GPU.

use super::pairs::{resident_matches, sanitize};
use super::{Bands, ExportFn, NccMatcher, PendingMatches, Side};
use crate::features::FeatureError;
use crate::features::gpu_data::{MatchOut, Pixel};
use crate::features::harris::Corner;
use crate::features::resident::{Refinement, ResidentImage, ResidentMatch};
use crate::gpu::{PassChain, WORKGROUP_1D, workgroups};

impl NccMatcher {
    /// Mutual best NCC matches between the features `a` of rows `a_rows`
    /// of the GPU-resident image `img_a` and `b` of rows `b_rows` of
    /// `img_b` (positions in each whole image's pixels; a window leaving
    /// its rows leaves its image; `offset_b`: where B's pixel (0, 0) lies
    /// in A's pixels, for the search radius): what [`NccMatcher::match_features`]
    /// gives on those rows as host images, without uploading or reading
    /// back any image. Both bands are copied on the GPU into the matcher's
    /// buffer. With `refine`, B's point of each match is moved to the
    /// sub-pixel NCC peak on the GPU, as [`crate::features::refine::refine_match`] does on
    /// the host. One readback of [`ResidentMatch`]'s few values per
    /// feature of `a`. Sorted by `a`.
    #[allow(clippy::too_many_arguments)]
    pub fn match_resident(
        &mut self,
        img_a: ResidentImage,
        a_rows: std::ops::Range<usize>,
        a: &[Corner],
        img_b: ResidentImage,
        b_rows: std::ops::Range<usize>,
        b: &[Corner],
        offset_b: [i32; 2],
        refine: Option<Refinement>,
    ) -> Result<Vec<ResidentMatch>, FeatureError> {
        if a.is_empty() || b.is_empty() || a_rows.is_empty() || b_rows.is_empty() {
            img_a.check(&a_rows)?;
            img_b.check(&b_rows)?;
            return Ok(Vec::new());
        }
        let y0 = b_rows.start as f64;
        let na = a.len();
        let bands = Bands {
            img_a,
            a_rows,
            img_b,
            b_rows,
            offset_b,
        };
        let enc = self.record_resident(bands, Side::Host(a), Side::Host(b), None, None, refine)?;
        let ctx = &self.ctx.clone();
        let out: Vec<MatchOut> = ctx.read_buffer_after(enc, self.matched.get(), na)?;
        Ok(resident_matches(&out, y0, refine.is_some()))
    }

    /// [`NccMatcher::match_resident`] with A's features written on the GPU
    /// by `export` (recorded into the matching's encoder before its passes,
    /// [`crate::features::Harris::export_corners`]) into the `slots` first
    /// positions of the buffer it is given, in A's band's pixels (slots
    /// without a feature far outside any image), and the matches' readback
    /// put off: the first `rows` rows come back with the next readback.
    /// [`NccMatcher::finish_exported`] returns the matches.
    #[allow(clippy::too_many_arguments)]
    pub fn match_resident_exported(
        &mut self,
        img_a: ResidentImage,
        a_rows: std::ops::Range<usize>,
        slots: usize,
        export: &mut ExportFn,
        img_b: ResidentImage,
        b_rows: std::ops::Range<usize>,
        b: &[Corner],
        offset_b: [i32; 2],
        refine: Option<Refinement>,
        rows: usize,
    ) -> Result<PendingMatches, FeatureError> {
        if slots == 0 || b.is_empty() || a_rows.is_empty() || b_rows.is_empty() {
            return Err(FeatureError::Config(format!(
                "an exported matching of {slots} slots and {} features in bands of {} and {} rows",
                b.len(),
                a_rows.len(),
                b_rows.len()
            )));
        }
        let bands = Bands {
            img_a,
            a_rows,
            img_b,
            b_rows,
            offset_b,
        };
        let sides = (Side::Exported(slots), Side::Host(b));
        self.record_later(bands, sides, export, None, refine, rows.min(slots))
    }

    /// [`NccMatcher::match_resident`] with B's features written on the
    /// GPU by `export` (recorded into the matching's encoder before its
    /// passes: [`crate::features::Harris::export_corners`] placed from
    /// slot `a.len()` on) into the `slots` positions after A's, in B's
    /// band's pixels (slots without a feature far outside any image: those
    /// outside the crop too, where the host leaves them out); with `gate`
    /// (a gather's samples at A's features, [`crate::gpu::GATHER_STRIDE`]
    /// floats each, its validity last, left on the GPU by
    /// [`crate::splat::Splatter::gather_later`]), A's features whose
    /// sample is empty left out as if not given. The matches' readback is
    /// put off (every row of A); [`NccMatcher::finish_exported`] with
    /// `a.len()` returns them, B's indices those of the slots. The same
    /// matches as [`NccMatcher::match_resident`] on the kept features.
    #[allow(clippy::too_many_arguments)]
    pub fn match_resident_exported_b(
        &mut self,
        img_a: ResidentImage,
        a_rows: std::ops::Range<usize>,
        a: &[Corner],
        gate: Option<&wgpu::Buffer>,
        img_b: ResidentImage,
        b_rows: std::ops::Range<usize>,
        slots: usize,
        export: &mut ExportFn,
        offset_b: [i32; 2],
        refine: Option<Refinement>,
    ) -> Result<PendingMatches, FeatureError> {
        if slots == 0 || a.is_empty() || a_rows.is_empty() || b_rows.is_empty() {
            return Err(FeatureError::Config(format!(
                "an exported matching of {} features and {slots} slots in bands of {} and {} rows",
                a.len(),
                a_rows.len(),
                b_rows.len()
            )));
        }
        let bands = Bands {
            img_a,
            a_rows,
            img_b,
            b_rows,
            offset_b,
        };
        let sides = (Side::Host(a), Side::Exported(slots));
        self.record_later(bands, sides, export, gate, refine, a.len())
    }

    /// Records an exported matching ([`NccMatcher::record_resident`]) and
    /// puts off the readback of its first `rows` rows of A.
    pub(super) fn record_later(
        &mut self,
        bands: Bands,
        (a, b): (Side, Side),
        export: &mut ExportFn,
        gate: Option<&wgpu::Buffer>,
        refine: Option<Refinement>,
        rows: usize,
    ) -> Result<PendingMatches, FeatureError> {
        let y0 = bands.b_rows.start as f64;
        let enc = self.record_resident(bands, a, b, Some(export), gate, refine)?;
        let size = std::mem::size_of::<MatchOut>();
        let read = self
            .ctx
            .read_buffer_later(enc, self.matched.get(), (rows * size) as u64)?;
        Ok(PendingMatches {
            read,
            rows,
            y0,
            refine: refine.is_some(),
        })
    }

    /// The matches of [`NccMatcher::match_resident_exported`] among the
    /// first `kept` features of A (at most the rows read back), as
    /// [`NccMatcher::match_resident`] gives them for those features.
    pub fn finish_exported(
        &mut self,
        pending: PendingMatches,
        kept: usize,
    ) -> Result<Vec<ResidentMatch>, FeatureError> {
        if kept > pending.rows {
            return Err(FeatureError::Config(format!(
                "{kept} features asked of an exported matching, {} read back",
                pending.rows
            )));
        }
        let bytes = pending.read.wait(&self.ctx)?;
        let size = std::mem::size_of::<MatchOut>();
        let out: Vec<MatchOut> = bytemuck::pod_collect_to_vec(&bytes[..kept * size]);
        Ok(resident_matches(&out, pending.y0, pending.refine))
    }

    /// Records a matching on GPU-resident bands (checked), each side's
    /// features from the host or written on the GPU by `export`, A's
    /// gated by `gate`, into an encoder for the caller to read from.
    pub(super) fn record_resident(
        &mut self,
        bands: Bands,
        a: Side,
        b: Side,
        export: Option<&mut ExportFn>,
        gate: Option<&wgpu::Buffer>,
        refine: Option<Refinement>,
    ) -> Result<crate::gpu::Encoder, FeatureError> {
        let Bands {
            img_a,
            a_rows,
            img_b,
            b_rows,
            offset_b,
        } = bands;
        img_a.check(&a_rows)?;
        img_b.check(&b_rows)?;
        if let Some(r) = &refine {
            r.validate()?;
        }
        let (na, nb) = (a.len(), b.len());
        if let Some(g) = gate {
            let need = (na * crate::gpu::GATHER_STRIDE * 4) as u64;
            if g.size() < need {
                return Err(FeatureError::Config(format!(
                    "a gate of {} bytes for {na} features ({need} needed)",
                    g.size()
                )));
            }
        }
        let sizes = [(img_a.width, a_rows.len()), (img_b.width, b_rows.len())];
        // B's band origin in A's band's pixels.
        let shift = [
            offset_b[0],
            offset_b[1] + b_rows.start as i32 - a_rows.start as i32,
        ];
        // B exported: its features in their own order (no spatial order).
        let b_in_order = matches!(b, Side::Exported(_));
        self.prepare(na, nb, sizes, shift, refine, b_in_order)?;
        let ctx = &self.ctx.clone();
        // Positions in the bands: y less the first row (exact in f32 for
        // image coordinates).
        let band = |c: &Corner, y0: usize| Corner {
            y: c.y - y0 as f32,
            ..*c
        };
        let in_band = |f: &[Corner], y0: usize| -> Vec<[f32; 2]> {
            f.iter().map(|c| sanitize(&band(c, y0))).collect()
        };
        match (&a, &b) {
            (Side::Host(a), Side::Host(b)) => {
                let mut pos = in_band(a, a_rows.start);
                pos.extend(in_band(b, b_rows.start));
                self.write_positions(&pos, na, 0);
            }
            // A's positions are the export's.
            (Side::Exported(_), Side::Host(b)) => {
                self.write_positions(&in_band(b, b_rows.start), 0, na);
            }
            // B's positions are the export's, in no spatial order
            // (`b_in_order`: nothing to upload for it).
            (Side::Host(a), Side::Exported(_)) => {
                let pos = in_band(a, a_rows.start);
                ctx.write_buffer(self.positions.get(), 0, bytemuck::cast_slice(&pos));
            }
            (Side::Exported(_), Side::Exported(_)) => {
                return Err(FeatureError::Config(
                    "a matching of two exported sides".into(),
                ));
            }
        }
        let px = std::mem::size_of::<Pixel>();
        let (len_a, len_b) = (img_a.width * a_rows.len(), img_b.width * b_rows.len());
        let mut enc = ctx.encoder();
        enc.copy_buffer_to_buffer(
            img_a.pixels,
            (a_rows.start * img_a.width * px) as u64,
            self.pixels.get(),
            0,
            (len_a * px) as u64,
        );
        enc.copy_buffer_to_buffer(
            img_b.pixels,
            (b_rows.start * img_b.width * px) as u64,
            self.pixels.get(),
            (len_a * px) as u64,
            (len_b * px) as u64,
        );
        // The export, the gate and the matching's passes: one compute
        // pass where untimed.
        let mut passes = PassChain::new(ctx, &mut enc);
        if let Some(export) = export {
            export(&mut passes, self.positions.get())?;
        }
        if let Some(g) = gate {
            self.record_gate(&mut passes, g, na)?;
        }
        self.encode(&mut passes, na, nb, true);
        drop(passes);
        Ok(enc)
    }

    /// Records the gate of A's `na` positions (the parameters' `na`,
    /// written by [`NccMatcher::prepare`]) by the gather's samples
    /// `samples` (`shaders/ncc_gate.wgsl`).
    pub(super) fn record_gate(
        &mut self,
        passes: &mut PassChain,
        samples: &wgpu::Buffer,
        na: usize,
    ) -> Result<(), FeatureError> {
        let bufs = [samples.clone(), self.positions.get().clone()];
        let (ctx, layout, params) = (&self.ctx, &self.gate_layout, self.params.buffer());
        let bind = self.gate_bind.get(bufs, |b| {
            ctx.bind_buffers_at("ncc gate", layout, &[(0, params), (20, &b[0]), (22, &b[1])])
        })?;
        let pass = passes.stage("gate", self.timer.as_mut());
        pass.set_pipeline(&self.gate);
        pass.set_bind_group(0, bind, &[]);
        pass.dispatch_workgroups(workgroups(na as u32, WORKGROUP_1D), 1, 1);
        Ok(())
    }
}
