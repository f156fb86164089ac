//! Memory accounting: the device's figures ([`GpuMemory`], from
//! [`GpuContext::memory_report`](super::GpuContext::memory_report)) and
//! byte counts in words ([`human_bytes`]).

/// Figures of [`GpuContext::memory_report`](super::GpuContext::memory_report).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GpuMemory {
    /// Live buffers (0 when wgpu is built without its counters).
    pub buffers: isize,
    /// Live textures (likewise).
    pub textures: isize,
    /// Bytes of buffer memory (likewise).
    pub buffer_bytes: isize,
    /// Bytes of texture memory (likewise).
    pub texture_bytes: isize,
    /// Bytes the allocator holds for resources, where reported.
    pub allocated_bytes: Option<u64>,
    /// Bytes it reserved from the driver, where reported.
    pub reserved_bytes: Option<u64>,
}

/// `bytes` as "12.3 MB" (powers of 1000).
pub fn human_bytes(bytes: u64) -> String {
    let units = ["B", "kB", "MB", "GB", "TB", "PB", "EB"];
    let mut v = bytes as f64;
    let mut u = 0;
    while v >= 1000.0 && u + 1 < units.len() {
        v /= 1000.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.1} {}", units[u])
    }
}
