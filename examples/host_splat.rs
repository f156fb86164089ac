//! The host splatter's time per render (`splat::cpu::HostSplatter`), the
//! median of many renders, on 1 and 2 threads: the real cube at its
//! initial pose in its window (with `SPLATTRACK_DATA`), a 100k-point
//! sphere at 640x480 and the same sphere filling the image. A quick
//! check beside `cargo bench --bench splat -- splat_cpu`. On Linux it
//! prints the CPU time a render costs too (all threads, from
//! `/proc/self/stat`), steadier than wall time on a busy machine.
//!
//! ```sh
//! cargo run --release --example host_splat -- [renders]
//! ```

use glam::Vec3;
use nalgebra::Vector3;
use splattrack::geometry::{Intrinsics, Pose, look_at};
use splattrack::model::{PointModel, shapes};
use splattrack::splat::cpu::{Accumulators, HostSplatter};
use splattrack::splat::{Attributes, ModelBounds, SplatParams, Window, pack_model};
use std::time::Instant;

fn cube() -> Option<(PointModel, Intrinsics, Pose)> {
    let dir = std::path::PathBuf::from(std::env::var_os("SPLATTRACK_DATA")?).join("visp_rbt_cube");
    let model = PointModel::load(dir.join("model.ply")).expect("the cube's model");
    let cam = Intrinsics::load(&dir.join("camera.json")).expect("the cube's camera");
    let pose = splattrack::io::read_poses(&dir.join("init.csv")).expect("init.csv")[0].pose;
    let pad = Vector3::repeat(model.radii.iter().fold(0.0f64, |m, &r| m.max(r as f64)));
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        -Vector3::repeat(f64::INFINITY),
    );
    for p in &model.positions {
        let p = Vector3::new(p.x as f64, p.y as f64, p.z as f64);
        (lo, hi) = (lo.inf(&p), hi.sup(&p));
    }
    let win = Window::of_box(&cam, &pose, &(lo - pad), &(hi + pad), 16.0, 8)?;
    Some((model, win.camera(&cam), pose))
}

/// The process's CPU time so far (user + system, ms; Linux only).
fn cpu_ms() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The fields after the command's closing parenthesis; utime and
    // stime are the 12th and 13th, in ticks of (nearly always) 10 ms.
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<f64> = rest
        .split_whitespace()
        .skip(11)
        .take(2)
        .filter_map(|v| v.parse().ok())
        .collect();
    (f.len() == 2).then(|| (f[0] + f[1]) * 10.0)
}

fn main() {
    let renders: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(30);
    let mut scenes = Vec::new();
    if let Some(c) = cube() {
        scenes.push(("cube, window".to_owned(), c));
    }
    let sphere = shapes::sphere(Vec3::ZERO, 0.5, 100_000, 1.2);
    let cam = Intrinsics::new(640, 480, 600.0, 600.0, 319.5, 239.5);
    let up = Vector3::new(0.0, -1.0, 0.0);
    for (name, eye) in [
        ("sphere 100k, 640x480", Vector3::new(0.3, -0.4, -1.9)),
        ("sphere 100k filling 640x480", Vector3::new(0.0, 0.0, -0.75)),
    ] {
        let pose = look_at(&eye, &Vector3::zeros(), &up);
        scenes.push((name.to_owned(), (sphere.clone(), cam, pose)));
    }
    let params = SplatParams::default();
    for (name, (model, cam, pose)) in &scenes {
        let packed = pack_model(model, &params).expect("a valid model");
        let uniform = ModelBounds::of(model)
            .view(cam, pose, &params)
            .expect("in view");
        for (what, attrs) in [
            ("colour", Attributes::COLOR),
            ("colour+predictors", Attributes::MOTION),
        ] {
            let mut line = format!("{name} ({}x{}), {what}:", cam.width, cam.height);
            for threads in [1, 2] {
                let mut host = HostSplatter::with_threads(threads);
                let mut out = Accumulators::default();
                host.render(&packed, &uniform, attrs, &mut out);
                let cpu0 = cpu_ms();
                let mut ms: Vec<f64> = (0..renders)
                    .map(|_| {
                        let t = Instant::now();
                        host.render(&packed, &uniform, attrs, &mut out);
                        t.elapsed().as_secs_f64() * 1e3
                    })
                    .collect();
                let cpu = cpu_ms().zip(cpu0).map(|(b, a)| (b - a) / renders as f64);
                ms.sort_by(f64::total_cmp);
                line += &format!(" {threads} thread(s) {:.2} ms", ms[ms.len() / 2]);
                if let Some(cpu) = cpu {
                    line += &format!(" (CPU {cpu:.1} ms)");
                }
            }
            println!("{line}");
        }
    }
}
