//! The detections: of host images, frames and resolved views, now or
//! with a later readback, and their finish.

use super::super::host::detect_packed;
use super::super::{Corner, merge, selected_starts};
use super::{Detected, Harris, Input, PendingCorners, capacity};
use crate::features::FeatureError;
use crate::features::gpu_data::{Candidate, Counters, RefineCorner, pack_with_holes_into};
use crate::features::image::{GreyImage, check_mask};
use crate::features::resident::ResidentImage;

impl Harris {
    /// The response map (row-major, [`crate::features::INVALID_RESPONSE`] where the
    /// support leaves the image or touches an invalid pixel), for tests and
    /// visualisation.
    pub fn response(&mut self, img: &GreyImage) -> Result<Vec<f32>, FeatureError> {
        check_mask(img, None)?;
        if img.is_empty() {
            return Ok(Vec::new());
        }
        if self.host {
            return super::super::harris_response_host(img, &self.config);
        }
        let enc = self.encode_maps(Input::Grey(img), None, false)?;
        let response = self
            .ctx
            .read_buffer_after(enc, self.response.get(), img.data.len())?;
        self.finish_timing()?;
        Ok(response)
    }

    /// Harris corners of `img`, strongest first. `mask` (row-major, one
    /// flag per pixel) restricts where corners may be reported; NaN pixels
    /// are invalid and no corner's support touches one.
    pub fn detect(
        &mut self,
        img: &GreyImage,
        mask: Option<&[bool]>,
    ) -> Result<Vec<Corner>, FeatureError> {
        check_mask(img, mask)?;
        self.detect_input(Input::Grey(img), mask)
    }

    /// Harris corners of an 8-bit RGB frame, converted to grey on the GPU
    /// (Rec. 601 luma, as [`GreyImage::from_rgb8`] on the CPU): uploads 4
    /// bytes a pixel instead of 8.
    pub fn detect_rgb8(
        &mut self,
        img: &image::RgbImage,
        mask: Option<&[bool]>,
    ) -> Result<Vec<Corner>, FeatureError> {
        let n = img.width() as usize * img.height() as usize;
        if let Some(m) = mask.filter(|m| m.len() != n) {
            return Err(FeatureError::MaskSize {
                expected: n,
                got: m.len(),
            });
        }
        self.detect_input(Input::Rgb(img), mask)
    }

