//! Mesh loading (OBJ, PLY with faces, STL) and sampling into point models.

mod data_common;
mod model_common;

use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use model_common::{El, TempFile, Val, ply_bytes};
use splattrack::model::{
    AttributeSource, LoadOptions, MESH_RADIUS_FACTOR, PointModel, TriangleMesh, load_mesh_ply,
    load_obj,
};

const CUBE_OBJ: &str = "visp_rbt_cube/mesh.obj";
const DRAGON_OBJ: &str = "visp_rbt_dragon/mesh.obj";
const HALF: f32 = 0.0425;

#[test]
fn cube_samples_lie_on_the_faces_with_outward_normals() {
    let Some(path) = data_common::real_data(CUBE_OBJ) else {
        return;
    };
    let mesh = load_obj(path).expect("cube obj");
    assert_eq!(mesh.vertices.len(), 8);
    assert_eq!(mesh.triangles.len(), 12, "six quads, fan-triangulated");
    assert!((mesh.area() - 6.0 * 0.085f64 * 0.085).abs() < 1e-6);
    let n = 30_000;
    let m = mesh.sample(n, 1).expect("sample");
    assert_eq!(m.len(), n);
    m.validate().expect("valid");
    assert_eq!(m.provenance.normals, AttributeSource::FromMesh);
    assert_eq!(m.provenance.radii, AttributeSource::FromMesh);
    assert_eq!(m.provenance.colors, AttributeSource::Absent);
    let mut per_face = [0usize; 6];
    for (p, nrm) in m.positions.iter().zip(&m.normals) {
        let axis = p.abs().max_position();
        assert!((p[axis].abs() - HALF).abs() < 1e-6, "{p} off the cube");
        let mut want = Vec3::ZERO;
        want[axis] = p[axis].signum();
        assert!((*nrm - want).length() < 1e-6, "{p}: normal {nrm}");
        per_face[axis * 2 + usize::from(p[axis] > 0.0)] += 1;
    }
    // Equal faces get equal shares, to the sample (one per triangle at most).
    for c in per_face {
        assert!((c as i64 - n as i64 / 6).abs() <= 2, "{per_face:?}");
    }
    let want_r = MESH_RADIUS_FACTOR * (mesh.area() / (std::f64::consts::PI * n as f64)).sqrt();
    assert!(
        m.radii
            .iter()
            .all(|&r| (f64::from(r) - want_r).abs() < 1e-9)
    );
}

#[test]
fn sampled_discs_cover_every_face() {
    let Some(path) = data_common::real_data(CUBE_OBJ) else {
        return;
    };
    let mesh = load_obj(path).expect("cube obj");
    for (n, seed) in [(12_000, 5), (40_000, 6)] {
        let m = mesh.sample(n, seed).expect("sample");
        let r = m.radii[0];
        let pts: Vec<[f32; 3]> = m.positions.iter().map(|p| p.to_array()).collect();
        let tree: ImmutableKdTree<f32, 3> = ImmutableKdTree::new_from_slice(&pts).expect("tree");
        let nearest = |q: Vec3| {
            tree.query(&q.to_array())
                .nearest_one::<SquaredEuclidean<f32>>()
                .execute()
                .distance
                .sqrt()
        };
        // The +z face, and the edge it shares with the +x face (where the
        // discs of both faces count: the edge lies in both their planes).
        let steps = 250;
        let (mut worst_face, mut worst_edge) = (0.0f32, 0.0f32);
        for i in 0..=steps {
            let s = i as f32 / steps as f32 * 2.0 * HALF - HALF;
            worst_edge = worst_edge.max(nearest(Vec3::new(HALF, s, HALF)));
            for j in 0..=steps {
                let t = j as f32 / steps as f32 * 2.0 * HALF - HALF;
                worst_face = worst_face.max(nearest(Vec3::new(s, t, HALF)));
            }
        }
        assert!(
            worst_face < r,
            "{n}: a hole {worst_face} from any sample, radius {r}"
        );
        assert!(
            worst_edge < r,
            "{n}: the edge is {worst_edge} from any sample, radius {r}"
        );
        // Not by a wide margin: discs half as large would leave holes.
        assert!(worst_face > 0.5 * r, "{worst_face} vs {r}");
    }
}

#[test]
fn sampling_is_reproducible_and_seeded() {
    let Some(path) = data_common::real_data(CUBE_OBJ) else {
        return;
    };
    let mesh = load_obj(path).expect("cube obj");
    let a = mesh.sample(1000, 42).expect("a");
    let b = mesh.sample(1000, 42).expect("b");
    let c = mesh.sample(1000, 43).expect("c");
    assert_eq!(a.positions, b.positions);
    assert_ne!(a.positions, c.positions);
}

