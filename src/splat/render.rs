//! The render pass back end of the splatter: the visibility and
//! attribute passes through the rasteriser (the compute back end, in
//! `compute`, writes the same targets). Occluders are extra draws at the
//! start of the visibility pass, each with its own camera uniform and
//! buffers, writing depth alone.

use super::Attributes;
use super::error::SplatError;
use super::gpu_data::{CameraUniform, camera_buffer};
use super::model::GpuModel;
use super::occluders::OccluderSet;
use super::params::Backend;
use super::splatter::GpuSplatter;
use super::targets::{SplatTargets, cleared_attachments};
use crate::geometry::{Intrinsics, Pose};
use crate::gpu::{GpuContext, GpuTimer};

impl GpuSplatter {
    /// [`Splatter::render`] with GPU timestamps for the passes "visibility"
    /// and "attributes" (resolved into `timer`; read it after the submit).
    #[allow(clippy::too_many_arguments)]
    pub fn render_timed(
        &self,
        ctx: &GpuContext,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        attrs: Attributes,
        targets: &mut SplatTargets,
        mut timer: Option<&mut GpuTimer>,
        occluders: &OccluderSet,
    ) -> Result<(), SplatError> {
        let uniform = self.checked_view(model, cam, pose, targets)?;
        let occluders = occluders.views(cam, &self.params, &uniform)?;
        targets.view = None;
        if let Some(compute) = &self.compute
            && self.backend_for(model, cam, pose) == Backend::Compute
        {
            let job = (model, &uniform, &occluders[..]);
            compute.render(ctx, job, attrs, false, targets, timer)?;
            targets.rendered = Some(attrs);
            targets.depth_only = false;
            targets.view = Some((*pose, *cam));
            return Ok(());
        }
        let bind = self.render_bind(ctx, model, &targets.g().uniform, &uniform);
        let hidden = self.occluder_binds(ctx, targets, &occluders);
        let mut enc = ctx.encoder();
        // Two render passes: the visibility, the attributes.
        ctx.count_passes(2);
        self.visibility_pass(
            &mut enc,
            (&self.visibility, "splat visibility", &[]),
            (&bind, model.count),
            (&self.visibility, &hidden),
            targets,
            timer.as_deref_mut(),
        );
        {
            let colors = cleared_attachments(targets, attrs);
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("splat attributes"),
                color_attachments: &colors,
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &targets.g().depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Load,
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: timer
                    .as_deref_mut()
                    .and_then(|t| t.render_pass("attributes")),
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.attribute[attrs.index()]);
            pass.set_bind_group(0, &bind, &[]);
            pass.draw(0..4, 0..model.count);
        }
        if let Some(t) = timer {
            t.resolve(&mut enc);
        }
        ctx.submit(enc);
        targets.rendered = Some(attrs);
        targets.depth_only = false;
        targets.view = Some((*pose, *cam));
        Ok(())
    }

    /// A depth-only render: the visibility pass alone (one pass over the
    /// splats instead of two, no attribute sums). Afterwards
    /// [`Splatter::read`] gives [`Attribute::Depth`](super::Attribute::Depth), the depth of the
    /// nearest surface pushed back by the visibility epsilon (`epsilon *
    /// r` along the ray, [`SplatParams::epsilon`](super::SplatParams::epsilon): what the attribute pass
    /// tests against, within a splat radius behind the averaged depth of a
    /// full render), and [`Attribute::Weight`](super::Attribute::Weight), 1 where covered; the
    /// coverage is exactly a full render's (a pixel is covered when a
    /// splat's kernel reaches it, and the nearest such splat passes the
    /// attribute pass's test). Other reads fail with
    /// [`SplatError::NotRendered`]. [`cpu::visibility_depth`](super::cpu::visibility_depth)
    /// is the reference. Timed as "visibility" (and, on the compute back
    /// end, "depth": its large splats and the conversion).
    #[allow(clippy::too_many_arguments)]
    pub fn render_depth(
        &self,
        ctx: &GpuContext,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        targets: &mut SplatTargets,
        mut timer: Option<&mut GpuTimer>,
        occluders: &OccluderSet,
    ) -> Result<(), SplatError> {
        let uniform = self.checked_view(model, cam, pose, targets)?;
        let occluders = occluders.views(cam, &self.params, &uniform)?;
        targets.view = None;
        if let Some(compute) = &self.compute
            && self.backend_for(model, cam, pose) == Backend::Compute
        {
            let job = (model, &uniform, &occluders[..]);
            compute.render(ctx, job, Attributes::GEOMETRY, true, targets, timer)?;
            targets.rendered = None;
            targets.depth_only = true;
            targets.view = Some((*pose, *cam));
            return Ok(());
        }
        let bind = self.render_bind(ctx, model, &targets.g().uniform, &uniform);
        let hidden = self.occluder_binds(ctx, targets, &occluders);
        let mut enc = ctx.encoder();
        ctx.count_passes(1);
        let colors = cleared_attachments(targets, Attributes::GEOMETRY);
        self.visibility_pass(
            &mut enc,
            (&self.visibility_depth, "splat visibility depth", &colors),
            (&bind, model.count),
            (&self.visibility_depth_occluder, &hidden),
            targets,
            timer.as_deref_mut(),
        );
        if let Some(t) = timer {
            t.resolve(&mut enc);
        }
        ctx.submit(enc);
        targets.rendered = None;
        targets.depth_only = true;
        targets.view = Some((*pose, *cam));
        Ok(())
    }

    /// The camera uniform of a render of `model` at `pose`, once `targets`
    /// are checked to be the camera's size.
    fn checked_view(
        &self,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        targets: &SplatTargets,
    ) -> Result<CameraUniform, SplatError> {
        targets.check_size(cam)?;
        model.bounds.view(cam, pose, &self.params)
    }

    /// The bind group and splat count of each occluder's draw, its
    /// uniform written to a buffer of its own in the targets (one per
    /// occluder: the writes all land before the pass runs).
    fn occluder_binds(
        &self,
        ctx: &GpuContext,
        targets: &mut SplatTargets,
        occluders: &[(&GpuModel, CameraUniform)],
    ) -> Vec<(wgpu::BindGroup, u32)> {
        let g = targets.g_mut();
        while g.occluder_uniforms.len() < occluders.len() {
            g.occluder_uniforms.push(camera_buffer(ctx));
        }
        occluders
            .iter()
            .zip(&g.occluder_uniforms)
            .map(|((m, u), buffer)| (self.render_bind(ctx, m, buffer, u), m.count))
            .collect()
    }

    /// The render pass back end's bind group, with `uniform` written to
    /// `buffer` (the targets' uniform, or an occluder's); kept for the
    /// buffers of the last few draws.
    fn render_bind(
        &self,
        ctx: &GpuContext,
        model: &GpuModel,
        buffer: &wgpu::Buffer,
        uniform: &CameraUniform,
    ) -> wgpu::BindGroup {
        ctx.write_buffer(buffer, 0, bytemuck::bytes_of(uniform));
        let (geometry, colors) = model.gpu_buffers();
        let bufs = [buffer.clone(), geometry.clone(), colors.clone()];
        let mut reuse = self.reuse.lock().unwrap_or_else(|p| p.into_inner());
        let made = reuse.render_binds.get(bufs, |b| {
            Ok(ctx.bind_group(&wgpu::BindGroupDescriptor {
                label: Some("splat"),
                layout: &self.render_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: b[0].as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: b[1].as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: b[2].as_entire_binding(),
                    },
                ],
            }))
        });
        let Ok::<_, std::convert::Infallible>(bind) = made;
        bind.clone()
    }

    /// The render pass back end's visibility pass into a cleared depth
    /// buffer: `pipeline`, its label and colour attachments (none for a
    /// full render's first pass, the depth-only render's targets for
    /// [`Splatter::render_depth`]), drawing the model's splats (its bind
    /// group and count) after the occluders' (their pipeline, which writes
    /// no colour, and draws); timed as "visibility".
    fn visibility_pass(
        &self,
        enc: &mut wgpu::CommandEncoder,
        (pipeline, label, colors): (
            &wgpu::RenderPipeline,
            &str,
            &[Option<wgpu::RenderPassColorAttachment<'_>>],
        ),
        (bind, count): (&wgpu::BindGroup, u32),
        (hidden_pipeline, hidden): (&wgpu::RenderPipeline, &[(wgpu::BindGroup, u32)]),
        targets: &SplatTargets,
        timer: Option<&mut GpuTimer>,
    ) {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(label),
            color_attachments: colors,
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.g().depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: timer.and_then(|t| t.render_pass("visibility")),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if !hidden.is_empty() {
            pass.set_pipeline(hidden_pipeline);
            for (b, n) in hidden {
                pass.set_bind_group(0, b, &[]);
                pass.draw(0..4, 0..*n);
            }
        }
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, bind, &[]);
        pass.draw(0..4, 0..count);
    }
}
