//! CPU reference splatter: the maths of shaders/splat.wgsl and
//! shaders/splat_resolve.wgsl, line by line, in `f32` from the same
//! [`CameraUniform`], so that tests can compare the GPU with it pixel by
//! pixel. Slow (one thread); meant for tests and for the CPU/GPU ratio.

use super::gpu_data::{CameraUniform, SplatGpu, unpack_color};
use super::{
    Attribute, GATHER_STRIDE, GatherMode, GatherSample, ModelBounds, PackedModel, SplatError,
    SplatImage, SplatParams, pack_model,
};
use crate::geometry::{Intrinsics, Pose};
use crate::model::PointModel;
use glam::{Vec2, Vec3};

/// The five accumulation targets of one render (layout in the module docs
/// of [`super`]), all attribute groups included.
#[derive(Debug, Clone)]
pub struct Accumulators {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The five targets T0..T4, each row-major RGBA (weighted sums, not
    /// normalised).
    pub targets: [Vec<[f32; 4]>; 5],
}

struct View {
    rot: [Vec3; 3],
    trans: Vec3,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    w: f32,
    h: f32,
    near: f32,
    far: f32,
    eps: f32,
    lowpass: f32,
}

impl View {
    fn new(u: &CameraUniform) -> Self {
        let v3 = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
        Self {
            rot: [v3(u.rot[0]), v3(u.rot[1]), v3(u.rot[2])],
            trans: v3(u.trans),
            fx: u.intr[0],
            fy: u.intr[1],
            cx: u.intr[2],
            cy: u.intr[3],
            w: u.size[0],
            h: u.size[1],
            near: u.size[2],
            far: u.size[3],
            eps: u.params[0],
            lowpass: u.params[1],
        }
    }

    fn apply(&self, p: Vec3) -> Vec3 {
        Vec3::new(self.rot[0].dot(p), self.rot[1].dot(p), self.rot[2].dot(p))
    }

    fn project(&self, x: Vec3) -> Vec2 {
        Vec2::new(self.fx * x.x / x.z + self.cx, self.fy * x.y / x.z + self.cy)
    }

