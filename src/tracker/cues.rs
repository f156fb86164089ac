//! The automatic choice of cues ([`TrackerConfig::auto_modalities`]):
//! before the first frame, how textured the object is, measured on its
//! own views, decides which modalities track it.
//!
//! How: the model is splatted at each keyframe's pose, textured by that
//! keyframe (or, without a keyframe store, at the initial pose with the
//! model's colours), and the view's own texture is measured as the pose
//! check measures it ([`VerifyScores::view_texture`]: the RMS of the grey
//! Laplacian at the step the object's size sets). The median over the
//! views decides ([`choose`]):
//!
//! - nothing to texture a view with (no keyframes, no model colours), or
//!   views of shading only (under [`SHADING_ONLY_BELOW`]): `contour`;
//! - a textured object (at least [`VerifyConfig::untextured_below`], the
//!   check's own line between texture and shading): `texture`, the most
//!   accurate there (the real cube: 0.35 degrees against 0.50 with the
//!   contour fused in);
//! - a weakly textured one (between the two): `texture,contour`, where
//!   texture alone loses the track and the texture still helps the
//!   contour (the real dragon: 2.07 degrees against 2.14 by the contour
//!   alone).
//!
//! The medians measured (synthetic sequences of `splattrack synth`, 640x480
//! unless said, with their 12 keyframes; the real ones with their 3):
//! textured: box 0.302, torus 0.240, blob 0.216, real cube 0.185; weakly
//! textured: real dragon 0.081; untextured: plain 0.058 (0.055 at
//! 320x240), plain box 0.050 (0.036). The check measures the same on every
//! frame: textured objects 0.135-0.330, untextured synthetic ones
//! 0.023-0.114, the real dragon 0.077-0.098.
//!
//! [`TrackerConfig::auto_modalities`]: super::TrackerConfig::auto_modalities
//! [`VerifyConfig::untextured_below`]: super::VerifyConfig::untextured_below
//! [`VerifyScores::view_texture`]: super::VerifyScores::view_texture

use super::config::{CueChoice, Modalities};
use super::error::TrackError;
use super::profile::Texture;
use super::state::Tracker;
use super::verify::{self, texture_step, view_texture};
use crate::features::GreyImage;
use crate::splat::{Attribute, Attributes};

/// Views whose texture ([`Tracker::view_texture`]) is under this show
/// shading only: the contour alone tracks them (module docs). Between the
/// untextured synthetic objects (at most 0.058) and the real dragon
/// (0.081), whose texture still helps. On the synthetic plain object
/// `texture,contour` measured 0.260 degrees (mean) against the contour's
/// 0.244, at 1.4 times its time a frame.
pub const SHADING_ONLY_BELOW: f64 = 0.07;

/// The cues for an object: `contour` without anything to texture a view
/// with (`textured_views` false) or with views of shading only (under
/// [`SHADING_ONLY_BELOW`]); `texture` when the views' texture
/// (`view_texture`, [`Tracker::view_texture`]) reaches `untextured_below`;
/// `texture,contour` between the two or when it could not be measured.
pub fn choose(
    textured_views: bool,
    view_texture: Option<f64>,
    untextured_below: f64,
) -> Modalities {
    match (textured_views, view_texture) {
        (false, _) => Modalities::CONTOUR,
        (true, Some(t)) if t >= untextured_below => Modalities::TEXTURE,
        (true, Some(t)) if t < SHADING_ONLY_BELOW => Modalities::CONTOUR,
        (true, _) => Modalities::BOTH,
    }
}

