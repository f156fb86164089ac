//! Several objects tracked together ([`MultiTracker`]) on synthetic scenes
//! of objects that cross and hide each other, rendered by the synth
//! rasteriser with one depth test for all objects (never by the splatter
//! under test), tracked on lavapipe.

use splattrack::geometry::{Intrinsics, Pose};
use splattrack::gpu::shared_test_context;
use splattrack::keyframes::{KeyframeConfig, KeyframeStore};
use splattrack::splat::Splatter;
use splattrack::synth::sequence::sample_model;
use splattrack::synth::{Layout, MultiConfig, MultiScene, SynthObject};
use splattrack::tracker::{LostReason, MultiError, MultiTracker, Status, Tracker, TrackerConfig};

/// The scenes' frames.
const FRAMES: usize = 90;

/// One object's frame: its status, whether it was reported occluded, its
/// rotation error (degrees) and its true visible fraction.
struct Seen {
    status: Status,
    occluded: bool,
    error_deg: f64,
    visible: f64,
}

/// Tracks `objects` (indices into the scene's, all when `None`) of
/// `layout` (its default sequence: 90 frames at 640x480); one list of
/// frames an object.
fn track(layout: Layout, objects: Option<&[usize]>) -> Vec<Vec<Seen>> {
    let scene = MultiScene::new(MultiConfig {
        layout,
        ..Default::default()
    })
    .expect("scene");
    let cam = scene.object_config(0).camera;
    let frames = FRAMES;
    let ctx = shared_test_context();
    let splatter = Splatter::new(ctx).expect("splatter");
    let all: Vec<usize> = (0..scene.names().len()).collect();
    let chosen = objects.unwrap_or(&all);
    let mut trackers = Vec::new();
    for &k in chosen {
        let object = SynthObject::by_name(&scene.object_config(k).object).expect("built-in");
        let model = sample_model(&object, 40_000, 5 + k as u64).expect("model");
        let store = KeyframeStore::build(
            ctx,
            &splatter,
            &model,
            &cam,
            &scene.keyframe_images(k),
            &KeyframeConfig::default(),
        )
        .expect("keyframes");
        let tracker = Tracker::builder(ctx, model, cam)
            .keyframes(store)
            .config(TrackerConfig::default())
            .initial_pose(scene.pose(k, 0))
            .build()
            .expect("tracker");
        trackers.push((scene.names()[k].to_string(), tracker));
    }
    let mut multi = MultiTracker::new(trackers).expect("objects");
    let mut seen: Vec<Vec<Seen>> = chosen.iter().map(|_| Vec::new()).collect();
    for i in 0..frames {
        let f = scene.frame(i);
        let results = multi.track(&f.image).expect("track");
        for (j, (&k, r)) in chosen.iter().zip(&results).enumerate() {
            let truth: &Pose = &f.poses[k];
            seen[j].push(Seen {
                status: r.status,
                occluded: matches!(r.reason, Some(LostReason::Occluded { .. })),
                error_deg: r.pose.rotation_error_deg(truth),
                visible: f.visibility[k],
            });
        }
    }
    seen
}

fn tracking(frames: &[Seen]) -> Vec<&Seen> {
    frames
        .iter()
        .filter(|s| s.status == Status::Tracking)
        .collect()
}

#[test]
fn two_crossing_objects_track_through_the_occlusion() {
    // The blob (farther) is up to 45% hidden by the box in the middle.
    let both = track(Layout::Cross, None);
    for (name, frames) in ["blob", "box"].iter().zip(&both) {
        let t = tracking(frames);
        let mean = t.iter().map(|s| s.error_deg).sum::<f64>() / t.len().max(1) as f64;
        let worst = t.iter().map(|s| s.error_deg).fold(0.0, f64::max);
        println!(
            "{name}: {} of {FRAMES} tracking, mean {mean:.3} deg, worst {worst:.2}",
            t.len()
        );
        assert!(
            t.len() >= FRAMES - 2,
            "{name}: {} of {FRAMES} frames tracking",
            t.len()
        );
        assert!(mean < 0.3, "{name}: mean {mean:.3} deg");
        assert!(worst < 10.0, "{name}: a frame tracking {worst:.1} deg off");
    }
    // Alone, with the box in the frames but not known, the blob's check
    // fails on the box's pixels: the occluders are what keeps it.
    let alone = track(Layout::Cross, Some(&[0]));
    let lost_alone = alone[0].len() - tracking(&alone[0]).len();
    let lost_both = both[0].len() - tracking(&both[0]).len();
    println!("blob lost alone {lost_alone}, with the box tracked {lost_both}");
    assert!(
        lost_alone > lost_both,
        "alone {lost_alone}, together {lost_both}"
    );
}

