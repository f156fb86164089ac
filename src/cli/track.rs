//! `splattrack track --model [NAME=]M.ply... (--sequence DIR | --video
//! FILE | --device N|PATH --camera C) [--keyframes DIR|FILE]...
//! [--init init.csv]... [--mode kf+it|it|kf] --out poses.csv [--overlay
//! DIR] [--profile] [--bop FILE] [--refused FILE] [--start N|Ts]
//! [--frames N]`: the flags ([`args`]), the input they name ([`input`])
//! and the objects ([`objects`]), then [`splattrack::app`] does the work
//! and [`output`] prints what it did.

mod args;
mod input;
#[cfg(not(feature = "view"))]
mod no_view;
mod objects;
mod output;
mod profile;
mod refused;

pub use args::Args;

use anyhow::{Context, bail};
use input::Input;
use splattrack::app::{AppError, TrackRun};
use splattrack::io::live::LiveSource;
use splattrack::io::source::Start;
use splattrack::tracker::Mode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

#[cfg(not(feature = "view"))]
use no_view::DisplaySink;
#[cfg(feature = "view")]
use splattrack::view::DisplaySink;

pub fn run(args: Args, target: &crate::cli::common::Target) -> anyhow::Result<()> {
    // The tuning flags checked first.
    args.config(args::Cues::Auto)?;
    if args.frames == Some(0) {
        bail!("--frames 0: nothing to track");
    }
    let input = Input::of(&args)?;
    let objects = objects::of(&args)?;
    output::check_outputs(&args, &objects)?;
    // A video or a camera is opened first: a missing ffmpeg, a file it
    // cannot decode or frames of the wrong size fail before the GPU and
    // the model are set up.
    let stop = Arc::new(AtomicBool::new(false));
    let source = input.open(args.realtime, &stop)?;
    let ctx = crate::cli::common::device(target)?;
    // Before anything is loaded or written: no display, no run.
    let mut display = match (args.view, &ctx) {
        (true, splattrack::Device::Gpu(gpu)) => Some(DisplaySink::open(
            gpu,
            &format!("splattrack track {}", input.describe()),
        )?),
        (true, splattrack::Device::Cpu) => {
            bail!("--view needs a GPU adapter to draw with; the CPU device has none")
        }
        (false, _) => None,
    };
    let (inputs, several) = objects::load(&ctx, &input, &objects)?;
    let mut config = args.config(objects[0].cues)?;
    let several = match several {
        None => {
            config.mode = mode_for(&args, inputs.textured(), inputs.init.is_some(), None)?;
            None
        }
        Some(mut list) => {
            for (o, given) in list.iter_mut().zip(&objects) {
                o.config = args.config(given.cues)?;
                o.config.mode = mode_for(&args, o.textured(), o.init.is_some(), Some(&o.name))?;
            }
            config.mode = list[0].config.mode;
            Some(list)
        }
    };
    let live = matches!(input, Input::Device { .. }) || args.realtime;
    if live {
        catch_ctrl_c(&stop)?;
    }
    let mode = config.mode;
    let prefix = match objects.len() {
        1 => format!("{} ", mode.name()),
        n => format!("{} {n} objects ", mode.name()),
    };
    let mut run = TrackRun::new(&ctx, &inputs, config)
        .limit(args.frames)
        .poses(&args.out)
        .progress(Some(crate::cli::progress::bars(prefix, 1)));
    if let Some(list) = several {
        run = run.objects(list);
    }
    if let Some(dir) = &args.overlay {
        run = run.overlays(dir, 1);
    }
    if let Some(path) = &args.bop {
        run = run.bop(path, args.obj_id.unwrap_or(1));
    }
    if args.profile {
        run = run.gpu_timing(true);
    }
    match (source, &input) {
        (Some(src), _) => run = run.source(src).stop_on(stop.clone()),
        (None, Input::Sequence(_)) => {
            if let Some(Start::Frame(k)) = args.start {
                run = run.start(k);
            }
        }
        (None, Input::Video { file, camera, .. }) => {
            let replay = LiveSource::replay(file, &inputs.camera, camera)?;
            run = run
                .source(Box::new(replay.stop_on(stop.clone())))
                .stop_on(stop.clone());
        }
        (None, Input::Device { .. }) => {}
    }
    if let Some(w) = display.as_mut() {
        run = run.sink(w);
    }
    let names = objects.iter().map(|o| o.name.clone()).collect();
    let mut refused = refused::Refused::create(args.refused.as_deref(), names)?;
    let wall = std::time::Instant::now();
    let stats = match run.run_objects(|frame, results| refused.frame(frame, results)) {
        Err(AppError::NoFrames) if args.start.is_some() => {
            refused.discard();
            bail!("{}", no_frame_at_start(&input, args.start))
        }
        Err(e) => {
            refused.discard();
            return Err(e.into());
        }
        Ok(s) => s,
    };
    refused.finish()?;
    let wall = wall.elapsed().as_secs_f64();
    output::print_summary(&args, mode, &ctx, &stats, &stop, live);
    if args.profile {
        output::print_profile(&ctx, &stats, wall, display.is_some());
        if let Some(w) = &display {
            let v = w.stats();
            println!(
                "live view: {} frames shown, {} skipped (surface not ready); {:.1} ms per frame to compose, draw and present",
                v.shown,
                v.skipped,
                v.busy.as_secs_f64() * 1e3 / (v.shown + v.skipped).max(1) as f64
            );
        }
    }
    Ok(())
}

