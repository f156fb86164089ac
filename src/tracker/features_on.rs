//! The tracker's corner detectors and matchers on either device: on a
//! GPU the shaders' objects ([`Harris`], [`NccMatcher`], whose host modes
//! serve CPU adapters), on the CPU device the host's detector and
//! matcher ([`HostHarris`], [`ncc_match_cpu`]) with no GPU object. Both
//! give the same corners and matches; the GPU-resident paths ask for the
//! GPU's object ([`CornerDetector::gpu`], [`Matcher::gpu`]) and are never
//! taken on the CPU device.

use crate::device::Device;
use crate::features::{
    Corner, FeatureError, GreyImage, Harris, HarrisConfig, HostHarris, Match, NccConfig,
    NccMatcher, ncc_match_cpu,
};
use crate::gpu::Timings;

/// What a GPU-only path says on the CPU device.
fn no_gpu() -> FeatureError {
    FeatureError::Config("a GPU path on the CPU device".into())
}

/// Harris corners on the tracker's device.
pub(in crate::tracker) enum CornerDetector {
    /// The GPU's detector (in host mode on CPU adapters).
    Gpu(Box<Harris>),
    /// The host's, on the CPU device.
    Host(Box<HostHarris>),
}

impl CornerDetector {
    /// A detector for `config` on `device`, detecting on the host where
    /// `on_host` (always on the CPU device).
    pub(in crate::tracker) fn new(
        device: &Device,
        config: HarrisConfig,
        on_host: bool,
    ) -> Result<Self, FeatureError> {
        match device.gpu() {
            Some(ctx) => {
                let mut h = Harris::new(ctx, config)?;
                h.set_host(on_host);
                Ok(Self::Gpu(Box::new(h)))
            }
            None => Ok(Self::Host(Box::new(HostHarris::new(config)?))),
        }
    }

    /// Another detector for `config` on `device` that runs as this one.
    pub(in crate::tracker) fn like(
        &self,
        device: &Device,
        config: HarrisConfig,
    ) -> Result<Self, FeatureError> {
        let mut d = Self::new(device, config, self.host())?;
        if let (Self::Gpu(mine), Self::Gpu(new)) = (self, &mut d)
            && mine.host()
        {
            new.set_options(mine.options());
        }
        Ok(d)
    }

    /// Whether corners are detected on the host.
    pub(in crate::tracker) fn host(&self) -> bool {
        match self {
            Self::Gpu(h) => h.host(),
            Self::Host(_) => true,
        }
    }

    /// The GPU's detector, for the GPU-resident paths.
    pub(in crate::tracker) fn gpu(&mut self) -> Result<&mut Harris, FeatureError> {
        match self {
            Self::Gpu(h) => Ok(h),
            Self::Host(_) => Err(no_gpu()),
        }
    }

    /// [`Harris::detect`].
    pub(in crate::tracker) fn detect(
        &mut self,
        img: &GreyImage,
        mask: Option<&[bool]>,
    ) -> Result<Vec<Corner>, FeatureError> {
        match self {
            Self::Gpu(h) => h.detect(img, mask),
            Self::Host(h) => h.detect(img, mask),
        }
    }

    /// The corners of a rendered view's grey levels, its pinholes
    /// flagged as [`Harris::detect_resolved`] does (the CPU device's).
    pub(in crate::tracker) fn detect_view(
        &mut self,
        grey: &GreyImage,
    ) -> Result<Vec<Corner>, FeatureError> {
        match self {
            Self::Gpu(_) => Err(FeatureError::Config(
                "a view read back on a GPU: use detect_resolved".into(),
            )),
            Self::Host(h) => Ok(h.detect_view(grey)),
        }
    }

    /// [`Harris::set_tiled_selection`] (nothing on the CPU device).
    pub(in crate::tracker) fn set_tiled_selection(&mut self, tiled: bool) {
        if let Self::Gpu(h) = self {
            h.set_tiled_selection(tiled);
        }
    }

    /// [`Harris::set_small_selection`] (nothing on the CPU device).
    pub(in crate::tracker) fn set_small_selection(&mut self, small: Option<bool>) {
        if let Self::Gpu(h) = self {
            h.set_small_selection(small);
        }
    }

    /// [`Harris::set_select_limit`] (nothing on the CPU device).
    pub(in crate::tracker) fn set_select_limit(&mut self, n: usize) {
        if let Self::Gpu(h) = self {
            h.set_select_limit(n);
        }
    }

    /// [`Harris::enable_timing`] (nothing on the CPU device).
    pub(in crate::tracker) fn enable_timing(&mut self) {
        if let Self::Gpu(h) = self {
            h.enable_timing();
        }
    }

    /// [`Harris::take_timings`] (none on the CPU device).
    pub(in crate::tracker) fn take_timings(&mut self) -> Timings {
        match self {
            Self::Gpu(h) => h.take_timings(),
            Self::Host(_) => Timings::default(),
        }
    }
}

/// NCC matching on the tracker's device.
pub(in crate::tracker) enum Matcher {
    /// The GPU's matcher (in host mode on CPU adapters).
    Gpu(Box<NccMatcher>),
    /// The host's, on the CPU device.
    Host(NccConfig),
}

impl Matcher {
    /// A matcher for `config` on `device`, matching host images on the
    /// host where `on_host` (always on the CPU device).
    pub(in crate::tracker) fn new(
        device: &Device,
        config: NccConfig,
        on_host: bool,
    ) -> Result<Self, FeatureError> {
        match device.gpu() {
            Some(ctx) => {
                let mut m = NccMatcher::new(ctx, config)?;
                m.set_host(on_host);
                Ok(Self::Gpu(Box::new(m)))
            }
            None => {
                config.validate()?;
                Ok(Self::Host(config))
            }
        }
    }

    /// The matcher's parameters.
    pub(in crate::tracker) fn config(&self) -> &NccConfig {
        match self {
            Self::Gpu(m) => m.config(),
            Self::Host(c) => c,
        }
    }

    /// The GPU's matcher, for the GPU-resident paths.
    pub(in crate::tracker) fn gpu(&mut self) -> Result<&mut NccMatcher, FeatureError> {
        match self {
            Self::Gpu(m) => Ok(m),
            Self::Host(_) => Err(no_gpu()),
        }
    }

    /// [`NccMatcher::match_features`].
    pub(in crate::tracker) fn match_features(
        &mut self,
        img_a: &GreyImage,
        a: &[Corner],
        img_b: &GreyImage,
        b: &[Corner],
    ) -> Result<Vec<Match>, FeatureError> {
        match self {
            Self::Gpu(m) => m.match_features(img_a, a, img_b, b),
            Self::Host(cfg) => ncc_match_cpu(img_a, a, img_b, b, cfg),
        }
    }

    /// [`NccMatcher::set_tiled`] (nothing on the CPU device).
    pub(in crate::tracker) fn set_tiled(&mut self, tiled: bool) {
        if let Self::Gpu(m) = self {
            m.set_tiled(tiled);
        }
    }

    /// [`NccMatcher::enable_timing`] (nothing on the CPU device).
    pub(in crate::tracker) fn enable_timing(&mut self) {
        if let Self::Gpu(m) = self {
            m.enable_timing();
        }
    }

    /// [`NccMatcher::take_timings`] (none on the CPU device).
    pub(in crate::tracker) fn take_timings(&mut self) -> Timings {
        match self {
            Self::Gpu(m) => m.take_timings(),
            Self::Host(_) => Timings::default(),
        }
    }
}
