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
//! same bit for bit whatever the thread count or band height. The
//! threads are a pool kept in the splatter, started by its first render
//! on more than one thread.
//!
//! A thinned render ([`HostSplatter::set_thinning`]) sets up about one
//! splat in n only, its radius grown by the square root of n: a level of
//! detail for models with many sub-pixel splats a pixel, whose outputs
//! differ from the full model's.

use super::accumulators::Accumulators;
use super::gpu_data::{CameraUniform, unpack_color};
use super::kernel::{Setup, View, intersect4, motion, setup, setup4, weight};
use super::{Attributes, PackedModel, SplatImage};
use glam::{BVec4A, Vec3, Vec4};
use std::sync::Mutex;

/// Splats with a setup part above this many points per thread go to the
/// threads; below, one thread sets them up (handing work to a thread
/// costs several µs).
const SETUP_PER_THREAD: usize = 4096;
/// Bits of a listed splat's index within its setup part (the part is in
/// the bits above).
const PART_BITS: u32 = 26;
/// The pixels of a band, about: its targets (up to 80 bytes a pixel) and
/// pass 1's hits fit in a core's L2 cache.
const BAND_PIXELS: usize = 8192;
/// The lanes' offsets from a row's first column.
const LANES: Vec4 = Vec4::new(0.0, 1.0, 2.0, 3.0);
/// The most threads a splatter runs on.
const MAX_THREADS: usize = 64;
/// The most setup parts of a render, all objects together (the bits of
/// a listed splat's index above [`PART_BITS`]).
const MAX_PARTS: usize = 1 << (32 - PART_BITS);

/// A reusable host splatter: threads and scratch kept across renders.
///
/// `HostSplatter::new().render(...)` gives what [`super::cpu::splat_packed`]
/// gives (that function is this, all groups on all cores); keeping one
/// splatter and one [`Accumulators`] across renders saves their
/// allocations, and [`Attributes`] without a group skips its work.
#[derive(Debug)]
pub struct HostSplatter {
    threads: usize,
    /// The visible splats, one list per setup part: the occluders' parts
    /// first, then the model's.
    parts: Vec<Vec<Setup>>,
    /// Each part's object (an index into the render's views; the model's
    /// is the last) and its range of the object's splats.
    jobs: Vec<(usize, std::ops::Range<usize>)>,
    /// The splats of each band (indices into `parts`), band after band.
    bins: Vec<u32>,
    /// Where each band's splats start in `bins` (one more than bands).
    starts: Vec<usize>,
    rays_x: Vec<f32>,
    rays_y: Vec<f32>,
    /// Each thread's depth band and pass 1's hits.
    scratch: Vec<(Vec<f32>, Vec<Frag>)>,
    /// The worker threads (none on one thread, or where they could not
    /// be started: then everything runs on the calling thread).
    pool: Option<rayon::ThreadPool>,
    /// About one splat in `thin` is rendered (1: all).
    thin: usize,
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
    /// `depth_of(x.z)`, pass 2's depth test (made four at a time in pass 1).
    dz: f32,
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

    /// A splatter on `threads` threads (0 counts as 1, and at most 64): on
    /// the calling thread alone for 1, else on a pool of `threads` threads
    /// started by the first render and kept while the splatter lives (the
    /// calling thread waits for them).
    pub fn with_threads(threads: usize) -> Self {
        Self {
            threads: threads.clamp(1, MAX_THREADS),
            parts: Vec::new(),
            jobs: Vec::new(),
            bins: Vec::new(),
            starts: Vec::new(),
            rays_x: Vec::new(),
            rays_y: Vec::new(),
            scratch: Vec::new(),
            pool: None,
            thin: 1,
        }
    }

    /// The threads it splats on.
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// A level of detail for the next renders: about one splat in `step`
    /// is rendered (picked by a hash of its index, the same ones on every
    /// render and thread count: a stride would alias with models sampled
    /// in a regular order), in the model's order, its radius grown by
    /// `sqrt(step)` so that the splats still cover the surface; 1 (the
    /// default, and what 0 means) renders every splat, the reference's
    /// sums bit for bit. Thinned renders differ from the full model's
    /// (docs/performance.md, "The host splatter", gives the depth error
    /// and coverage against a mesh); worth it where several splats fall
    /// in a pixel.
    pub fn set_thinning(&mut self, step: usize) {
        self.thin = step.max(1);
    }

