//! The checks of every shader and every Rust/WGSL twin: each shader
//! validates, each file under `shaders/` is part of a shader, each prelude
//! holds its constants bit for bit, each twin matches its WGSL struct and
//! each struct a shader binds as a buffer has a twin. Add a new shader to
//! [`shaders`] and a new twin to [`rust_twins`].

use super::*;

/// Every shader of the crate.
fn shaders() -> Vec<&'static Shader> {
    vec![
        &crate::gpu::selftest::SHADER,
        &crate::splat::gpu_data::SPLAT_SHADER,
        &crate::splat::gpu_data::RESOLVE_SHADER,
        &crate::splat::gpu_data::COMPUTE_SHADER,
        &crate::features::harris::SHADER,
        &crate::features::ncc::SHADER,
        &crate::features::resident::SHADER,
        &crate::view::present::SHADER,
        &crate::tracker::verify_gpu::SHADER,
        &crate::tracker::outline_gpu::SHADER,
    ]
}

/// Every struct the host shares with a shader.
fn rust_twins() -> Vec<RustLayout> {
    use crate::features::gpu_data as f;
    use crate::splat::gpu_data as s;
    vec![
        RustLayout::of::<crate::gpu::selftest::SelftestParams>(),
        RustLayout::of::<s::SplatGpu>(),
        RustLayout::of::<s::CameraUniform>(),
        RustLayout::of::<s::ResolveParams>(),
        RustLayout::of::<s::ComputeParams>(),
        RustLayout::of::<f::Pixel>(),
        RustLayout::of::<f::HarrisParams>(),
        RustLayout::of::<f::Candidate>(),
        RustLayout::of::<f::Counters>(),
        RustLayout::of::<f::RefineCorner>(),
        RustLayout::of::<f::ExportParams>(),
        RustLayout::of::<f::NccParams>(),
        RustLayout::of::<f::Best>(),
        RustLayout::of::<f::MatchOut>(),
        RustLayout::of::<crate::view::present::PresentParams>(),
        RustLayout::of::<crate::tracker::verify_gpu::CheckParams>(),
        RustLayout::of::<crate::tracker::outline_gpu::OutlineParams>(),
        RustLayout::of::<crate::tracker::outline_gpu::OutlinePoint>(),
        RustLayout::of::<crate::features::resident::FrameParams>(),
        RustLayout::of::<crate::features::resident::WindowParams>(),
    ]
}

fn modules() -> Vec<(&'static str, naga::Module)> {
    shaders()
        .into_iter()
        .map(|s| (s.name, s.validate().unwrap_or_else(|e| panic!("{e}")).1))
        .collect()
}

#[test]
fn every_shader_validates() {
    let failures: Vec<String> = shaders()
        .into_iter()
        .filter_map(|s| s.validate().err())
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn shader_names_are_unique() {
    let names: Vec<&str> = shaders().iter().map(|s| s.name).collect();
    for (i, n) in names.iter().enumerate() {
        assert!(!names[..i].contains(n), "two shaders are named {n}");
    }
}

#[test]
fn every_wgsl_file_is_part_of_a_shader() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let parts: Vec<&str> = shaders()
        .iter()
        .flat_map(|s| s.parts.iter().map(|(path, _)| *path))
        .collect();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "wgsl") {
            let name = path.file_name().unwrap().to_str().unwrap().to_owned();
            assert!(
                parts.contains(&format!("shaders/{name}").as_str()),
                "shaders/{name} is in no shader"
            );
        }
    }
}

#[test]
fn a_broken_shader_is_reported() {
    let err = validate("broken", "fn f() -> f32 { return vec2<f32>(1.0); }").unwrap_err();
    assert!(err.contains("broken"), "{err}");
}

#[test]
fn every_prelude_holds_the_rust_values_bit_for_bit() {
    for shader in shaders() {
        let module = validate(shader.name, &shader.prelude()).unwrap();
        for (name, value) in shader.constants.iter().copied().flatten() {
            let (_, c) = module
                .constants
                .iter()
                .find(|(_, c)| c.name.as_deref() == Some(*name))
                .unwrap_or_else(|| panic!("{name} is not in the prelude of {}", shader.name));
            let got = match module.global_expressions[c.init] {
                naga::Expression::Literal(naga::Literal::U32(v)) => WgslValue::U32(v),
                naga::Expression::Literal(naga::Literal::F32(v)) => WgslValue::F32(v),
                ref e => panic!("{name} = {e:?}"),
            };
            let same = match (got, value) {
                (WgslValue::U32(a), WgslValue::U32(b)) => a == *b,
                (WgslValue::F32(a), WgslValue::F32(b)) => a.to_bits() == b.to_bits(),
                _ => false,
            };
            assert!(same, "{} {name}: WGSL {got:?}, Rust {value:?}", shader.name);
        }
    }
}

#[test]
fn every_rust_twin_matches_its_wgsl_struct() {
    let modules = modules();
    let mut failures = Vec::new();
    for twin in rust_twins() {
        let mut found = false;
        for (name, module) in &modules {
            match compare_twin(module, &twin) {
                Ok(f) => found |= f,
                Err(e) => failures.push(format!("shader {name}: {e}")),
            }
        }
        if !found {
            failures.push(format!("{} has no WGSL twin in any shader", twin.name));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn every_buffer_struct_has_a_rust_twin() {
    let twins = rust_twins();
    let mut failures = Vec::new();
    for (name, module) in modules() {
        for s in untwinned_buffer_structs(&module, &twins) {
            failures.push(format!("shader {name}: {s} has no Rust twin"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

crate::wgsl_struct! {
    #[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
    struct Pair {
        a: f32,
        b: u32,
    }
}

fn pair_module(wgsl: &str) -> naga::Module {
    validate("pair", wgsl).unwrap()
}

#[test]
fn a_matching_pair_passes() {
    let m = pair_module("struct Pair { a: f32, b: u32 }");
    assert_eq!(compare_twin(&m, &RustLayout::of::<Pair>()), Ok(true));
}

#[test]
fn a_member_on_one_side_only_fails() {
    let m = pair_module("struct Pair { a: f32, b: u32, c: u32 }");
    let err = compare_twin(&m, &RustLayout::of::<Pair>()).unwrap_err();
    assert!(err.contains("3 members in WGSL, 2 in Rust"), "{err}");
    assert!(err.contains("size: WGSL 12, Rust 8"), "{err}");
}

#[test]
fn reordered_retyped_or_renamed_members_fail() {
    for wgsl in [
        "struct Pair { b: u32, a: f32 }",
        "struct Pair { a: f32, b: vec2<u32> }",
        "struct Pair { a: f32, c: u32 }",
        "struct Pair { a: f32, @align(8) b: u32 }",
    ] {
        let m = pair_module(wgsl);
        assert!(
            compare_twin(&m, &RustLayout::of::<Pair>()).is_err(),
            "{wgsl} passed"
        );
    }
}

#[test]
fn a_buffer_struct_without_twin_is_found() {
    let m = pair_module(
        "struct Pair { a: f32, b: u32 }\n struct Lone { x: f32 }\n\
         @group(0) @binding(0) var<storage, read> lone: array<Lone>;\n\
         @group(0) @binding(1) var<uniform> pair: Pair;",
    );
    let twins = [RustLayout::of::<Pair>()];
    assert_eq!(
        untwinned_buffer_structs(&m, &twins),
        vec!["Lone".to_owned()]
    );
}
