//! The host splatter's accumulation targets and what is read from them:
//! the normalisation (`resolve` of shaders/splat_resolve.wgsl) and the
//! gather of predictors at points (`gather`).

use super::{Attribute, Attributes, GATHER_STRIDE, GatherMode, GatherSample, SplatImage};

/// The five accumulation targets of one render (layout in the module docs
/// of [`super`]).
///
/// A target of an attribute group the render left out is empty (no
/// pixels), and what is read from it is empty (NaN) too:
/// [`Accumulators::attributes`] says which groups are there.
#[derive(Debug, Clone, Default)]
pub struct Accumulators {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The five targets T0..T4, each row-major RGBA (weighted sums, not
    /// normalised): `width * height` pixels each, or none for a group not
    /// rendered (T1: geometry, T2..T4: motion).
    pub targets: [Vec<[f32; 4]>; 5],
}

impl Accumulators {
    fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Whether target `k` holds every pixel.
    fn has(&self, k: usize) -> bool {
        self.targets[k].len() == self.pixels()
    }

    /// The attribute groups these targets hold (colour and weight always).
    pub fn attributes(&self) -> Attributes {
        Attributes {
            geometry: self.has(1),
            motion: (2..5).all(|k| self.has(k)),
        }
    }

    /// The normalisation pass (`resolve` in shaders/splat_resolve.wgsl).
    /// An attribute whose group was not rendered is NaN everywhere.
    pub fn resolve(&self, attribute: Attribute) -> SplatImage {
        let n = self.pixels();
        let ch = attribute.channels();
        let present = self.has(0) && self.attributes().contains(attribute.needs());
        if !present {
            return SplatImage {
                width: self.width,
                height: self.height,
                channels: ch,
                data: vec![f32::NAN; n * ch],
            };
        }
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
    /// translation predictor du/dtx at every pixel, NaN where empty (and
    /// everywhere when the predictors were not rendered).
    pub fn depth_from_motion(&self, fx: f32) -> SplatImage {
        let motion = self.has(0) && self.has(2);
        let data = (0..self.pixels())
            .map(|i| {
                let w = if motion { self.targets[0][i][3] } else { 0.0 };
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

    /// The gather kernel (`gather` in shaders/splat_resolve.wgsl) on these
    /// targets: the normalised predictors at `points` (pixels of this
    /// render) and the depth they give, `fx / (du/dtx)`, without resolving
    /// the whole image. The same values as [`super::cpu::sample_at`] on
    /// [`Self::resolve`]`(Attribute::Motion)`; invalid everywhere when the
    /// predictors were not rendered.
    pub fn gather(&self, fx: f32, points: &[[f32; 2]], mode: GatherMode) -> Vec<GatherSample> {
        let motion = self.has(0) && self.attributes().motion;
        let w = self.width as usize;
        let load = |x: i64, y: i64| -> Option<[f32; 12]> {
            let i = y as usize * w + x as usize;
            let wt = self.targets[0][i][3];
            if !motion || wt <= 0.0 {
                return None;
            }
            let mut v = [0.0; 12];
            for k in 0..3 {
                for (j, &a) in self.targets[2 + k][i].iter().enumerate() {
                    v[4 * k + j] = a / wt;
                }
            }
            Some(v)
        };
        gather_with(self.width, self.height, load, fx, points, mode)
    }
}

/// The gather rule on any image of predictors: `load(x, y)` gives a pixel
/// inside the image's normalised predictors, `None` where it is empty.
pub(super) fn gather_with(
    width: u32,
    height: u32,
    load: impl Fn(i64, i64) -> Option<[f32; 12]>,
    fx: f32,
    points: &[[f32; 2]],
    mode: GatherMode,
) -> Vec<GatherSample> {
    let (w, h) = (width as i64, height as i64);
    let inside = |x: i64, y: i64| x >= 0 && y >= 0 && x < w && y < h;
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
