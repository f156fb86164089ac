//! The automatic choice of cues (`TrackerConfig::auto_modalities`, the
//! CLI's default `--modalities auto`): measured on the keyframes' views of
//! synthetic objects rendered by the synth rasteriser (textured blob,
//! untextured plain object), on a model without any texture, and on the
//! real cube (textured) and dragon (weakly textured) when `SPLATTRACK_DATA`
//! names the real data.

mod tracking_common;

use splattrack::geometry::Pose;
use splattrack::gpu::shared_test_context;
use splattrack::keyframes::KeyframeStore;
use splattrack::model::PointModel;
use splattrack::synth::keyframe_poses;
use splattrack::tracker::{CueChoice, Modalities, Mode, Tracker, TrackerConfig};
use tracking_common::{RealSequence, Scene, camera_320};

const DISTANCE: f64 = 0.55;

/// What the choice measures and picks for `model` with `store`, starting
/// at `pose` (mode it without a store: nothing for the KF step).
fn choice(
    model: PointModel,
    cam: splattrack::Intrinsics,
    store: Option<KeyframeStore>,
    pose: Pose,
) -> CueChoice {
    let mode = if store.is_some() || model.colors.is_some() {
        Mode::KfIt
    } else {
        Mode::It
    };
    let t = Tracker::builder(shared_test_context(), model, cam)
        .maybe_keyframes(store)
        .config(TrackerConfig {
            mode,
            auto_modalities: true,
            ..Default::default()
        })
        .initial_pose(pose)
        .build()
        .expect("tracker");
    let c = t.cue_choice().expect("the choice ran");
    assert_eq!(t.config().modalities, c.modalities);
    c
}

#[test]
fn a_textured_object_gets_texture_and_an_untextured_one_the_contour() {
    let pose = keyframe_poses(DISTANCE)[1];
    let blob = Scene::new("blob", camera_320(), 20_000);
    let c = choice(
        blob.model.clone(),
        blob.cam,
        Some(blob.keyframe_store(DISTANCE)),
        pose,
    );
    assert_eq!(c.modalities, Modalities::TEXTURE, "{c:?}");
    assert!(c.view_texture.unwrap() > c.untextured_below, "{c:?}");

    // The plain object: its keyframes show shading only.
    let plain = Scene::new("plain", camera_320(), 20_000);
    let c = choice(
        plain.model.clone(),
        plain.cam,
        Some(plain.keyframe_store(DISTANCE)),
        pose,
    );
    assert_eq!(c.modalities, Modalities::CONTOUR, "{c:?}");
    let t = c.view_texture.unwrap();
    assert!(
        t > 0.0 && t < splattrack::tracker::cues::SHADING_ONLY_BELOW,
        "{c:?}"
    );

    // Model colours alone serve as the texture: the blob's albedo is
    // textured, the plain object's one colour is not.
    let c = choice(blob.model.clone(), blob.cam, None, pose);
    assert_eq!(c.modalities, Modalities::TEXTURE, "{c:?}");
    let c = choice(plain.model.clone(), plain.cam, None, pose);
    assert_eq!(c.modalities, Modalities::CONTOUR, "{c:?}");
    assert!(c.view_texture.unwrap() < 0.01, "{c:?}");
}

#[test]
fn a_model_without_colours_or_keyframes_gets_the_contour_unmeasured() {
    let blob = Scene::new("blob", camera_320(), 20_000);
    let mut bare = blob.model.clone();
    bare.colors = None;
    let c = choice(bare, blob.cam, None, keyframe_poses(DISTANCE)[0]);
    assert_eq!(c.modalities, Modalities::CONTOUR);
    assert!(!c.textured_views && c.view_texture.is_none(), "{c:?}");
    assert!(c.describe().contains("no keyframes"), "{}", c.describe());
}

#[test]
fn the_real_cube_gets_texture_and_the_real_dragon_texture_and_contour() {
    for (name, want) in [
        ("visp_rbt_cube", Modalities::TEXTURE),
        ("visp_rbt_dragon", Modalities::BOTH),
    ] {
        let Some(r) = RealSequence::load(name) else {
            return;
        };
        let init = splattrack::io::read_poses(&r.dir.join("init.csv")).unwrap()[0].pose;
        let c = choice(r.model, r.seq.camera, Some(r.store), init);
        assert_eq!(c.modalities, want, "{name}: {c:?}");
        assert!(c.describe().starts_with(want.name()), "{}", c.describe());
    }
}
