//! Tabulates the criterion medians of `cargo bench` (splat, features,
//! pose, tracker) as the markdown tables of BENCHMARKS.md and draws how time
//! grows with model and image size.
//!
//! ```sh
//! cargo run --release --example bench_report -- [target/criterion] [--plot growth.png]
//! ```
//!
//! Reads every `*/new/benchmark.json` (the id) and `*/new/estimates.json`
//! (the median, in ns) under the criterion directory.

use splattrack::plot::{LineChart, stack};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn collect(dir: &Path, out: &mut BTreeMap<String, f64>) -> std::io::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        if !path.is_dir() {
            continue;
        }
        let (bench, est) = (path.join("benchmark.json"), path.join("estimates.json"));
        if path.file_name().is_some_and(|n| n == "new") && bench.is_file() && est.is_file() {
            let b: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&bench)?)?;
            let e: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&est)?)?;
            if let (Some(id), Some(ns)) = (
                b["full_id"].as_str(),
                e["median"]["point_estimate"].as_f64(),
            ) {
                out.insert(id.to_owned(), ns * 1e-6);
            }
        } else {
            collect(&path, out)?;
        }
    }
    Ok(())
}

fn fmt(ms: Option<f64>) -> String {
    match ms {
        Some(v) if v >= 100.0 => format!("{v:.0}"),
        Some(v) if v >= 1.0 => format!("{v:.1}"),
        Some(v) => format!("{v:.3}"),
        None => "-".into(),
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut dir = PathBuf::from("target/criterion");
    let mut plot = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--plot" {
            plot = Some(PathBuf::from(args.next().ok_or("--plot needs a file")?));
        } else {
            dir = PathBuf::from(a);
        }
    }
    let mut m = BTreeMap::new();
    collect(&dir, &mut m).map_err(|e| format!("{}: {e}", dir.display()))?;
    if m.is_empty() {
        return Err(format!(
            "{}: no criterion results (run cargo bench first)",
            dir.display()
        )
        .into());
    }
    let get = |id: String| m.get(&id).copied();
    let sizes = ["640x480", "1280x720"];
    let points = [10_000usize, 100_000, 1_000_000];

    println!("### Splatting (ms per render, median)\n");
    println!(
        "| image | points | render: colour | render: colour + predictors | compute: colour | compute: colour + predictors | CPU reference: colour + predictors | CPU / best GPU |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    for s in sizes {
        for n in points {
            let v = |b: &str, a: &str| get(format!("splat/{b}/{a}/{s}/{n}"));
            let (rc, rp, cc, cp, cpu) = (
                v("render", "color"),
                v("render", "color+predictors"),
                v("compute", "color"),
                v("compute", "color+predictors"),
                v("cpu", "color+predictors"),
            );
            if rc.is_none() && cc.is_none() {
                continue;
            }
            let best = match (rp, cp) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
            let ratio = match (cpu, best) {
                (Some(c), Some(g)) => format!("{:.2}", c / g),
                _ => "-".into(),
            };
            println!(
                "| {s} | {n} | {} | {} | {} | {} | {} | {ratio} |",
                fmt(rc),
                fmt(rp),
                fmt(cc),
                fmt(cp),
                fmt(cpu)
            );
        }
    }

    println!("\n### Features (ms, median)\n");
    println!("| step | GPU | CPU reference | CPU / GPU |");
    println!("|---|---:|---:|---:|");
    for (name, g, c) in [
        ("Harris 640x480", "harris_gpu_640x480", "harris_cpu_640x480"),
        (
            "Harris 1280x720",
            "harris_gpu_1280x720",
            "harris_cpu_1280x720",
        ),
        (
            "NCC 900 x 900, 9x9, all pairs",
            "ncc_gpu_900x900_9x9",
            "ncc_cpu_900x900_9x9",
        ),
    ] {
        let (g, c) = (get(format!("features/{g}")), get(format!("features/{c}")));
        let ratio = match (g, c) {
            (Some(g), Some(c)) => format!("{:.2}", c / g),
            _ => "-".into(),
        };
        println!("| {name} | {} | {} | {ratio} |", fmt(g), fmt(c));
    }

    println!("\n### IRLS (host, ms, median)\n");
    println!("| matches | ms |");
    println!("|---:|---:|");
    for n in [100, 900, 3000] {
        if let Some(v) = get(format!("irls/{n}")) {
            println!("| {n} | {} |", fmt(Some(v)));
        }
    }

    println!("\n### Tracking (ms per frame, median)\n");
    println!(
        "| image | points | IT (auto) | KF (auto) | KF+IT render | KF+IT compute | KF+IT + contour (auto) |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for s in sizes {
        for n in points {
            let v = |id: &str| get(format!("track/{id}/{s}/{n}"));
            let row = [
                v("it/auto"),
                v("kf/auto"),
                v("kf+it/render"),
                v("kf+it/compute"),
                v("kf+it+contour/auto"),
            ];
            if row.iter().all(Option::is_none) {
                continue;
            }
            println!(
                "| {s} | {n} | {} | {} | {} | {} | {} |",
                fmt(row[0]),
                fmt(row[1]),
                fmt(row[2]),
                fmt(row[3]),
                fmt(row[4])
            );
        }
    }

    if let Some(path) = plot {
        let mut splat = LineChart::new(
            "Splatting colour + predictors (median per render)",
            "log10(points)",
            "ms",
        );
        let mut track = LineChart::new("KF+IT (median per frame)", "log10(points)", "ms");
        for s in sizes {
            for b in ["render", "compute"] {
                let curve = |prefix: &str| -> Vec<(f64, f64)> {
                    points
                        .iter()
                        .filter_map(|&n| {
                            get(format!("{prefix}/{s}/{n}")).map(|v| ((n as f64).log10(), v))
                        })
                        .collect()
                };
                let p = curve(&format!("splat/{b}/color+predictors"));
                if !p.is_empty() {
                    splat.add(&format!("{b} {s}"), p);
                }
                let p = curve(&format!("track/kf+it/{b}"));
                if !p.is_empty() {
                    track.add(&format!("{b} {s}"), p);
                }
            }
        }
        stack(&[splat, track], 900, 420)
            .save(&path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}
