//! The host steps that the GPU detector and the CPU reference share: pixel
//! packing, the spread selection and the merge of refined duplicates.

use super::config::{Corner, HarrisConfig};
use crate::features::gpu_data::{Candidate, Pixel};
use crate::features::image::GreyImage;

/// The image and mask as the GPU sees them: NaN (invalid) pixels become 0
/// with the valid flag cleared.
pub(crate) fn pack_pixels(img: &GreyImage, mask: Option<&[bool]>) -> Vec<Pixel> {
    crate::features::gpu_data::pack_with_holes(img, mask, true)
}

/// The best `max_corners` candidates, spread over the image: each is ranked
/// within its `grid_cell`-sized cell, and candidates are taken rank by rank
/// (ties by score, then position). Deterministic whatever the input order.
pub(crate) fn select_spread(cands: Vec<Candidate>, cfg: &HarrisConfig) -> Vec<Candidate> {
    select_spread_indices(&cands, cfg)
        .into_iter()
        .map(|i| cands[i])
        .collect()
}

/// [`select_spread`] as indices into `cands`, in the selection's order.
pub(crate) fn select_spread_indices(cands: &[Candidate], cfg: &HarrisConfig) -> Vec<usize> {
    let by_score = |a: &Candidate, b: &Candidate| {
        b.score
            .total_cmp(&a.score)
            .then(a.y.cmp(&b.y))
            .then(a.x.cmp(&b.x))
    };
    let mut order: Vec<usize> = (0..cands.len()).collect();
    order.sort_by(|&a, &b| by_score(&cands[a], &cands[b]));
    if cfg.grid_cell == 0 {
        order.truncate(cfg.max_corners);
        return order;
    }
    let cell = cfg.grid_cell;
    let mut rank_in_cell = std::collections::HashMap::new();
    let mut ranked: Vec<(u32, usize)> = order
        .into_iter()
        .map(|i| {
            let c = &cands[i];
            let r = rank_in_cell.entry((c.x / cell, c.y / cell)).or_insert(0u32);
            *r += 1;
            (*r, i)
        })
        .collect();
    ranked.sort_by(|&(ra, a), &(rb, b)| ra.cmp(&rb).then(by_score(&cands[a], &cands[b])));
    ranked.truncate(cfg.max_corners);
    ranked.into_iter().map(|(_, i)| i).collect()
}

/// The corners [`select_spread_indices`] selects among `cands`, at their
/// pixels (before any refinement), in the selection's order.
pub(crate) fn selected_starts(cands: &[Candidate], cfg: &HarrisConfig) -> Vec<Corner> {
    select_spread_indices(cands, cfg)
        .iter()
        .map(|&i| Corner {
            x: cands[i].x as f32,
            y: cands[i].y as f32,
            score: cands[i].score,
        })
        .collect()
}

/// Greedy merge of refined corners closer than `radius`, strongest first
/// (refinement pulls the split maxima of an X-junction onto one point).
/// The result is sorted by decreasing score.
pub(crate) fn merge(mut corners: Vec<Corner>, radius: f32) -> Vec<Corner> {
    corners.sort_by(|a, b| {
        b.score
            .total_cmp(&a.score)
            .then(a.y.total_cmp(&b.y))
            .then(a.x.total_cmp(&b.x))
    });
    if radius <= 0.0 {
        return corners;
    }
    let r2 = radius * radius;
    let mut kept: Vec<Corner> = Vec::with_capacity(corners.len());
    for c in corners {
        if kept
            .iter()
            .all(|k| (k.x - c.x).powi(2) + (k.y - c.y).powi(2) >= r2)
        {
            kept.push(c);
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_selection_takes_every_cell_first() {
        let cfg = HarrisConfig::default()
            .with_max_corners(3)
            .with_grid_cell(10);
        let c = |x, y, score| Candidate {
            x,
            y,
            score,
            _pad: 0,
        };
        // Three strong corners in one cell, one weak corner in another.
        let got = select_spread(
            vec![c(1, 1, 9.0), c(2, 5, 8.0), c(5, 2, 7.0), c(50, 50, 1.0)],
            &cfg,
        );
        let xs: Vec<u32> = got.iter().map(|c| c.x).collect();
        assert_eq!(xs, vec![1, 50, 2]);
    }

    #[test]
    fn merge_keeps_the_strongest_of_close_corners() {
        let c = |x, y, score| Corner { x, y, score };
        let got = merge(
            vec![c(10.0, 10.0, 1.0), c(10.5, 10.2, 2.0), c(20.0, 10.0, 0.5)],
            1.5,
        );
        assert_eq!(got, vec![c(10.5, 10.2, 2.0), c(20.0, 10.0, 0.5)]);
    }
}
