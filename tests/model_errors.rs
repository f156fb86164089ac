//! Bad input: every fault gives a typed error whose one-line message names the
//! file, nothing panics, and lying headers allocate nothing large.

mod model_common;

use glam::Vec3;
use model_common::{El, TempFile, Val, ply_bytes, vertex_element};
use splattrack::model::{LoadOptions, ModelError, PointModel, load_mesh_ply, load_obj, shapes};
use splattrack::rng::Rng;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::Path;

/// Records the largest single allocation made by the current thread, so a
/// test can prove that a lying header is refused before anything big is
/// allocated.
struct TrackingAlloc;

thread_local! {
    static LARGEST: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for TrackingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = LARGEST.try_with(|m| m.set(m.get().max(layout.size())));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = LARGEST.try_with(|m| m.set(m.get().max(new_size)));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOC: TrackingAlloc = TrackingAlloc;

fn quiet() -> LoadOptions {
    LoadOptions {
        progress: None,
        ..Default::default()
    }
}

fn load(path: &Path) -> Result<PointModel, ModelError> {
    PointModel::load_with(path, &quiet())
}

/// The message is one line and names the file.
fn check_message(err: &ModelError, path: &Path) -> String {
    let msg = err.to_string();
    assert!(!msg.contains('\n'), "multi-line message: {msg:?}");
    let name = path.file_name().expect("file name").to_string_lossy();
    assert!(msg.contains(name.as_ref()), "{msg:?} does not name {name}");
    assert_eq!(err.path(), path);
    msg
}

fn small_cloud(n: usize) -> (Vec<Vec3>, Vec<Vec3>) {
    shapes::jittered_sphere(n, Vec3::ZERO, 1.0, 11)
}

#[test]
fn missing_file() {
    let path = std::env::temp_dir().join("splattrack-definitely-missing.ply");
    let err = load(&path).expect_err("missing");
    match &err {
        ModelError::Io { source, .. } => {
            assert_eq!(source.kind(), std::io::ErrorKind::NotFound)
        }
        other => panic!("{other:?}"),
    }
    check_message(&err, &path);
    let obj = path.with_extension("obj");
    let err = load_obj(&obj).expect_err("missing obj");
    check_message(&err, &obj);
}

#[test]
fn not_a_ply() {
    for bytes in [
        &b"OFF\n3 1 0\n"[..],
        b"",
        b"\x89PNG\r\n\x1a\n",
        b"plyx\nformat ascii 1.0\n",
    ] {
        let f = TempFile::with_bytes("notply", "ply", bytes);
        let err = load(f.path()).expect_err("not a ply");
        assert!(matches!(err, ModelError::NotPly { .. }), "{err:?}");
        check_message(&err, f.path());
    }
}

#[test]
fn unsupported_format_line() {
    for line in [
        "format binary_middle_endian 1.0",
        "format ascii 2.0",
        "format ascii",
    ] {
        let text = format!("ply\n{line}\nelement vertex 1\nproperty float x\nend_header\n1\n");
        let f = TempFile::with_bytes("format", "ply", text.as_bytes());
        let err = load(f.path()).expect_err("unsupported");
        assert!(
            matches!(err, ModelError::UnsupportedFormat { .. }),
            "{err:?}"
        );
        let msg = check_message(&err, f.path());
        assert!(msg.contains(line), "{msg}");
    }
}

#[test]
fn malformed_headers() {
    for text in [
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty flaot x\nend_header\n",
        "ply\nformat ascii 1.0\nproperty float x\nelement vertex 3\nend_header\n",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n",
        "ply\nformat ascii 1.0\nelement vertex\nend_header\n",
        "ply\nformat ascii 1.0\nelement vertex 1\nelement vertex 1\nend_header\n",
        "ply\nelement vertex 1\nproperty float x\nend_header\n",
    ] {
        let f = TempFile::with_bytes("header", "ply", text.as_bytes());
        let err = load(f.path()).expect_err("bad header");
        assert!(
            matches!(err, ModelError::Header { .. }),
            "{text:?}: {err:?}"
        );
        check_message(&err, f.path());
    }
}

#[test]
fn truncated_bodies() {
    let (pos, nrm) = small_cloud(50);
    for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let bytes = ply_bytes(format, &[vertex_element(&pos, Some(&nrm), Some(0.1))]);
        // Cut in the middle of the body: the count check passes (an ASCII
        // token may be two bytes) or the body runs out while reading.
        let cut = bytes.len() - (bytes.len() - header_len(&bytes)) / 3;
        let f = TempFile::with_bytes("trunc", "ply", &bytes[..cut]);
        let err = load(f.path()).expect_err("truncated");
        match &err {
            ModelError::Truncated { read, count, .. } => {
                assert_eq!(*count, 50);
                assert!(*read > 0 && *read < 50, "{format}: read {read}");
            }
            other => panic!("{format}: {other:?}"),
        }
        let msg = check_message(&err, f.path());
        assert!(msg.contains("truncated"), "{msg}");
    }
}

