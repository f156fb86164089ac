//! PLY reading and writing: every encoding, property type and layout the
//! format spec of FORMATS.md allows, the shared data sets, and the writer
//! checked against an independent parser (ply-rs-bw).

mod data_common;
mod model_common;

use glam::Vec3;
use model_common::{El, TempFile, Val, ply_bytes};
use splattrack::model::{AttributeSource, LoadOptions, PointModel, load_mesh_ply, shapes};

const FORMATS: [&str; 3] = ["ascii", "binary_little_endian", "binary_big_endian"];

fn quiet() -> LoadOptions {
    LoadOptions {
        progress: None,
        ..Default::default()
    }
}

/// 60 points with every attribute: positions on a sphere, exact outward
/// normals, uchar colours, radii.
fn full_element(coord_type: &str, color_type: &str) -> (El, Vec<Vec3>, Vec<Vec3>, Vec<[f32; 3]>) {
    let (pos, nrm) = shapes::jittered_sphere(60, Vec3::new(0.5, -1.0, 2.0), 0.25, 1);
    let mut el = El::new(
        "vertex",
        &[
            (coord_type, "x"),
            (coord_type, "y"),
            (coord_type, "z"),
            ("float", "nx"),
            ("float", "ny"),
            ("float", "nz"),
            (color_type, "red"),
            (color_type, "green"),
            (color_type, "blue"),
            ("float", "radius"),
        ],
    );
    let mut colors = Vec::new();
    for (i, (p, n)) in pos.iter().zip(&nrm).enumerate() {
        let c = [
            (i * 4 % 256) as f64,
            (255 - i) as f64,
            (i * 37 % 256) as f64,
        ];
        let (stored, loaded) = match color_type {
            "uchar" => (c, c.map(|v| (v / 255.0) as f32)),
            "ushort" => (
                c.map(|v| v * 257.0),
                c.map(|v| (v * 257.0 / 65535.0) as f32),
            ),
            _ => (c.map(|v| v / 255.0), c.map(|v| (v / 255.0) as f32)),
        };
        colors.push(loaded);
        let mut row: Vec<Val> = p.to_array().iter().map(|&v| Val::S(f64::from(v))).collect();
        row.extend(n.to_array().iter().map(|&v| Val::S(f64::from(v))));
        row.extend(stored.iter().map(|&v| Val::S(v)));
        row.push(Val::S(0.01 + i as f64 * 1e-4));
        el.rows.push(row);
    }
    (el, pos, nrm, colors)
}

fn assert_matches(m: &PointModel, pos: &[Vec3], nrm: &[Vec3], colors: &[[f32; 3]], what: &str) {
    assert_eq!(m.len(), pos.len(), "{what}");
    m.validate().expect("valid model");
    for i in 0..pos.len() {
        assert_eq!(m.positions[i], pos[i], "{what}: position {i}");
        assert!(
            (m.normals[i] - nrm[i]).length() < 1e-6,
            "{what}: normal {i}"
        );
        let c = m.colors.as_ref().expect("colours")[i];
        for ch in 0..3 {
            assert!((c[ch] - colors[i][ch]).abs() < 1e-6, "{what}: colour {i}");
        }
        assert_eq!(
            m.radii[i],
            (0.01 + i as f64 * 1e-4) as f32,
            "{what}: radius {i}"
        );
    }
    assert_eq!(m.provenance.normals, AttributeSource::Loaded);
    assert_eq!(m.provenance.radii, AttributeSource::Loaded);
    assert_eq!(m.provenance.colors, AttributeSource::Loaded);
    assert_eq!(m.provenance.dropped_non_finite, 0);
}

#[test]
fn every_encoding_and_colour_type_round_trips() {
    for format in FORMATS {
        for color_type in ["uchar", "ushort", "float", "double"] {
            let (el, pos, nrm, colors) = full_element("float", color_type);
            let f = TempFile::with_bytes("enc", "ply", &ply_bytes(format, &[el]));
            let m = PointModel::load_with(f.path(), &quiet()).expect("load");
            assert_matches(&m, &pos, &nrm, &colors, &format!("{format}/{color_type}"));
        }
    }
}

#[test]
fn double_coordinates_are_read() {
    for format in FORMATS {
        let mut el = El::new(
            "vertex",
            &[("double", "x"), ("double", "y"), ("double", "z")],
        );
        let values: Vec<[f64; 3]> = (0..20)
            .map(|i| {
                let t = i as f64 * 0.1;
                [t.cos() + 1e-9, t.sin() * 3.0, 1.0 / 3.0 + t * t]
            })
            .collect();
        for v in &values {
            el.rows.push(v.iter().map(|&x| Val::S(x)).collect());
        }
        let f = TempFile::with_bytes("double", "ply", &ply_bytes(format, &[el]));
        let m = PointModel::load_with(f.path(), &quiet()).expect("load");
        for (p, v) in m.positions.iter().zip(&values) {
            assert_eq!(
                *p,
                Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32),
                "{format}"
            );
        }
        assert_eq!(m.provenance.normals, AttributeSource::Estimated);
        assert_eq!(m.provenance.radii, AttributeSource::Estimated);
        assert_eq!(m.provenance.colors, AttributeSource::Absent);
        assert!(m.colors.is_none());
    }
}

