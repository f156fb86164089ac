//! The splatting maths on the host: shaders/splat_common.wgsl and the
//! fragment stages of shaders/splat.wgsl, line by line, in `f32` from the
//! same [`CameraUniform`]. The host splatter ([`super::cpu`]) runs these
//! per splat and per pixel; change them together with the shaders.
//!
//! Per-splat terms that the shaders recompute at every fragment (`m . c`,
//! `r * r`, the low-pass reach) are computed once here, with the same
//! operations in the same order, so every value keeps its bits.

use super::gpu_data::{CameraUniform, SplatGpu};
use glam::{Vec2, Vec3, Vec4};

/// The camera of a render, unpacked from its uniform.
#[derive(Debug, Clone)]
pub(super) struct View {
    rot: [Vec3; 3],
    trans: Vec3,
    pub(super) fx: f32,
    pub(super) fy: f32,
    pub(super) cx: f32,
    pub(super) cy: f32,
    /// Width and height in pixels (0 when the uniform's are not positive).
    pub(super) width: usize,
    pub(super) height: usize,
    w: f32,
    h: f32,
    near: f32,
    /// The depth buffer's range (`CameraUniform::depth_range`).
    depth_near: f32,
    depth_far: f32,
    eps: f32,
    lowpass: f32,
}