#[test]
fn a_wholly_hidden_object_is_lost_as_occluded_and_never_misreported() {
    let frames = track(Layout::Hide, None);
    let (hidden, front) = (&frames[0], &frames[1]);
    let mut wholly = 0;
    for (i, s) in hidden.iter().enumerate() {
        if s.visible == 0.0 {
            wholly += 1;
            assert_eq!(s.status, Status::Lost, "frame {i}: wholly hidden, tracking");
            assert!(
                s.occluded,
                "frame {i}: wholly hidden, not reported occluded"
            );
        }
    }
    assert!(wholly >= 4, "{wholly} frames wholly hidden");
    // Found again after it shows again: within 25 frames of the first
    // frame after the hidden span with a quarter of it in view (the share
    // under which a tracked object counts as occluded). Measured: frame 68,
    // 8 frames on, in 5 runs (the recovery's starts about where the box's
    // drift carried it), and 80 once with the file's other tests running
    // beside it. The starts a lost frame has time for move with the
    // machine's load (before the drift: 10-23 frames on, over 10 runs),
    // hence the margin over the aim (10 frames).
    let last_hidden = hidden.iter().rposition(|s| s.visible == 0.0).unwrap();
    let back = last_hidden
        + hidden[last_hidden..]
            .iter()
            .position(|s| s.visible >= 0.25)
            .unwrap();
    let found = hidden[back..]
        .iter()
        .position(|s| s.status == Status::Tracking && s.error_deg < 5.0)
        .map(|i| back + i);
    eprintln!("box: a quarter shows again at frame {back}, tracking from {found:?}");
    assert!(
        found.is_some_and(|f| f <= back + 25),
        "a quarter of the box shows from frame {back}; tracking again from {found:?}"
    );
    for (name, f) in [("box", hidden), ("blob", front)] {
        let worst = tracking(f).iter().map(|s| s.error_deg).fold(0.0, f64::max);
        assert!(worst < 10.0, "{name}: a frame tracking {worst:.1} deg off");
    }
    assert_eq!(
        tracking(front).len(),
        FRAMES,
        "the front object tracks every frame"
    );
}

#[test]
fn a_set_of_objects_is_checked() {
    let ctx = shared_test_context();
    let cam = Intrinsics::new(160, 120, 150.0, 150.0, 79.5, 59.5);
    let other = Intrinsics::new(160, 120, 151.0, 150.0, 79.5, 59.5);
    let object = SynthObject::by_name("blob").unwrap();
    let model = sample_model(&object, 2_000, 1).unwrap();
    let pose = Pose::new(
        nalgebra::Matrix3::identity(),
        nalgebra::Vector3::new(0.0, 0.0, 0.6),
    )
    .unwrap();
    let make = |cam: Intrinsics| {
        Tracker::builder(ctx, model.clone(), cam)
            .initial_pose(pose)
            .build()
            .unwrap()
    };
    assert_eq!(MultiTracker::new(Vec::new()).err(), Some(MultiError::Empty));
    let dup = vec![("a".to_string(), make(cam)), ("a".to_string(), make(cam))];
    assert_eq!(
        MultiTracker::new(dup).err(),
        Some(MultiError::DuplicateName("a".into()))
    );
    let bad = vec![("a,b".to_string(), make(cam))];
    assert!(matches!(
        MultiTracker::new(bad).err(),
        Some(MultiError::BadName(_))
    ));
    let many: Vec<(String, Tracker)> = (0..18).map(|k| (format!("o{k}"), make(cam))).collect();
    assert_eq!(MultiTracker::new(many).err(), Some(MultiError::TooMany(18)));
    let cams = vec![("a".to_string(), make(cam)), ("b".to_string(), make(other))];
    assert_eq!(
        MultiTracker::new(cams).err(),
        Some(MultiError::OtherCamera("b".into()))
    );
}