#[test]
fn other_properties_and_elements_are_ignored_and_faces_give_vertices() {
    let (pos, nrm) = shapes::jittered_sphere(40, Vec3::ZERO, 1.0, 2);
    for format in FORMATS {
        let camera = El::new("camera", &[("float", "fx"), ("list uchar float", "dist")])
            .row(vec![Val::S(500.0), Val::L(vec![0.1, 0.2])]);
        let mut vertex = El::new(
            "vertex",
            &[
                ("uchar", "flags"),
                ("float", "z"),
                ("float", "y"),
                ("float", "x"),
                ("list uchar int", "tags"),
                ("float", "nz"),
                ("float", "ny"),
                ("float", "nx"),
                ("double", "confidence"),
            ],
        );
        for (i, (p, n)) in pos.iter().zip(&nrm).enumerate() {
            vertex.rows.push(vec![
                Val::S(7.0),
                Val::S(f64::from(p.z)),
                Val::S(f64::from(p.y)),
                Val::S(f64::from(p.x)),
                Val::L((0..i % 4).map(|k| k as f64).collect()),
                Val::S(f64::from(n.z)),
                Val::S(f64::from(n.y)),
                Val::S(f64::from(n.x)),
                Val::S(0.5),
            ]);
        }
        let mut face = El::new("face", &[("list uchar int", "vertex_indices")]);
        for i in 0..10 {
            face.rows
                .push(vec![Val::L(vec![i as f64, (i + 1) as f64, (i + 2) as f64])]);
        }
        let f = TempFile::with_bytes("extra", "ply", &ply_bytes(format, &[camera, vertex, face]));
        let m = PointModel::load_with(f.path(), &quiet()).expect("load");
        assert_eq!(m.positions, pos, "{format}");
        for (a, b) in m.normals.iter().zip(&nrm) {
            assert!((*a - *b).length() < 1e-6);
        }
        assert_eq!(m.provenance.normals, AttributeSource::Loaded);
        // The faces are there for whoever asks.
        let mesh = load_mesh_ply(f.path()).expect("mesh");
        assert_eq!(mesh.triangles.len(), 10);
        assert_eq!(mesh.triangles[3], [3, 4, 5]);
        let pos: Vec<_> = pos.iter().map(|p| p.as_dvec3()).collect();
        assert_eq!(mesh.vertices, pos);
    }
}

#[test]
fn crlf_headers_and_type_aliases() {
    let text = "ply\r\nformat ascii 1.0\r\nelement vertex 4\r\nproperty float32 x\r\n\
                property float32 y\r\nproperty float32 z\r\nproperty uint8 red\r\n\
                property uint8 green\r\nproperty uint8 blue\r\nend_header\r\n\
                0 0 0 255 0 0\r\n1 0 0 0 255 0\r\n0 1 0 0 0 255\r\n\r\n0 0 1 255 255 255";
    let f = TempFile::with_bytes("crlf", "ply", text.as_bytes());
    let m = PointModel::load_with(f.path(), &quiet()).expect("load");
    assert_eq!(m.positions[3], Vec3::Z);
    assert_eq!(m.colors.as_ref().expect("colours")[1], [0.0, 1.0, 0.0]);
    // Four points on a tetrahedron: normals estimated, unit, radii positive.
    m.validate().expect("valid");
}

#[test]
fn shared_models_load() {
    for (name, half_size) in [
        ("visp_rbt_cube", Some(0.0425f32)),
        ("visp_rbt_dragon", None),
    ] {
        let Some(path) = data_common::real_data(&format!("{name}/model.ply")) else {
            return;
        };
        let m = PointModel::load_with(&path, &quiet()).expect("shared model loads");
        assert_eq!(m.len(), 100_000, "{name}");
        m.validate().expect("valid");
        assert_eq!(m.provenance.normals, AttributeSource::Loaded);
        assert_eq!(m.provenance.radii, AttributeSource::Loaded);
        assert_eq!(m.provenance.colors, AttributeSource::Loaded);
        let (lo, hi) = m.bounds();
        assert!(lo.cmplt(hi).all());
        assert!(
            m.diameter() > 0.05 && m.diameter() < 0.2,
            "{name}: {}",
            m.diameter()
        );
        if let Some(h) = half_size {
            assert!((lo + Vec3::splat(h)).abs().max_element() < 1e-4, "{lo}");
            assert!((hi - Vec3::splat(h)).abs().max_element() < 1e-4, "{hi}");
            assert!(m.centroid().length() < 1e-3);
            assert!((m.diameter() - 2.0 * h * 3f32.sqrt()).abs() < 1e-4);
            // Every point on a face of the cube, its normal along that face's axis.
            for (p, n) in m.positions.iter().zip(&m.normals) {
                let axis = p.abs().max_position();
                assert!((p[axis].abs() - h).abs() < 1e-5);
                assert!(n[axis] * p[axis].signum() > 0.99, "{p} {n}");
            }
        }
    }
}

