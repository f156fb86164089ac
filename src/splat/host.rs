//! The host splatter: the render pass's two passes ([`super::kernel`]'s
//! maths) on the CPU's cores, with no GPU.
//!
//! How it works: the splats are set up (transformed, culled when behind
//! the camera, back-facing or outside the image, their pixel range found)
//! in one part per thread; each visible splat is then listed in the bands
//! of rows it covers, in the model's order; threads take bands in turn,
//! and in each band run the visibility pass over the band's splats, then
//! the attribute pass, straight into the band's rows of the targets. No
//! two threads write the same pixel, and every pixel sees the splats in
//! the model's order, as the rasteriser draws them, so the sums are the
//! same bit for bit whatever the thread count or band height.

use super::accumulators::Accumulators;
use super::gpu_data::{CameraUniform, unpack_color};
use super::kernel::{Setup, View, intersect4, motion, setup, weight};
use super::{Attributes, PackedModel, SplatImage};
use glam::{Vec3, Vec4};
use std::sync::Mutex;

/// Splats with a setup part above this many points per thread go to the
/// threads; below, one thread sets them up (a thread costs tens of µs).
const SETUP_PER_THREAD: usize = 4096;
/// Bits of a listed splat's index within its setup part (the part is in
/// the bits above).
const PART_BITS: u32 = 26;
/// The pixels of a band, about: its targets (up to 80 bytes a pixel) and
/// pass 1's hits fit in a core's L2 cache.
const BAND_PIXELS: usize = 8192;
/// The lanes' offsets from a row's first column.
const LANES: Vec4 = Vec4::new(0.0, 1.0, 2.0, 3.0);
/// The most threads a splatter runs on (and parts of 2^26 splats).
const MAX_THREADS: usize = 64;

/// A reusable host splatter: threads and scratch kept across renders.
///
/// `HostSplatter::new().render(...)` gives what [`super::cpu::splat_packed`]
/// gives (that function is this, all groups on all cores); keeping one
/// splatter and one [`Accumulators`] across renders saves their
/// allocations, and [`Attributes`] without a group skips its work.
#[derive(Debug)]
pub struct HostSplatter {
    threads: usize,
    /// The visible splats, one list per setup part.
    parts: Vec<Vec<Setup>>,
    /// The splats of each band (indices into `parts`), band after band.
    bins: Vec<u32>,
    /// Where each band's splats start in `bins` (one more than bands).
    starts: Vec<usize>,
    rays_x: Vec<f32>,
    rays_y: Vec<f32>,
    /// Each thread's depth band and pass 1's hits.
    scratch: Vec<(Vec<f32>, Vec<Frag>)>,
}

impl Default for HostSplatter {
    fn default() -> Self {
        Self::new()
    }
}

/// A pixel that a splat covers: pass 1's hit, blended by pass 2.
#[derive(Debug, Clone, Copy)]
struct Frag {
    /// The pixel within the band.
    pixel: u32,
    /// The splat (as listed in the bins).
    splat: u32,
    x: Vec3,
    rho2: f32,
}

/// A band's rows of every output, handed to one thread.
struct Band<'a> {
    index: usize,
    targets: [Option<&'a mut [[f32; 4]]>; 5],
    z: Option<&'a mut [f32]>,
}

impl HostSplatter {
    /// A splatter on every core this process may use.
    pub fn new() -> Self {
        Self::with_threads(crate::par::cores())
    }

    /// A splatter on `threads` threads (the calling one included; 0 counts
    /// as 1, and at most 64).
    pub fn with_threads(threads: usize) -> Self {
        Self {
            threads: threads.clamp(1, MAX_THREADS),
            parts: Vec::new(),
            bins: Vec::new(),
            starts: Vec::new(),
            rays_x: Vec::new(),
            rays_y: Vec::new(),
            scratch: Vec::new(),
        }
    }

