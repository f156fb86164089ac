//! Tests of the scenes of several objects: ground truth from the
//! rasteriser's object ids.

use super::multi::*;
use crate::geometry::Intrinsics;

#[test]
#[ignore]
fn print_layout_numbers() {
    for layout in [Layout::Cross, Layout::Hide, Layout::Mixed, Layout::Cross3] {
        let t = std::time::Instant::now();
        let scene = MultiScene::new(MultiConfig {
            layout,
            ..MultiConfig::default()
        })
        .unwrap();
        let made = t.elapsed();
        let n = scene.config.frames;
        let k = scene.objects.len();
        let mut min_vis = vec![1.0f64; k];
        let mut hidden = vec![0; k];
        let mut first = vec![0.0; k];
        let mut last = vec![0.0; k];
        let cam = scene.config.camera;
        for i in 0..n {
            let poses: Vec<_> = (0..k).map(|j| scene.pose(j, i)).collect();
            let meshes: Vec<_> = scene
                .objects
                .iter()
                .map(|o| &o.object.mesh)
                .zip(&poses)
                .collect();
            let v = super::raster::visible_fractions(&meshes, &cam, 1);
            for j in 0..k {
                min_vis[j] = min_vis[j].min(v[j]);
                if v[j] == 0.0 {
                    hidden[j] += 1;
                }
                if i == 0 {
                    first[j] = v[j];
                }
                last[j] = v[j];
            }
        }
        let sizes: Vec<_> = (0..k).map(|j| scene.size_px(j)).collect();
        let dist: Vec<_> = scene.objects.iter().map(|o| o.distance()).collect();
        println!(
            "{}: made in {made:?}, sizes {sizes:?}, distances {dist:?}, min visible {min_vis:?}, hidden frames {hidden:?}, first {first:?} last {last:?}",
            layout.name()
        );
        let _ = Intrinsics::new(1, 1, 1.0, 1.0, 0.0, 0.0);
    }
}
