//! The picture of the README's "Contour" section: the contour points of the
//! model splatted at a frame's pose, with their search lines, over the frame.
//!
//! `cargo run --release --example contour_picture -- MODEL.ply SEQUENCE_DIR FRAME OUT.png`
//! (the pose is the sequence's ground truth, poses.csv).

use nalgebra::Vector2;
use splattrack::draw;
use splattrack::gpu::{AdapterChoice, GpuContext};
use splattrack::io::{Sequence, read_poses};
use splattrack::splat::{Attribute, Attributes, GpuModel, SplatTargets, Splatter};
use splattrack::tracker::ContourConfig;
use splattrack::tracker::contour::{extract_contour, inset, limb_normals};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 5 {
        return Err("usage: contour_picture MODEL.ply SEQUENCE_DIR FRAME OUT.png".into());
    }
    let ctx = GpuContext::new(&AdapterChoice::from_env()?)?;
    let model = splattrack::PointModel::load(&args[1])?;
    let seq = Sequence::open(Path::new(&args[2]))?;
    let k: usize = args[3].parse()?;
    let pose = read_poses(&Path::new(&args[2]).join("poses.csv"))?[k].pose;
    let cam = seq.camera;
    let splatter = Splatter::new(&ctx)?;
    let gm = GpuModel::new(&ctx, &model)?;
    let mut t = SplatTargets::new(&ctx, cam.width, cam.height);
    splatter.render(&ctx, &gm, &cam, &pose, Attributes::GEOMETRY, &mut t)?;
    let depth = splatter.read(&ctx, &t, Attribute::Depth)?;
    let normals = splatter.read(&ctx, &t, Attribute::Normal)?;
    let mask: Vec<bool> = depth.data.iter().map(|v| v.is_finite()).collect();
    let mut points = extract_contour(&mask, cam.width as usize, cam.height as usize, 8);
    limb_normals(&cam, &normals, &mut points);
    inset(&mut points, ContourConfig::default().inset_px);
    let mut img = image::open(&seq.frames[k])?.to_rgb8();
    for p in &points {
        let (a, b): (Vector2<f64>, Vector2<f64>) =
            (p.position - p.normal * 16.0, p.position + p.normal * 16.0);
        draw::line(&mut img, a.x, a.y, b.x, b.y, [255, 255, 255], 1.0);
        draw::circle(&mut img, p.position.x, p.position.y, 2.0, [255, 0, 0]);
    }
    // Cropped to the outline and a 40 px margin.
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, 0.0f64, 0.0f64);
    for p in &points {
        x0 = x0.min(p.position.x);
        y0 = y0.min(p.position.y);
        x1 = x1.max(p.position.x);
        y1 = y1.max(p.position.y);
    }
    let cx0 = (x0 - 40.0).max(0.0) as u32;
    let cy0 = (y0 - 40.0).max(0.0) as u32;
    let cx1 = ((x1 + 40.0) as u32).min(cam.width - 1);
    let cy1 = ((y1 + 40.0) as u32).min(cam.height - 1);
    let img = image::imageops::crop_imm(&img, cx0, cy0, cx1 - cx0 + 1, cy1 - cy0 + 1).to_image();
    img.save(&args[4])?;
    println!("{} contour points drawn into {}", points.len(), args[4]);
    Ok(())
}