/// The mode of an object's tracker (`object`: its name, in a run of
/// several): `--mode`, else kf+it where there is a texture for the KF
/// step's views (keyframes or model colours) and it (frame to frame)
/// where there is none, said once. A KF mode asked for without a
/// texture, or no first pose and nothing to search for the object with,
/// fails naming what would help.
fn mode_for(args: &Args, textured: bool, init: bool, object: Option<&str>) -> anyhow::Result<Mode> {
    let of = object.map_or_else(String::new, |name| format!("object {name:?}: "));
    if !textured && !init {
        bail!(
            "{of}no first pose (init.csv or --init) and nothing to search for the object with (keyframes or model colours): give the pose of the first frame with --init"
        );
    }
    match splattrack::app::run_mode(args.mode, textured) {
        Err(m) => bail!(
            "{of}--mode {m} needs keyframes (--keyframes DIR or SEQUENCE/keyframes) or a model with colours for the KF step's views; without them use --mode it (frame to frame)"
        ),
        Ok(m) => {
            if args.mode.is_none() && m == Mode::It {
                log::info!(
                    "{of}no keyframes and no model colours: tracking frame to frame (mode it)"
                );
            }
            Ok(m)
        }
    }
}

/// Ctrl-C: the run ends after the frame being tracked, its outputs
/// complete; a second Ctrl-C ends it at once (the rows so far stay in
/// OUT.partial).
fn catch_ctrl_c(stop: &Arc<AtomicBool>) -> anyhow::Result<()> {
    let flag = stop.clone();
    ctrlc::set_handler(move || {
        if flag.swap(true, Ordering::SeqCst) {
            eprintln!("stopped at once: the rows so far are in the .partial file");
            std::process::exit(130);
        }
        eprintln!("stopping after the current frame (Ctrl-C again to stop at once)");
    })
    .context("cannot catch Ctrl-C")
}

/// The error of a `--start` past the last frame.
fn no_frame_at_start(input: &Input, start: Option<Start>) -> String {
    let what = input.describe();
    let start = match start {
        Some(Start::Seconds(t)) => format!("{t}s"),
        Some(Start::Frame(k)) => k.to_string(),
        None => String::new(),
    };
    format!("{what}: no frame at or after --start {start}")
}