fn header_len(bytes: &[u8]) -> usize {
    let at = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("end_header");
    at + 11
}

#[test]
fn huge_counts_are_refused_before_allocating() {
    for (format, count) in [
        ("binary_little_endian", 4_000_000_000usize),
        ("ascii", 4_000_000_000),
        ("binary_big_endian", usize::MAX),
    ] {
        let text = format!(
            "ply\nformat {format} 1.0\nelement vertex {count}\nproperty float x\n\
             property float y\nproperty float z\nend_header\n"
        );
        let mut bytes = text.into_bytes();
        bytes.extend_from_slice(&[0u8; 1200]);
        let f = TempFile::with_bytes("huge", "ply", &bytes);
        LARGEST.with(|m| m.set(0));
        let err = load(f.path()).expect_err("too many vertices");
        let largest = LARGEST.with(|m| m.get());
        assert!(largest < 1 << 20, "{format}: allocated {largest} bytes");
        match &err {
            ModelError::CountExceedsFile {
                count: c,
                max_possible,
                ..
            } => {
                assert_eq!(*c, count);
                assert!(*max_possible <= 1200 / 6, "{max_possible}");
            }
            other => panic!("{format}: {other:?}"),
        }
        check_message(&err, f.path());
    }

    // A face list longer than the file, read as a mesh.
    let (pos, _) = small_cloud(10);
    let mut bytes = ply_bytes("binary_little_endian", &[vertex_element(&pos, None, None)]);
    let at = header_len(&bytes);
    let header = String::from_utf8_lossy(&bytes[..at]).replace(
        "end_header\n",
        "element face 1\nproperty list uint int vertex_indices\nend_header\n",
    );
    let mut body = bytes.split_off(at);
    body.extend_from_slice(&u32::MAX.to_le_bytes());
    body.extend_from_slice(&[1, 0, 0, 0]);
    let mut all = header.into_bytes();
    all.extend_from_slice(&body);
    let f = TempFile::with_bytes("hugelist", "ply", &all);
    LARGEST.with(|m| m.set(0));
    let err = load_mesh_ply(f.path()).expect_err("list longer than the file");
    assert!(LARGEST.with(|m| m.get()) < 1 << 20);
    assert!(matches!(err, ModelError::Truncated { .. }), "{err:?}");
    check_message(&err, f.path());
}

#[test]
fn missing_coordinates() {
    for missing in ["x", "y", "z"] {
        let props: Vec<(&str, &str)> = ["x", "y", "z"]
            .iter()
            .filter(|&&a| a != missing)
            .map(|&a| ("float", a))
            .collect();
        let el = El::new("vertex", &props)
            .row(vec![Val::S(1.0), Val::S(2.0)])
            .row(vec![Val::S(3.0), Val::S(4.0)]);
        let f = TempFile::with_bytes("noxyz", "ply", &ply_bytes("ascii", &[el]));
        let err = load(f.path()).expect_err("missing coordinate");
        assert!(matches!(err, ModelError::MissingProperty { .. }), "{err:?}");
        let msg = check_message(&err, f.path());
        assert!(msg.contains(&format!("'{missing}'")), "{msg}");
    }
    let el = El::new("point", &[("float", "x"), ("float", "y"), ("float", "z")]);
    let f = TempFile::with_bytes("novertex", "ply", &ply_bytes("ascii", &[el]));
    let err = load(f.path()).expect_err("no vertex element");
    assert!(matches!(err, ModelError::MissingElement { .. }), "{err:?}");
    check_message(&err, f.path());
}

#[test]
fn non_finite_coordinates_are_dropped_and_counted() {
    let (mut pos, mut nrm) = small_cloud(40);
    pos[3].x = f32::NAN;
    pos[17].z = f32::INFINITY;
    pos[39].y = f32::NEG_INFINITY;
    nrm[5] = Vec3::ZERO; // also exercise re-estimation next to dropped points
    for format in ["ascii", "binary_little_endian"] {
        let bytes = ply_bytes(format, &[vertex_element(&pos, Some(&nrm), None)]);
        let f = TempFile::with_bytes("nan", "ply", &bytes);
        let m = load(f.path()).expect("loads without the bad points");
        assert_eq!(m.len(), 37, "{format}");
        assert_eq!(m.provenance.dropped_non_finite, 3);
        assert_eq!(m.provenance.normals_reestimated, 1);
        assert!(m.positions.iter().all(|p| p.is_finite()));
        assert_eq!(m.positions[3], pos[4], "order kept");
        m.validate().expect("valid");
    }
    let all_bad = vec![Vec3::new(f32::NAN, 0.0, 0.0); 5];
    let f = TempFile::with_bytes(
        "allnan",
        "ply",
        &ply_bytes("ascii", &[vertex_element(&all_bad, None, None)]),
    );
    let err = load(f.path()).expect_err("all dropped");
    assert!(
        matches!(err, ModelError::AllNonFinite { dropped: 5, .. }),
        "{err:?}"
    );
    check_message(&err, f.path());
}