    /// The buffer of packed pixels (8 bytes each: grey value and flags,
    /// as [`crate::features::FrameIntake::pack_window`] writes
    /// them) that [`Harris::detect_packed`] reads, sized for a
    /// `width x height` image.
    pub fn input_target(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<wgpu::Buffer, FeatureError> {
        self.prepare(width.max(1), height.max(1))?;
        Ok(self.pixels.get().clone())
    }

    /// Harris corners of the `width x height` pixels packed into
    /// [`Harris::input_target`] on the GPU (corners only where a pixel is
    /// allowed): the image never comes to the host. Not in host mode.
    pub fn detect_packed(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<Vec<Corner>, FeatureError> {
        self.detect_input(Input::Packed { width, height }, None)
    }

    /// The buffer to resolve a splatted view's colour into (3 f32 a
    /// pixel, NaN where empty: [`crate::splat::Splatter::resolve_into`]) for
    /// [`Harris::detect_resolved`] on a `width x height` view.
    pub fn colour_target(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<wgpu::Buffer, FeatureError> {
        self.prepare(width.max(1), height.max(1))?;
        Ok(self.rgba.get().clone())
    }

    /// Harris corners of the view resolved into [`Harris::colour_target`]:
    /// grey conversion (as [`GreyImage::from_rgb_f32`]) and packing (as
    /// the host packs a [`GreyImage`], pinholes included) on the GPU, so
    /// the view's colour never comes back. Returns the corners (as
    /// [`Harris::detect`] of that grey image without a mask) and the grey
    /// image (one float a pixel, read back for NCC windows and refinement).
    pub fn detect_resolved(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<(Vec<Corner>, GreyImage), FeatureError> {
        if width == 0 || height == 0 {
            return Ok((Vec::new(), GreyImage::filled(width, height, 0.0)));
        }
        if self.host {
            let grey = self.resolved_grey(width, height)?;
            pack_with_holes_into(&grey, None, true, &mut self.scratch.pixels);
            let corners = detect_packed(&mut self.scratch, width, height, &self.config);
            return Ok((corners, grey));
        }
        let input = Input::Resolved {
            width,
            height,
            keep_grey: true,
        };
        let corners = self.detect_input(input, None)?;
        let data = self.ctx.read_buffer(self.grey_out.get(), width * height)?;
        Ok((corners, GreyImage::new(width, height, data)?))
    }

    /// [`Harris::detect_resolved`] without the grey image coming back: the
    /// view stays on the GPU, packed (grey levels, pinholes flagged) as
    /// NCC reads it, in [`Harris::resident_view`] until the next detection.
    pub fn detect_resolved_resident(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<Vec<Corner>, FeatureError> {
        if width == 0 || height == 0 {
            return Ok(Vec::new());
        }
        if self.host {
            // Detected on the host, then packed on the GPU as NCC reads
            // it (the packing the shaders would have left there).
            let grey = self.resolved_grey(width, height)?;
            pack_with_holes_into(&grey, None, true, &mut self.scratch.pixels);
            self.ctx.write_buffer(
                self.pixels.get(),
                0,
                bytemuck::cast_slice(&self.scratch.pixels),
            );
            return Ok(detect_packed(
                &mut self.scratch,
                width,
                height,
                &self.config,
            ));
        }
        let input = Input::Resolved {
            width,
            height,
            keep_grey: false,
        };
        self.detect_input(input, None)
    }

    /// The grey levels of the view resolved into [`Harris::colour_target`]
    /// (`width x height`), converted on the host as the `grey_pack_f32` pass
    /// converts them ([`GreyImage::from_rgb_f32`]).
    pub(super) fn resolved_grey(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<GreyImage, FeatureError> {
        self.prepare(width, height)?;
        let rgb: Vec<f32> = self.ctx.read_buffer(self.rgba.get(), width * height * 3)?;
        self.timings = Default::default();
        GreyImage::from_rgb_f32(width, height, &rgb)
    }

    /// The view of the last [`Harris::detect_resolved_resident`] (or
    /// [`Harris::detect_resolved`]) of a `width x height` view, as packed
    /// on the GPU (the pixels of [`GreyImage`] the host would pack with
    /// its pinholes, every pixel allowed): valid until the next detection.
    pub fn resident_view(
        &self,
        width: usize,
        height: usize,
    ) -> Result<ResidentImage<'_>, FeatureError> {
        if self.pixels.size() == 0 {
            return Err(FeatureError::Config("no view detected yet".into()));
        }
        Ok(ResidentImage {
            pixels: self.pixels.get(),
            width,
            height,
        })
    }

    pub(super) fn detect_input(
        &mut self,
        input: Input,
        mask: Option<&[bool]>,
    ) -> Result<Vec<Corner>, FeatureError> {
        let (w, h) = input.size();
        if w == 0 || h == 0 {
            return Ok(Vec::new());
        }
        if self.host {
            self.timings = Default::default();
            let pixels = &mut self.scratch.pixels;
            match input {
                Input::Grey(img) => pack_with_holes_into(img, mask, true, pixels),
                Input::Rgb(img) => {
                    pack_with_holes_into(&GreyImage::from_rgb8(img), mask, true, pixels)
                }
                // detect_resolved* detect these on the host themselves.
                Input::Resolved { .. } => {
                    return Err(FeatureError::Config(
                        "a resolved view in host mode: use detect_resolved".into(),
                    ));
                }
                Input::Packed { .. } => {
                    return Err(FeatureError::Config(
                        "pixels packed on the GPU in host mode".into(),
                    ));
                }
            }
            return Ok(detect_packed(&mut self.scratch, w, h, &self.config));
        }
        // The maps, the candidates and their selection in one submission,
        // and one readback: the counts and the corners, as many as recent
        // detections kept and a quarter more (the rest, when there are
        // more, in a second). With more candidates than the GPU selects
        // among (HarrisGpuOptions::select_limit), they come back in a second readback, the
        // host selects, and the selected are refined on the GPU after it
        // (a third).
        self.kind = matches!(input, Input::Resolved { .. }) as usize;
        let limit = self.select_limit_now();
        let rows = self.readback_rows(w, h);
        let enc = self.encode_maps(input, mask, true)?;
        let ctx = &self.ctx.clone();
        let size = std::mem::size_of::<RefineCorner>();
        let counters_size = std::mem::size_of::<Counters>() as u64;
        let reads = [
            (self.counters.get(), counters_size),
            (self.corners.get(), (rows * size) as u64),
        ];
        let parts = ctx.read_buffers_after(enc, &reads)?;
        let counters: Counters = bytemuck::pod_read_unaligned(&parts[0]);
        let detected = self.finish_detection(w, h, &counters, &parts[1], rows, limit)?;
        self.finish_timing()?;
        Ok(detected.corners)
    }

    /// The corners read back with a detection's counters in a `w x h`
    /// image: as many as the last two detections of its kind kept and a
    /// quarter more, at most as many as it can keep.
    pub(super) fn readback_rows(&self, w: usize, h: usize) -> usize {
        let cap = self.config.max_corners.min(capacity(w, h));
        let recent = self.recent_corners[self.kind]
            .iter()
            .max()
            .copied()
            .unwrap_or(0);
        (recent * 5 / 4 + 64).min(cap)
    }

    /// Records the corners a detection of the current kind kept.
    pub(super) fn note_kept(&mut self, n: usize) {
        let r = &mut self.recent_corners[self.kind];
        *r = [r[1], n];
    }

    /// The corners of a detection in a `w x h` image from its counters
    /// and the first `rows` corners read back with them: selected on the
    /// GPU, or (more candidates than it selects among) read back and
    /// selected on the host.
    pub(super) fn finish_detection(
        &mut self,
        w: usize,
        h: usize,
        counters: &Counters,
        part: &[u8],
        rows: usize,
        limit: usize,
    ) -> Result<Detected, FeatureError> {
        let room = capacity(w, h);
        let cap = self.config.max_corners.min(room);
        let count = (counters.count as usize).min(room);
        self.recent_candidates[self.kind] = count;
        if count <= limit {
            log::trace!(
                "harris: {count} candidates, {} corners, {rows} read back",
                counters.selected
            );
            return self.selected_corners(counters, part, count.min(cap));
        }
        log::trace!("harris: {count} candidates, selected on the host");
        let ctx = &self.ctx.clone();
        let cands: Vec<Candidate> = ctx.read_buffer(self.candidates.get(), count)?;
        let starts = selected_starts(&cands, &self.config);
        self.note_kept(starts.len());
        let corners = if self.config.refine && !starts.is_empty() {
            self.refine(w, h, &starts)?
        } else {
            starts
        };
        Ok(Detected {
            corners: merge(corners, self.config.merge_radius),
            exported: false,
        })
    }

    /// [`Harris::detect_resolved_resident`] whose corners come back with
    /// a later readback: the detection is recorded and submitted (within
    /// a batch, put off with it) and the reads of its counters and first
    /// corners put off ([`crate::gpu::GpuContext::read_buffer_later`]), so that work
    /// fed from its corners on the GPU ([`Harris::export_corners`]) goes
    /// before the one wait. Finish it with [`Harris::finish_later`]. Not
    /// in host mode, nor for an empty view.
    pub fn detect_resolved_resident_later(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<PendingCorners, FeatureError> {
        let input = Input::Resolved {
            width,
            height,
            keep_grey: false,
        };
        self.detect_later(input, 1)
    }

    /// [`Harris::detect_packed`] whose corners come back with a later
    /// readback, as [`Harris::detect_resolved_resident_later`] (a frame's
    /// window: its readback sized by recent frames' detections). Not in
    /// host mode, nor for an empty window.
    pub fn detect_packed_later(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<PendingCorners, FeatureError> {
        self.detect_later(Input::Packed { width, height }, 0)
    }

    /// A detection of `input` (of `kind`: frames 0, views 1) recorded and
    /// submitted, its readbacks put off.
    pub(super) fn detect_later(
        &mut self,
        input: Input,
        kind: usize,
    ) -> Result<PendingCorners, FeatureError> {
        let (width, height) = input.size();
        if self.host {
            return Err(FeatureError::Config(
                "a detection read back later in host mode".into(),
            ));
        }
        if width == 0 || height == 0 {
            return Err(FeatureError::Config(format!(
                "a detection read back later in an empty {width}x{height} image"
            )));
        }
        self.kind = kind;
        let limit = self.select_limit_now();
        let rows = self.readback_rows(width, height);
        let enc = self.encode_maps(input, None, true)?;
        let ctx = &self.ctx.clone();
        let size = std::mem::size_of::<RefineCorner>();
        let counters_size = std::mem::size_of::<Counters>() as u64;
        let counters = ctx.read_buffer_later(enc, self.counters.get(), counters_size)?;
        let corners =
            ctx.read_buffer_later(ctx.encoder(), self.corners.get(), (rows * size) as u64)?;
        Ok(PendingCorners {
            counters,
            corners,
            rows,
            slots: self.config.max_corners.min(capacity(width, height)),
            width,
            height,
            kind,
            limit,
        })
    }

    /// The corners of a detection from
    /// [`Harris::detect_resolved_resident_later`]: its readback (one wait,
    /// which brings every readback put off since with it), and where the
    /// host finishes the selection, its waits.
    pub fn finish_later(&mut self, pending: PendingCorners) -> Result<Detected, FeatureError> {
        let ctx = &self.ctx.clone();
        let counters = pending.counters.wait(ctx)?;
        let part = pending.corners.wait(ctx)?;
        let counters: Counters = bytemuck::pod_read_unaligned(&counters);
        self.kind = pending.kind;
        let detected = self.finish_detection(
            pending.width,
            pending.height,
            &counters,
            &part,
            pending.rows,
            pending.limit,
        )?;
        self.finish_timing()?;
        Ok(detected)
    }
}
