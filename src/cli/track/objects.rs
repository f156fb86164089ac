//! Which objects `splattrack track` follows: the `--model` flags (or the
//! sequence's `objects/NAME/model.ply`), each object's name, and its
//! keyframes, cues and first pose from the per-model flags, given once
//! for all or once per model in the `--model` order.

use super::args::{Args, Cues};
use super::input::Input;
use crate::cli::common::model_options;
use anyhow::{Context, bail};
use splattrack::app::{ObjectInputs, TrackInputs};
use splattrack::geometry::Pose;
use splattrack::io::read_poses;
use std::path::{Path, PathBuf};

/// One object of the run, as the flags name it.
#[derive(Debug, Clone)]
pub struct Object {
    /// Its name: the NAME of `--model NAME=PATH`, else the file's stem.
    pub name: String,
    pub model: PathBuf,
    /// Its keyframes, given or found (`None`: the sequence's default for
    /// one model, none for several).
    pub keyframes: Option<PathBuf>,
    pub cues: Cues,
    /// The pose file of its first pose (given, or the sequence's
    /// init.csv), and whether it is shared by several models (its rows
    /// then found by the object column).
    pub init: Option<(PathBuf, bool)>,
}

/// The models of the run: the `--model` flags, else with `--sequence
/// DIR` every `DIR/objects/NAME/model.ply`, sorted by name.
fn models(args: &Args) -> anyhow::Result<Vec<(String, PathBuf)>> {
    if !args.model.is_empty() {
        return args
            .model
            .iter()
            .map(|m| crate::cli::common::named_path("--model", m))
            .collect();
    }
    let found = match &args.sequence {
        Some(dir) => sequence_objects(dir)?,
        None => Vec::new(),
    };
    if found.is_empty() {
        bail!(
            "no model: give --model PATH (once per object), or a --sequence with objects/NAME/model.ply"
        );
    }
    Ok(found)
}

/// `DIR/objects/NAME/model.ply`, sorted by name.
fn sequence_objects(dir: &Path) -> anyhow::Result<Vec<(String, PathBuf)>> {
    let objects = dir.join("objects");
    if !objects.is_dir() {
        return Ok(Vec::new());
    }
    let entries = std::fs::read_dir(&objects)
        .with_context(|| format!("{}: cannot list", objects.display()))?;
    let mut found = Vec::new();
    for e in entries {
        let e = e.with_context(|| format!("{}: cannot list", objects.display()))?;
        let model = e.path().join("model.ply");
        if model.is_file() {
            found.push((e.file_name().to_string_lossy().into_owned(), model));
        }
    }
    found.sort();
    Ok(found)
}

/// A per-model flag given `given` times for `n` models: once (for all),
/// once per model, or not at all.
fn per_model<T: Clone>(
    flag: &str,
    values: &[T],
    n: usize,
    once: bool,
) -> anyhow::Result<Vec<Option<T>>> {
    match values.len() {
        0 => Ok(vec![None; n]),
        1 if once || n == 1 => Ok(vec![Some(values[0].clone()); n]),
        k if k == n => Ok(values.iter().cloned().map(Some).collect()),
        k => {
            let how = if once {
                "once, or once per --model"
            } else {
                "once per --model"
            };
            bail!("{flag} is given {k} times for {n} models: give it {how}, in the --model order")
        }
    }
}