    fn depth_of(&self, z: f32) -> f32 {
        ((z - self.near) / (self.far - self.near)).clamp(0.0, 1.0)
    }
}

/// A splat after the vertex stage: camera-space data and its pixel range.
struct Setup {
    c: Vec3,
    m: Vec3,
    r: f32,
    proj: Vec2,
    color: Vec3,
    lo: Vec2,
    hi: Vec2,
}

fn tangent(n: Vec3) -> Vec3 {
    let a = n.abs();
    let axis = if a.y <= a.x && a.y <= a.z {
        Vec3::Y
    } else if a.z <= a.x && a.z <= a.y {
        Vec3::Z
    } else {
        Vec3::X
    };
    n.cross(axis).normalize()
}

fn setup(v: &View, s: &SplatGpu, color: u32) -> Option<Setup> {
    let p = Vec3::new(s.pos_radius[0], s.pos_radius[1], s.pos_radius[2]);
    let r = s.pos_radius[3];
    let c = v.apply(p) + v.trans;
    let m = v
        .apply(Vec3::new(s.normal[0], s.normal[1], s.normal[2]))
        .normalize();
    // Same culling as vs_splat (a NaN radius is culled too).
    if c.z <= v.near || m.dot(c) >= 0.0 || r.is_nan() || r <= 0.0 {
        return None;
    }
    let pc = v.project(c);
    let hh = Vec2::splat(v.lowpass);
    let (mut lo, mut hi) = (pc - hh, pc + hh);
    let t = tangent(m);
    let tu = t * r;
    let tv = m.cross(t) * r;
    let k = [c + tu + tv, c + tu - tv, c - tu + tv, c - tu - tv];
    let size = Vec2::new(v.w, v.h);
    if k.iter().any(|k| k.z <= v.near) {
        lo = Vec2::splat(-1.0);
        hi = size;
    } else {
        for k in k {
            let q = v.project(k);
            lo = lo.min(q);
            hi = hi.max(q);
        }
    }
    lo = (lo - 0.5).clamp(Vec2::splat(-1.0), size);
    hi = (hi + 0.5).clamp(Vec2::splat(-1.0), size);
    Some(Setup {
        c,
        m,
        r,
        proj: pc,
        color: Vec3::from(unpack_color(color)),
        lo,
        hi,
    })
}

/// `intersect` of shaders/splat.wgsl: (X, w, |d|), or None outside the
/// support. `uv` is the pixel centre in OpenCV coordinates.
fn intersect(v: &View, s: &Setup, uv: Vec2) -> Option<(Vec3, f32, f32)> {
    let d = Vec3::new((uv.x - v.cx) / v.fx, (uv.y - v.cy) / v.fy, 1.0);
    let ray_len = d.length();
    let denom = s.m.dot(d);
    let mut rho_obj2 = 1e30f32;
    let mut x = d * s.c.z;
    if denom.abs() > 1e-12 {
        let t = s.m.dot(s.c) / denom;
        if t > v.near {
            let xi = d * t;
            let q = xi - s.c;
            rho_obj2 = q.dot(q) / (s.r * s.r);
            let reach = s.r + 3.0 * v.lowpass * s.c.z / v.fx.min(v.fy);
            if rho_obj2 <= 1.0 || q.dot(q) <= reach * reach {
                x = xi;
            }
        }
    }
    let e = (uv - s.proj) / v.lowpass;
    let rho2 = rho_obj2.min(e.dot(e));
    if rho2 > 1.0 || x.z <= v.near {
        return None;
    }
    Some((x, (-2.0 * rho2).exp(), ray_len))
}

/// Iterates over the pixels whose centres the GPU rasteriser would shade
/// for this splat's quad (centres inside `[lo, hi]`).
fn pixels(v: &View, s: &Setup) -> impl Iterator<Item = (u32, u32)> {
    let x0 = s.lo.x.ceil().max(0.0) as u32;
    let y0 = s.lo.y.ceil().max(0.0) as u32;
    let x1 = (s.hi.x.floor().min(v.w - 1.0)).max(-1.0) as i64;
    let y1 = (s.hi.y.floor().min(v.h - 1.0)).max(-1.0) as i64;
    (y0 as i64..=y1).flat_map(move |y| (x0 as i64..=x1).map(move |x| (x as u32, y as u32)))
}

/// `jac` of shaders/splat.wgsl: `J(X) v`.
fn jac(v: &View, x: Vec3, d: Vec3) -> [f32; 2] {
    let iz = 1.0 / x.z;
    [
        v.fx * iz * (d.x - x.x * iz * d.z),
        v.fy * iz * (d.y - x.y * iz * d.z),
    ]
}

fn motion(v: &View, x: Vec3) -> [f32; 12] {
    let g = [
        Vec3::X,
        Vec3::Y,
        Vec3::Z,
        Vec3::new(0.0, -x.z, x.y),
        Vec3::new(x.z, 0.0, -x.x),
        Vec3::new(-x.y, x.x, 0.0),
    ];
    let mut out = [0.0; 12];
    for (j, gj) in g.iter().enumerate() {
        let l = jac(v, x, *gj);
        out[2 * j] = l[0];
        out[2 * j + 1] = l[1];
    }
    out
}

/// The splats of `model` that reach the view, set up for rasterising.
fn setups(v: &View, model: &PackedModel) -> Vec<Setup> {
    model
        .splats
        .iter()
        .zip(&model.colors)
        .filter_map(|(s, &c)| setup(v, s, c))
        .collect()
}

/// Splats a packed model with a view uniform: passes 1 and 2.
pub fn splat_packed(model: &PackedModel, uniform: &CameraUniform) -> Accumulators {
    let v = View::new(uniform);
    let (w, h) = (v.w as usize, v.h as usize);
    let setups = setups(&v, model);
    let uv = |x: u32, y: u32| Vec2::new(x as f32, y as f32);
    let (depth, _) = visibility(&v, &setups);
    // Pass 2: attributes, depth test less-or-equal, no depth writes.
    let mut t: [Vec<[f32; 4]>; 5] = std::array::from_fn(|_| vec![[0.0; 4]; w * h]);
    for s in &setups {
        for (x, y) in pixels(&v, s) {
            let Some((xx, wt, _)) = intersect(&v, s, uv(x, y)) else {
                continue;
            };
            let i = y as usize * w + x as usize;
            if v.depth_of(xx.z) > depth[i] {
                continue;
            }
            let l = motion(&v, xx);
            let add = |acc: &mut [f32; 4], a: [f32; 4]| {
                for k in 0..4 {
                    acc[k] += a[k] * wt;
                }
            };
            add(&mut t[0][i], [s.color.x, s.color.y, s.color.z, 1.0]);
            add(&mut t[1][i], [xx.z, s.m.x, s.m.y, s.m.z]);
            add(&mut t[2][i], [l[0], l[1], l[2], l[3]]);
            add(&mut t[3][i], [l[4], l[5], l[6], l[7]]);
            add(&mut t[4][i], [l[8], l[9], l[10], l[11]]);
        }
    }
    Accumulators {
        width: w as u32,
        height: h as u32,
        targets: t,
    }
}

/// Pass 1 (visibility): per pixel, the nearest depth ([0, 1], 1 where
/// empty) pushed back by epsilon along the ray, and the camera-space z it
/// stands for (the pushed-back z of the first splat to reach it, in the
/// order the rasteriser draws them; NaN where empty).
fn visibility(v: &View, setups: &[Setup]) -> (Vec<f32>, Vec<f32>) {
    let (w, h) = (v.w as usize, v.h as usize);
    let uv = |x: u32, y: u32| Vec2::new(x as f32, y as f32);
    let mut depth = vec![1.0f32; w * h];
    let mut z = vec![f32::NAN; w * h];
    for s in setups {
        for (x, y) in pixels(v, s) {
            if let Some((xx, _, len)) = intersect(v, s, uv(x, y)) {
                let zp = xx.z + v.eps * s.r / len;
                let dd = v.depth_of(zp);
                let i = y as usize * w + x as usize;
                if dd < depth[i] {
                    depth[i] = dd;
                    z[i] = zp;
                }
            }
        }
    }
    (depth, z)
}

/// The reference of [`super::Splatter::render_depth`] read as
/// [`Attribute::Depth`]: the visibility pass alone, one channel, the
/// pushed-back camera-space z of the nearest surface, NaN where no splat
/// covers the pixel.
pub fn visibility_depth(model: &PackedModel, uniform: &CameraUniform) -> SplatImage {
    let v = View::new(uniform);
    let setups = setups(&v, model);
    let (_, data) = visibility(&v, &setups);
    SplatImage {
        width: v.w as u32,
        height: v.h as u32,
        channels: 1,
        data,
    }
}

/// The CPU reference of a whole render: the same checks, bounds and
/// uniform as the GPU path.
pub fn splat(
    model: &PointModel,
    cam: &Intrinsics,
    pose: &Pose,
    params: &SplatParams,
) -> Result<Accumulators, SplatError> {
    let packed = pack_model(model, params)?;
    let uniform = ModelBounds::of(model).view(cam, pose, params)?;
    Ok(splat_packed(&packed, &uniform))
}

impl Accumulators {
    /// The normalisation pass (`resolve` in shaders/splat_resolve.wgsl).
    pub fn resolve(&self, attribute: Attribute) -> SplatImage {
        let n = self.width as usize * self.height as usize;
        let ch = attribute.channels();
        let mut data = Vec::with_capacity(n * ch);
        for i in 0..n {
            let a = self.targets[0][i];
            let w = a[3];
            let ok = w > 0.0;
            let div = |x: f32| if ok { x / w } else { f32::NAN };
            match attribute {
                Attribute::Color => data.extend(a[..3].iter().map(|&x| div(x))),
                Attribute::Depth => data.push(div(self.targets[1][i][0])),
                Attribute::Normal => {
                    let t = self.targets[1][i];
                    let len = (t[1] * t[1] + t[2] * t[2] + t[3] * t[3]).sqrt();
                    data.extend(
                        t[1..]
                            .iter()
                            .map(|&x| if ok && len > 0.0 { x / len } else { f32::NAN }),
                    );
                }
                Attribute::Motion => {
                    for k in 2..5 {
                        data.extend(self.targets[k][i].iter().map(|&x| div(x)));
                    }
                }
                Attribute::Weight => data.push(w),
            }
        }
        SplatImage {
            width: self.width,
            height: self.height,
            channels: ch,
            data,
        }
    }

