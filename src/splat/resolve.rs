//! Normalisation, the splatter's third pass: whole images resolved on
//! the GPU ([`Splatter::resolve_into`], [`Splatter::read`]) or sampled at
//! points ([`Splatter::gather`], its readback put off as a
//! [`PendingGather`]).

use super::SplatImage;
use super::error::SplatError;
use super::gpu_data::{
    GATHER_BILINEAR, GATHER_NEAREST, GATHER_STRIDE, RESOLVE_DEPTH_MOTION, RESOLVE_WORKGROUP,
    ResolveParams,
};
use super::reuse::{BindKey, Grown, KEPT_BINDS, resolve_params};
use super::splatter::GpuSplatter;
use super::targets::SplatTargets;
use super::{Attribute, Attributes, GatherMode, GatherSample};
use crate::device::AsDevice;
use crate::gpu::{GpuContext, PassChain, STORAGE_IN, WORKGROUP_1D, workgroups};

impl GpuSplatter {
    /// The bind group of a resolve or gather into `out` from `targets`,
    /// with its uniform set to `params` (written now). Each kind of
    /// resolve, and the gather, has a uniform of its own: a batch of
    /// submissions ([`GpuContext::batch`]) may hold one of each. Kept per
    /// (targets, out, points) and reused (no allocation per
    /// frame).
    fn resolve_bind(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        params: ResolveParams,
        out: &wgpu::Buffer,
        points: Option<&wgpu::Buffer>,
    ) -> wgpu::BindGroup {
        let mut reuse = self.reuse.lock().unwrap_or_else(|p| p.into_inner());
        let slot = params.kind as usize % reuse.params.len();
        let uniform = if points.is_some() {
            reuse
                .gather_params
                .get_or_insert_with(|| resolve_params(ctx))
        } else {
            reuse.params[slot].get_or_insert_with(|| resolve_params(ctx))
        };
        uniform.write(ctx, bytemuck::bytes_of(&params));
        let pbuf = uniform.buffer().clone();
        let key = BindKey {
            view: targets.g().acc_views[0].clone(),
            params: pbuf.clone(),
            out: out.clone(),
            points: points.cloned(),
        };
        if let Some(i) = reuse.binds.iter().position(|(k, _)| *k == key) {
            let hit = reuse.binds.remove(i);
            let bind = hit.1.clone();
            reuse.binds.insert(0, hit);
            return bind;
        }
        let mut entries = vec![wgpu::BindGroupEntry {
            binding: 0,
            resource: pbuf.as_entire_binding(),
        }];
        for (i, v) in targets.g().acc_views.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: 1 + i as u32,
                resource: wgpu::BindingResource::TextureView(v),
            });
        }
        entries.push(wgpu::BindGroupEntry {
            binding: 6,
            resource: out.as_entire_binding(),
        });
        entries.push(wgpu::BindGroupEntry {
            binding: 7,
            resource: points.unwrap_or(&self.dummy_points).as_entire_binding(),
        });
        let bind = ctx.bind_group(&wgpu::BindGroupDescriptor {
            label: Some("splat resolve"),
            layout: &self.resolve_layout,
            entries: &entries,
        });
        reuse.binds.insert(0, (key, bind.clone()));
        reuse.binds.truncate(KEPT_BINDS);
        bind
    }

    /// Normalises one attribute of the last render on the GPU into `out`
    /// (at least width x height x channels floats, `STORAGE`), where it
    /// stays: nothing is read back. Submitted at once.
    pub fn resolve_into(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        attribute: Attribute,
        out: &wgpu::Buffer,
    ) -> Result<(), SplatError> {
        let enc = self.encode_resolve(ctx, targets, attribute, out)?;
        ctx.submit(enc);
        Ok(())
    }

    /// Records [`Splatter::resolve_into`]'s pass (its parameters queued)
    /// for the caller to submit, with a readback behind it, say.
    fn encode_resolve(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        attribute: Attribute,
        out: &wgpu::Buffer,
    ) -> Result<crate::gpu::Encoder, SplatError> {
        let mut enc = ctx.encoder();
        self.record_resolve(
            ctx,
            &mut PassChain::new(ctx, &mut enc),
            targets,
            attribute,
            out,
        )?;
        Ok(enc)
    }

    /// [`Splatter::resolve_into`] recorded as a stage of `passes` (its
    /// parameters queued), for the caller to submit with the stages
    /// around it: in one compute pass with them where untimed. Resolves
    /// of different attributes may share a submission (each kind has
    /// its parameters).
    pub fn record_resolve(
        &self,
        ctx: &GpuContext,
        passes: &mut PassChain,
        targets: &SplatTargets,
        attribute: Attribute,
        out: &wgpu::Buffer,
    ) -> Result<(), SplatError> {
        targets.check(attribute.needs(), attribute)?;
        let (w, h) = (targets.width, targets.height);
        let n = w as u64 * h as u64 * attribute.channels() as u64;
        if out.size() < n * 4 {
            return Err(SplatError::Unsupported(format!(
                "resolve_into: a {}-byte buffer for {} bytes",
                out.size(),
                n * 4
            )));
        }
        let bind = self.resolve_bind(
            ctx,
            targets,
            ResolveParams {
                width: w,
                height: h,
                kind: if attribute == Attribute::Depth && targets.depth_from_motion() {
                    RESOLVE_DEPTH_MOTION
                } else {
                    attribute.kind()
                },
                mode: GATHER_NEAREST,
                fx: targets.fx(),
                ..Default::default()
            },
            out,
            None,
        );
        let pass = passes.stage("resolve", None);
        pass.set_pipeline(&self.resolve);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(
            workgroups(w, RESOLVE_WORKGROUP),
            workgroups(h, RESOLVE_WORKGROUP),
            1,
        );
        Ok(())
    }

    /// Normalises one attribute of the last render on the GPU and reads the
    /// whole image back (for the CLI and tests; the tracker uses
    /// [`Splatter::gather`]).
    pub fn read(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        attribute: Attribute,
    ) -> Result<SplatImage, SplatError> {
        targets.check(attribute.needs(), attribute)?;
        let (w, h) = (targets.width, targets.height);
        let n = w as usize * h as usize * attribute.channels();
        let _busy = self.busy.lock().unwrap_or_else(|p| p.into_inner());
        let out = self.grown(ctx, Grown::Read, (n * 4) as u64);
        let enc = self.encode_resolve(ctx, targets, attribute, &out)?;
        let data = ctx.read_buffer_after::<f32>(enc, &out, n)?;
        Ok(SplatImage {
            width: w,
            height: h,
            channels: attribute.channels(),
            data,
        })
    }

    /// A kept buffer of at least `size` bytes (grow-only).
    fn grown(&self, ctx: &GpuContext, which: Grown, size: u64) -> wgpu::Buffer {
        let mut reuse = self.reuse.lock().unwrap_or_else(|p| p.into_inner());
        let b = &mut reuse.buffers[which as usize];
        b.ensure(ctx, size);
        b.get().clone()
    }

    /// [`Splatter::gather`] without waiting: the gather is recorded and
    /// submitted (within a batch, put off with it) and its readback goes
    /// with the calling thread's next one ([`GpuContext::read_buffer_later`]);
    /// [`PendingGather::wait`] returns the samples. The next gather
    /// submits a put-off one first (they share the points' buffer).
    pub fn gather_later(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        points: &[[f32; 2]],
        mode: GatherMode,
    ) -> Result<PendingGather, SplatError> {
        self.gather_at(ctx, targets, Points::Host(points), mode)
    }

    /// The buffer of points [`Splatter::gather_written_later`] gathers
    /// at, grown to hold `n` (8 bytes each: x, y as f32), for work on the
    /// GPU to write into (such as [`crate::features::Harris::export_corners`]).
    /// The next [`Splatter::gather_later`] overwrites it.
    pub fn gather_points(&self, ctx: &GpuContext, n: usize) -> Result<wgpu::Buffer, SplatError> {
        let bytes = (n.max(1) * 8) as u64;
        ctx.check_buffer_size("gather points", bytes, STORAGE_IN)?;
        Ok(self.grown(ctx, Grown::Points, bytes))
    }

    /// The buffer the last gather wrote its samples into
    /// ([`GATHER_STRIDE`] floats a point, its validity last), for work on
    /// the GPU fed from them (such as
    /// [`crate::features::NccMatcher::match_resident_exported_b`]'s gate),
    /// recorded after that gather; the next gather overwrites it.
    pub fn gathered_samples(&self, ctx: &GpuContext) -> wgpu::Buffer {
        self.grown(ctx, Grown::Gather, 0)
    }

    /// [`Splatter::gather_later`] at the first `n` points written on the
    /// GPU into [`Splatter::gather_points`] (recorded before this call).
    pub fn gather_written_later(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        n: usize,
        mode: GatherMode,
    ) -> Result<PendingGather, SplatError> {
        self.gather_at(ctx, targets, Points::Written(n), mode)
    }

    fn gather_at(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        points: Points,
        mode: GatherMode,
    ) -> Result<PendingGather, SplatError> {
        targets.check(Attributes::MOTION, Attribute::Motion)?;
        let count = match points {
            Points::Host(p) => p.len(),
            Points::Written(n) => n,
        };
        if count == 0 {
            return Ok(PendingGather {
                read: None,
                n: 0,
                ready: None,
            });
        }
        let size = (count * 8) as u64;
        let _busy = self.busy.lock().unwrap_or_else(|p| p.into_inner());
        ctx.check_buffer_size("gather points", size, STORAGE_IN)?;
        let last = self
            .reuse
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .last_gather
            .take();
        // Only where the last gather is still put off: a readback since
        // submitted it (as IT's chain does before KF's gather) leaves
        // nothing to flush, and no submission of its own.
        if last.is_some_and(|m| !ctx.submitted_since(m)) {
            ctx.flush();
        }
        let pbuf = match points {
            Points::Host(p) => {
                let pbuf = self.grown(ctx, Grown::Points, size);
                ctx.write_buffer(&pbuf, 0, bytemuck::cast_slice(p));
                pbuf
            }
            Points::Written(_) => {
                let pbuf = self.grown(ctx, Grown::Points, 0);
                if pbuf.size() < size {
                    return Err(SplatError::Gpu(crate::gpu::GpuError::Readback(format!(
                        "a gather at {count} written points of a {}-byte buffer",
                        pbuf.size()
                    ))));
                }
                pbuf
            }
        };
        let n = count * GATHER_STRIDE;
        let out = self.grown(ctx, Grown::Gather, (n * 4) as u64);
        let bind = self.resolve_bind(
            ctx,
            targets,
            ResolveParams {
                width: targets.width,
                height: targets.height,
                kind: count as u32,
                mode: match mode {
                    GatherMode::Nearest => GATHER_NEAREST,
                    GatherMode::Bilinear => GATHER_BILINEAR,
                },
                fx: targets.fx(),
                ..Default::default()
            },
            &out,
            Some(&pbuf),
        );
        let mut enc = ctx.encoder();
        {
            let mut passes = PassChain::new(ctx, &mut enc);
            let pass = passes.stage("gather", None);
            pass.set_pipeline(&self.gather);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(workgroups(count as u32, WORKGROUP_1D), 1, 1);
        }
        let read = ctx.read_buffer_later(enc, &out, (n * 4) as u64)?;
        self.reuse
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .last_gather = Some(ctx.submission_mark());
        Ok(PendingGather {
            read: Some(read),
            n: count,
            ready: None,
        })
    }
}