#[test]
fn zero_points() {
    let f = TempFile::with_bytes(
        "empty",
        "ply",
        &ply_bytes("binary_little_endian", &[vertex_element(&[], None, None)]),
    );
    let err = load(f.path()).expect_err("no points");
    assert!(matches!(err, ModelError::Empty { .. }), "{err:?}");
    check_message(&err, f.path());

    // Too few to estimate anything from.
    let f = TempFile::with_bytes(
        "two",
        "ply",
        &ply_bytes(
            "ascii",
            &[vertex_element(&[Vec3::ZERO, Vec3::X], None, None)],
        ),
    );
    let err = load(f.path()).expect_err("two points");
    assert!(matches!(err, ModelError::Estimation { .. }), "{err:?}");
    check_message(&err, f.path());

    // All points coincide: normals can be anything, radii cannot be estimated.
    let same = vec![Vec3::ONE; 30];
    let f = TempFile::with_bytes(
        "same",
        "ply",
        &ply_bytes("ascii", &[vertex_element(&same, None, None)]),
    );
    let err = load(f.path()).expect_err("coincident");
    assert!(matches!(err, ModelError::Estimation { .. }), "{err:?}");
    check_message(&err, f.path());
}

#[test]
fn bad_radii_are_refused() {
    let (pos, nrm) = small_cloud(20);
    for bad in [-0.5, 0.0, f64::NAN, f64::INFINITY] {
        let mut el = vertex_element(&pos, Some(&nrm), Some(0.1));
        el.rows[7][6] = Val::S(bad);
        let f = TempFile::with_bytes("radius", "ply", &ply_bytes("binary_little_endian", &[el]));
        let err = load(f.path()).expect_err("bad radius");
        assert!(
            matches!(err, ModelError::BadRadius { index: 7, .. }),
            "{bad}: {err:?}"
        );
        let msg = check_message(&err, f.path());
        assert!(msg.contains("point 7"), "{msg}");
    }
}

#[test]
fn ascii_value_errors_give_line_numbers() {
    let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                property float z\nend_header\n0 0 0\n1 zero 0\n0 1 0\n";
    let f = TempFile::with_bytes("parse", "ply", text.as_bytes());
    let err = load(f.path()).expect_err("bad number");
    assert!(matches!(err, ModelError::Parse { line: 9, .. }), "{err:?}");
    check_message(&err, f.path());

    let text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                property float z\nend_header\n0 0 0 7\n1 1 0\n";
    let f = TempFile::with_bytes("extra", "ply", text.as_bytes());
    let err = load(f.path()).expect_err("extra value");
    assert!(matches!(err, ModelError::Parse { line: 8, .. }), "{err:?}");
}

#[test]
fn bad_faces_and_obj_files() {
    let (pos, _) = small_cloud(4);
    let face = El::new("face", &[("list uchar int", "vertex_indices")])
        .row(vec![Val::L(vec![0.0, 1.0, 9.0])]);
    let f = TempFile::with_bytes(
        "badface",
        "ply",
        &ply_bytes("ascii", &[vertex_element(&pos, None, None), face]),
    );
    let err = load_mesh_ply(f.path()).expect_err("index out of range");
    assert!(matches!(err, ModelError::Invalid { .. }), "{err:?}");
    check_message(&err, f.path());
    // Without faces a mesh cannot be read.
    let f = TempFile::with_bytes(
        "noface",
        "ply",
        &ply_bytes("ascii", &[vertex_element(&pos, None, None)]),
    );
    let err = load_mesh_ply(f.path()).expect_err("no faces");
    assert!(matches!(err, ModelError::MissingElement { .. }), "{err:?}");

    for (text, line) in [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", None),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", Some(4)),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", Some(4)),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n", Some(4)),
        ("v 0 0\n", Some(1)),
        ("v 0 0 zero\n", Some(1)),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/x 3.5\n", Some(4)),
    ] {
        let f = TempFile::with_bytes("badobj", "obj", text.as_bytes());
        let err = load_obj(f.path()).expect_err("bad obj");
        match (line, &err) {
            (Some(l), ModelError::Parse { line, .. }) => assert_eq!(*line, l, "{text:?}"),
            (None, ModelError::Invalid { .. }) => {}
            _ => panic!("{text:?}: {err:?}"),
        }
        check_message(&err, f.path());
    }
    // A mesh of only degenerate triangles has no surface to sample.
    let f = TempFile::with_bytes("flat", "obj", b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n");
    let err = load_obj(f.path())
        .expect("parses")
        .sample(100, 0)
        .expect_err("zero area");
    assert!(matches!(err, ModelError::Empty { .. }), "{err:?}");
    check_message(&err, f.path());
}

