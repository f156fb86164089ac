//! Where other objects hide an object, on the host: a coarse depth image
//! of each object (a thinned subset of its points drawn as discs,
//! [`DepthProxy`]) at its latest pose. The renders leave hidden pixels
//! out exactly (the splatter's occluders); this coarse image answers what
//! the renders cannot: how much of an object is hidden (a wholly hidden
//! object is lost, not searched for), and which of its outline's points
//! lie at the edge of an object in front (an edge that moves with that
//! object, not with this one: left out of the contour step).

use crate::geometry::{Intrinsics, Pose};
use crate::model::PointModel;
use nalgebra::{Vector2, Vector3};

/// At most this many points draw an object's depth image (a few tenths
/// of a millisecond a frame; the discs grow to close the gaps).
const PROXY_POINTS: usize = 4096;

/// A thinned point set of an object, with disc radii that close the
/// gaps the thinning opens.
pub(crate) struct DepthProxy {
    points: Vec<Vector3<f32>>,
    radii: Vec<f32>,
}

impl DepthProxy {
    /// Every `k`-th point of `model` (at most [`PROXY_POINTS`]), its
    /// radius grown by `sqrt(k)` (the same surface covered by `1/k` of
    /// the points).
    pub(crate) fn new(model: &PointModel) -> Self {
        let n = model.positions.len();
        let k = n.div_ceil(PROXY_POINTS).max(1);
        let grow = (k as f32).sqrt();
        let mut points = Vec::with_capacity(n / k + 1);
        let mut radii = Vec::with_capacity(n / k + 1);
        for i in (0..n).step_by(k) {
            let p = model.positions[i];
            points.push(Vector3::new(p.x, p.y, p.z));
            radii.push(model.radii[i] * grow);
        }
        Self { points, radii }
    }

    /// Draws the object at `pose` into `layer` (cleared first): each
    /// point a disc of its projected radius at its depth, the nearest
    /// kept.
    pub(crate) fn draw(&self, pose: &Pose, cam: &Intrinsics, layer: &mut DepthLayer) {
        layer.clear();
        let (w, h) = (layer.width as i64, layer.height as i64);
        let r = pose.rotation.cast::<f32>();
        let t = pose.translation.cast::<f32>();
        let (fx, fy) = (cam.fx as f32, cam.fy as f32);
        let (cx, cy) = (cam.cx as f32, cam.cy as f32);
        let (mut x0, mut y0, mut x1, mut y1) = (w, h, -1i64, -1i64);
        for (p, &radius) in self.points.iter().zip(&self.radii) {
            let q = r * p + t;
            if q.z <= 1e-6 {
                continue;
            }
            let u = fx * q.x / q.z + cx;
            let v = fy * q.y / q.z + cy;
            // At least one pixel, however far.
            let rp = (fx * radius / q.z).max(0.75);
            let (ua, ub) = ((u - rp).ceil() as i64, (u + rp).floor() as i64);
            let (va, vb) = ((v - rp).ceil() as i64, (v + rp).floor() as i64);
            if ub < 0 || vb < 0 || ua >= w || va >= h {
                continue;
            }
            let (ua, ub) = (ua.max(0), ub.min(w - 1));
            let (va, vb) = (va.max(0), vb.min(h - 1));
            let r2 = rp * rp;
            for y in va..=vb {
                let dy = y as f32 - v;
                let row = &mut layer.depth[(y * w) as usize..((y + 1) * w) as usize];
                for (x, d) in row
                    .iter_mut()
                    .enumerate()
                    .take(ub as usize + 1)
                    .skip(ua as usize)
                {
                    let dx = x as f32 - u;
                    if dx * dx + dy * dy <= r2 && q.z < *d {
                        *d = q.z;
                    }
                }
            }
            x0 = x0.min(ua);
            y0 = y0.min(va);
            x1 = x1.max(ub);
            y1 = y1.max(vb);
        }
        layer.rect = (x0 <= x1).then_some([x0 as usize, y0 as usize, x1 as usize, y1 as usize]);
    }
}