#[test]
fn dragon_samples_agree_with_the_shared_point_model() {
    let Some(path) = data_common::real_data(DRAGON_OBJ) else {
        return;
    };
    let mesh = load_obj(path).expect("dragon obj");
    assert!(mesh.triangles.len() > 10_000);
    let m = mesh.sample(20_000, 3).expect("sample");
    m.validate().expect("valid");
    // The shared model was sampled from the same mesh: every sample has a
    // model point nearby, whose normal points the same way.
    let Some(ply) = data_common::real_data("visp_rbt_dragon/model.ply") else {
        return;
    };
    let model = PointModel::load_with(
        ply,
        &LoadOptions {
            progress: None,
            ..Default::default()
        },
    )
    .expect("model");
    let pts: Vec<[f32; 3]> = model.positions.iter().map(|p| p.to_array()).collect();
    let tree: ImmutableKdTree<f32, 3> = ImmutableKdTree::new_from_slice(&pts).expect("tree");
    let mut agree = 0;
    for (p, n) in m.positions.iter().zip(&m.normals) {
        let nearest = tree
            .query(&p.to_array())
            .nearest_one::<SquaredEuclidean<f32>>()
            .execute();
        assert!(
            nearest.distance.sqrt() < 5.0 * model.radii[0],
            "{p} far from the model"
        );
        if n.dot(model.normals[nearest.item as usize]) > 0.0 {
            agree += 1;
        }
    }
    assert!(
        agree as f64 > 0.995 * m.len() as f64,
        "{agree} of {}",
        m.len()
    );
}

#[test]
fn obj_forms_negative_indices_polygons_and_colours() {
    // A unit square in z = 0 as a quad with v/vt/vn, then a pentagon with
    // negative indices and v//vn, plus everything that should be ignored.
    let text = "# comment\nmtllib x.mtl\no thing\ng group\ns off\n\
                v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 1 1 0 0 0 1\nv 0 1 0 1 1 1\n\
                vt 0 0\nvt 1 0\nvn 0 0 1\nusemtl m\n\
                f 1/1/1 2/2/1 3/1/1 4/2/1 # quad\n\
                v 0 0 1 0 0 0\nv 1 0 1 0 0 0\nv 1.5 0.5 1 0 0 0\nv 1 1 1 0 0 0\nv 0 1 1 0 0 0\n\
                f -5//1 -4//1 -3//1 -2//1 -1//1\nl 1 2\np 3\n";
    let f = TempFile::with_bytes("forms", "obj", text.as_bytes());
    let mesh = load_obj(f.path()).expect("obj");
    assert_eq!(mesh.vertices.len(), 9);
    assert_eq!(
        mesh.triangles,
        vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7], [4, 7, 8]]
    );
    let colors = mesh.colors.as_ref().expect("vertex colours");
    assert_eq!(colors[2], [0.0, 0.0, 1.0]);

    let m = mesh.sample(4000, 0).expect("sample");
    assert_eq!(m.provenance.colors, AttributeSource::FromMesh);
    let cols = m.colors.as_ref().expect("colours");
    let (mut bottom, mut top) = (0usize, 0usize);
    for ((p, n), c) in m.positions.iter().zip(&m.normals).zip(cols) {
        assert!(
            (*n - Vec3::Z).length() < 1e-6,
            "CCW in the xy plane faces +z"
        );
        if p.z == 0.0 {
            bottom += 1;
            // On the quad the colours are barycentric: they blend red, green,
            // blue and white by where the point is.
            let expect_r = (1.0 - p.x) * (1.0 - p.y) + (1.0 - p.x) * p.y;
            let in_first = p.x >= p.y; // triangle (0,0)-(1,0)-(1,1)
            if in_first {
                assert!((c[0] - (1.0 - p.x)).abs() < 1e-4, "{p} {c:?}");
                assert!((c[2] - p.y).abs() < 1e-4, "{p} {c:?}");
            } else {
                assert!((c[0] - expect_r).abs() < 1e-4, "{p} {c:?}");
            }
        } else {
            top += 1;
            assert_eq!(*c, [0.0, 0.0, 0.0]);
        }
    }
    // Areas 1 and 1.25: samples split 4 to 5.
    assert!(
        (bottom as f64 - 4000.0 / 2.25).abs() <= 3.0,
        "{bottom} {top}"
    );
}