    /// The level of detail set by [`Self::set_thinning`] (1: every splat).
    pub fn thinning(&self) -> usize {
        self.thin
    }

    /// Starts the pool of worker threads if it is wanted and not there.
    fn start_pool(&mut self) {
        if self.threads < 2 || self.pool.is_some() {
            return;
        }
        let built = rayon::ThreadPoolBuilder::new()
            .num_threads(self.threads)
            .thread_name(|i| format!("host-splat-{i}"))
            .build();
        match built {
            Ok(pool) => self.pool = Some(pool),
            Err(e) => log::debug!("host splatter: on the calling thread ({e})"),
        }
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
        self.render_occluded(model, uniform, &[], attrs, out);
    }

    /// [`Self::render`] behind `occluders`, each a model with its own view
    /// (its pose, the same camera, and `uniform`'s depth range:
    /// [`CameraUniform::with_depth_range`]): pass 1 runs over the
    /// occluders' splats, in their order, then the model's; pass 2 over
    /// the model's alone, so the targets are empty where an occluder is
    /// nearer than the model (beyond the push-back) and, elsewhere, those
    /// of a render without them. A thinned render thins the occluders too.
    pub fn render_occluded(
        &mut self,
        model: &PackedModel,
        uniform: &CameraUniform,
        occluders: &[(&PackedModel, CameraUniform)],
        attrs: Attributes,
        out: &mut Accumulators,
    ) {
        self.render_full(model, uniform, occluders, attrs, out, None);
    }

    /// [`Self::render_occluded`] that writes its visibility pass's depth
    /// into `depth` too: what [`Self::render_depth_occluded`] gives, bit
    /// for bit (the same pass over the same splats), for one pass more of
    /// writes, not a render more.
    pub fn render_occluded_with_depth(
        &mut self,
        model: &PackedModel,
        uniform: &CameraUniform,
        occluders: &[(&PackedModel, CameraUniform)],
        attrs: Attributes,
        out: &mut Accumulators,
        depth: &mut SplatImage,
    ) {
        self.render_full(model, uniform, occluders, attrs, out, Some(depth));
    }

    fn render_full(
        &mut self,
        model: &PackedModel,
        uniform: &CameraUniform,
        occluders: &[(&PackedModel, CameraUniform)],
        attrs: Attributes,
        out: &mut Accumulators,
        depth: Option<&mut SplatImage>,
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
        let views = self.views(&v, occluders);
        let band_rows = self.prepare(&views, model, occluders);
        let stride = band_rows * v.width;
        let mut chunks = out
            .targets
            .each_mut()
            .map(|t| (!t.is_empty()).then(|| t.chunks_mut(stride.max(1))));
        let mut z = depth.map(|d| {
            d.width = v.width as u32;
            d.height = v.height as u32;
            d.channels = 1;
            d.data.resize(n, f32::NAN);
            d.data.chunks_mut(stride.max(1))
        });
        let bands = (0..self.starts.len() - 1)
            .map(|index| Band {
                index,
                targets: chunks.each_mut().map(|c| c.as_mut().and_then(|c| c.next())),
                z: z.as_mut().and_then(|c| c.next()),
            })
            .collect();
        self.run_bands(&views, band_rows, bands);
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
        self.render_depth_occluded(model, uniform, &[], out);
    }

    /// [`Self::render_depth`] behind `occluders` (as in
    /// [`Self::render_occluded`]): NaN too where an occluder's pushed-back
    /// depth is nearer than the model's, or equal (drawn first, it wins
    /// the test), never the occluder's depth.
    pub fn render_depth_occluded(
        &mut self,
        model: &PackedModel,
        uniform: &CameraUniform,
        occluders: &[(&PackedModel, CameraUniform)],
        out: &mut SplatImage,
    ) {
        let v = View::new(uniform);
        out.width = v.width as u32;
        out.height = v.height as u32;
        out.channels = 1;
        out.data.resize(v.width * v.height, f32::NAN);
        let views = self.views(&v, occluders);
        let band_rows = self.prepare(&views, model, occluders);
        let mut chunks = out.data.chunks_mut((band_rows * v.width).max(1));
        let bands = (0..self.starts.len() - 1)
            .map(|index| Band {
                index,
                targets: Default::default(),
                z: chunks.next(),
            })
            .collect();
        self.run_bands(&views, band_rows, bands);
    }