/// The objects the flags name, checked: names unique, the per-model
/// flags' counts right, and what cannot apply to several objects refused.
pub fn of(args: &Args) -> anyhow::Result<Vec<Object>> {
    let models = models(args)?;
    let n = models.len();
    for (k, (name, path)) in models.iter().enumerate() {
        if let Some((_, other)) = models[..k].iter().find(|(m, _)| m == name) {
            bail!(
                "two objects are named {name:?} ({} and {}): name them apart with --model NAME=PATH",
                other.display(),
                path.display()
            );
        }
    }
    if n > 1 && args.obj_id.is_some() {
        bail!(
            "--obj-id names one object's BOP id: with several models each object's id comes from its name (obj_000005 -> 5) or its position"
        );
    }
    let keyframes = per_model("--keyframes", &args.keyframes, n, false)?;
    let cues = per_model("--modalities", &args.modalities, n, true)?;
    let inits = per_model("--init", &args.init, n, true)?;
    let shared_init = args.init.len() == 1 && n > 1;
    let seq_init = args
        .sequence
        .as_ref()
        .map(|d| d.join("init.csv"))
        .filter(|p| p.is_file());
    Ok(models
        .into_iter()
        .zip(keyframes)
        .zip(cues)
        .zip(inits)
        .map(|((((name, model), kf), cues), init)| {
            let own_kf = args
                .sequence
                .as_ref()
                .map(|d| d.join("objects").join(&name).join("keyframes"))
                .filter(|p| p.join("poses.csv").is_file());
            let init = match init {
                Some(p) => Some((p, shared_init)),
                None => seq_init.clone().map(|p| (p, n > 1)),
            };
            Object {
                keyframes: kf.or(own_kf),
                cues: cues.unwrap_or(Cues::Auto),
                init,
                name,
                model,
            }
        })
        .collect())
}

/// Object `name`'s first pose in `path`: in a file with an object
/// column its first row; in a plain file the first row, unless the file
/// is `shared` by several models.
pub fn init_pose(path: &Path, name: &str, shared: bool) -> anyhow::Result<Pose> {
    let rows = read_poses(path)?;
    if rows[0].object.is_none() {
        if shared {
            bail!(
                "{}: no object column, so no pose for each of several models: give --init once per --model, or a file with an object column",
                path.display()
            );
        }
        return Ok(rows[0].pose);
    }
    if let Some(r) = rows.iter().find(|r| r.object.as_deref() == Some(name)) {
        return Ok(r.pose);
    }
    let mut names: Vec<&str> = rows.iter().filter_map(|r| r.object.as_deref()).collect();
    names.dedup();
    bail!(
        "{}: no row for object {name:?} (its objects: {})",
        path.display(),
        names.join(", ")
    )
}

/// The run's inputs: for one object those of today's single-object run
/// (its first pose found by name in a file with an object column); for
/// several, the camera and frames with each object's model, keyframes
/// and first pose loaded (settings still to set).
pub fn load(
    ctx: &splattrack::Device,
    input: &Input,
    objects: &[Object],
) -> anyhow::Result<(TrackInputs, Option<Vec<ObjectInputs>>)> {
    if let [one] = objects {
        let init = one.init.as_ref().map(|(p, _)| p.as_path());
        let mut inputs = input.load(ctx, &one.model, one.keyframes.as_deref(), init)?;
        if let Some((path, shared)) = &one.init {
            inputs.init = Some(init_pose(path, &one.name, *shared)?);
        }
        return Ok((inputs, None));
    }
    let (sequence, camera, camera_path) = match input {
        Input::Sequence(dir) => {
            let seq = splattrack::io::sequence::Sequence::open(dir)?;
            let (cam, path) = (seq.camera, seq.camera_path.clone());
            (Some(seq), cam, path)
        }
        Input::Video { camera, .. } | Input::Device { camera, .. } => {
            (None, splattrack::Intrinsics::load(camera)?, camera.clone())
        }
    };
    let mut loaded = Vec::with_capacity(objects.len());
    for o in objects {
        let mut obj = ObjectInputs::load(
            ctx,
            &o.name,
            &o.model,
            &model_options(),
            &camera,
            o.keyframes.as_deref(),
        )?;
        if let Some((path, shared)) = &o.init {
            obj.init = Some(init_pose(path, &o.name, *shared)?);
        }
        loaded.push(obj);
    }
    let first = &loaded[0];
    let inputs = TrackInputs {
        model: first.model.clone(),
        sequence,
        camera,
        camera_path,
        init: first.init,
        keyframes: first.keyframes.clone(),
    };
    Ok((inputs, Some(loaded)))
}