/// Where a gather's points come from.
#[derive(Clone, Copy)]
enum Points<'p> {
    /// Uploaded.
    Host(&'p [[f32; 2]]),
    /// The first n of the points' buffer, written on the GPU.
    Written(usize),
}

/// A gather whose readback is put off ([`super::Splatter::gather_later`]);
/// on the CPU device, samples already made.
#[must_use = "a pending gather is only useful waited for"]
pub struct PendingGather {
    pub(super) read: Option<crate::gpu::PendingRead>,
    /// Points gathered.
    pub(super) n: usize,
    /// The CPU device's samples.
    pub(super) ready: Option<Vec<GatherSample>>,
}

impl PendingGather {
    /// The samples, one a point: at once when a readback since brought
    /// them (or on the CPU device), else after a readback of their own.
    /// `device` is the splatter's (a [`GpuContext`] or a
    /// [`crate::Device`]).
    pub fn wait(self, device: &impl AsDevice) -> Result<Vec<GatherSample>, SplatError> {
        if let Some(samples) = self.ready {
            return Ok(samples);
        }
        let Some(read) = self.read else {
            return Ok(Vec::new());
        };
        let ctx = device
            .gpu_context()
            .ok_or(SplatError::WrongDevice("a GPU gather"))?;
        let bytes = read.wait(ctx)?;
        let data: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes);
        debug_assert_eq!(data.len(), self.n * GATHER_STRIDE);
        Ok(data
            .chunks(GATHER_STRIDE)
            .map(GatherSample::from_floats)
            .collect())
    }
}
