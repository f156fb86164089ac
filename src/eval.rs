//! Accuracy of tracked poses against ground truth (docs/accuracy.md):
//! per-frame rotation and translation errors, their summary, success rates
//! and plots.

#![warn(missing_docs)]

use crate::io::PoseRow;
use crate::plot::LineChart;
use std::collections::{HashMap, HashSet};

/// Errors of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameError {
    /// The frame label as in the ground-truth file.
    pub frame: String,
    /// Angle of `R_gt^T R`, degrees.
    pub rotation_deg: f64,
    /// Distance between translations, model units.
    pub translation: f64,
    /// `translation` as a percentage of the model's diameter.
    pub translation_pct: Option<f64>,
    /// The translation error's part along the viewing ray to the true
    /// position (the camera-frame ground truth's translation), model units:
    /// negative when the estimate is nearer the camera.
    pub along_ray: f64,
    /// The length of its part across that ray, model units.
    pub across_ray: f64,
    /// The tracker reported this frame `lost`.
    pub lost: bool,
    /// Left out of the statistics (e.g. unreliable ground truth).
    pub excluded: bool,
}

/// Summary statistics over the evaluated (not excluded) frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// The run's name (the file stem by default).
    pub name: String,
    /// Ground-truth frames evaluated.
    pub frames: usize,
    /// Ground-truth frames with no estimate at all (count as failures).
    pub missing: usize,
    /// Frames left out of the statistics ([`EvalOptions::exclude`]).
    pub excluded: usize,
    /// Evaluated frames the tracker reported `lost` (they count as
    /// failures).
    pub lost: usize,
    /// Mean rotation error, degrees.
    pub rotation_mean: f64,
    /// Median rotation error, degrees.
    pub rotation_median: f64,
    /// Largest rotation error, degrees.
    pub rotation_max: f64,
    /// Mean translation error, model units.
    pub translation_mean: f64,
    /// Median translation error, model units.
    pub translation_median: f64,
    /// Largest translation error, model units.
    pub translation_max: f64,
    /// Mean translation error as a percentage of the diameter.
    pub translation_mean_pct: Option<f64>,
    /// Mean of [`FrameError::along_ray`] (signed: negative when the
    /// estimates lie nearer the camera on average), model units.
    pub along_ray_mean: f64,
    /// Mean of [`FrameError::across_ray`], model units.
    pub across_ray_mean: f64,
    /// Fraction of frames within 5 degrees and 5 cm (RBOT), 0..1.
    pub success_5deg_5cm: f64,
    /// Fraction within 2 degrees and 2% of the diameter.
    pub success_2deg_2pct: Option<f64>,
}

/// A whole evaluation: per-frame errors and their summary.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// One entry per ground-truth frame that has an estimate, in
    /// ground-truth order.
    pub frames: Vec<FrameError>,
    /// The statistics over them.
    pub summary: Summary,
}

/// Why an evaluation is impossible.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EvalError {
    /// The estimate and the ground truth share no frame label (after
    /// [`frame_key`] normalisation).
    #[error("no frame of the estimate matches a ground-truth frame (labels differ?)")]
    NoCommonFrames,
    /// A frame label occurs twice in one file (`estimate` or `ground truth`)
    /// for one object.
    #[error("duplicate frame {0:?} in the {1}")]
    Duplicate(String, &'static str),
    /// An object of the estimate has no row in the ground truth.
    #[error("object {0:?} of the estimate is not in the ground truth")]
    UnknownObject(String),
    /// One file names its rows' objects (the `object` column) and the
    /// other does not, and the objects cannot be told apart.
    #[error("the {0} has no object column, the {1} names several objects")]
    NoObjectColumn(&'static str, &'static str),
}

/// Normalises a frame label so that `000043`, `43` and `000043.png` agree.
pub fn frame_key(label: &str) -> String {
    let stem = std::path::Path::new(label)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or(label);
    match stem.parse::<u64>() {
        Ok(n) => n.to_string(),
        Err(_) => stem.to_owned(),
    }
}

fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// Settings of [`evaluate`].
#[derive(Debug, Clone)]
pub struct EvalOptions {
    /// Bounding diameter of the model (model units), for the % figures.
    pub diameter: Option<f64>,
    /// Model units per metre (1 for metre-scale models), for the 5 cm test.
    pub units_per_metre: f64,
    /// Frame keys (see [`frame_key`]) left out of the statistics.
    pub exclude: HashSet<String>,
    /// Each object's diameter by name, in place of `diameter`
    /// ([`evaluate_objects`]).
    pub object_diameters: HashMap<String, f64>,
}

