//! The Python package's native module, `splattrack._splattrack`: a thin
//! binding over the library the `splattrack` command runs (camera, model,
//! tracker, novel views), its errors mapped onto a Python hierarchy
//! ([`errors`]). The GIL is released around every load, build, track and
//! render, which run on the library's own threads and the GPU.

mod arrays;
mod camera;
mod errors;
mod model;
mod multi;
mod settings;
mod tracker;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use splattrack::gpu::{AdapterChoice, GpuContext};
use splattrack::{Device, DeviceChoice};
use std::sync::Mutex;

/// The process's GPU context: made once, at the first use, on the adapter
/// `$SPLATTRACK_ADAPTER` names (as the command line), then shared by every
/// tracker (a cheap clone).
fn context(py: Python<'_>) -> PyResult<GpuContext> {
    static CTX: Mutex<Option<GpuContext>> = Mutex::new(None);
    py.detach(|| {
        let mut slot = CTX.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(ctx) = slot.as_ref() {
            return Ok::<_, splattrack::gpu::GpuError>(ctx.clone());
        }
        let ctx = GpuContext::new(&AdapterChoice::from_env()?)?;
        *slot = Some(ctx.clone());
        Ok(ctx)
    })
    .map_err(errors::gpu)
}

/// The device `name` asks for: `"gpu"` (the process's GPU context),
/// `"cpu"` (the host's cores, no GPU object) or `"auto"` (the GPU context
/// when one can be made, else the CPU; the CPU too where the context is a
/// software adapter that `$SPLATTRACK_ADAPTER` did not name: the rule of
/// [`Device::new`], so that the package and the command line run alike).
pub(crate) fn device_of(py: Python<'_>, name: &str) -> PyResult<Device> {
    let choice: DeviceChoice = name
        .parse()
        .map_err(|e: splattrack::gpu::GpuError| PyValueError::new_err(e.to_string()))?;
    match choice {
        DeviceChoice::Cpu => Ok(Device::Cpu),
        DeviceChoice::Gpu => Ok(Device::Gpu(context(py)?)),
        DeviceChoice::Auto => {
            let adapter = AdapterChoice::from_env().map_err(errors::gpu)?;
            Ok(Device::auto(
                context(py).map_err(|e| e.to_string()),
                &adapter,
            ))
        }
    }
}

/// The device the package runs on for `device` (`"auto"`: a hardware GPU
/// adapter when one opens, else the CPU), as the command line names it
/// (`llvmpipe (...) (Cpu, Vulkan)`); makes the GPU context when needed.
#[pyfunction]
#[pyo3(signature = (device="auto"))]
fn device(py: Python<'_>, device: &str) -> PyResult<String> {
    Ok(device_of(py, device)?.describe())
}

#[pymodule]
fn _splattrack(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<camera::Camera>()?;
    m.add_class::<model::Model>()?;
    m.add_class::<tracker::Tracker>()?;
    m.add_class::<tracker::TrackResult>()?;
    m.add_class::<multi::MultiTracker>()?;
    m.add_function(wrap_pyfunction!(device, m)?)?;
    m.add_function(wrap_pyfunction!(arrays::read_image, m)?)?;
    m.add_function(wrap_pyfunction!(arrays::list_images, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