    /// [`Attribute::Depth`] of a render with the predictors and without
    /// the geometry (`RESOLVE_DEPTH_MOTION`): `fx` over the normalised
    /// translation predictor du/dtx at every pixel, NaN where empty.
    pub fn depth_from_motion(&self, fx: f32) -> SplatImage {
        let data = (0..self.width as usize * self.height as usize)
            .map(|i| {
                let w = self.targets[0][i][3];
                if w > 0.0 {
                    fx / (self.targets[2][i][0] / w)
                } else {
                    f32::NAN
                }
            })
            .collect();
        SplatImage {
            width: self.width,
            height: self.height,
            channels: 1,
            data,
        }
    }
}

/// The gather kernel on a full image of predictors (12 channels): the
/// predictors sampled at `points` with the same rule as the GPU (`gather`
/// in shaders/splat_resolve.wgsl), and the depth they give, `fx / (du/dtx)`
/// (`fx`: the render's focal length in x, pixels).
pub fn sample_at(
    motion: &SplatImage,
    fx: f32,
    points: &[[f32; 2]],
    mode: GatherMode,
) -> Vec<GatherSample> {
    let (w, h) = (motion.width as i64, motion.height as i64);
    let inside = |x: i64, y: i64| x >= 0 && y >= 0 && x < w && y < h;
    let load = |x: i64, y: i64| -> Option<[f32; 12]> {
        if !motion.is_valid(x as u32, y as u32) {
            return None;
        }
        let mut v = [0.0; 12];
        v.copy_from_slice(motion.pixel(x as u32, y as u32));
        Some(v)
    };
    points
        .iter()
        .map(|&[x, y]| {
            let mut out: Option<[f32; 12]> = None;
            if mode == GatherMode::Bilinear && x.is_finite() && y.is_finite() {
                let (fx, fy) = (x.floor(), y.floor());
                let (x0, y0) = (fx as i64, fy as i64);
                let (tx, ty) = (x - fx, y - fy);
                if inside(x0, y0) && inside(x0 + 1, y0 + 1) {
                    if let (Some(a), Some(b), Some(c), Some(d)) = (
                        load(x0, y0),
                        load(x0 + 1, y0),
                        load(x0, y0 + 1),
                        load(x0 + 1, y0 + 1),
                    ) {
                        let k = [
                            (1.0 - tx) * (1.0 - ty),
                            tx * (1.0 - ty),
                            (1.0 - tx) * ty,
                            tx * ty,
                        ];
                        out = Some(std::array::from_fn(|i| {
                            k[0] * a[i] + k[1] * b[i] + k[2] * c[i] + k[3] * d[i]
                        }));
                    }
                }
            }
            if out.is_none() && x.is_finite() && y.is_finite() {
                let (px, py) = ((x + 0.5).floor() as i64, (y + 0.5).floor() as i64);
                if inside(px, py) {
                    out = load(px, py);
                }
            }
            let mut v = [f32::NAN; GATHER_STRIDE];
            v[13] = 0.0;
            if let Some(o) = out {
                v[..12].copy_from_slice(&o);
                v[12] = fx / o[0];
                v[13] = 1.0;
            }
            GatherSample::from_floats(&v)
        })
        .collect()
}