#[test]
fn save_ply_round_trips_and_ply_rs_agrees() {
    let Some(path) = data_common::real_data("visp_rbt_cube/model.ply") else {
        return;
    };
    let m = PointModel::load_with(path, &quiet()).expect("load shared cube");
    let out = TempFile::new("save", "ply");
    m.save_ply(out.path()).expect("save");
    let back = PointModel::load_with(out.path(), &quiet()).expect("reload");
    assert_eq!(back.positions, m.positions);
    assert_eq!(back.radii, m.radii);
    for (a, b) in back.normals.iter().zip(&m.normals) {
        assert!((*a - *b).length() < 1e-6);
    }
    let (ca, cb) = (
        back.colors.expect("colours"),
        m.colors.as_ref().expect("colours"),
    );
    for (a, b) in ca.iter().zip(cb) {
        for ch in 0..3 {
            assert!((a[ch] - b[ch]).abs() <= 0.5 / 255.0 + 1e-6);
        }
    }

    // An independent parser reads the same numbers.
    use ply_rs_bw::ply::{DefaultElement, Property};
    let mut file = std::fs::File::open(out.path()).expect("open");
    let ply = ply_rs_bw::parser::Parser::<DefaultElement>::new()
        .read_ply(&mut file)
        .expect("ply-rs-bw parses our output");
    let vertices = &ply.payload["vertex"];
    assert_eq!(vertices.len(), m.len());
    for i in [0, 1, 777, m.len() - 1] {
        let v = &vertices[i];
        let f = |k: &str| match v.get(k) {
            Some(Property::Float(x)) => *x,
            other => panic!("{k}: {other:?}"),
        };
        assert_eq!(Vec3::new(f("x"), f("y"), f("z")), m.positions[i]);
        assert_eq!(f("radius"), m.radii[i]);
        assert!((Vec3::new(f("nx"), f("ny"), f("nz")) - m.normals[i]).length() < 1e-6);
        match v.get("green") {
            Some(Property::UChar(g)) => {
                let want = m.colors.as_ref().expect("colours")[i][1];
                assert!((f32::from(*g) / 255.0 - want).abs() <= 0.5 / 255.0 + 1e-6);
            }
            other => panic!("green: {other:?}"),
        }
    }
}

#[test]
fn save_without_colours_and_refuse_invalid_models() {
    let (pos, nrm) = shapes::jittered_sphere(30, Vec3::ZERO, 1.0, 3);
    let mut m = PointModel::from_points(pos.clone(), None, &quiet()).expect("from points");
    assert!(m.provenance.path.is_none());
    for (a, b) in m.normals.iter().zip(&nrm) {
        assert!(a.dot(*b) > 0.9, "outward normals from bare points");
    }
    let out = TempFile::new("nocolour", "ply");
    m.save_ply(out.path()).expect("save");
    let back = PointModel::load_with(out.path(), &quiet()).expect("reload");
    assert!(back.colors.is_none());
    assert_eq!(back.positions, pos);

    m.radii[3] = -1.0;
    let bad = TempFile::new("invalid", "ply");
    let err = m.save_ply(bad.path()).expect_err("negative radius refused");
    assert!(err.to_string().contains("radius"), "{err}");
    assert!(!bad.path().exists());
}

#[test]
fn load_auto_dispatches_on_type_and_faces() {
    let Some(ply) = data_common::real_data("visp_rbt_cube/model.ply") else {
        return;
    };
    let mesh = data_common::real_data("visp_rbt_cube/mesh.obj").expect("beside model.ply");
    let cube = PointModel::load_auto(ply, 0).expect("ply");
    assert_eq!(cube.len(), 100_000);
    assert_eq!(cube.provenance.normals, AttributeSource::Loaded);
    let obj = PointModel::load_auto(mesh, 5_000).expect("obj");
    assert_eq!(obj.len(), 5_000);
    assert_eq!(obj.provenance.normals, AttributeSource::FromMesh);

    // A PLY mesh: vertices unless sampling is asked for.
    let verts = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
    let mut vertex = El::new("vertex", &[("float", "x"), ("float", "y"), ("float", "z")]);
    for v in verts {
        vertex
            .rows
            .push(v.to_array().iter().map(|&c| Val::S(f64::from(c))).collect());
    }
    let face = El::new("face", &[("list uchar uint", "vertex_index")])
        .row(vec![Val::L(vec![0.0, 1.0, 3.0, 2.0])]);
    let f = TempFile::with_bytes(
        "auto",
        "ply",
        &ply_bytes("binary_little_endian", &[vertex, face]),
    );
    let as_points = PointModel::load_auto(f.path(), 0).expect("vertices");
    assert_eq!(as_points.positions, verts);
    let sampled = PointModel::load_auto(f.path(), 500).expect("sampled");
    assert_eq!(sampled.len(), 500);
    assert!(
        sampled
            .normals
            .iter()
            .all(|n| (*n - Vec3::Z).length() < 1e-6)
    );
}
