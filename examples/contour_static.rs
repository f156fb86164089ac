//! Where the contour alone puts a static frame: from the ground-truth pose
//! of frame FRAME, renders (depth and normals), searches the lines
//! (half-length 5 px, colours learnt from this frame at its true pose) and
//! solves, ROUNDS times, each from the last estimate; prints the rotation
//! error against the ground truth after each round (the rotation vector
//! of `estimate * truth^-1`, camera axes, degrees) and writes the first
//! round's line results (point, normal, boundary offset `d`, pixels,
//! positive outward) to OUT.csv. On the real dragon this showed the
//! outline's own optimum 1.5-2.5 degrees from the ground truth (README
//! "Contour").
//!
//! `cargo run --release --example contour_static -- MODEL.ply SEQUENCE_DIR FRAME ROUNDS OUT.csv`

use nalgebra::{Vector2, Vector6};
use splattrack::gpu::{AdapterChoice, GpuContext};
use splattrack::io::{Sequence, read_poses};
use splattrack::pose::{IrlsConfig, Observation, irls};
use splattrack::splat::{Attribute, Attributes, GpuModel, SplatTargets, Splatter};
use splattrack::tracker::ContourConfig;
use splattrack::tracker::contour::{
    ColourModel, contour_predictors, extract_contour, inset, limb_normals, search_line,
};
use std::io::Write;
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 6 {
        return Err("usage: contour_static MODEL.ply SEQUENCE_DIR FRAME ROUNDS OUT.csv".into());
    }
    let ctx = GpuContext::new(&AdapterChoice::from_env()?)?;
    let model = splattrack::PointModel::load(&args[1])?;
    let seq = Sequence::open(Path::new(&args[2]))?;
    let k: usize = args[3].parse()?;
    let rounds: usize = args[4].parse()?;
    let gt = read_poses(&Path::new(&args[2]).join("poses.csv"))?[k].pose;
    let cam = seq.camera;
    let cfg = ContourConfig::default();
    let splatter = Splatter::new(&ctx)?;
    let gm = GpuModel::new(&ctx, &model)?;
    let mut t = SplatTargets::new(&ctx, cam.width, cam.height);
    let frame = image::open(&seq.frames[k])?.to_rgb8();
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut colours = ColourModel::new(cfg.bins);
    let mut pose = gt;
    let mut out = std::fs::File::create(&args[5])?;
    writeln!(out, "x,y,nx,ny,d")?;
    for round in 0..rounds {
        splatter.render(&ctx, &gm, &cam, &pose, Attributes::GEOMETRY, &mut t)?;
        let depth = splatter.read(&ctx, &t, Attribute::Depth)?;
        let normals = splatter.read(&ctx, &t, Attribute::Normal)?;
        let mask: Vec<bool> = depth.data.iter().map(|v| v.is_finite()).collect();
        if round == 0 {
            colours.learn(
                &frame,
                &mask,
                (0, 0, w - 1, h - 1),
                cfg.learn_margin_px,
                1.0,
            );
        }
        let mut points = extract_contour(&mask, w, h, cfg.spacing_px as usize);
        limb_normals(&cam, &normals, &mut points);
        inset(&mut points, cfg.inset_px);
        let rows = contour_predictors(&cam, &depth, &points);
        let mut obs = Vec::new();
        for (p, row) in points.iter().zip(&rows) {
            let Some(d) = search_line(&frame, &colours, p.position, p.normal, 5.0, cfg.slope_px)
            else {
                continue;
            };
            if round == 0 {
                writeln!(
                    out,
                    "{},{},{},{},{}",
                    p.position.x, p.position.y, p.normal.x, p.normal.y, d
                )?;
            }
            obs.push(Observation {
                displacement: Vector2::new(d, 0.0),
                ..*row
            });
        }
        let s = irls(&obs, &IrlsConfig::default())?;
        let tw: Vector6<f64> = s.twist;
        pose = pose.apply_twist(&tw).orthonormalized();
        let e = pose.compose(&gt.inverse());
        let el = e.log();
        let dt = pose.translation - gt.translation;
        println!(
            "round {round}: {} rows, scale {:.2} px; error rot {:.2} deg [{:.2} {:.2} {:.2}] translation [{:.2} {:.2} {:.2}] mm (model units x 1000)",
            obs.len(),
            s.scale_px,
            pose.rotation_error_deg(&gt),
            el[3].to_degrees(),
            el[4].to_degrees(),
            el[5].to_degrees(),
            dt.x * 1e3,
            dt.y * 1e3,
            dt.z * 1e3
        );
    }
    Ok(())
}
