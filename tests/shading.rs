//! The check of an untextured object's shading against the track's own
//! level (`VerifyConfig::shading_drop`), end to end: the untextured `plain`
//! object turning a full circle (`splattrack synth`, ground truth from the
//! synth CPU triangle rasteriser), 30,000 points, tracked from its first
//! pose with default flags on the CPU device and on lavapipe. Measured
//! without the rule: from frame 77 its pose slips about the object's near
//! symmetry while its outline stays on the frame's edges, and frames 77-82
//! were reported `tracking` 6-32 degrees off (six samplings of the model,
//! both devices). With it the slip's first frame is refused
//! (`shading_drop`: 2.9 times the recent level where right poses measured
//! at most 1.9) and the recovery's slipped poses stay refused. The
//! assertion is the guarantee itself: no frame reported `tracking` more
//! than 5 degrees off.

mod cli_common;

use cli_common::{ok, s, tracking_within};
use std::path::Path;

#[test]
fn a_slip_about_a_near_symmetry_is_refused_by_its_shading() {
    let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("shading");
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(&root).unwrap();
    let seq = root.join("plain_turn");
    ok(&[
        "synth",
        "--object",
        "plain",
        "--trajectory",
        "turn",
        "--frames",
        "100",
        "--points",
        "30000",
        "--out",
        s(&seq),
    ]);
    let gt = seq.join("poses.csv");
    for compute in ["cpu", "gpu"] {
        let out = root.join(format!("poses_{compute}.csv"));
        let refused = root.join(format!("refused_{compute}.csv"));
        ok(&[
            "track",
            "--model",
            s(&seq.join("model.ply")),
            "--sequence",
            s(&seq),
            "--out",
            s(&out),
            "--refused",
            s(&refused),
            "--compute",
            compute,
        ]);
        let (tracking, frames) = tracking_within(&out, &gt, &refused, 5.0, compute);
        assert_eq!(frames, 100);
        let refusals = std::fs::read_to_string(&refused).unwrap();
        // Tracked up to the slip (measured: 77 of 100 frames).
        assert!(tracking >= 70, "{compute}: {tracking} of 100 tracking");
        assert!(
            refusals.contains("shading_drop"),
            "{compute}: no shading_drop refusal:\n{refusals}"
        );
        eprintln!("{compute}: {tracking} of 100 frames tracking, none more than 5 degrees off");
    }
}