#[test]
fn winding_decides_the_normal() {
    let v = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let ccw = PointModel::from_mesh(&v, &[[0, 1, 2]], 50, 0).expect("ccw");
    let cw = PointModel::from_mesh(&v, &[[0, 2, 1]], 50, 0).expect("cw");
    assert!(ccw.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
    assert!(cw.normals.iter().all(|n| (*n + Vec3::Z).length() < 1e-6));
    assert!(ccw.provenance.path.is_none());

    // Degenerate and non-finite triangles get no samples; bad indices are refused.
    let v = [
        Vec3::ZERO,
        Vec3::X,
        Vec3::Y,
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::NAN,
    ];
    let m = PointModel::from_mesh(&v, &[[0, 1, 3], [0, 1, 2], [4, 1, 2]], 200, 0).expect("mesh");
    assert_eq!(m.provenance.dropped_non_finite, 1);
    assert!(
        m.positions
            .iter()
            .all(|p| p.x + p.y <= 1.0 + 1e-6 && p.z == 0.0)
    );
    let err = PointModel::from_mesh(&v, &[[0, 1, 9]], 10, 0).expect_err("bad index");
    assert!(err.to_string().contains("<memory>"), "{err}");
    assert!(PointModel::from_mesh(&v, &[[0, 1, 2]], 0, 0).is_err());
    assert!(PointModel::from_mesh(&v, &[[0, 1, 2]], usize::MAX, 0).is_err());
}

#[test]
fn ply_meshes_with_quads_and_colours() {
    let mut vertex = El::new(
        "vertex",
        &[
            ("float", "x"),
            ("float", "y"),
            ("float", "z"),
            ("uchar", "red"),
            ("uchar", "green"),
            ("uchar", "blue"),
        ],
    );
    for (p, c) in [
        ([0.0, 0.0, 0.0], [255.0, 0.0, 0.0]),
        ([1.0, 0.0, 0.0], [255.0, 0.0, 0.0]),
        ([1.0, 0.0, 1.0], [255.0, 0.0, 0.0]),
        ([0.0, 0.0, 1.0], [255.0, 0.0, 0.0]),
    ] {
        vertex
            .rows
            .push(p.iter().chain(&c).map(|&v| Val::S(v)).collect());
    }
    // The quad (0,0,0) (0,0,1) (1,0,1) (1,0,0) winds to face +y, plus a
    // two-vertex face that is skipped.
    let face = El::new("face", &[("list uchar int", "vertex_indices")])
        .row(vec![Val::L(vec![0.0, 3.0, 2.0, 1.0])])
        .row(vec![Val::L(vec![0.0, 1.0])]);
    for format in ["ascii", "binary_big_endian"] {
        let f = TempFile::with_bytes(
            "plymesh",
            "ply",
            &ply_bytes(format, &[vertex.clone(), face.clone()]),
        );
        let mesh: TriangleMesh = load_mesh_ply(f.path()).expect("ply mesh");
        assert_eq!(mesh.triangles, vec![[0, 3, 2], [0, 2, 1]]);
        let m = mesh.sample(300, 9).expect("sample");
        assert!(m.normals.iter().all(|n| (*n - Vec3::Y).length() < 1e-6));
        assert!(
            m.colors
                .expect("colours")
                .iter()
                .all(|c| (c[0] - 1.0).abs() < 1e-5 && c[1] == 0.0)
        );
    }
}

#[test]
fn load_any_samples_every_mesh_and_loads_clouds_as_points() {
    // An ASCII STL of the unit square in z = 0 (two triangles, counter-
    // clockwise from +z), and the same square as a PLY with faces.
    let stl = "solid sq\n\
        facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 1 1 0\n endloop\nendfacet\n\
        facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 1 0\n  vertex 0 1 0\n endloop\nendfacet\n\
        endsolid sq\n";
    let f = TempFile::with_bytes("square", "STL", stl.as_bytes());
    let mesh = TriangleMesh::load_stl(f.path()).expect("stl");
    assert!((mesh.area() - 1.0).abs() < 1e-12);
    let opts = LoadOptions::default();
    let m = PointModel::load_any_with(f.path(), 2000, &opts).expect("sampled stl");
    assert_eq!(m.len(), 2000);
    assert_eq!(m.provenance.normals, AttributeSource::FromMesh);
    assert!(m.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
    assert!(
        m.positions
            .iter()
            .all(|p| p.z == 0.0 && (0.0..=1.0).contains(&p.x) && (0.0..=1.0).contains(&p.y))
    );
    // 0 points: the default count, as `track` samples.
    let m = PointModel::load_any_with(f.path(), 0, &opts).expect("default count");
    assert_eq!(m.len(), splattrack::model::DEFAULT_MESH_POINTS);

    let mut vertex = El::new("vertex", &[("float", "x"), ("float", "y"), ("float", "z")]);
    for p in [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ] {
        vertex.rows.push(p.iter().map(|&v| Val::S(v)).collect());
    }
    let face = El::new("face", &[("list uchar int", "vertex_indices")])
        .row(vec![Val::L(vec![0.0, 1.0, 2.0, 3.0])]);
    let mesh_ply = TempFile::with_bytes(
        "squareply",
        "ply",
        &ply_bytes("ascii", &[vertex.clone(), face]),
    );
    // Its 4 vertices alone are no surface: sampled even when asked for 0.
    let m = PointModel::load_any_with(mesh_ply.path(), 0, &opts).expect("ply mesh");
    assert_eq!(m.len(), splattrack::model::DEFAULT_MESH_POINTS);
    // load_auto keeps loading it as its vertices.
    assert_eq!(PointModel::load_auto(mesh_ply.path(), 0).unwrap().len(), 4);
    // A PLY without faces is a point model.
    for y in [0.5, 0.25] {
        vertex.rows.push(vec![Val::S(0.5), Val::S(y), Val::S(0.0)]);
    }
    let cloud = TempFile::with_bytes("cloud", "ply", &ply_bytes("ascii", &[vertex]));
    let m = PointModel::load_any_with(cloud.path(), 0, &opts).expect("cloud");
    assert_eq!(m.len(), 6);
    assert_eq!(m.provenance.normals, AttributeSource::Estimated);
}