    /// The views of a render: the occluders' (their own pose and near
    /// plane, the model's camera and depth range), then the model's.
    fn views(&self, v: &View, occluders: &[(&PackedModel, CameraUniform)]) -> Vec<View> {
        let (near, far) = v.depth_range();
        occluders
            .iter()
            .map(|(_, u)| View::new(&u.with_depth_range(near, far)))
            .chain(std::iter::once(v.clone()))
            .collect()
    }

    /// Sets up and bins the splats of the occluders and the model
    /// (`views`: theirs, the model's last); returns the band height in
    /// rows.
    fn prepare(
        &mut self,
        views: &[View],
        model: &PackedModel,
        occluders: &[(&PackedModel, CameraUniform)],
    ) -> usize {
        let v = views.last().expect("the model's view");
        self.start_pool();
        self.rays_x.clear();
        // Three more columns, so that every pixel starts four lanes.
        self.rays_x.extend((0..v.width + 3).map(|x| v.ray_x(x)));
        self.rays_y.clear();
        self.rays_y.extend((0..v.height).map(|y| v.ray_y(y)));
        let objects: Vec<&PackedModel> = occluders
            .iter()
            .map(|(m, _)| *m)
            .chain(std::iter::once(model))
            .collect();
        self.set_up(views, &objects);
        // Bands of about BAND_PIXELS, so that a band's targets and hits
        // stay in the cache, and several a thread, so that a band dense
        // with splats does not keep one thread busy while the others wait.
        let band_rows = (BAND_PIXELS / v.width.max(1))
            .min(v.height / (4 * self.threads))
            .clamp(2, 64);
        self.bin(v.height.div_ceil(band_rows), band_rows);
        band_rows
    }