    /// The threads it splats on.
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Renders `model` with the view `uniform` into `out` (resized to the
    /// uniform's image): colour and weight, plus the groups of `attrs`;
    /// the targets of the other groups are left empty. The same sums as
    /// the render pass's visibility and attribute passes.
    pub fn render(
        &mut self,
        model: &PackedModel,
        uniform: &CameraUniform,
        attrs: Attributes,
        out: &mut Accumulators,
    ) {
        let v = View::new(uniform);
        let n = v.width * v.height;
        out.width = v.width as u32;
        out.height = v.height as u32;
        let wanted = [
            true,
            attrs.geometry,
            attrs.motion,
            attrs.motion,
            attrs.motion,
        ];
        for (t, want) in out.targets.iter_mut().zip(wanted) {
            // Zeroed by the bands, where they are written.
            t.resize(if want { n } else { 0 }, [0.0; 4]);
        }
        let band_rows = self.prepare(&v, model);
        let stride = band_rows * v.width;
        let mut chunks = out
            .targets
            .each_mut()
            .map(|t| (!t.is_empty()).then(|| t.chunks_mut(stride.max(1))));
        let bands = (0..self.starts.len() - 1)
            .map(|index| Band {
                index,
                targets: chunks.each_mut().map(|c| c.as_mut().and_then(|c| c.next())),
                z: None,
            })
            .collect();
        self.run_bands(&v, band_rows, bands);
    }

    /// The visibility pass alone (the reference of
    /// [`super::Splatter::render_depth`]): one channel, the pushed-back
    /// camera-space z of the nearest surface, NaN where no splat covers
    /// the pixel; `out` is resized to the uniform's image.
    pub fn render_depth(
        &mut self,
        model: &PackedModel,
        uniform: &CameraUniform,
        out: &mut SplatImage,
    ) {
        let v = View::new(uniform);
        out.width = v.width as u32;
        out.height = v.height as u32;
        out.channels = 1;
        out.data.resize(v.width * v.height, f32::NAN);
        let band_rows = self.prepare(&v, model);
        let mut chunks = out.data.chunks_mut((band_rows * v.width).max(1));
        let bands = (0..self.starts.len() - 1)
            .map(|index| Band {
                index,
                targets: Default::default(),
                z: chunks.next(),
            })
            .collect();
        self.run_bands(&v, band_rows, bands);
    }

    /// Sets up and bins the splats; returns the band height in rows.
    fn prepare(&mut self, v: &View, model: &PackedModel) -> usize {
        self.rays_x.clear();
        // Three more columns, so that every pixel starts four lanes.
        self.rays_x.extend((0..v.width + 3).map(|x| v.ray_x(x)));
        self.rays_y.clear();
        self.rays_y.extend((0..v.height).map(|y| v.ray_y(y)));
        self.set_up(v, model);
        // Bands of about BAND_PIXELS, so that a band's targets and hits
        // stay in the cache, and several a thread, so that a band dense
        // with splats does not keep one thread busy while the others wait.
        let band_rows = (BAND_PIXELS / v.width.max(1))
            .min(v.height / (4 * self.threads))
            .clamp(2, 64);
        self.bin(v.height.div_ceil(band_rows), band_rows);
        band_rows
    }

    /// The visible splats, in the model's order, in parts of consecutive
    /// splats, one part per thread.
    fn set_up(&mut self, v: &View, model: &PackedModel) {
        let n = model.splats.len().min(model.colors.len());
        let parts = self
            .threads
            .min(n.div_ceil(SETUP_PER_THREAD))
            .max(n.div_ceil(1 << PART_BITS))
            .max(1);
        let per = n.div_ceil(parts).max(1);
        self.parts.resize_with(parts, Vec::new);
        let run = |i: usize, out: &mut Vec<Setup>| {
            out.clear();
            let range = (i * per).min(n)..((i + 1) * per).min(n);
            let splats = &model.splats[range.clone()];
            let colors = &model.colors[range];
            out.extend(
                splats
                    .iter()
                    .zip(colors)
                    .filter_map(|(s, &c)| setup(v, s, c)),
            );
        };
        if parts == 1 {
            run(0, &mut self.parts[0]);
            return;
        }
        let run = &run;
        let failed = std::thread::scope(|scope| {
            let (first, rest) = self.parts.split_first_mut().expect("parts >= 1");
            let mut failed = Vec::new();
            for (i, out) in rest.iter_mut().enumerate() {
                let started =
                    std::thread::Builder::new().spawn_scoped(scope, move || run(i + 1, out));
                if let Err(e) = started {
                    log::debug!("host splatter: setup on the calling thread ({e})");
                    failed.push(i + 1);
                }
            }
            run(0, first);
            failed
        });
        for i in failed {
            run(i, &mut self.parts[i]);
        }
    }

    /// Lists every visible splat in the bands it covers (a counting sort:
    /// counts, starts, then the lists, in the model's order).
    fn bin(&mut self, bands: usize, band_rows: usize) {
        self.starts.clear();
        self.starts.resize(bands + 1, 0);
        for s in self.parts.iter().flatten() {
            for b in s.y0 as usize / band_rows..=s.y1 as usize / band_rows {
                self.starts[b + 1] += 1;
            }
        }
        for b in 0..bands {
            self.starts[b + 1] += self.starts[b];
        }
        self.bins.resize(self.starts[bands], 0);
        let mut next = self.starts.clone();
        for (p, part) in self.parts.iter().enumerate() {
            for (i, s) in part.iter().enumerate() {
                let id = (p as u32) << PART_BITS | i as u32;
                for at in &mut next[s.y0 as usize / band_rows..=s.y1 as usize / band_rows] {
                    self.bins[*at] = id;
                    *at += 1;
                }
            }
        }
    }

    /// The bands, taken in turn by the threads.
    fn run_bands(&mut self, v: &View, band_rows: usize, bands: Vec<Band<'_>>) {
        let threads = self.threads.min(bands.len()).max(1);
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.resize_with(threads, Default::default);
        let queue = Mutex::new(bands.into_iter());
        let this = &*self;
        let work = |(depth, frags): &mut (Vec<f32>, Vec<Frag>)| {
            loop {
                // A poisoned queue: another thread panicked, and the scope
                // passes its panic on.
                let Some(band) = queue.lock().ok().and_then(|mut q| q.next()) else {
                    return;
                };
                this.band(v, band_rows, band, depth, frags);
            }
        };
        if threads == 1 {
            work(&mut scratch[0]);
        } else {
            let work = &work;
            std::thread::scope(|scope| {
                let (first, rest) = scratch.split_first_mut().expect("threads >= 1");
                for s in rest {
                    let started = std::thread::Builder::new().spawn_scoped(scope, move || work(s));
                    if let Err(e) = started {
                        log::debug!("host splatter: fewer threads ({e})");
                    }
                }
                work(first);
            });
        }
        self.scratch = scratch;
    }

    fn splat(&self, id: u32) -> &Setup {
        &self.parts[(id >> PART_BITS) as usize][(id & ((1 << PART_BITS) - 1)) as usize]
    }

    /// Both passes over one band's rows.
    fn band(
        &self,
        v: &View,
        band_rows: usize,
        mut band: Band<'_>,
        depth: &mut Vec<f32>,
        frags: &mut Vec<Frag>,
    ) {
        let w = v.width;
        let y0 = band.index * band_rows;
        let rows = band_rows.min(v.height - y0);
        let list = &self.bins[self.starts[band.index]..self.starts[band.index + 1]];
        depth.clear();
        depth.resize(rows * w, 1.0);
        if let Some(z) = band.z.as_deref_mut() {
            z.fill(f32::NAN);
        }
        for t in band.targets.iter_mut().flatten() {
            t.fill([0.0; 4]);
        }
        // The rows and columns of a splat within the band.
        let span = |s: &Setup| {
            let ya = (s.y0 as usize).max(y0);
            let yb = (s.y1 as usize).min(y0 + rows - 1);
            (ya..=yb, s.x0 as usize..=s.x1 as usize)
        };
        // Pass 1 (visibility): the nearest pushed-back depth; the z of
        // the first splat to reach it. Its hits are kept for pass 2, which
        // would find the same ones.
        let keep = band.targets[0].is_some();
        frags.clear();
        for &id in list {
            let s = self.splat(id);
            let (ys, xs) = span(s);
            let x1 = *xs.end();
            for y in ys {
                let ry = self.rays_y[y];
                let row = (y - y0) * w;
                let yf = y as f32;
                for x in xs.clone().step_by(4) {
                    let dx = Vec4::from_slice(&self.rays_x[x..x + 4]);
                    let u = Vec4::splat(x as f32) + LANES;
                    let hits = intersect4(v, s, u, dx, ry, yf);
                    // Lanes past the splat's last column are not its.
                    let mut mask = hits.mask & (0xf >> 3usize.saturating_sub(x1 - x));
                    if mask == 0 {
                        continue;
                    }
                    // |d|, as (dx dx + dy dy) + 1 1.
                    let len = (dx * dx + Vec4::splat(ry * ry) + Vec4::ONE).sqrt();
                    let zp = (hits.x[2] + Vec4::splat(s.push) / len).to_array();
                    let [hx, hy, hz] = hits.x.map(|c| c.to_array());
                    let rho2 = hits.rho2.to_array();
                    while mask != 0 {
                        let k = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        let dd = v.depth_of(zp[k]);
                        let i = row + x + k;
                        if dd < depth[i] {
                            depth[i] = dd;
                            if let Some(z) = band.z.as_deref_mut() {
                                z[i] = zp[k];
                            }
                        }
                        if keep {
                            frags.push(Frag {
                                pixel: i as u32,
                                splat: id,
                                x: Vec3::new(hx[k], hy[k], hz[k]),
                                rho2: rho2[k],
                            });
                        }
                    }
                }
            }
        }
        let [t0, t1, t2, t3, t4] = band.targets;
        let Some(t0) = t0 else {
            return;
        };
        let mut predictors = match (t2, t3, t4) {
            (Some(a), Some(b), Some(c)) => Some([a, b, c]),
            _ => None,
        };
        let mut geometry = t1;
        // Pass 2 (attributes) over pass 1's hits, in the same order:
        // depth test less-or-equal, no depth writes.
        let mut last = u32::MAX;
        let (mut color, mut normal) = ([0.0; 4], Vec3::ZERO);
        for f in frags.iter() {
            let i = f.pixel as usize;
            if v.depth_of(f.x.z) > depth[i] {
                continue;
            }
            if f.splat != last {
                last = f.splat;
                let s = self.splat(last);
                let [r, g, b] = unpack_color(s.color);
                color = [r, g, b, 1.0];
                normal = s.m;
            }
            let wt = weight(f.rho2);
            add(&mut t0[i], color, wt);
            if let Some(t1) = geometry.as_deref_mut() {
                add(&mut t1[i], [f.x.z, normal.x, normal.y, normal.z], wt);
            }
            if let Some([t2, t3, t4]) = predictors.as_mut() {
                let l = motion(v, f.x);
                add(&mut t2[i], [l[0], l[1], l[2], l[3]], wt);
                add(&mut t3[i], [l[4], l[5], l[6], l[7]], wt);
                add(&mut t4[i], [l[8], l[9], l[10], l[11]], wt);
            }
        }
    }
}

/// Additive blending of `w * a`.
#[inline(always)]
fn add(acc: &mut [f32; 4], a: [f32; 4], w: f32) {
    for k in 0..4 {
        acc[k] += a[k] * w;
    }
}
