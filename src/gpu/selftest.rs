//! A tiny end-to-end check of the device: upload, compute dispatch and
//! readback of `y = a x + y`, compared with the same sum on the host.

use super::{GpuContext, GpuError, STORAGE_IN, STORAGE_OUT, WORKGROUP_1D, workgroups};
use crate::shaders::{Shader, WgslValue};
use crate::wgsl_struct;

/// The self-test's shader (`saxpy`).
pub static SHADER: Shader = Shader {
    name: "selftest",
    parts: &[crate::wgsl_file!("selftest.wgsl")],
    constants: &[&[("WORKGROUP_1D", WgslValue::U32(WORKGROUP_1D))]],
};

wgsl_struct! {
    /// The uniform of the `saxpy` kernel.
    #[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
    pub struct SelftestParams {
        /// The factor `a` of `a * x + y`.
        pub a: f32,
        /// Number of elements.
        pub n: u32,
        /// Padding to a 16-byte size.
        pub _pad0: u32,
        /// Padding to a 16-byte size.
        pub _pad1: u32,
    }
}

/// CPU reference of the `saxpy` kernel.
pub fn saxpy_cpu(a: f32, x: &[f32], y: &[f32]) -> Vec<f32> {
    x.iter().zip(y).map(|(x, y)| a.mul_add(*x, *y)).collect()
}

/// The `saxpy` kernel bound to device copies of `x` and `y`: the self-test's
/// dispatch, and a small real one for tests and benches of the context
/// (timers, submissions, a pass's cost).
pub struct Saxpy {
    pipeline: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    y: wgpu::Buffer,
    n: u32,
}

impl Saxpy {
    /// `y = a x + y` over uploaded copies of `x` and `y` (equal lengths).
    pub fn new(ctx: &GpuContext, a: f32, x: &[f32], y: &[f32]) -> Result<Self, GpuError> {
        assert_eq!(x.len(), y.len(), "saxpy: x and y differ in length");
        let n = x.len() as u32;
        let pipeline = ctx.compute_pipeline(&SHADER, "saxpy")?;
        let params = ctx.buffer_init(
            "saxpy params",
            &[SelftestParams {
                a,
                n,
                _pad0: 0,
                _pad1: 0,
            }],
            wgpu::BufferUsages::UNIFORM,
        );
        let xb = ctx.buffer_init("saxpy x", x, STORAGE_IN);
        let yb = ctx.buffer_init("saxpy y", y, STORAGE_OUT);
        let bind = ctx.bind_buffers(
            "saxpy",
            &pipeline.get_bind_group_layout(0),
            &[&params, &xb, &yb],
        )?;
        Ok(Self {
            pipeline,
            bind,
            y: yb,
            n,
        })
    }

    /// Records one `y += a x` over every element into `pass`.
    pub fn dispatch(&self, pass: &mut wgpu::ComputePass<'_>) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind, &[]);
        pass.dispatch_workgroups(workgroups(self.n, WORKGROUP_1D), 1, 1);
    }

    /// The device's `y`.
    pub fn y(&self) -> &wgpu::Buffer {
        &self.y
    }
}

/// Runs the `saxpy` kernel on the GPU.
pub fn saxpy_gpu(ctx: &GpuContext, a: f32, x: &[f32], y: &[f32]) -> Result<Vec<f32>, GpuError> {
    let k = Saxpy::new(ctx, a, x, y)?;
    let mut enc = ctx.encoder();
    k.dispatch(super::PassChain::new(ctx, &mut enc).stage("saxpy", None));
    ctx.submit(enc);
    ctx.read_buffer(k.y(), x.len())
}

/// Runs the kernel on `n` pseudo-random values and returns the largest
/// difference from the host result in units of f32 epsilon relative to
/// `|a x| + |y|`: at most 1 on a working device (WGSL's `fma` may be
/// evaluated unfused, which rounds the product once more).
pub fn run(ctx: &GpuContext, n: usize) -> Result<f32, GpuError> {
    let mut rng = crate::rng::Rng::new(n as u64);
    let x: Vec<f32> = (0..n).map(|_| rng.uniform(-100.0, 100.0) as f32).collect();
    let y: Vec<f32> = (0..n).map(|_| rng.uniform(-100.0, 100.0) as f32).collect();
    let a = rng.uniform(-3.0, 3.0) as f32;
    let gpu = saxpy_gpu(ctx, a, &x, &y)?;
    let cpu = saxpy_cpu(a, &x, &y);
    Ok(gpu
        .iter()
        .zip(&cpu)
        .zip(x.iter().zip(&y))
        .map(|((g, c), (x, y))| (g - c).abs() / ((a * x).abs() + y.abs()) / f32::EPSILON)
        .fold(0.0, f32::max))
}
