//! Several objects in one picture (the live view's [`super::compose`] and
//! `--overlay`): each outline in its object's colour, its name beside it.

use super::sink::ViewObject;
use crate::draw::{self, Colour};
use crate::tracker::Status;
use image::RgbImage;

/// The colour of the outline and the status word: green tracking, red
/// lost (as `--overlay` draws them).
pub fn status_colour(status: Status) -> Colour {
    match status {
        Status::Tracking => [40, 230, 60],
        Status::Lost => [240, 40, 40],
    }
}

/// The colours of the objects after the first, while they track: far
/// from the first object's green and red and from each other.
const PALETTE: [Colour; 6] = [
    [0, 200, 255],
    [255, 80, 220],
    [255, 215, 0],
    [255, 140, 0],
    [150, 130, 255],
    [255, 255, 255],
];

/// The colour of object `k` (from 0) of a run: the first keeps the
/// colour one object has ([`status_colour`]: green tracking, red lost);
/// the others have a colour of a fixed palette each, at half brightness
/// while lost.
pub fn object_colour(k: usize, status: Status) -> Colour {
    if k == 0 {
        return status_colour(status);
    }
    let c = PALETTE[(k - 1) % PALETTE.len()];
    match status {
        Status::Tracking => c,
        Status::Lost => c.map(|v| v / 2),
    }
}

/// How many of the objects are tracking: `2/3 tracking`.
pub fn objects_tracking(objects: &[ViewObject<'_>]) -> String {
    let tracking = objects
        .iter()
        .filter(|o| o.result.status == Status::Tracking)
        .count();
    format!("{tracking}/{} tracking", objects.len())
}

/// Draws every object's outline in its colour ([`object_colour`]) and
/// its name (with `lost` when it is) above the top-left corner of its
/// silhouette; an object without a mask, or outside the picture, is not
/// drawn.
pub fn draw_objects(img: &mut RgbImage, objects: &[ViewObject<'_>]) {
    for (k, o) in objects.iter().enumerate() {
        if let Some(mask) = o.mask {
            draw::silhouette(img, mask, object_colour(k, o.result.status));
        }
    }
    // The names after every outline, so none is drawn over.
    let w = img.width() as usize;
    for (k, o) in objects.iter().enumerate() {
        let Some(mask) = o.mask else { continue };
        let Some(first) = mask.iter().position(|&m| m) else {
            continue;
        };
        let left = (0..mask.len())
            .filter(|&p| mask[p])
            .map(|p| p % w.max(1))
            .min()
            .unwrap_or(0);
        let top = first / w.max(1);
        let text = match o.result.status {
            Status::Tracking => o.name.to_owned(),
            Status::Lost => format!("{} lost", o.name),
        };
        let y = (top as i64 - 12).max(2);
        let colour = object_colour(k, o.result.status);
        draw::label(img, left as i64 + 2, y, &text, colour, draw::BLACK, 1);
    }
}

/// `frame` with every object drawn ([`draw_objects`]) and `text` as a
/// label in the top-left corner (the `--overlay` picture of a run of
/// several objects).
pub fn objects_overlay(frame: &RgbImage, objects: &[ViewObject<'_>], text: &str) -> RgbImage {
    let mut img = frame.clone();
    draw_objects(&mut img, objects);
    draw::label(&mut img, 6, 6, text, draw::WHITE, draw::BLACK, 1);
    img
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use crate::tracker::{Modalities, TrackResult};

    fn result(status: Status) -> TrackResult {
        TrackResult {
            pose: Pose::identity(),
            inliers: 0,
            residual_px: f64::NAN,
            status,
            reason: None,
            keyframe: None,
            times: Default::default(),
            verify: None,
            texture_set_aside: false,
            cues: Modalities::NONE,
            refused: None,
        }
    }

    #[test]
    fn the_first_object_keeps_the_status_colours_the_others_differ() {
        assert_eq!(
            object_colour(0, Status::Tracking),
            status_colour(Status::Tracking)
        );
        assert_eq!(object_colour(0, Status::Lost), status_colour(Status::Lost));
        let mut seen = vec![status_colour(Status::Tracking), status_colour(Status::Lost)];
        for k in 1..=PALETTE.len() {
            let c = object_colour(k, Status::Tracking);
            assert!(!seen.contains(&c), "object {k}: {c:?}");
            seen.push(c);
            assert_ne!(object_colour(k, Status::Lost), c);
        }
    }

    #[test]
    fn each_outline_has_its_colour_and_a_name_above_it() {
        let (w, h) = (64u32, 48u32);
        let square = |x0: usize, y0: usize| {
            let mut m = vec![false; (w * h) as usize];
            for y in y0..y0 + 10 {
                for x in x0..x0 + 10 {
                    m[y * w as usize + x] = true;
                }
            }
            m
        };
        let (a, b) = (square(5, 20), square(40, 25));
        let (ra, rb) = (result(Status::Tracking), result(Status::Lost));
        let objects = [
            ViewObject {
                name: "a",
                result: &ra,
                mask: Some(&a),
            },
            ViewObject {
                name: "b",
                result: &rb,
                mask: Some(&b),
            },
        ];
        assert_eq!(objects_tracking(&objects), "1/2 tracking");
        let mut img = RgbImage::new(w, h);
        draw_objects(&mut img, &objects);
        // The outlines' corners in each object's colour.
        assert_eq!(img.get_pixel(5, 20).0, object_colour(0, Status::Tracking));
        assert_eq!(img.get_pixel(40, 25).0, object_colour(1, Status::Lost));
        // Each name's text, in its colour, in the rows above its outline.
        let has = |c: Colour, ys: std::ops::Range<u32>| {
            ys.flat_map(|y| (0..w).map(move |x| (x, y)))
                .any(|(x, y)| img.get_pixel(x, y).0 == c)
        };
        assert!(has(object_colour(0, Status::Tracking), 8..18));
        assert!(has(object_colour(1, Status::Lost), 13..23));
    }
}