    /// The visible splats of each object (`views[k]` is `objects[k]`'s),
    /// in its order, in parts of consecutive splats, about one part per
    /// thread an object (fewer where the objects need more than
    /// [`MAX_PARTS`] in all); the objects' parts in order.
    fn set_up(&mut self, views: &[View], objects: &[&PackedModel]) {
        let step = self.thin;
        let sizes: Vec<usize> = objects
            .iter()
            .map(|m| m.splats.len().min(m.colors.len()))
            .collect();
        let least: Vec<usize> = sizes
            .iter()
            .map(|n| n.div_ceil(1 << PART_BITS).max(1))
            .collect();
        let mut counts: Vec<usize> = sizes
            .iter()
            .zip(&least)
            .map(|(n, &l)| {
                self.threads
                    .min(n.div_ceil(step).div_ceil(SETUP_PER_THREAD))
                    .max(l)
            })
            .collect();
        // Over the bits of a listed index: fewer parts for the objects
        // with the most (never fewer than their size needs).
        while counts.iter().sum::<usize>() > MAX_PARTS {
            let Some(k) = (0..counts.len())
                .filter(|&k| counts[k] > least[k])
                .max_by_key(|&k| counts[k])
            else {
                break;
            };
            counts[k] -= 1;
        }
        self.jobs.clear();
        for (k, (&n, &parts)) in sizes.iter().zip(&counts).enumerate() {
            let per = n.div_ceil(parts).max(1);
            self.jobs
                .extend((0..parts).map(|i| (k, (i * per).min(n)..((i + 1) * per).min(n))));
        }
        self.parts.resize_with(self.jobs.len(), Vec::new);
        let grow = (step as f32).sqrt();
        let jobs = &self.jobs;
        let run = |i: usize, out: &mut Vec<Setup>| {
            out.clear();
            let (k, range) = &jobs[i];
            let (v, model) = (&views[*k], objects[*k]);
            let first = range.start;
            let splats = &model.splats[range.clone()];
            let colors = &model.colors[range.clone()];
            if step == 1 {
                let (s4, c4) = (splats.chunks_exact(4), colors.chunks_exact(4));
                let (s_rest, c_rest) = (s4.remainder(), c4.remainder());
                for (s, c) in s4.zip(c4) {
                    setup4(v, s, c, out);
                }
                out.extend(
                    s_rest
                        .iter()
                        .zip(c_rest)
                        .filter_map(|(s, &c)| setup(v, s, c)),
                );
            } else {
                out.extend(
                    splats
                        .iter()
                        .zip(colors)
                        .enumerate()
                        .filter(|&(j, _)| kept(first + j, step))
                        .filter_map(|(_, (s, &c))| {
                            let mut s = *s;
                            s.pos_radius[3] *= grow;
                            setup(v, &s, c)
                        }),
                );
            }
        };
        on_each(self.pool.as_ref(), &mut self.parts, &run);
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
    fn run_bands(&mut self, views: &[View], band_rows: usize, bands: Vec<Band<'_>>) {
        let threads = self.threads.min(bands.len()).max(1);
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.resize_with(threads, Default::default);
        let queue = Mutex::new(bands.into_iter());
        let this = &*self;
        let work = |_: usize, (depth, frags): &mut (Vec<f32>, Vec<Frag>)| {
            loop {
                // A poisoned queue: another thread panicked, and the pool
                // passes its panic on.
                let Some(band) = queue.lock().ok().and_then(|mut q| q.next()) else {
                    return;
                };
                this.band(views, band_rows, band, depth, frags);
            }
        };
        on_each(self.pool.as_ref(), &mut scratch[..threads], &work);
        self.scratch = scratch;
    }

    fn splat(&self, id: u32) -> &Setup {
        &self.parts[(id >> PART_BITS) as usize][(id & ((1 << PART_BITS) - 1)) as usize]
    }

    /// Both passes over one band's rows: pass 1 over every object's
    /// splats (`views`: the occluders', then the model's), pass 2 over
    /// the model's.
    fn band(
        &self,
        views: &[View],
        band_rows: usize,
        mut band: Band<'_>,
        depth: &mut Vec<f32>,
        frags: &mut Vec<Frag>,
    ) {
        let model = views.len() - 1;
        let v = &views[model];
        let w = v.width;
        let y0 = band.index * band_rows;
        let rows = band_rows.min(v.height - y0);
        let list = &self.bins[self.starts[band.index]..self.starts[band.index + 1]];
        depth.clear();
        // Three more, so that every pixel starts four lanes.
        depth.resize(rows * w + 3, 1.0);
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
            let object = self.jobs[(id >> PART_BITS) as usize].0;
            // An occluder's splat: its own view; it writes the depth alone.
            let (v, own) = (&views[object], object == model);
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
                    let zp4 = hits.x[2] + Vec4::splat(s.push) / len;
                    // The depth test in four lanes: they are four pixels, so
                    // each lane's test and write is the scalar one's.
                    let i0 = row + x;
                    let dd = v.depth_of4(zp4);
                    let old = Vec4::from_slice(&depth[i0..i0 + 4]);
                    let lanes =
                        BVec4A::new(mask & 1 != 0, mask & 2 != 0, mask & 4 != 0, mask & 8 != 0);
                    let closer = dd.cmplt(old) & lanes;
                    Vec4::select(closer, dd, old).write_to_slice(&mut depth[i0..i0 + 4]);
                    if !own {
                        continue;
                    }
                    if let Some(z) = band.z.as_deref_mut() {
                        let zp = zp4.to_array();
                        let mut c = closer.bitmask();
                        while c != 0 {
                            let k = c.trailing_zeros() as usize;
                            c &= c - 1;
                            z[i0 + k] = zp[k];
                        }
                    }
                    if !keep {
                        continue;
                    }
                    let dz = v.depth_of4(hits.x[2]).to_array();
                    let [hx, hy, hz] = hits.x.map(|c| c.to_array());
                    let rho2 = hits.rho2.to_array();
                    while mask != 0 {
                        let k = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        frags.push(Frag {
                            pixel: (i0 + k) as u32,
                            splat: id,
                            x: Vec3::new(hx[k], hy[k], hz[k]),
                            rho2: rho2[k],
                            dz: dz[k],
                        });
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
            if f.dz > depth[i] {
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

/// Whether a thinned render keeps splat `i`: about one in `step`, by a
/// hash of the index (splitmix64's finaliser).
fn kept(i: usize, step: usize) -> bool {
    let mut z = (i as u64).wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    (z ^ (z >> 31)).is_multiple_of(step as u64)
}

/// `work` on each of `items` (with its index), one item a task of `pool`,
/// or all on the calling thread without one; returns when all are done.
fn on_each<T: Send>(
    pool: Option<&rayon::ThreadPool>,
    items: &mut [T],
    work: &(impl Fn(usize, &mut T) + Sync),
) {
    match pool {
        Some(pool) if items.len() > 1 => pool.scope(|scope| {
            for (i, item) in items.iter_mut().enumerate() {
                scope.spawn(move |_| work(i, item));
            }
        }),
        _ => {
            for (i, item) in items.iter_mut().enumerate() {
                work(i, item);
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
