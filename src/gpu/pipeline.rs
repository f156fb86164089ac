//! Bind-group layouts, pipelines, passes, bind groups kept and workgroup
//! sizes: the plumbing every GPU module (the splatter, Harris, NCC) builds
//! the same way.

use super::context::GpuContext;
use super::error::GpuError;
use super::health::Health;
use super::stats::Counters;
use super::timer::GpuTimer;

/// A bind group layout entry for a whole buffer, visible to `visibility`.
pub fn buffer_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    ty: wgpu::BufferBindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A bind group layout entry for a compute-visible buffer.
pub fn compute_entry(binding: u32, ty: wgpu::BufferBindingType) -> wgpu::BindGroupLayoutEntry {
    buffer_entry(binding, wgpu::ShaderStages::COMPUTE, ty)
}

/// A bind group layout entry for an unfilterable 2-D float texture read
/// with `textureLoad`.
pub fn texture_entry(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

/// A storage buffer binding type.
pub const fn storage(read_only: bool) -> wgpu::BufferBindingType {
    wgpu::BufferBindingType::Storage { read_only }
}

impl GpuContext {
    /// A bind group layout of `entries`.
    pub fn bind_group_layout(
        &self,
        label: &str,
        entries: &[wgpu::BindGroupLayoutEntry],
    ) -> wgpu::BindGroupLayout {
        self.device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries,
            })
    }

    /// Compute pipelines of the entry points `entries` of one shader, sharing
    /// one explicit bind group layout, so that a single bind group serves
    /// every pass.
    pub fn compute_pipelines(
        &self,
        shader: &crate::shaders::Shader,
        layout: &wgpu::BindGroupLayout,
        entries: &[&str],
    ) -> Result<Vec<wgpu::ComputePipeline>, GpuError> {
        let module = self.shader(shader)?;
        let shader = shader.name;
        let pl = self.catch(shader, || {
            self.device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(shader),
                    bind_group_layouts: &[Some(layout)],
                    immediate_size: 0,
                })
        })?;
        entries
            .iter()
            .map(|entry| {
                self.catch(&format!("{shader}::{entry}"), || {
                    self.device
                        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                            label: Some(entry),
                            layout: Some(&pl),
                            module: &module,
                            entry_point: Some(entry),
                            compilation_options: Default::default(),
                            cache: None,
                        })
                })
            })
            .collect()
    }
}

/// The compute passes of a chain of stages recorded into one encoder:
/// one pass for all of them, or one a stage where stages are timed (a
/// pass's timestamps are written at its beginning and end). Each pass
/// costs the host more than its dispatches (wgpu-core records it into a
/// driver command buffer of its own, with another before it for its
/// barriers: 16.1 us a pass on lavapipe, the `features` bench's
/// `dispatches_40_in_40_passes` against `_in_1_pass`), and the GPU
/// nothing: wgpu places the same barriers between dispatches of one pass
/// as between passes. The open pass ends when the chain is dropped or
/// [`PassChain::encoder`] is asked for.
pub struct PassChain<'e> {
    enc: &'e mut wgpu::CommandEncoder,
    pass: Option<wgpu::ComputePass<'static>>,
    /// Passes begun.
    begun: usize,
    /// Whether an untimed run would have a pass open here.
    untimed_open: bool,
    /// Counted in [`GpuStats::passes`](super::GpuStats::passes).
    health: std::sync::Arc<Health>,
}

impl<'e> PassChain<'e> {
    /// A chain recording into `enc`, its passes counted by `ctx`
    /// ([`GpuStats::passes`](super::GpuStats::passes)).
    pub fn new(ctx: &GpuContext, enc: &'e mut wgpu::CommandEncoder) -> Self {
        Self {
            enc,
            pass: None,
            begun: 0,
            untimed_open: false,
            health: ctx.health.clone(),
        }
    }

