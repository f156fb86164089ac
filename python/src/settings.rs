//! The tracker's keyword arguments: `mode`, `modalities`, the code paths
//! (`splatter`, `feature_backend`, `resident`) and the tuning settings of
//! `splattrack track` under the same names (`--kf-search` is
//! `kf_search=`), checked as the command line checks them.

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use splattrack::app::{Tuning, TuningError};
use splattrack::tracker::{Modalities, Mode, TrackerConfig};

/// The tracker's settings from its keyword arguments, and the mode asked
/// for (`None`: chosen by [`splattrack::app::run_mode`]).
pub struct Settings {
    pub config: TrackerConfig,
    pub mode: Option<Mode>,
}

fn value_error(name: &str, e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("{name}: {e}"))
}

fn parsed<T: std::str::FromStr>(name: &str, v: &Bound<'_, PyAny>) -> PyResult<T>
where
    T::Err: std::fmt::Display,
{
    let s: String = v
        .extract()
        .map_err(|_| PyTypeError::new_err(format!("{name} must be a string")))?;
    s.parse().map_err(|e| value_error(name, e))
}

fn number<'py, T>(name: &str, v: &Bound<'py, PyAny>) -> PyResult<Option<T>>
where
    T: for<'a> FromPyObject<'a, 'py>,
{
    if v.is_none() {
        return Ok(None);
    }
    v.extract().map(Some).map_err(|_| {
        PyTypeError::new_err(format!(
            "{name} must be a number of the right kind (a non-negative int where counts are asked), not {v}"
        ))
    })
}

/// Parses `mode`, `modalities` and the other keyword arguments.
pub fn parse(
    mode: Option<&str>,
    modalities: &str,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<Settings> {
    let mode: Option<Mode> = match mode {
        None => None,
        Some(m) => Some(m.parse().map_err(|e| value_error("mode", e))?),
    };
    let (modalities, auto_modalities) = if modalities.trim().eq_ignore_ascii_case("auto") {
        (Modalities::default(), true)
    } else {
        let m: Modalities = modalities
            .parse()
            .map_err(|e: String| value_error("modalities", e.replace("(use ", "(use auto, ")))?;
        (m, false)
    };
    let mut t = Tuning::default();
    let mut config = TrackerConfig::default();
    for (k, v) in kwargs.into_iter().flat_map(|d| d.iter()) {
        let name: String = k.extract()?;
        let n = name.as_str();
        match n {
            "splatter" => config.splatter = parsed(n, &v)?,
            "feature_backend" => config.feature_backend = parsed(n, &v)?,
            "resident" => {
                config.resident = if v.is_none() {
                    None
                } else if let Ok(b) = v.extract::<bool>() {
                    Some(b)
                } else {
                    match parsed::<String>(n, &v)?.to_ascii_lowercase().as_str() {
                        "auto" => None,
                        "on" => Some(true),
                        "off" => Some(false),
                        s => return Err(value_error(n, format!("{s:?} (use auto, on, off)"))),
                    }
                }
            }
            "harris_threshold" => t.harris_threshold = number(n, &v)?,
            "max_corners" => t.max_corners = number(n, &v)?,
            "min_score" => t.min_score = number(n, &v)?,
            "ncc_window" => t.ncc_window = number(n, &v)?,
            "it_search" => t.it_search = number(n, &v)?,
            "kf_search" => t.kf_search = number(n, &v)?,
            "recover_search" => t.recover_search = number(n, &v)?,
            "kf_iterations" => t.kf_iterations = number(n, &v)?,
            "refine_iterations" => t.refine_iterations = number(n, &v)?,
            "roi_margin" => t.roi_margin = number(n, &v)?,
            "min_inliers" => t.min_inliers = number(n, &v)?,
            "max_residual" => t.max_residual = number(n, &v)?,
            "min_splat_px" => t.min_splat_px = number(n, &v)?,
            "detail_px" => t.detail_px = number(n, &v)?,
            "keep_radii" => t.keep_radii = v.is_truthy()?,
            "min_valid" => t.min_valid = number(n, &v)?,
            "max_it_only" => t.max_it_only = number(n, &v)?,
            "it_interior" => t.it_interior = number(n, &v)?,
            "contour_rounds" => t.contour_rounds = number(n, &v)?,
            "contour_converged" => t.contour_converged = number(n, &v)?,
            "contour_spacing" => t.contour_spacing = number(n, &v)?,
            "contour_damping" => t.contour_damping = number(n, &v)?,
            "contour_full_render" => t.contour_full_render = v.is_truthy()?,
            "contour_reproject" => t.contour_reproject = number(n, &v)?,
            "contour_sectors" => t.contour_sectors = number(n, &v)?,
            "contour_no_seed" => t.contour_no_seed = v.is_truthy()?,
            "full_frame" => t.full_frame = v.is_truthy()?,
            _ => {
                return Err(PyTypeError::new_err(format!(
                    "Tracker() got an unexpected keyword argument {n:?}"
                )));
            }
        }
    }
    let tuned = t.apply(TrackerConfig::default()).map_err(|e| match e {
        // The command line's message, with the argument's name.
        TuningError::OutOfRange {
            setting,
            value,
            rule,
        } => PyValueError::new_err(format!(
            "{}={value}: must be {rule}",
            setting.replace('-', "_")
        )),
        e => PyValueError::new_err(e.to_string()),
    })?;
    config = TrackerConfig {
        mode: mode.unwrap_or_default(),
        modalities,
        auto_modalities,
        splatter: config.splatter,
        feature_backend: config.feature_backend,
        resident: config.resident,
        ..tuned
    };
    Ok(Settings { config, mode })
}