impl Tracker {
    /// The object's texture as its own views show it (module docs): the
    /// median of [`VerifyScores::view_texture`](super::VerifyScores::view_texture)
    /// over the keyframes' views; `None` without a keyframe store (nor
    /// model colours) or when no view is in the image with enough pixels.
    pub fn view_texture(&mut self) -> Result<Option<f64>, TrackError> {
        let Some(store) = self.store.clone() else {
            return Ok(None);
        };
        let mut values = Vec::with_capacity(store.keyframes.len());
        for (k, kf) in store.keyframes.iter().enumerate() {
            let pose = kf.pose;
            if self.roi(&pose).is_none() {
                continue;
            }
            let window = self.view_window(&pose);
            let cam = self.use_window(window);
            self.splat(Texture::Keyframe(k), &cam, &pose, Attributes::COLOR, "cues")?;
            let weight = self
                .splatter
                .read(&self.device, &self.targets, Attribute::Weight)?;
            let colour = self
                .splatter
                .read(&self.device, &self.targets, Attribute::Color)?;
            let (w, h) = (colour.width as usize, colour.height as usize);
            let mut view = GreyImage::from_rgb_f32(w, h, &colour.data)?;
            let covered: Vec<bool> = weight.data.iter().map(|v| *v > 0.0).collect();
            for (v, c) in view.data.iter_mut().zip(&covered) {
                if !*c || !v.is_finite() {
                    *v = 0.0;
                }
            }
            let step = texture_step(self.radius_px(&pose));
            let texture = view_texture(&view.data, &covered, w, h, step);
            log::debug!(
                "cues: keyframe {} ({}): view texture {:?} at a step of {step} px",
                k,
                kf.name,
                texture
            );
            values.extend(texture);
        }
        if values.is_empty() {
            return Ok(None);
        }
        values.sort_by(f64::total_cmp);
        let n = values.len();
        Ok(Some(if n % 2 == 1 {
            values[n / 2]
        } else {
            0.5 * (values[n / 2 - 1] + values[n / 2])
        }))
    }

    /// Whether the object's views show shading only (its texture, as
    /// [`Tracker::view_texture`] measures it, under [`SHADING_ONLY_BELOW`]:
    /// the objects the automatic choice tracks by the contour alone), taken
    /// from the automatic choice where it ran, else measured once. The
    /// search judges such an object's outline candidates strictly and
    /// holds its starts (`Tracker::confirm_start`).
    pub(super) fn shading_only(&mut self) -> Result<bool, TrackError> {
        if let Some(s) = self.shading_only {
            return Ok(s);
        }
        let texture = match &self.cue_choice {
            Some(c) => c.view_texture,
            None => self.view_texture()?,
        };
        let s = texture.is_some_and(|t| t < SHADING_ONLY_BELOW);
        self.shading_only = Some(s);
        Ok(s)
    }

    /// [`Tracker::shading_only`] where it decides [`verify::judge_contour_alone`]
    /// for scores `s` and a fit of RMS `residual_px`, else `false` without
    /// measuring: the measure renders and reads back a dozen views, which
    /// a tight fit, a textured view or a strongly supported outline never
    /// needs.
    pub(super) fn shading_only_for(
        &mut self,
        s: &verify::VerifyScores,
        residual_px: f64,
    ) -> Result<bool, TrackError> {
        if verify::shading_rule_applies(s, &self.config.verify, residual_px) {
            self.shading_only()
        } else {
            Ok(false)
        }
    }

    /// Measures the object's texture and sets the modalities [`choose`]
    /// picks (logged at info level; kept for [`Tracker::cue_choice`]).
    pub fn choose_modalities(&mut self) -> Result<CueChoice, TrackError> {
        let textured_views = self.store.is_some();
        let view_texture = self.view_texture()?;
        let modalities = choose(
            textured_views,
            view_texture,
            self.config.verify.untextured_below,
        );
        let c = CueChoice {
            modalities,
            textured_views,
            view_texture,
            untextured_below: self.config.verify.untextured_below,
            shading_only_below: SHADING_ONLY_BELOW,
        };
        log::info!("cues: {}", c.describe());
        self.config.modalities = modalities;
        self.cue_choice = Some(c);
        Ok(c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_choice_follows_what_there_is_and_how_textured_it_is() {
        let line = 0.125;
        // No keyframes, no colours: only the outline.
        assert_eq!(choose(false, None, line), Modalities::CONTOUR);
        // The real cube's and the synthetic textured objects' measures.
        for t in [0.135, 0.153, 0.192, 0.33] {
            assert_eq!(choose(true, Some(t), line), Modalities::TEXTURE, "{t}");
        }
        // The real dragon's: weakly textured.
        for t in [0.077, 0.081, 0.098, 0.114] {
            assert_eq!(choose(true, Some(t), line), Modalities::BOTH, "{t}");
        }
        // The untextured synthetic objects': shading only.
        for t in [0.0, 0.023, 0.036, 0.058] {
            assert_eq!(choose(true, Some(t), line), Modalities::CONTOUR, "{t}");
        }
        // Views too small to measure: both, the safe side.
        assert_eq!(choose(true, None, line), Modalities::BOTH);
    }
}