impl Default for EvalOptions {
    fn default() -> Self {
        Self {
            diameter: None,
            units_per_metre: 1.0,
            exclude: HashSet::new(),
            object_diameters: HashMap::new(),
        }
    }
}

/// Compares `estimate` with `gt` frame by frame. Frames of `gt` without an
/// estimate count as failures; a row whose `status` column says `lost`
/// counts as lost and as a failure, whatever its pose.
pub fn evaluate(
    name: &str,
    estimate: &[PoseRow],
    gt: &[PoseRow],
    opts: &EvalOptions,
) -> Result<Evaluation, EvalError> {
    let mut est: HashMap<String, &PoseRow> = HashMap::new();
    for r in estimate {
        if est.insert(frame_key(&r.frame), r).is_some() {
            return Err(EvalError::Duplicate(r.frame.clone(), "estimate"));
        }
    }
    let mut seen = HashSet::new();
    let mut frames = Vec::new();
    let mut missing = 0;
    for g in gt {
        let key = frame_key(&g.frame);
        if !seen.insert(key.clone()) {
            return Err(EvalError::Duplicate(g.frame.clone(), "ground truth"));
        }
        let Some(e) = est.get(&key) else {
            if !opts.exclude.contains(&key) {
                missing += 1;
            }
            continue;
        };
        let t = e.pose.translation_error(&g.pose);
        let (along_ray, across_ray) = along_and_across(&e.pose, &g.pose);
        frames.push(FrameError {
            frame: g.frame.clone(),
            rotation_deg: e.pose.rotation_error_deg(&g.pose),
            translation: t,
            translation_pct: opts.diameter.map(|d| 100.0 * t / d),
            along_ray,
            across_ray,
            lost: e
                .extra
                .iter()
                .any(|(k, v)| k == "status" && v.trim() == "lost"),
            excluded: opts.exclude.contains(&key),
        });
    }
    if frames.is_empty() {
        return Err(EvalError::NoCommonFrames);
    }
    let used: Vec<&FrameError> = frames.iter().filter(|f| !f.excluded).collect();
    let n = used.len() + missing;
    let rot: Vec<f64> = used.iter().map(|f| f.rotation_deg).collect();
    let tr: Vec<f64> = used.iter().map(|f| f.translation).collect();
    let mean = |v: &[f64]| {
        if v.is_empty() {
            f64::NAN
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    let max = |v: &[f64]| v.iter().copied().fold(f64::NAN, f64::max);
    let rate = |ok: &dyn Fn(&FrameError) -> bool| {
        if n == 0 {
            f64::NAN
        } else {
            used.iter().filter(|f| !f.lost && ok(f)).count() as f64 / n as f64
        }
    };
    let five_cm = 0.05 * opts.units_per_metre;
    let summary = Summary {
        name: name.to_owned(),
        frames: n,
        missing,
        excluded: frames.iter().filter(|f| f.excluded).count(),
        lost: used.iter().filter(|f| f.lost).count(),
        rotation_mean: mean(&rot),
        rotation_median: median(&rot),
        rotation_max: max(&rot),
        translation_mean: mean(&tr),
        translation_median: median(&tr),
        translation_max: max(&tr),
        translation_mean_pct: opts.diameter.map(|d| 100.0 * mean(&tr) / d),
        along_ray_mean: mean(&used.iter().map(|f| f.along_ray).collect::<Vec<_>>()),
        across_ray_mean: mean(&used.iter().map(|f| f.across_ray).collect::<Vec<_>>()),
        success_5deg_5cm: rate(&|f| f.rotation_deg < 5.0 && f.translation < five_cm),
        success_2deg_2pct: opts
            .diameter
            .map(|d| rate(&|f| f.rotation_deg < 2.0 && f.translation < 0.02 * d)),
    };
    Ok(Evaluation { frames, summary })
}

/// [`evaluate`] object by object, for pose files with an `object` column
/// (several objects' rows): each object of `estimate`, in the order it
/// first appears, against the ground-truth rows of the same name, matched
/// by (object, frame); its [`Summary::name`] is `name`, a space and the
/// object's name; its diameter is [`EvalOptions::object_diameters`]'
/// entry, else [`EvalOptions::diameter`]. Files without the column give one evaluation named
/// `name`, as [`evaluate`]; an estimate without it against a ground truth
/// of one object is that object's. An estimate's object missing from the
/// ground truth is refused ([`EvalError::UnknownObject`]).
pub fn evaluate_objects(
    name: &str,
    estimate: &[PoseRow],
    gt: &[PoseRow],
    opts: &EvalOptions,
) -> Result<Vec<(Option<String>, Evaluation)>, EvalError> {
    let est_objects = objects_of(estimate);
    let gt_objects = objects_of(gt);
    match (est_objects.is_empty(), gt_objects.is_empty()) {
        (true, true) => return Ok(vec![(None, evaluate(name, estimate, gt, opts)?)]),
        (true, false) if gt_objects.len() == 1 => {
            return Ok(vec![(None, evaluate(name, estimate, gt, opts)?)]);
        }
        (true, false) => return Err(EvalError::NoObjectColumn("estimate", "ground truth")),
        (false, true) if est_objects.len() == 1 => {
            return Ok(vec![(
                Some(est_objects[0].to_owned()),
                evaluate(name, estimate, gt, opts)?,
            )]);
        }
        (false, true) => return Err(EvalError::NoObjectColumn("ground truth", "estimate")),
        (false, false) => {}
    }
    let rows_of = |rows: &[PoseRow], object: &str| -> Vec<PoseRow> {
        rows.iter()
            .filter(|r| r.object.as_deref() == Some(object))
            .cloned()
            .collect()
    };
    let mut out = Vec::with_capacity(est_objects.len());
    for object in est_objects {
        let truth = rows_of(gt, object);
        if truth.is_empty() {
            return Err(EvalError::UnknownObject(object.to_owned()));
        }
        let own = EvalOptions {
            diameter: opts.object_diameters.get(object).copied().or(opts.diameter),
            ..opts.clone()
        };
        let e = evaluate(
            &format!("{name} {object}"),
            &rows_of(estimate, object),
            &truth,
            &own,
        )?;
        out.push((Some(object.to_owned()), e));
    }
    Ok(out)
}

/// The objects the rows name, in the order they first appear.
fn objects_of(rows: &[PoseRow]) -> Vec<&str> {
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if let Some(o) = r.object.as_deref()
            && !names.contains(&o)
        {
            names.push(o);
        }
    }
    names
}

/// The translation error of `estimate` against `truth` split along the
/// viewing ray to the true position (signed, negative: nearer the camera)
/// and across it (its length). Camera-frame poses (object to camera).
pub fn along_and_across(
    estimate: &crate::geometry::Pose,
    truth: &crate::geometry::Pose,
) -> (f64, f64) {
    let d = estimate.translation - truth.translation;
    let Some(ray) = truth.translation.try_normalize(1e-12) else {
        return (0.0, d.norm());
    };
    let along = d.dot(&ray);
    (along, (d - ray * along).norm())
}

/// The translation errors along and across the viewing ray, one row per
/// evaluation, as printed by `eval` below [`table`].
pub fn ray_table(summaries: &[Summary], unit: &str) -> String {
    let mut s = format!(
        "{:<16} {:>16} {:>17}\n",
        "run",
        format!("along ray {unit}"),
        format!("across ray {unit}")
    );
    for m in summaries {
        s.push_str(&format!(
            "{:<16} {:>+16.5} {:>17.5}\n",
            m.name, m.along_ray_mean, m.across_ray_mean
        ));
    }
    s
}

/// The summary table (one row per evaluation), as printed by `eval`.
pub fn table(summaries: &[Summary], unit: &str) -> String {
    let mut s = format!(
        "{:<16} {:>6} {:>5} {:>9} {:>9} {:>9} {:>11} {:>11} {:>8} {:>9} {:>9}\n",
        "run",
        "frames",
        "lost",
        "rot mean",
        "rot med",
        "rot max",
        format!("tr mean {unit}"),
        format!("tr med {unit}"),
        "tr mean%",
        "5deg/5cm",
        "2deg/2%"
    );
    let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}%"));
    for m in summaries {
        s.push_str(&format!(
            "{:<16} {:>6} {:>5} {:>9.3} {:>9.3} {:>9.3} {:>11.5} {:>11.5} {:>8} {:>8.1}% {:>9}\n",
            m.name,
            m.frames,
            m.lost + m.missing,
            m.rotation_mean,
            m.rotation_median,
            m.rotation_max,
            m.translation_mean,
            m.translation_median,
            pct(m.translation_mean_pct),
            100.0 * m.success_5deg_5cm,
            pct(m.success_2deg_2pct.map(|v| 100.0 * v)),
        ));
    }
    s
}