impl View {
    pub(super) fn new(u: &CameraUniform) -> Self {
        let v3 = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
        Self {
            rot: [v3(u.rot[0]), v3(u.rot[1]), v3(u.rot[2])],
            trans: v3(u.trans),
            fx: u.intr[0],
            fy: u.intr[1],
            cx: u.intr[2],
            cy: u.intr[3],
            // `as` saturates: NaN and negative sizes give empty images.
            width: u.size[0] as usize,
            height: u.size[1] as usize,
            w: u.size[0],
            h: u.size[1],
            near: u.size[2],
            depth_near: u.params[2],
            depth_far: u.params[3],
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

    /// `depth_of`: camera-space z to `[0, 1]`, linear over the depth
    /// buffer's range.
    #[cfg(test)]
    fn depth_of(&self, z: f32) -> f32 {
        ((z - self.depth_near) / (self.depth_far - self.depth_near)).clamp(0.0, 1.0)
    }

    /// [`Self::depth_of`] in four lanes, each with the scalar's
    /// operations; where a lane is NaN the two differ, and the callers
    /// read only lanes that hit, whose z is past the near plane.
    #[inline(always)]
    pub(super) fn depth_of4(&self, z: Vec4) -> Vec4 {
        ((z - Vec4::splat(self.depth_near)) / Vec4::splat(self.depth_far - self.depth_near))
            .clamp(Vec4::ZERO, Vec4::ONE)
    }

    /// The depth buffer's range: the camera-space z at depth 0 and 1.
    pub(super) fn depth_range(&self) -> (f32, f32) {
        (self.depth_near, self.depth_far)
    }

    /// The x component of the ray through pixel column `x` (the y
    /// component of row `y` is [`Self::ray_y`]; z is 1).
    pub(super) fn ray_x(&self, x: usize) -> f32 {
        (x as f32 - self.cx) / self.fx
    }

    pub(super) fn ray_y(&self, y: usize) -> f32 {
        (y as f32 - self.cy) / self.fy
    }
}

/// A splat after the vertex stage (`view_splat`): camera-space data, the
/// per-splat terms of the intersection, and the pixels its quad covers
/// (columns `x0..=x1`, rows `y0..=y1`, never empty).
#[derive(Debug, Clone, Copy)]
pub(super) struct Setup {
    c: Vec3,
    pub(super) m: Vec3,
    proj: Vec2,
    /// The colour as packed (unpacked where it is blended).
    pub(super) color: u32,
    /// `m . c`.
    mc: f32,
    /// `r * r`.
    r2: f32,
    /// The square of the low-pass reach, `r + 3 h z_c / min(fx, fy)`.
    reach2: f32,
    /// The push-back along the ray, `epsilon * r`.
    pub(super) push: f32,
    pub(super) x0: u32,
    pub(super) x1: u32,
    pub(super) y0: u32,
    pub(super) y1: u32,
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

/// `view_splat`: `None` for a culled splat (behind the near plane,
/// back-facing, no radius) and for one whose quad covers no pixel centre
/// of the image (which the rasteriser would not shade either).
pub(super) fn setup(v: &View, s: &SplatGpu, color: u32) -> Option<Setup> {
    let p = Vec3::new(s.pos_radius[0], s.pos_radius[1], s.pos_radius[2]);
    let r = s.pos_radius[3];
    let c = v.apply(p) + v.trans;
    let m = v
        .apply(Vec3::new(s.normal[0], s.normal[1], s.normal[2]))
        .normalize();
    // Same culling as view_splat (a NaN radius is culled too).
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
        // The four corners' projections at once (the same operations in
        // each lane); their order does not change a min or a max.
        let kz = Vec4::new(k[0].z, k[1].z, k[2].z, k[3].z);
        let u =
            Vec4::splat(v.fx) * Vec4::new(k[0].x, k[1].x, k[2].x, k[3].x) / kz + Vec4::splat(v.cx);
        let w =
            Vec4::splat(v.fy) * Vec4::new(k[0].y, k[1].y, k[2].y, k[3].y) / kz + Vec4::splat(v.cy);
        lo = lo.min(Vec2::new(u.min_element(), w.min_element()));
        hi = hi.max(Vec2::new(u.max_element(), w.max_element()));
    }
    lo = (lo - 0.5).clamp(Vec2::splat(-1.0), size);
    hi = (hi + 0.5).clamp(Vec2::splat(-1.0), size);
    // The pixel centres inside [lo, hi] (what the rasteriser shades).
    let x0 = lo.x.ceil().max(0.0);
    let y0 = lo.y.ceil().max(0.0);
    let x1 = hi.x.floor().min(v.w - 1.0);
    let y1 = hi.y.floor().min(v.h - 1.0);
    if !(x0 <= x1 && y0 <= y1) {
        return None;
    }
    let reach = r + 3.0 * v.lowpass * c.z / v.fx.min(v.fy);
    Some(Setup {
        c,
        m,
        proj: pc,
        color,
        mc: m.dot(c),
        r2: r * r,
        reach2: reach * reach,
        push: v.eps * r,
        x0: x0 as u32,
        x1: x1 as u32,
        y0: y0 as u32,
        y1: y1 as u32,
    })
}

/// Three coordinates of four splats, one lane a splat.
#[derive(Clone, Copy)]
struct V3x4 {
    x: Vec4,
    y: Vec4,
    z: Vec4,
}

impl V3x4 {
    fn splat(v: Vec3) -> Self {
        Self {
            x: Vec4::splat(v.x),
            y: Vec4::splat(v.y),
            z: Vec4::splat(v.z),
        }
    }

    /// `Vec3::dot`'s operations: `(x x' + y y') + z z'`.
    fn dot(self, o: Self) -> Vec4 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// `Vec3::cross`'s operations.
    fn cross(self, o: Self) -> Self {
        Self {
            x: self.y * o.z - o.y * self.z,
            y: self.z * o.x - o.z * self.x,
            z: self.x * o.y - o.x * self.y,
        }
    }

    /// `Vec3::normalize`'s operations: times `1 / sqrt(dot)`.
    fn normalize(self) -> Self {
        let recip = Vec4::ONE / self.dot(self).sqrt();
        self.scale(recip)
    }

    fn scale(self, k: Vec4) -> Self {
        Self {
            x: self.x * k,
            y: self.y * k,
            z: self.z * k,
        }
    }

    fn add(self, o: Self) -> Self {
        Self {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }

    fn sub(self, o: Self) -> Self {
        Self {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }

    fn lane(&self, k: usize) -> Vec3 {
        Vec3::new(self.x[k], self.y[k], self.z[k])
    }
}

impl View {
    /// [`View::apply`] in four lanes.
    fn apply4(&self, p: V3x4) -> V3x4 {
        V3x4 {
            x: V3x4::splat(self.rot[0]).dot(p),
            y: V3x4::splat(self.rot[1]).dot(p),
            z: V3x4::splat(self.rot[2]).dot(p),
        }
    }
}

/// [`setup`] of four splats at once, one a lane, each lane with the
/// scalar's operations in its order (the same bits; `tests/splat_host.rs`
/// compares the renders with the shader's transcription): the visible
/// ones pushed onto `out` in their order. One splat at a time, the set-up
/// was about a sixth of a render's time (perf, the real cube); here each
/// of its divisions and square roots is one instruction for four splats.
pub(super) fn setup4(v: &View, s: &[SplatGpu], colors: &[u32], out: &mut Vec<Setup>) {
    let sp = Vec4::splat;
    let pr = glam::Mat4::from_cols_array_2d(&[
        s[0].pos_radius,
        s[1].pos_radius,
        s[2].pos_radius,
        s[3].pos_radius,
    ])
    .transpose();
    let nn = glam::Mat4::from_cols_array_2d(&[s[0].normal, s[1].normal, s[2].normal, s[3].normal])
        .transpose();
    let p = V3x4 {
        x: pr.x_axis,
        y: pr.y_axis,
        z: pr.z_axis,
    };
    let r = pr.w_axis;
    let c = v.apply4(p).add(V3x4::splat(v.trans));
    let m = v
        .apply4(V3x4 {
            x: nn.x_axis,
            y: nn.y_axis,
            z: nn.z_axis,
        })
        .normalize();
    let mc = m.dot(c);
    let culled =
        c.z.cmple(sp(v.near)) | mc.cmpge(Vec4::ZERO) | r.is_nan_mask() | r.cmple(Vec4::ZERO);
    if culled.all() {
        return;
    }
    let pc = [
        sp(v.fx) * c.x / c.z + sp(v.cx),
        sp(v.fy) * c.y / c.z + sp(v.cy),
    ];
    let hh = sp(v.lowpass);
    // tangent(m): the axis m leans least towards, crossed with m.
    let a = V3x4 {
        x: m.x.abs(),
        y: m.y.abs(),
        z: m.z.abs(),
    };
    let on_y = a.y.cmple(a.x) & a.y.cmple(a.z);
    let on_z = !on_y & a.z.cmple(a.x) & a.z.cmple(a.y);
    let one_if = |b| Vec4::select(b, Vec4::ONE, Vec4::ZERO);
    let axis = V3x4 {
        x: one_if(!on_y & !on_z),
        y: one_if(on_y),
        z: one_if(on_z),
    };
    let t = m.cross(axis).normalize();
    let tu = t.scale(r);
    let tv = m.cross(t).scale(r);
    let k = [
        c.add(tu).add(tv),
        c.add(tu).sub(tv),
        c.sub(tu).add(tv),
        c.sub(tu).sub(tv),
    ];
    let near = sp(v.near);
    let behind = k[0].z.cmple(near) | k[1].z.cmple(near) | k[2].z.cmple(near) | k[3].z.cmple(near);
    let proj = |k: &V3x4| {
        [
            sp(v.fx) * k.x / k.z + sp(v.cx),
            sp(v.fy) * k.y / k.z + sp(v.cy),
        ]
    };
    let q = [proj(&k[0]), proj(&k[1]), proj(&k[2]), proj(&k[3])];
    let size = [sp(v.w), sp(v.h)];
    let mut bounds = [[Vec4::ZERO; 2]; 2];
    for d in 0..2 {
        // Vec4::min_element's and max_element's order over the corners.
        let lo_k = q[0][d].min(q[2][d]).min(q[1][d].min(q[3][d]));
        let hi_k = q[0][d].max(q[2][d]).max(q[1][d].max(q[3][d]));
        let lo = Vec4::select(behind, sp(-1.0), (pc[d] - hh).min(lo_k));
        let hi = Vec4::select(behind, size[d], (pc[d] + hh).max(hi_k));
        // Vec2::clamp's operations: max, then min.
        bounds[0][d] = (lo - sp(0.5)).max(sp(-1.0)).min(size[d]);
        bounds[1][d] = (hi + sp(0.5)).max(sp(-1.0)).min(size[d]);
    }
    let x0 = bounds[0][0].ceil().max(Vec4::ZERO);
    let y0 = bounds[0][1].ceil().max(Vec4::ZERO);
    let x1 = bounds[1][0].floor().min(sp(v.w - 1.0));
    let y1 = bounds[1][1].floor().min(sp(v.h - 1.0));
    let shown = !culled & x0.cmple(x1) & y0.cmple(y1);
    let reach = r + sp(3.0 * v.lowpass) * c.z / sp(v.fx.min(v.fy));
    for l in 0..4 {
        if !shown.test(l) {
            continue;
        }
        let rl = r[l];
        out.push(Setup {
            c: c.lane(l),
            m: m.lane(l),
            proj: Vec2::new(pc[0][l], pc[1][l]),
            color: colors[l],
            mc: mc[l],
            r2: rl * rl,
            reach2: reach[l] * reach[l],
            push: v.eps * rl,
            x0: x0[l] as u32,
            x1: x1[l] as u32,
            y0: y0[l] as u32,
            y1: y1[l] as u32,
        });
    }
}

/// `ray_hit` at one pixel, as [`intersect4`] makes it in each lane: the
/// camera-space point `X` seen through the pixel centre
/// `uv` (OpenCV coordinates; `d` its ray, `(ray_x, ray_y, 1)`) and
/// `rho^2`, or `None` outside the splat's support. The weight is
/// [`weight`]`(rho^2)`.
#[cfg(test)]
fn intersect(v: &View, s: &Setup, uv: Vec2, d: Vec3) -> Option<(Vec3, f32)> {
    let denom = s.m.dot(d);
    let mut rho_obj2 = 1e30f32;
    let mut x = d * s.c.z;
    if denom.abs() > 1e-12 {
        let t = s.mc / denom;
        if t > v.near {
            let xi = d * t;
            let q = xi - s.c;
            let qq = q.dot(q);
            rho_obj2 = qq / s.r2;
            if rho_obj2 <= 1.0 || qq <= s.reach2 {
                x = xi;
            }
        }
    }
    let e = (uv - s.proj) / v.lowpass;
    let rho2 = rho_obj2.min(e.dot(e));
    if rho2 > 1.0 || x.z <= v.near {
        return None;
    }
    Some((x, rho2))
}

/// [`intersect`] at four consecutive pixel centres of a row: `u` their
/// columns, `dx` their rays' x, `dy` and `y` the row's. Each lane makes
/// the scalar version's operations in its order (no fused multiply-add,
/// `f32::min`'s NaN rule), so it gives the same bits.
pub(super) struct Hits4 {
    /// Bit `k` set: lane `k` hits.
    pub(super) mask: u32,
    /// The points `X`, by coordinate.
    pub(super) x: [Vec4; 3],
    pub(super) rho2: Vec4,
}

#[inline(always)]
pub(super) fn intersect4(v: &View, s: &Setup, u: Vec4, dx: Vec4, dy: f32, y: f32) -> Hits4 {
    let sp = Vec4::splat;
    // m . d, as (m.x dx + m.y dy) + m.z 1.
    let denom = sp(s.m.x) * dx + sp(s.m.y * dy) + sp(s.m.z);
    let t = sp(s.mc) / denom;
    let on_plane = denom.abs().cmpgt(sp(1e-12)) & t.cmpgt(sp(v.near));
    // xi = d t = (dx t, dy t, t).
    let q = [dx * t - sp(s.c.x), sp(dy) * t - sp(s.c.y), t - sp(s.c.z)];
    let qq = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
    let rho_obj2 = Vec4::select(on_plane, qq / sp(s.r2), sp(1e30));
    let use_xi = on_plane & (rho_obj2.cmple(sp(1.0)) | qq.cmple(sp(s.reach2)));
    let x = [
        Vec4::select(use_xi, dx * t, dx * sp(s.c.z)),
        Vec4::select(use_xi, sp(dy) * t, sp(dy * s.c.z)),
        Vec4::select(use_xi, t, sp(s.c.z)),
    ];
    let ex = (u - sp(s.proj.x)) / sp(v.lowpass);
    let ey = (y - s.proj.y) / v.lowpass;
    let ee = ex * ex + sp(ey * ey);
    let m = rho_obj2.min(ee);
    let rho2 = Vec4::select(
        rho_obj2.is_nan_mask(),
        ee,
        Vec4::select(ee.is_nan_mask(), rho_obj2, m),
    );
    let miss = rho2.cmpgt(sp(1.0)) | x[2].cmple(sp(v.near));
    Hits4 {
        mask: !miss.bitmask() & 0xf,
        x,
        rho2,
    }
}

/// The Gaussian kernel's weight at `rho^2`.
#[inline(always)]
pub(super) fn weight(rho2: f32) -> f32 {
    (-2.0 * rho2).exp()
}

/// `jac` of shaders/splat.wgsl: `J(X) v`.
#[inline(always)]
fn jac(v: &View, x: Vec3, d: Vec3) -> [f32; 2] {
    let iz = 1.0 / x.z;
    [
        v.fx * iz * (d.x - x.x * iz * d.z),
        v.fy * iz * (d.y - x.y * iz * d.z),
    ]
}

/// `motion` of shaders/splat.wgsl: the 12 predictors at `x`.
#[inline(always)]
pub(super) fn motion(v: &View, x: Vec3) -> [f32; 12] {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Intrinsics;
    use crate::rng::Rng;
    use crate::splat::gpu_data::pack_color;
    use nalgebra::Vector3;

    /// A set-up's values as bits, to compare two bit for bit.
    fn bits(s: &Setup) -> Vec<u32> {
        [s.c, s.m]
            .iter()
            .flat_map(|v| v.to_array())
            .chain(s.proj.to_array())
            .chain([s.mc, s.r2, s.reach2, s.push])
            .map(f32::to_bits)
            .chain([s.color, s.x0, s.x1, s.y0, s.y1])
            .collect()
    }

    #[test]
    fn four_splats_in_lanes_are_set_up_as_one_at_a_time() {
        let mut rng = Rng::new(21);
        let (mut kept, mut culled) = (0, 0);
        for _ in 0..400 {
            let cam = Intrinsics::new(96, 72, 80.0, 84.0, 47.3, 35.8);
            let eye = rng.unit_vector() * rng.uniform(0.3, 3.0);
            let pose = crate::geometry::look_at(&eye, &Vector3::zeros(), &rng.unit_vector());
            let u = CameraUniform::new(&cam, &pose, 0.05, 5.0, 0.4, 0.75);
            let v = View::new(&u);
            // Splats behind the camera, across the near plane, off the
            // image, back-facing, with zero, negative and NaN radii.
            let splats: Vec<SplatGpu> = (0..16)
                .map(|i| {
                    let p = rng.unit_vector() * rng.uniform(0.0, 1.5);
                    let n = rng.unit_vector();
                    let r = match i % 8 {
                        0 => 0.0,
                        1 => -0.1,
                        2 => f32::NAN,
                        3 => rng.uniform(0.3, 1.0) as f32,
                        _ => rng.uniform(0.001, 0.2) as f32,
                    };
                    SplatGpu {
                        pos_radius: [p.x as f32, p.y as f32, p.z as f32, r],
                        normal: [n.x as f32, n.y as f32, n.z as f32, 0.0],
                    }
                })
                .collect();
            let colors: Vec<u32> = (0..16).map(|i| pack_color([i as f32 / 16.0; 3])).collect();
            let one: Vec<Setup> = splats
                .iter()
                .zip(&colors)
                .filter_map(|(s, &c)| setup(&v, s, c))
                .collect();
            let mut four = Vec::new();
            for (s, c) in splats.chunks(4).zip(colors.chunks(4)) {
                setup4(&v, s, c, &mut four);
            }
            assert_eq!(one.len(), four.len());
            for (a, b) in one.iter().zip(&four) {
                assert_eq!(bits(a), bits(b));
            }
            kept += one.len();
            culled += 16 - one.len();
        }
        assert!(kept > 1000 && culled > 1000, "{kept} kept, {culled} culled");
    }

    #[test]
    fn four_lanes_give_the_scalar_intersection_s_bits() {
        let mut rng = Rng::new(9);
        let mut hits = 0;
        for _ in 0..3000 {
            let cam = Intrinsics::new(96, 72, 80.0, 84.0, 47.3, 35.8);
            let eye = rng.unit_vector() * rng.uniform(1.0, 3.0);
            let pose = crate::geometry::look_at(&eye, &Vector3::zeros(), &rng.unit_vector());
            let u = CameraUniform::new(&cam, &pose, 0.05, 5.0, 0.4, 0.75);
            let v = View::new(&u);
            let p = rng.unit_vector() * rng.uniform(0.0, 0.5);
            let n = rng.unit_vector();
            let r = rng.uniform(0.001, 0.3) as f32;
            let g = SplatGpu {
                pos_radius: [p.x as f32, p.y as f32, p.z as f32, r],
                normal: [n.x as f32, n.y as f32, n.z as f32, 0.0],
            };
            let Some(s) = setup(&v, &g, pack_color([0.5; 3])) else {
                continue;
            };
            for y in s.y0..=s.y1 {
                let (yy, dy) = (y as usize, v.ray_y(y as usize));
                for x in (s.x0..=s.x1).step_by(4) {
                    let xs: [usize; 4] = std::array::from_fn(|k| x as usize + k);
                    let dx = Vec4::from_array(xs.map(|x| v.ray_x(x)));
                    let u4 = Vec4::from_array(xs.map(|x| x as f32));
                    let four = intersect4(&v, &s, u4, dx, dy, yy as f32);
                    for (k, &xk) in xs.iter().enumerate() {
                        let uv = Vec2::new(xk as f32, yy as f32);
                        let d = Vec3::new(v.ray_x(xk), dy, 1.0);
                        let one = intersect(&v, &s, uv, d);
                        assert_eq!(four.mask >> k & 1 == 1, one.is_some());
                        if let Some((p, rho2)) = one {
                            hits += 1;
                            let lane = [four.x[0][k], four.x[1][k], four.x[2][k], four.rho2[k]];
                            let want = [p.x, p.y, p.z, rho2];
                            assert_eq!(lane.map(f32::to_bits), want.map(f32::to_bits));
                            let depth = v.depth_of4(four.x[2])[k];
                            assert_eq!(depth.to_bits(), v.depth_of(p.z).to_bits());
                        }
                    }
                }
            }
        }
        assert!(hits > 10_000, "{hits} hits");
    }
}