/// A few hundred seeded corruptions of valid files: errors are fine, panics
/// are not.
#[test]
fn corrupted_files_never_panic() {
    let (pos, nrm) = small_cloud(60);
    let mut with_all = vertex_element(&pos, Some(&nrm), Some(0.05));
    with_all.props.push(("uchar".into(), "red".into()));
    with_all.props.push(("uchar".into(), "green".into()));
    with_all.props.push(("uchar".into(), "blue".into()));
    for row in &mut with_all.rows {
        row.extend([Val::S(10.0), Val::S(200.0), Val::S(30.0)]);
    }
    let face = El::new("face", &[("list uchar int", "vertex_indices")])
        .row(vec![Val::L(vec![0.0, 1.0, 2.0])])
        .row(vec![Val::L(vec![3.0, 4.0, 5.0, 6.0])]);
    let bases = [
        ply_bytes("binary_little_endian", &[with_all.clone(), face.clone()]),
        ply_bytes(
            "binary_big_endian",
            &[vertex_element(&pos, None, None), face.clone()],
        ),
        ply_bytes("ascii", &[vertex_element(&pos, None, None), face]),
        ply_bytes("ascii", &[with_all]),
    ];
    let obj =
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1 0.5 0.5 0.5\nf 1 2 3\nf 1/1/1 3//2 4\nf -1 -2 -3 -4\n";
    let mut rng = Rng::new(2024);
    let mut outcomes = [0usize; 2];
    for case in 0..400 {
        let base: &[u8] = if case % 10 == 9 {
            obj
        } else {
            &bases[case % bases.len()]
        };
        let mut bytes = base.to_vec();
        match rng.below(5) {
            0 => {
                for _ in 0..=rng.below(8) {
                    let at = rng.below(bytes.len() as u64) as usize;
                    bytes[at] = rng.next_u64() as u8;
                }
            }
            1 => bytes.truncate(rng.below(bytes.len() as u64) as usize),
            2 => {
                let at = rng.below(bytes.len() as u64) as usize;
                let junk: Vec<u8> = (0..rng.below(16)).map(|_| rng.next_u64() as u8).collect();
                bytes.splice(at..at, junk);
            }
            3 => {
                // Rewrite a digit of the header (counts, types' sizes).
                let end = header_len_or_all(&bytes);
                let digits: Vec<usize> = (0..end).filter(|&i| bytes[i].is_ascii_digit()).collect();
                if !digits.is_empty() {
                    let at = digits[rng.below(digits.len() as u64) as usize];
                    bytes[at] = b"0123456789"[rng.below(10) as usize];
                    if rng.below(2) == 0 {
                        bytes.insert(at, b'9');
                    }
                }
            }
            _ => {
                // Flip bytes in the body only, to reach the value checks.
                let start = header_len_or_all(&bytes).min(bytes.len().saturating_sub(1));
                for _ in 0..=rng.below(4) {
                    let at = start + rng.below((bytes.len() - start) as u64) as usize;
                    bytes[at] ^= 1 << rng.below(8);
                }
            }
        }
        let ext = if case % 10 == 9 { "obj" } else { "ply" };
        let f = TempFile::with_bytes("fuzz", ext, &bytes);
        let result = std::panic::catch_unwind(|| {
            let a = PointModel::load_auto_with(f.path(), 0, &quiet());
            let b = PointModel::load_auto_with(f.path(), 200, &quiet());
            if let Ok(m) = &a {
                m.validate().expect("a loaded model is valid");
            }
            if let Ok(m) = &b {
                m.validate().expect("a sampled model is valid");
            }
            for r in [&a, &b] {
                if let Err(e) = r {
                    assert!(!e.to_string().contains('\n'), "{e}");
                }
            }
            a.is_ok()
        });
        match result {
            Ok(ok) => outcomes[usize::from(ok)] += 1,
            Err(_) => panic!(
                "case {case} panicked (bytes: {:?})",
                String::from_utf8_lossy(&bytes)
            ),
        }
    }
    // Both outcomes occur, so the corruptions are neither all fatal nor all harmless.
    assert!(outcomes[0] > 20 && outcomes[1] > 20, "{outcomes:?}");
}

fn header_len_or_all(bytes: &[u8]) -> usize {
    bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .map_or(bytes.len(), |at| at + 11)
}