/// A whole-frame depth image: the nearest depth drawn at each pixel
/// (infinite where nothing was), and the rectangle drawn into.
#[derive(Clone)]
pub(crate) struct DepthLayer {
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) depth: Vec<f32>,
    /// `[x0, y0, x1, y1]`, inclusive; `None`: nothing drawn.
    pub(crate) rect: Option<[usize; 4]>,
}

impl DepthLayer {
    /// An empty layer of `width x height`.
    pub(crate) fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            depth: vec![f32::INFINITY; width * height],
            rect: None,
        }
    }

    fn clear(&mut self) {
        if let Some([x0, y0, x1, y1]) = self.rect.take() {
            for y in y0..=y1 {
                self.depth[y * self.width + x0..=y * self.width + x1].fill(f32::INFINITY);
            }
        }
    }

    /// The depth at pixel `(x, y)` (infinite outside the image).
    pub(crate) fn at(&self, x: i64, y: i64) -> f32 {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return f32::INFINITY;
        }
        self.depth[y as usize * self.width + x as usize]
    }

    /// The nearest of `layers` at each pixel, into `self` (sized alike).
    pub(crate) fn nearest_of<'a>(&mut self, layers: impl Iterator<Item = &'a DepthLayer>) {
        self.clear();
        let mut rect: Option<[usize; 4]> = None;
        for l in layers {
            let Some([x0, y0, x1, y1]) = l.rect else {
                continue;
            };
            for y in y0..=y1 {
                let at = y * self.width;
                for (d, &s) in self.depth[at + x0..=at + x1]
                    .iter_mut()
                    .zip(&l.depth[at + x0..=at + x1])
                {
                    *d = d.min(s);
                }
            }
            rect = Some(match rect {
                None => [x0, y0, x1, y1],
                Some(r) => [r[0].min(x0), r[1].min(y0), r[2].max(x1), r[3].max(y1)],
            });
        }
        self.rect = rect;
    }
}

/// What the other objects hide of one object: their nearest depth at
/// each pixel, at their latest poses.
pub(crate) struct Hidden {
    pub(crate) others: DepthLayer,
    /// Depths closer than `z * (1 - tolerance)` hide a point at `z` (the
    /// coarse images' error, and objects that touch).
    pub(crate) tolerance: f32,
}

impl Hidden {
    /// Whether a point at pixel position `p`, depth `z`, is hidden.
    pub(crate) fn hides(&self, p: Vector2<f64>, z: f32) -> bool {
        let d = self.others.at(p.x.round() as i64, p.y.round() as i64);
        d < z * (1.0 - self.tolerance)
    }

    /// Whether an outline point at `p` (depth `z`, outward normal `n`)
    /// has an object in front of it within `reach` pixels along its
    /// normal, either way: its edge in the image may be that object's.
    pub(crate) fn near_edge(&self, p: Vector2<f64>, n: Vector2<f64>, z: f32, reach: f64) -> bool {
        let steps = reach.ceil() as i64;
        (-steps..=steps).any(|k| self.hides(p + n * k as f64, z))
    }

    /// The fraction of `own`'s drawn pixels not hidden by the others
    /// (1 where nothing is drawn: nothing to hide).
    pub(crate) fn visible_fraction(&self, own: &DepthLayer) -> f64 {
        let Some([x0, y0, x1, y1]) = own.rect else {
            return 1.0;
        };
        let (mut drawn, mut seen) = (0usize, 0usize);
        for y in y0..=y1 {
            let at = y * own.width;
            for (&z, &o) in own.depth[at + x0..=at + x1]
                .iter()
                .zip(&self.others.depth[at + x0..=at + x1])
            {
                if z.is_finite() {
                    drawn += 1;
                    seen += usize::from(o >= z * (1.0 - self.tolerance));
                }
            }
        }
        if drawn == 0 {
            1.0
        } else {
            seen as f64 / drawn as f64
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Intrinsics;
    use glam::Vec3;

    /// A square of `n x n` points, side `side`, in the plane z = 0.
    fn square(n: usize, side: f32) -> PointModel {
        let mut pos = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let s = side / (n - 1) as f32;
                pos.push(Vec3::new(
                    i as f32 * s - side / 2.0,
                    j as f32 * s - side / 2.0,
                    0.0,
                ));
            }
        }
        let mut model =
            PointModel::from_points(pos, None, &crate::model::LoadOptions::default()).unwrap();
        let r = side / (n - 1) as f32 * 0.8;
        model.radii.fill(r);
        model
    }

