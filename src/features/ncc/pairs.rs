//! The host's side of the pairs: positions as uploaded, the order of B's
//! features, the mutual bests, the dispatch grid, the resident matches.

use super::config::Match;
use crate::features::gpu_data::{Best, MatchOut, NO_INDEX};
use crate::features::harris::Corner;
use crate::features::resident::ResidentMatch;

/// Positions as uploaded: non-finite or absurd coordinates become a point
/// far outside any image, whose window is then invalid.
pub(crate) fn sanitize(c: &Corner) -> [f32; 2] {
    let ok = |v: f32| v.is_finite() && v.abs() < 1.0e7;
    if ok(c.x) && ok(c.y) {
        [c.x, c.y]
    } else {
        [-1.0e9, -1.0e9]
    }
}

/// B's features (`b`: their uploaded positions) in the order the
/// one-thread-per-score kernel visits them: by bands of rows as tall as the
/// search radius (at least 8 px), then by x, so that consecutive threads
/// hold nearby features and skip together the pairs beyond the radius.
/// Without a radius, B's own order. Every index once.
pub(crate) fn spatial_order(b: &[[f32; 2]], radius: Option<f32>) -> Vec<u32> {
    let mut order: Vec<u32> = (0..b.len() as u32).collect();
    if let Some(r) = radius.filter(|r| r.is_finite() && *r > 0.0) {
        let band = r.max(8.0);
        let key = |j: &u32| {
            let [x, y] = b[*j as usize];
            ((y / band).floor() as i64, x)
        };
        order.sort_by(|p, q| {
            let ((bp, xp), (bq, xq)) = (key(p), key(q));
            bp.cmp(&bq).then(xp.total_cmp(&xq))
        });
    }
    order
}

/// Mutual best matches from the best entry per row and per column.
pub(crate) fn mutual(rows: &[Best], cols: &[Best], min_score: f32) -> Vec<Match> {
    rows.iter()
        .enumerate()
        .filter_map(|(a, r)| {
            let b = r.index as usize;
            (r.index != NO_INDEX
                && r.score >= min_score
                && cols.get(b).is_some_and(|c| c.index as usize == a))
            .then_some(Match {
                a,
                b,
                score: r.score,
            })
        })
        .collect()
}

/// `n` workgroups as a grid of rows of at most 65535 (a dispatch's most
/// in x), x first; the last row's surplus does nothing.
pub(super) fn split_groups(n: u32) -> (u32, u32) {
    let x = n.clamp(1, 65_535);
    (x, n.div_ceil(x).max(1))
}

/// The matches among `mutual_refine`'s rows (one a feature of A), B's
/// points moved from its band (first row `y0`) into its image.
pub(super) fn resident_matches(out: &[MatchOut], y0: f64, refine: bool) -> Vec<ResidentMatch> {
    out.iter()
        .enumerate()
        .filter(|(_, m)| m.b != NO_INDEX)
        .map(|(i, m)| ResidentMatch {
            a: i,
            b: m.b as usize,
            score: m.score,
            at: (!refine || m.refined == 1).then_some([m.x as f64, m.y as f64 + y0]),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{spatial_order, split_groups};

    #[test]
    fn workgroups_beyond_a_dispatch_row_wrap_into_rows() {
        for n in [0u32, 1, 64, 65_535, 65_536, 200_000] {
            let (x, y) = split_groups(n);
            assert!((1..=65_535).contains(&x) && y >= 1, "{n}: {x} x {y}");
            assert!(x as u64 * y as u64 >= n as u64, "{n}: {x} x {y} too few");
            assert!(
                (x as u64 * (y as u64 - 1)) < n.max(1) as u64,
                "{n}: {x} x {y}: a whole row too many"
            );
        }
    }

    #[test]
    fn spatial_order_is_a_permutation_by_bands_then_x() {
        let b = [
            [50.0, 3.0],
            [10.0, 25.0],
            [5.0, 9.9],
            [7.0, 0.0],
            [-1.0e9, -1.0e9],
            [30.0, 19.0],
        ];
        // Bands of 10 px: y in [0, 10) holds 0, 2, 3; [10, 20) holds 5;
        // [20, 30) holds 1; the far point first.
        assert_eq!(spatial_order(&b, Some(10.0)), vec![4, 2, 3, 0, 5, 1]);
        // Bands are at least 8 px tall.
        assert_eq!(spatial_order(&b, Some(1.0)), spatial_order(&b, Some(8.0)));
        // No radius (or a meaningless one): B's own order.
        for r in [None, Some(0.0), Some(f32::NAN), Some(f32::INFINITY)] {
            assert_eq!(spatial_order(&b, r), vec![0, 1, 2, 3, 4, 5]);
        }
        let mut sorted = spatial_order(&b, Some(10.0));
        sorted.sort();
        assert_eq!(sorted, vec![0, 1, 2, 3, 4, 5]);
    }
}
