//! What a render produces ([`Attributes`]) and what can be read back
//! ([`Attribute`]).

use super::gpu_data::{
    RESOLVE_COLOR, RESOLVE_DEPTH, RESOLVE_MOTION, RESOLVE_NORMAL, RESOLVE_WEIGHT,
};

/// One attribute image that can be read back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Attribute {
    /// Linear RGB, 3 channels.
    Color,
    /// Camera-space z (model units), 1 channel: the fragments' weighted
    /// mean after a render with [`Attributes::GEOMETRY`]; after one with
    /// the predictors and no geometry ([`Attributes::MOTION`]), their
    /// weighted harmonic mean from the translation predictor (`fx /
    /// (du/dtx)`, eq. 5: the depth [`super::Splatter::gather`] gives); after
    /// [`super::Splatter::render_depth`], the visibility depth.
    Depth,
    /// Camera-space unit normal, 3 channels.
    Normal,
    /// Motion predictors, 12 channels: du_tx, dv_tx, du_ty, dv_ty, ..., du_rz, dv_rz.
    Motion,
    /// The summed kernel weight (not normalised; 0 where empty), 1 channel.
    Weight,
}

impl Attribute {
    /// Number of f32 channels of this attribute's image.
    pub fn channels(self) -> usize {
        match self {
            Self::Color | Self::Normal => 3,
            Self::Depth | Self::Weight => 1,
            Self::Motion => 12,
        }
    }

    /// `ResolveParams.kind` of this attribute.
    pub(crate) fn kind(self) -> u32 {
        match self {
            Self::Color => RESOLVE_COLOR,
            Self::Depth => RESOLVE_DEPTH,
            Self::Normal => RESOLVE_NORMAL,
            Self::Motion => RESOLVE_MOTION,
            Self::Weight => RESOLVE_WEIGHT,
        }
    }

    /// Which attribute set must have been rendered to read this one.
    pub(crate) fn needs(self) -> Attributes {
        match self {
            Self::Color | Self::Weight => Attributes::COLOR,
            Self::Depth | Self::Normal => Attributes::GEOMETRY,
            Self::Motion => Attributes::MOTION,
        }
    }
}

/// Which attribute groups a render produces, besides colour and weight
/// (always produced). Each group costs render targets: colour 1, geometry
/// (depth + normal) 1, motion 3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Attributes {
    /// Whether depth and normals are rendered.
    pub geometry: bool,
    /// Whether the motion predictors are rendered.
    pub motion: bool,
}

impl Attributes {
    /// Colour and weight only (novel views).
    pub const COLOR: Self = Self {
        geometry: false,
        motion: false,
    };
    /// Colour, depth and normal.
    pub const GEOMETRY: Self = Self {
        geometry: true,
        motion: false,
    };
    /// Colour and the motion predictors (the paper's single pass: 16
    /// floats): what `gather` needs, its depth included.
    pub const MOTION: Self = Self {
        geometry: false,
        motion: true,
    };
    /// Everything: colour, depth, normal, predictors.
    pub const ALL: Self = Self {
        geometry: true,
        motion: true,
    };

    pub(crate) fn contains(self, other: Self) -> bool {
        (self.geometry || !other.geometry) && (self.motion || !other.motion)
    }

    pub(crate) fn index(self) -> usize {
        self.geometry as usize + 2 * self.motion as usize
    }
}
