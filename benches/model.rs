//! Point model loading: read a PLY and estimate normals (PCA + orientation)
//! and radii, for 10k, 100k and 1M point clouds (a randomly sampled torus,
//! written once to a temporary binary PLY with positions only); reading alone
//! for the same clouds once every attribute is in the file; and sampling a
//! mesh.
//!
//! `cargo bench --bench model`

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use splattrack::model::{LoadOptions, PointModel, TriangleMesh, shapes};
use std::hint::black_box;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

const SIZES: [usize; 3] = [10_000, 100_000, 1_000_000];

/// Writes a positions-only binary PLY.
fn write_xyz(path: &Path, pos: &[Vec3]) {
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\nend_header\n",
        pos.len()
    )
    .into_bytes();
    for p in pos {
        for c in p.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    let mut f = std::fs::File::create(path).expect("create bench file");
    f.write_all(&out).expect("write bench file");
}

struct Files(Vec<PathBuf>);

impl Drop for Files {
    fn drop(&mut self) {
        for p in &self.0 {
            let _ = std::fs::remove_file(p);
        }
    }
}

fn bench_load(c: &mut Criterion) {
    let quiet = LoadOptions {
        progress: None,
        ..Default::default()
    };
    let dir = std::env::temp_dir();
    let mut files = Files(Vec::new());
    let mut full = Vec::new();
    for n in SIZES {
        let bare = dir.join(format!("splattrack-bench-{}-{n}.ply", std::process::id()));
        write_xyz(&bare, &shapes::random_torus(n, 1.0, 0.3, n as u64).0);
        files.0.push(bare.clone());
        // The same cloud with normals and radii in the file, for reading alone.
        let model = PointModel::load_with(&bare, &quiet).expect("estimate");
        let complete = dir.join(format!(
            "splattrack-bench-full-{}-{n}.ply",
            std::process::id()
        ));
        model.save_ply(&complete).expect("save");
        files.0.push(complete.clone());
        full.push((n, bare, complete));
    }

    let mut group = c.benchmark_group("load_and_estimate");
    group.sample_size(10);
    for (n, bare, _) in &full {
        if *n >= 1_000_000 {
            group.measurement_time(Duration::from_secs(30));
            group.warm_up_time(Duration::from_secs(1));
        }
        group.throughput(Throughput::Elements(*n as u64));
        group.bench_with_input(BenchmarkId::from_parameter(n), bare, |b, path| {
            b.iter(|| black_box(PointModel::load_with(path, &quiet).expect("load")))
        });
    }
    group.finish();

    let mut group = c.benchmark_group("load_complete");
    group.sample_size(10);
    for (n, _, complete) in &full {
        group.throughput(Throughput::Elements(*n as u64));
        group.bench_with_input(BenchmarkId::from_parameter(n), complete, |b, path| {
            b.iter(|| black_box(PointModel::load_with(path, &quiet).expect("load")))
        });
    }
    group.finish();
}

fn bench_sample(c: &mut Criterion) {
    let root = std::env::var_os("SPLATTRACK_DATA").unwrap_or_else(|| "../shared/data".into());
    let path = std::path::Path::new(&root).join("visp_rbt_dragon/mesh.obj");
    let Ok(mesh) = TriangleMesh::load_obj(&path) else {
        eprintln!(
            "{} not found (SPLATTRACK_DATA); no sampling bench",
            path.display()
        );
        return;
    };
    let mut group = c.benchmark_group("sample_dragon_mesh");
    group.sample_size(10);
    for n in [100_000usize, 1_000_000] {
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, &n| {
            b.iter(|| black_box(mesh.sample(n, 1).expect("sample")))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_load, bench_sample);
criterion_main!(benches);