    /// The pass to record stage `label` into: the open one, or a new one
    /// where there is none or `timer` times the stage.
    pub fn stage(
        &mut self,
        label: &str,
        timer: Option<&mut GpuTimer>,
    ) -> &mut wgpu::ComputePass<'static> {
        if !self.untimed_open {
            self.untimed_open = true;
            Counters::add(&self.health.counts.passes_untimed, 1);
        }
        let timestamps = timer.and_then(|t| t.compute_pass(label));
        if timestamps.is_some() || self.pass.is_none() {
            // The open pass ends before the encoder begins the next.
            self.pass = None;
            let pass = self.enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(label),
                timestamp_writes: timestamps,
            });
            self.begun += 1;
            Counters::add(&self.health.counts.passes, 1);
            self.pass = Some(pass.forget_lifetime());
        }
        self.pass.as_mut().expect("just begun")
    }

    /// The encoder, the open pass ended (for copies, clears, timestamp
    /// resolves between or after the stages).
    pub fn encoder(&mut self) -> &mut wgpu::CommandEncoder {
        self.pass = None;
        self.untimed_open = false;
        self.enc
    }

    /// How many passes the chain has begun.
    pub fn passes(&self) -> usize {
        self.begun
    }
}

/// Workgroup size of the kernels that run one thread per item (Harris's
/// refinement, NCC's vectorisation and reductions, the splatter's gather,
/// the self-test), a power of two (the NCC reductions halve it).
pub const WORKGROUP_1D: u32 = 64;

/// Workgroup edge of the kernels that run one thread per pixel in
/// `WORKGROUP_2D x WORKGROUP_2D` tiles (Harris's image passes).
pub const WORKGROUP_2D: u32 = 16;

/// Floats per gathered point: 12 predictors, depth, validity (the stride
/// of `gather`'s output in shaders/splat_resolve.wgsl; the NCC gate,
/// shaders/ncc_gate.wgsl, reads the validity).
pub const GATHER_STRIDE: usize = 14;

/// Number of workgroups of `size` threads covering `n` items.
pub fn workgroups(n: u32, size: u32) -> u32 {
    n.div_ceil(size)
}

/// Bind groups kept for as long as the buffers they bind are the same
/// ones (wgpu buffers compare by identity): a pass whose inputs are
/// grow-only buffers, or buffers lent by another stage, binds anew only
/// when one of them was replaced. The last two sets are kept, so that a
/// pass fed in turn by two stages (Harris's export, into IT's matching
/// and then KF's, each frame) binds nothing anew either.
pub struct BindCache<const N: usize> {
    /// The most recently used first.
    held: Vec<([wgpu::Buffer; N], wgpu::BindGroup)>,
    /// How many sets are kept.
    keep: usize,
}

impl<const N: usize> Default for BindCache<N> {
    fn default() -> Self {
        Self::keeping(2)
    }
}

impl<const N: usize> BindCache<N> {
    /// A cache of the bind groups of the last `keep` sets of buffers (at
    /// least one).
    pub fn keeping(keep: usize) -> Self {
        let keep = keep.max(1);
        Self {
            held: Vec::with_capacity(keep),
            keep,
        }
    }

    /// The bind group of `buffers`: a held one when it binds these, else
    /// `bind(&buffers)`'s, held from now on (in place of the least
    /// recently used).
    pub fn get<E>(
        &mut self,
        buffers: [wgpu::Buffer; N],
        bind: impl FnOnce(&[wgpu::Buffer; N]) -> Result<wgpu::BindGroup, E>,
    ) -> Result<&wgpu::BindGroup, E> {
        match self.held.iter().position(|(held, _)| *held == buffers) {
            Some(i) => self.held[..=i].rotate_right(1),
            None => {
                let group = bind(&buffers)?;
                self.held.truncate(self.keep - 1);
                self.held.insert(0, (buffers, group));
            }
        }
        Ok(&self.held[0].1)
    }
}
