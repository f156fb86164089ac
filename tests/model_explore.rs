use splattrack::model::*;
use std::time::Instant;

#[test]
fn explore() {
    for name in ["visp_rbt_cube", "visp_rbt_dragon"] {
        let path = format!("../shared/data/{name}/model.ply");
        let t = Instant::now();
        let m = PointModel::load(&path).unwrap();
        println!(
            "{name}: load {:?} n={} {:?}",
            t.elapsed(),
            m.len(),
            m.provenance
        );
        let opts = LoadOptions {
            recompute_normals: true,
            recompute_radii: true,
            ..Default::default()
        };
        let t = Instant::now();
        let e = PointModel::load_with(&path, &opts).unwrap();
        println!("estimate {:?}", t.elapsed());
        let agree = m
            .normals
            .iter()
            .zip(&e.normals)
            .filter(|(a, b)| a.dot(**b) > 0.0)
            .count();
        let mut angles: Vec<f32> = m
            .normals
            .iter()
            .zip(&e.normals)
            .map(|(a, b)| a.dot(*b).abs().min(1.0).acos().to_degrees())
            .collect();
        angles.sort_by(f32::total_cmp);
        let mut ratios: Vec<f32> = m.radii.iter().zip(&e.radii).map(|(a, b)| b / a).collect();
        ratios.sort_by(f32::total_cmp);
        println!(
            "sign agree {}/{} ; angle median {} p95 {} ; radius ratio p5 {} median {} p95 {}",
            agree,
            m.len(),
            angles[angles.len() / 2],
            angles[angles.len() * 95 / 100],
            ratios[ratios.len() / 20],
            ratios[ratios.len() / 2],
            ratios[ratios.len() * 19 / 20]
        );
        let (lo, hi) = m.bounds();
        println!(
            "bounds {lo} {hi} diam {} centroid {}",
            m.diameter(),
            m.centroid()
        );
    }
    for name in ["visp_rbt_cube", "visp_rbt_dragon"] {
        let path = format!("../shared/data/{name}/mesh.obj");
        let t = Instant::now();
        let mesh = load_obj(&path).unwrap();
        let m = mesh.sample(100_000, 1).unwrap();
        println!(
            "{name} mesh: {} verts {} tris area {} ; sample {:?} r={}",
            mesh.vertices.len(),
            mesh.triangles.len(),
            mesh.area(),
            t.elapsed(),
            m.radii[0]
        );
    }
}