    fn at(x: f64, z: f64) -> Pose {
        Pose::new(nalgebra::Matrix3::identity(), Vector3::new(x, 0.0, z)).unwrap()
    }

    #[test]
    fn a_near_square_hides_half_of_a_far_one() {
        let cam = Intrinsics::new(320, 240, 300.0, 300.0, 160.0, 120.0);
        // 10 000 points: thinned to a quarter, discs grown twice.
        let model = square(100, 0.2);
        let proxy = DepthProxy::new(&model);
        assert!(proxy.points.len() <= PROXY_POINTS);
        let mut far = DepthLayer::new(320, 240);
        let mut near = DepthLayer::new(320, 240);
        // The far square spans 0.2 m at 1.5 m: 40 px; the near one, at
        // 1 m and shifted by half its side, has its left edge on the
        // optical axis, the far one's centre line: it hides the far one's
        // right half.
        proxy.draw(&at(0.0, 1.5), &cam, &mut far);
        proxy.draw(&at(0.1, 1.0), &cam, &mut near);
        let [x0, _, x1, _] = far.rect.unwrap();
        assert!(
            (x1 - x0) as f64 > 38.0 && ((x1 - x0) as f64) < 44.0,
            "{x0}..{x1}"
        );
        let hidden = Hidden {
            others: near.clone(),
            tolerance: 0.02,
        };
        let v = hidden.visible_fraction(&far);
        assert!((v - 0.5).abs() < 0.06, "visible {v}");
        // The near one is not hidden by the far one.
        let behind = Hidden {
            others: far.clone(),
            tolerance: 0.02,
        };
        assert_eq!(behind.visible_fraction(&near), 1.0);
        // Points: the far square's centre is hidden, its left edge not;
        // its top edge's points near the near square's edge see it.
        let c = Vector2::new(160.0, 120.0);
        assert!(!hidden.hides(c - Vector2::new(10.0, 0.0), 1.5));
        assert!(hidden.hides(c + Vector2::new(10.0, 0.0), 1.5));
        let top = Vector2::new(158.0, 100.0);
        assert!(hidden.near_edge(top, Vector2::new(1.0, 0.0), 1.5, 6.0));
        assert!(!hidden.near_edge(
            top - Vector2::new(10.0, 0.0),
            Vector2::new(1.0, 0.0),
            1.5,
            6.0
        ));
        // Moved away: nothing hidden; the layer cleared where it was.
        proxy.draw(&at(0.6, 1.0), &cam, &mut near);
        let hidden = Hidden {
            others: near,
            tolerance: 0.02,
        };
        assert_eq!(hidden.visible_fraction(&far), 1.0);
    }

    #[test]
    fn nearest_of_takes_the_minimum() {
        let cam = Intrinsics::new(160, 120, 150.0, 150.0, 80.0, 60.0);
        let proxy = DepthProxy::new(&square(30, 0.2));
        let (mut a, mut b) = (DepthLayer::new(160, 120), DepthLayer::new(160, 120));
        proxy.draw(&at(0.0, 1.0), &cam, &mut a);
        proxy.draw(&at(0.1, 0.8), &cam, &mut b);
        let mut m = DepthLayer::new(160, 120);
        m.nearest_of([&a, &b].into_iter());
        for i in 0..m.depth.len() {
            assert_eq!(m.depth[i], a.depth[i].min(b.depth[i]));
        }
    }
}