/// Rotation and translation error curves over the frames, one curve per
/// evaluation (like the paper's Fig. 10).
pub fn error_plot(evals: &[Evaluation], title: &str) -> image::RgbImage {
    let mut rot = LineChart::new(
        &format!("{title}: rotation error"),
        "frame",
        "rotation error (deg)",
    );
    let pct = evals
        .iter()
        .all(|e| e.summary.translation_mean_pct.is_some());
    let mut tr = LineChart::new(
        &format!("{title}: translation error"),
        "frame",
        if pct {
            "translation error (% of diameter)"
        } else {
            "translation error (model units)"
        },
    );
    for e in evals {
        let x = |i: usize, f: &FrameError| {
            f.frame
                .parse::<f64>()
                .or_else(|_| frame_key(&f.frame).parse::<f64>())
                .unwrap_or(i as f64)
        };
        rot.add(
            &e.summary.name,
            e.frames
                .iter()
                .enumerate()
                .map(|(i, f)| (x(i, f), f.rotation_deg))
                .collect(),
        );
        tr.add(
            &e.summary.name,
            e.frames
                .iter()
                .enumerate()
                .map(|(i, f)| {
                    (
                        x(i, f),
                        if pct {
                            f.translation_pct.unwrap_or(f64::NAN)
                        } else {
                            f.translation
                        },
                    )
                })
                .collect(),
        );
    }
    crate::plot::stack(&[rot, tr], 900, 330)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Pose, rotation_exp};
    use nalgebra::Vector3;

    fn row(frame: &str, deg: f64, t: f64, status: Option<&str>) -> PoseRow {
        let mut r = PoseRow::new(
            frame,
            Pose::new(
                rotation_exp(&Vector3::new(0.0, deg.to_radians(), 0.0)),
                Vector3::new(t, 0.0, 0.5),
            )
            .unwrap(),
        );
        if let Some(s) = status {
            r.extra.push(("status".into(), s.into()));
        }
        r
    }

    #[test]
    fn objects_are_matched_by_name_and_frame() {
        let of = |o: &str, f: &str, deg: f64| row(f, deg, 0.0, None).of_object(o);
        let gt = vec![
            of("a", "0", 0.0),
            of("b", "0", 0.0),
            of("a", "1", 0.0),
            of("b", "1", 0.0),
        ];
        // b's rows first, a's frame 1 missing: each object its own figures.
        let est = vec![of("b", "0", 2.0), of("a", "0", 1.0), of("b", "1", 4.0)];
        let out = evaluate_objects("run", &est, &gt, &EvalOptions::default()).unwrap();
        let names: Vec<_> = out.iter().map(|(o, _)| o.as_deref().unwrap()).collect();
        assert_eq!(names, ["b", "a"]);
        let (b, a) = (&out[0].1.summary, &out[1].1.summary);
        assert_eq!((b.name.as_str(), b.frames, b.missing), ("run b", 2, 0));
        assert!((b.rotation_mean - 3.0).abs() < 1e-9);
        assert_eq!((a.frames, a.missing), (2, 1));
        assert!((a.rotation_mean - 1.0).abs() < 1e-9);
        // An object the ground truth lacks, or files that cannot be told
        // apart, are refused naming why.
        let e = evaluate_objects("run", &[of("c", "0", 0.0)], &gt, &EvalOptions::default());
        assert_eq!(e.unwrap_err(), EvalError::UnknownObject("c".into()));
        let plain = vec![row("0", 0.0, 0.0, None)];
        let e = evaluate_objects("run", &plain, &gt, &EvalOptions::default()).unwrap_err();
        assert!(
            e.to_string().contains("estimate has no object column"),
            "{e}"
        );
        // Plain files: one evaluation, as evaluate gives.
        let one = evaluate_objects("run", &plain, &plain, &EvalOptions::default()).unwrap();
        assert_eq!(one.len(), 1);
        assert_eq!(
            (one[0].0.as_deref(), one[0].1.summary.name.as_str()),
            (None, "run")
        );
    }

    #[test]
    fn errors_and_rates_are_what_was_put_in() {
        let gt: Vec<PoseRow> = (0..4)
            .map(|i| row(&format!("{i:06}"), 0.0, 0.0, None))
            .collect();
        let est = vec![
            row("0", 1.0, 0.01, Some("tracking")),
            row("1", 3.0, 0.0, Some("tracking")),
            row("2.png", 10.0, 0.0, Some("tracking")),
            // frame 3 missing
        ];
        let opts = EvalOptions {
            diameter: Some(0.2),
            ..Default::default()
        };
        let e = evaluate("t", &est, &gt, &opts).unwrap();
        let s = &e.summary;
        assert_eq!((s.frames, s.missing, s.lost), (4, 1, 0));
        assert!((e.frames[0].rotation_deg - 1.0).abs() < 1e-9);
        assert!((e.frames[0].translation_pct.unwrap() - 5.0).abs() < 1e-9);
        assert!((s.rotation_mean - 14.0 / 3.0).abs() < 1e-9);
        assert!((s.rotation_median - 3.0).abs() < 1e-9);
        // 5deg/5cm: frames 0 and 1 of 4. 2deg/2% (4 mm): none (frame 0 is 1 cm off).
        assert!((s.success_5deg_5cm - 0.5).abs() < 1e-12);
        assert_eq!(s.success_2deg_2pct, Some(0.0));
        let table = table(std::slice::from_ref(s), "m");
        assert!(table.contains("50.0%"), "{table}");
    }

    #[test]
    fn translation_errors_split_along_and_across_the_ray() {
        let pose = |t: Vector3<f64>| Pose::new(rotation_exp(&Vector3::zeros()), t).unwrap();
        // The truth 0.5 m away along (3, 0, 4) / 5; the estimate 2 mm
        // nearer along the ray and 1 mm across it (along y).
        let ray = Vector3::new(0.3, 0.0, 0.4);
        let truth = pose(ray);
        let est = pose(ray - ray.normalize() * 0.002 + Vector3::new(0.0, 0.001, 0.0));
        let (along, across) = along_and_across(&est, &truth);
        assert!((along + 0.002).abs() < 1e-12, "{along}");
        assert!((across - 0.001).abs() < 1e-12, "{across}");
        let gt = vec![PoseRow::new("0", truth)];
        let e = evaluate("t", &[PoseRow::new("0", est)], &gt, &EvalOptions::default()).unwrap();
        assert!((e.summary.along_ray_mean + 0.002).abs() < 1e-12);
        assert!((e.summary.across_ray_mean - 0.001).abs() < 1e-12);
        let t = ray_table(std::slice::from_ref(&e.summary), "m");
        assert!(t.contains("-0.00200") && t.contains("0.00100"), "{t}");
    }

    #[test]
    fn lost_frames_fail_and_excluded_frames_are_left_out() {
        let gt: Vec<PoseRow> = (0..3)
            .map(|i| row(&i.to_string(), 0.0, 0.0, None))
            .collect();
        let est = vec![
            row("0", 0.0, 0.0, Some("lost")),
            row("1", 0.0, 0.0, Some("tracking")),
            row("2", 90.0, 0.0, Some("tracking")),
        ];
        let opts = EvalOptions {
            exclude: ["2".to_string()].into(),
            ..Default::default()
        };
        let s = evaluate("t", &est, &gt, &opts).unwrap().summary;
        assert_eq!((s.frames, s.lost, s.excluded), (2, 1, 1));
        assert!((s.success_5deg_5cm - 0.5).abs() < 1e-12);
        assert!(
            s.rotation_max < 1e-6,
            "excluded frame leaked: {}",
            s.rotation_max
        );
    }

    #[test]
    fn mismatched_files_are_errors() {
        let gt = vec![row("0", 0.0, 0.0, None)];
        assert_eq!(
            evaluate(
                "t",
                &[row("7", 0.0, 0.0, None)],
                &gt,
                &EvalOptions::default()
            )
            .unwrap_err(),
            EvalError::NoCommonFrames
        );
        let dup = vec![row("0", 0.0, 0.0, None), row("000", 0.0, 0.0, None)];
        assert!(matches!(
            evaluate("t", &dup, &gt, &EvalOptions::default()),
            Err(EvalError::Duplicate(..))
        ));
    }
}
