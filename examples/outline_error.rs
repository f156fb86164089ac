//! Where the contour's two sides err, against the exact outline: at the
//! true pose of frames of a synthetic sequence (`synth`'s Fig. 10
//! trajectory, 200 frames, 100k points), the model's contour points
//! (splatted, inset) and the boundaries that the line searches find in the
//! frame (lines of 5 px, colours learnt at the true pose) are compared with
//! the mesh's outline rasterised at 8x along each point's normal. Prints
//! per frame the model side (exact - model point) and the frame side
//! (found - exact), pixels; with OUT_DIR, writes each frame's points to
//! OUT_DIR/outline_OBJECT_FRAME.csv (x, y, nx, ny, exact offset b, found
//! offset d, pixel). It showed the found boundaries 0.06 px inside the
//! outline on average, 0.3-0.7 px on darkened limbs (README "Contour").
//!
//! `cargo run --release --example outline_error -- OBJECT FRAME[,FRAME...] [OUT_DIR]`
use splattrack::gpu::{AdapterChoice, GpuContext};
use splattrack::splat::{Attribute, Attributes, GpuModel, SplatTargets, Splatter};
use splattrack::synth::{SynthConfig, SynthObject, Trajectory, background, raster, render_frame};
use splattrack::tracker::ContourConfig;
use splattrack::tracker::contour::{
    ColourModel, extract_contour, inset_each, insets, limb_normals, search_line, straight_edges,
};
use std::io::Write;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args: Vec<String> = std::env::args().collect();
    let mut option = |name: &str| -> Option<String> {
        let i = args.iter().position(|a| a == name)?;
        let v = args.get(i + 1).cloned();
        args.drain(i..(i + 2).min(args.len()));
        v
    };
    let n_points: usize = option("--points").map_or(Ok(100_000), |v| v.parse())?;
    let distance: Option<f64> = option("--distance").map(|v| v.parse()).transpose()?;
    if !(3..=4).contains(&args.len()) {
        return Err(
            "usage: outline_error OBJECT FRAME[,FRAME...] [OUT_DIR] [--points N] [--distance M]"
                .into(),
        );
    }
    let obj = &args[1];
    let frames = args[2]
        .split(',')
        .map(|s| s.parse::<usize>())
        .collect::<Result<Vec<_>, _>>()?;
    let out_dir = args.get(3).map(std::path::PathBuf::from);
    let ctx = GpuContext::new(&AdapterChoice::from_env()?)?;
    let cfg = SynthConfig {
        object: obj.clone(),
        trajectory: Trajectory::Fig10,
        frames: 200,
        ..Default::default()
    };
    let cfg = SynthConfig {
        distance: distance.unwrap_or(cfg.distance),
        ..cfg
    };
    let cam = cfg.camera;
    let object = SynthObject::by_name(&cfg.object).ok_or("unknown object")?;
    let model = splattrack::synth::sequence::sample_model(&object, n_points, cfg.seed)?;
    let splatter = Splatter::new(&ctx)?;
    let gm = GpuModel::new(&ctx, &model)?;
    let mut t = SplatTargets::new(&ctx, cam.width, cam.height);
    let bg = background(&cam, cfg.seed);
    let c = ContourConfig::default();
    for &k in &frames {
        let f = render_frame(&cfg, &object, &bg, k);
        splatter.render(&ctx, &gm, &cam, &f.pose, Attributes::GEOMETRY, &mut t)?;
        let depth = splatter.read(&ctx, &t, Attribute::Depth)?;
        let normals = splatter.read(&ctx, &t, Attribute::Normal)?;
        let mask: Vec<bool> = depth.data.iter().map(|v| v.is_finite()).collect();
        let mut points = extract_contour(&mask, cam.width as usize, cam.height as usize, 4);
        let (w, h) = (cam.width as i64, cam.height as i64);
        straight_edges(&mut points, |x, y| {
            x < 0 || y < 0 || x >= w || y >= h || mask[(y * w + x) as usize]
        });
        let creases = limb_normals(&cam, &normals, &mut points);
        let depths: Vec<f32> = points
            .iter()
            .map(|p| depth.pixel(p.pixel[0], p.pixel[1])[0])
            .collect();
        let lowpass = splattrack::splat::SplatParams::default().lowpass_px as f64;
        let (radius, sampling) = splattrack::tracker::contour::crease_radii(
            &model,
            splattrack::tracker::contour::ModelNormals::new(&model).as_ref(),
        );
        let by = insets(
            &creases,
            &depths,
            (radius, sampling),
            cam.fx,
            c.inset_px,
            lowpass,
        );
        inset_each(&mut points, &by);
        let mut colours = ColourModel::new(c.bins);
        colours.learn(
            &f.image,
            &mask,
            (0, 0, cam.width as usize - 1, cam.height as usize - 1),
            c.learn_margin_px,
            1.0,
        );
        let exact = raster::ExactOutline::new(&object.mesh, &f.pose, &cam, 8);
        let mut out = match &out_dir {
            Some(dir) => {
                let mut f = std::fs::File::create(dir.join(format!("outline_{obj}_{k}.csv")))?;
                writeln!(f, "x,y,nx,ny,b,d,px,py")?;
                Some(f)
            }
            None => None,
        };
        let (mut bs, mut ds) = (Vec::new(), Vec::new());
        // The model side apart on limbs (the surface normal across the ray)
        // and on creases (a face ending at an edge), and the splats' radius
        // in pixels there.
        let (mut limb, mut crease, mut r_px) = (Vec::new(), Vec::new(), Vec::new());
        for p in &points {
            let boundary = exact.boundary_along(p.position, p.normal, 4.0);
            let found = search_line(&f.image, &colours, p.position, p.normal, 5.0, c.slope_px);
            if let (Some(b), Some(d)) = (boundary, found) {
                if let Some(out) = out.as_mut() {
                    writeln!(
                        out,
                        "{},{},{},{},{},{},{},{}",
                        p.position.x,
                        p.position.y,
                        p.normal.x,
                        p.normal.y,
                        b,
                        d,
                        p.pixel[0],
                        p.pixel[1]
                    )?;
                }
                bs.push(b);
                let nv = normals.pixel(p.pixel[0], p.pixel[1]);
                let n3 = nalgebra::Vector3::new(nv[0] as f64, nv[1] as f64, nv[2] as f64);
                let ray = cam
                    .unproject(
                        &nalgebra::Vector2::new(p.pixel[0] as f64, p.pixel[1] as f64),
                        1.0,
                    )
                    .normalize();
                if n3.norm() > 0.5 && n3.normalize().dot(&ray).abs() > 0.3 {
                    crease.push(b);
                } else {
                    limb.push(b);
                }
                let z = depth.pixel(p.pixel[0], p.pixel[1])[0] as f64;
                r_px.push(model.radii[0] as f64 * cam.fx / z);
                ds.push(d - b);
            }
        }
        let st = |v: &mut Vec<f64>| {
            let n = v.len() as f64;
            let mean = v.iter().sum::<f64>() / n;
            let rms = (v.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
            v.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
            format!(
                "mean {mean:+.3} rms {rms:.3} med|.| {:.3} p90 {:.3}",
                v[v.len() / 2].abs(),
                v[v.len() * 9 / 10].abs()
            )
        };
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        println!(
            "{obj} {k}: model side on limbs {:+.3} ({} pts), on creases {:+.3} ({} pts); splat radius {:.2} px",
            mean(&limb),
            limb.len(),
            mean(&crease),
            crease.len(),
            mean(&r_px)
        );
        println!(
            "{obj} {k}: {} pts; model side (exact - model) {}; frame side (found - exact) {}",
            bs.len(),
            st(&mut bs),
            st(&mut ds)
        );
    }
    Ok(())
}
