//! What the subcommands share: the logger, the parser of enumerated
//! flags, the GPU context of `--adapter` and model loading with progress
//! bars.

use super::progress;
use clap::ValueEnum;
use clap::builder::{PossibleValue, TypedValueParser};
use splattrack::PointModel;
use splattrack::gpu::{AdapterChoice, GpuContext};
use splattrack::model::LoadOptions;
use splattrack::{Device, DeviceChoice};
use std::io::Write;
use std::marker::PhantomData;

/// The logger: `RUST_LOG` when set (env_logger's syntax), else warnings
/// from this crate and errors from others, `-v` this crate's info, `-vv`
/// debug from every crate (wgpu and naga included). One line a message:
/// `level: message`, other crates' messages naming their module.
pub fn init_logging(verbose: u8) {
    let filters = match std::env::var("RUST_LOG") {
        Ok(s) if !s.trim().is_empty() => s,
        _ => match verbose {
            0 => "error,splattrack=warn",
            1 => "error,splattrack=info",
            _ => "debug",
        }
        .to_string(),
    };
    env_logger::Builder::new()
        .parse_filters(&filters)
        .format(|f, r| {
            let level = r.level().as_str().to_ascii_lowercase();
            if r.target().starts_with("splattrack") {
                writeln!(f, "{level}: {}", r.args())
            } else {
                writeln!(f, "{level}: {}: {}", r.target(), r.args())
            }
        })
        .target(env_logger::Target::Stderr)
        .init();
}

/// A parser for an enumerated flag ([`ValueEnum`]: its values listed in
/// `--help`) that refuses a bad value in one line naming it and the
/// choices: `unknown NOUN "x" (use a, b, c)`.
pub struct Choice<E> {
    noun: &'static str,
    values: PhantomData<fn() -> E>,
}

impl<E> Choice<E> {
    pub fn new(noun: &'static str) -> Self {
        Self {
            noun,
            values: PhantomData,
        }
    }
}

impl<E> Clone for Choice<E> {
    fn clone(&self) -> Self {
        Self::new(self.noun)
    }
}

impl<E: ValueEnum + Clone + Send + Sync + 'static> TypedValueParser for Choice<E> {
    type Value = E;

    fn parse_ref(
        &self,
        _cmd: &clap::Command,
        _arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<E, clap::Error> {
        let s = value.to_string_lossy();
        E::from_str(&s, false).map_err(|_| {
            let names: Vec<String> = E::value_variants()
                .iter()
                .filter_map(|v| v.to_possible_value())
                .map(|p| p.get_name().to_owned())
                .collect();
            clap::Error::raw(
                clap::error::ErrorKind::InvalidValue,
                format!("unknown {} {s:?} (use {})\n", self.noun, names.join(", ")),
            )
        })
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(
            E::value_variants()
                .iter()
                .filter_map(ValueEnum::to_possible_value),
        ))
    }
}

/// The name a [`ValueEnum`] value has on the command line.
pub fn choice_name<E: ValueEnum>(v: &E) -> String {
    v.to_possible_value()
        .map(|p| p.get_name().to_owned())
        .unwrap_or_default()
}

/// Where the commands run: `--compute` (the device: auto, gpu or cpu)
/// and `--adapter` (the GPU adapter), each else from the environment.
#[derive(Debug, Clone, Default)]
pub struct Target {
    pub adapter: Option<String>,
    pub compute: Option<String>,
}

impl Target {
    fn adapter(&self) -> anyhow::Result<AdapterChoice> {
        Ok(match &self.adapter {
            Some(a) => a.parse()?,
            None => AdapterChoice::from_env()?,
        })
    }

    fn choice(&self) -> anyhow::Result<DeviceChoice> {
        Ok(match &self.compute {
            Some(c) => c.parse()?,
            None => DeviceChoice::from_env()?,
        })
    }
}

/// The device of `--compute` and `--adapter`: auto takes a GPU adapter
/// when one opens, else the CPU device (a log line says which and why).
pub fn device(target: &Target) -> anyhow::Result<Device> {
    Ok(Device::new(target.choice()?, &target.adapter()?)?)
}

/// The GPU context for `--adapter`, for the commands that need a GPU
/// (`--compute cpu` is refused in one line naming `what`).
pub fn gpu(target: &Target, what: &str) -> anyhow::Result<GpuContext> {
    if target.choice()? == DeviceChoice::Cpu {
        anyhow::bail!("{what} needs a GPU adapter; the CPU device (--compute cpu) has none");
    }
    Ok(GpuContext::new(&target.adapter()?)?)
}

/// How the commands load point models: with progress bars for clouds large
/// enough to take a while.
pub fn model_options() -> LoadOptions {
    LoadOptions {
        progress: Some(progress::bars("", 200_000)),
        ..Default::default()
    }
}

/// Loads a point model with [`model_options`]; a mesh (OBJ, STL, PLY
/// with faces) is sampled into one ([`PointModel::load_any_with`]).
pub fn load_model(path: &std::path::Path) -> anyhow::Result<PointModel> {
    Ok(PointModel::load_any_with(path, 0, &model_options())?)
}

/// `FLAG NAME=PATH` or `FLAG PATH` (`--model`): the name (NAME, else the
/// file's stem; for `objects/NAME/model.*`, a sequence's layout, the
/// folder's NAME) and the path. A `=` after a path separator is part of
/// the path.
pub fn named_path(flag: &str, arg: &str) -> anyhow::Result<(String, std::path::PathBuf)> {
    use anyhow::Context;
    if let Some((name, path)) = arg.split_once('=')
        && !name.is_empty()
        && !name.contains(['/', '\\'])
    {
        if path.is_empty() {
            anyhow::bail!("{flag} {arg}: no path after {name}=");
        }
        return Ok((name.to_owned(), std::path::PathBuf::from(path)));
    }
    let path = std::path::PathBuf::from(arg);
    let folder = path.parent().filter(|d| {
        path.file_stem().is_some_and(|s| s == "model")
            && d.parent()
                .and_then(|o| o.file_name())
                .is_some_and(|o| o == "objects")
    });
    let name = folder
        .and_then(|d| d.file_name())
        .or_else(|| path.file_stem())
        .map(|s| s.to_string_lossy().into_owned())
        .filter(|s| !s.is_empty())
        .with_context(|| format!("{flag} {arg}: no file name to name the object by"))?;
    Ok((name, path))
}
