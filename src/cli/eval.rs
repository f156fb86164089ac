//! `splattrack eval --poses poses.csv --gt gt.csv [--model [NAME=]M.ply]...
//! [--plot errors.png]`: files of one object, or of several (the object
//! column), each object's figures apart.

use anyhow::{Context, bail};
use splattrack::eval::{self, EvalOptions, frame_key};
use std::collections::HashSet;
use std::io::Write;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Tracked poses (tracker output or any pose CSV); repeat to compare
    /// several runs in one table and one plot.
    #[arg(long, required = true)]
    pub poses: Vec<PathBuf>,
    /// Ground-truth poses.
    #[arg(long)]
    pub gt: PathBuf,
    /// The model, for its diameter (errors in % of it, the 2deg/2% rate).
    /// Files of several objects: once per object, NAME=PATH or PATH (named
    /// by the file's stem), matched to the object column by name.
    #[arg(long, value_name = "[NAME=]PATH")]
    pub model: Vec<String>,
    /// The model's diameter in model units, instead of --model.
    #[arg(long, conflicts_with = "model")]
    pub diameter: Option<f64>,
    /// Names for the runs, in --poses order (default: the file stems).
    #[arg(long, value_delimiter = ',')]
    pub names: Vec<String>,
    /// Model units per metre, for the 5 cm threshold (1 for metres, 1000 for mm).
    #[arg(long, default_value_t = 1.0)]
    pub units_per_metre: f64,
    /// A CSV with `frame` and `gt_ok` columns (as the real data sets have):
    /// frames with gt_ok = 0 are left out of the statistics.
    #[arg(long)]
    pub gt_quality: Option<PathBuf>,
    /// Write the error curves here (PNG).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write per-frame errors here (CSV).
    #[arg(long)]
    pub csv: Option<PathBuf>,
}

/// Frame keys whose `gt_ok` column is 0.
fn excluded_frames(path: &Path) -> anyhow::Result<HashSet<String>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .with_context(|| format!("{}: empty file", path.display()))?
        .split(',')
        .map(str::trim)
        .collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|c| *c == name)
            .with_context(|| format!("{}: no {name:?} column", path.display()))
    };
    let (fc, oc) = (col("frame")?, col("gt_ok")?);
    let mut out = HashSet::new();
    for (i, line) in lines.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let (Some(frame), Some(ok)) = (f.get(fc), f.get(oc)) else {
            bail!("{}, line {}: too few fields", path.display(), i + 2);
        };
        if ok.parse::<f64>().ok() == Some(0.0) {
            out.insert(frame_key(frame));
        }
    }
    Ok(out)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // Outputs never overwrite inputs.
    let models = args
        .model
        .iter()
        .map(|m| super::common::named_path("--model", m))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut inputs: Vec<&Path> = args.poses.iter().map(PathBuf::as_path).collect();
    inputs.push(&args.gt);
    inputs.extend(models.iter().map(|(_, p)| p.as_path()));
    inputs.extend(args.gt_quality.as_deref());
    for (out, flag) in [(&args.plot, "--plot"), (&args.csv, "--csv")] {
        if let Some(out) = out {
            splattrack::io::guard::check_output(out, flag, &inputs)?;
        }
    }
    let gt = splattrack::io::read_poses(&args.gt)?;
    let objects = gt.iter().any(|r| r.object.is_some());
    if !models.is_empty() && args.diameter.is_some() {
        bail!("give --model or --diameter, not both");
    }
    let diameter = match (models.as_slice(), args.diameter) {
        ([(_, m)], _) if !objects => Some(super::common::load_model(m)?.diameter() as f64),
        ([_, _, ..], _) if !objects => bail!(
            "--model is given {} times, and {} holds one object's poses: give it once",
            models.len(),
            args.gt.display()
        ),
        (_, Some(d)) if d.is_finite() && d > 0.0 => Some(d),
        (_, Some(d)) => bail!("--diameter {d}: must be a positive number"),
        _ => None,
    };
    let mut object_diameters = std::collections::HashMap::new();
    if objects {
        for (name, m) in &models {
            if !gt.iter().any(|r| r.object.as_deref() == Some(name)) {
                bail!(
                    "--model {}: no object {name:?} in {} (name the model's object with --model NAME=PATH)",
                    m.display(),
                    args.gt.display()
                );
            }
            let d = super::common::load_model(m)?.diameter() as f64;
            object_diameters.insert(name.clone(), d);
        }
    }
    if !(args.units_per_metre.is_finite() && args.units_per_metre > 0.0) {
        bail!(
            "--units-per-metre {}: must be a positive number",
            args.units_per_metre
        );
    }
    if !args.names.is_empty() && args.names.len() != args.poses.len() {
        bail!(
            "--names gives {} names for {} --poses files",
            args.names.len(),
            args.poses.len()
        );
    }
    let opts = EvalOptions {
        diameter,
        units_per_metre: args.units_per_metre,
        exclude: match &args.gt_quality {
            Some(p) => excluded_frames(p)?,
            None => HashSet::new(),
        },
        object_diameters,
    };
    let mut evals = Vec::new();
    for (i, p) in args.poses.iter().enumerate() {
        let est = splattrack::io::read_poses(p)?;
        let name = args.names.get(i).cloned().unwrap_or_else(|| {
            p.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| format!("run{i}"))
        });
        let per_object = eval::evaluate_objects(&name, &est, &gt, &opts)
            .with_context(|| format!("{} against {}", p.display(), args.gt.display()))?;
        for (object, mut e) in per_object {
            if let Some(object) = object {
                if !models.is_empty() && !opts.object_diameters.contains_key(&object) {
                    bail!(
                        "{}: object {object:?} has no --model (give --model {object}=PATH for each object, or none)",
                        p.display()
                    );
                }
                // One file: the objects' names alone.
                if args.poses.len() == 1 {
                    e.summary.name = object;
                }
            }
            evals.push(e);
        }
    }
    let summaries: Vec<_> = evals.iter().map(|e| e.summary.clone()).collect();
    print!("{}", eval::table(&summaries, "units"));
    print!("{}", eval::ray_table(&summaries, "units"));
    if !opts.exclude.is_empty() {
        println!(
            "({} frames with gt_ok = 0 left out of the statistics)",
            summaries[0].excluded
        );
    }
    if let Some(path) = &args.plot {
        let title = args
            .gt
            .parent()
            .and_then(|d| d.file_name())
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        eval::error_plot(&evals, &title)
            .save(path)
            .with_context(|| format!("{}: cannot write the plot", path.display()))?;
        println!("plot: {}", path.display());
    }
    if let Some(path) = &args.csv {
        let mut s = String::from(
            "run,frame,rotation_deg,translation,translation_pct,lost,excluded,along_ray,across_ray\n",
        );
        for e in &evals {
            for f in &e.frames {
                s.push_str(&format!(
                    "{},{},{:.6},{:.7},{},{},{},{:.7},{:.7}\n",
                    e.summary.name,
                    f.frame,
                    f.rotation_deg,
                    f.translation,
                    f.translation_pct
                        .map_or(String::new(), |v| format!("{v:.4}")),
                    f.lost as u8,
                    f.excluded as u8,
                    f.along_ray,
                    f.across_ray
                ));
            }
        }
        splattrack::io::write_atomic(path, |w| w.write_all(s.as_bytes()))
            .with_context(|| format!("{}: cannot write", path.display()))?;
    }
    Ok(())
}
