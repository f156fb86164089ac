//! The crate's WGSL shaders and the one source of every contract between
//! them and the Rust code, validated by naga (the tests need no GPU).
//!
//! # How it works
//!
//! Each shader is composed as
//! 1. a prelude generated from the Rust constants ([`CONSTANTS`]): pixel
//!    flags, sentinels, the NCC tile, the gather stride and modes, the
//!    resolve kinds, the Harris tap count, the workgroup sizes; a WGSL file never defines one itself (a
//!    second definition does not compile);
//! 2. `shaders/common.wgsl`: the structs several shaders share
//!    (`CameraUniform`, `Pixel`) and their helpers;
//! 3. for the two splatters (`splat`, `splat_compute`),
//!    `shaders/splat_common.wgsl`: the splat, the view uniform, culling,
//!    screen bounds and the ray-splat intersection;
//! 4. the shader's own file.
//!
//! Every struct the host shares with WGSL is declared with [`wgsl_struct!`](crate::wgsl_struct),
//! which records its members' names, offsets and sizes; the tests compare
//! each with naga's layout of the WGSL struct of the same name (and check
//! that every struct a shader binds as a buffer has a Rust twin), so a
//! field added, moved or resized on one side only fails the build's tests.

use std::fmt::Write;
use std::sync::OnceLock;

/// Every shader under `shaders/` (except `common.wgsl` and
/// `splat_common.wgsl`, composed into others), by file stem. Add new files
/// here.
pub const ALL: &[(&str, &str)] = &[
    ("selftest", include_str!("../shaders/selftest.wgsl")),
    ("splat", include_str!("../shaders/splat.wgsl")),
    (
        "splat_resolve",
        include_str!("../shaders/splat_resolve.wgsl"),
    ),
    (
        "splat_compute",
        include_str!("../shaders/splat_compute.wgsl"),
    ),
    ("harris", include_str!("../shaders/harris.wgsl")),
    ("ncc", include_str!("../shaders/ncc.wgsl")),
    ("present", include_str!("../shaders/present.wgsl")),
    ("verify", include_str!("../shaders/verify.wgsl")),
    ("frame", include_str!("../shaders/frame.wgsl")),
    ("outline", include_str!("../shaders/outline.wgsl")),
];

/// What every shader shares: structs and helpers (composed after the
/// prelude).
pub const COMMON: &str = include_str!("../shaders/common.wgsl");

/// What the two splatters share (`splat` and `splat_compute`): the splat
/// struct, the view uniform, culling, screen bounds and the ray-splat
/// intersection (composed after common.wgsl).
pub const SPLAT_COMMON: &str = include_str!("../shaders/splat_common.wgsl");

/// The shaders [`SPLAT_COMMON`] is composed into.
const SPLATTERS: [&str; 2] = ["splat", "splat_compute"];

/// The value of a constant shared with WGSL.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WgslValue {
    U32(u32),
    F32(f32),
}

/// Every constant shared between Rust and WGSL, by its name on both sides.
/// The Rust constant is the definition; the prelude writes it for WGSL.
pub const CONSTANTS: &[(&str, WgslValue)] = {
    use crate::features::gpu_data as f;
    use crate::gpu;
    use crate::splat::gpu_data as s;
    use WgslValue::{F32, U32};
    &[
        ("WORKGROUP_1D", U32(gpu::WORKGROUP_1D)),
        ("WORKGROUP_2D", U32(gpu::WORKGROUP_2D)),
        ("PIXEL_VALID", U32(f::PIXEL_VALID)),
        ("PIXEL_ALLOWED", U32(f::PIXEL_ALLOWED)),
        ("PIXEL_HOLE", U32(f::PIXEL_HOLE)),
        ("PINHOLE_NEIGHBOURS", U32(f::PINHOLE_NEIGHBOURS as u32)),
        ("INVALID_RESPONSE", F32(f::INVALID_RESPONSE)),
        ("MAX_TAPS", U32(f::MAX_TAPS as u32)),
        ("MAX_DERIV_RADIUS", U32(f::MAX_DERIV_RADIUS as u32)),
        (
            "MAX_INTEGRATION_RADIUS",
            U32(f::MAX_INTEGRATION_RADIUS as u32),
        ),
        ("HARRIS_BLOCK", U32(f::HARRIS_BLOCK)),
        ("FUSED_HALO", U32(f::FUSED_HALO)),
        ("SELECT_MAX", U32(f::SELECT_MAX)),
        ("MERGE_LINKS", U32(f::MERGE_LINKS)),
        ("NO_SCORE", F32(f::NO_SCORE)),
        ("NO_INDEX", U32(f::NO_INDEX)),
        ("NCC_TILE", U32(f::NCC_TILE)),
        ("REFINE_LOCAL_WINDOW", U32(f::REFINE_LOCAL_WINDOW)),
        ("REFINE_GROUP_RADIUS", U32(f::REFINE_GROUP_RADIUS)),
        ("VECTORIZE_GROUP_WINDOW", U32(f::VECTORIZE_GROUP_WINDOW)),
        ("GATHER_STRIDE", U32(s::GATHER_STRIDE as u32)),
        ("RESOLVE_WORKGROUP", U32(s::RESOLVE_WORKGROUP)),
        ("RESOLVE_COLOR", U32(s::RESOLVE_COLOR)),
        ("RESOLVE_DEPTH", U32(s::RESOLVE_DEPTH)),
        ("RESOLVE_NORMAL", U32(s::RESOLVE_NORMAL)),
        ("RESOLVE_MOTION", U32(s::RESOLVE_MOTION)),
        ("RESOLVE_WEIGHT", U32(s::RESOLVE_WEIGHT)),
        ("RESOLVE_DEPTH_MOTION", U32(s::RESOLVE_DEPTH_MOTION)),
        ("GATHER_NEAREST", U32(s::GATHER_NEAREST)),
        ("GATHER_BILINEAR", U32(s::GATHER_BILINEAR)),
        ("COMPUTE_GEOMETRY", U32(s::COMPUTE_GEOMETRY)),
        ("COMPUTE_MOTION", U32(s::COMPUTE_MOTION)),
        ("ACC_STRIDE", U32(s::ACC_STRIDE)),
        ("FIXED_SCALE", F32(s::FIXED_SCALE)),
        ("BIG_SPLAT_PIXELS", U32(s::BIG_SPLAT_PIXELS)),
        ("CHECK_SUMS", U32(crate::tracker::verify_gpu::CHECK_SUMS)),
        (
            "CHECK_WORKGROUP",
            U32(crate::tracker::verify_gpu::CHECK_WORKGROUP),
        ),
        (
            "OUTLINE_WINDOW",
            U32(crate::tracker::outline_gpu::OUTLINE_WINDOW),
        ),
        (
            "OUTLINE_MIN_GRADIENT",
            U32(crate::tracker::outline_gpu::OUTLINE_MIN_GRADIENT),
        ),
        ("LUMA_R", F32(crate::features::image::LUMA[0])),
        ("LUMA_G", F32(crate::features::image::LUMA[1])),
        ("LUMA_B", F32(crate::features::image::LUMA[2])),
    ]
};

/// The WGSL declarations of [`CONSTANTS`]: f32 values are written with the
/// shortest decimal that reads back to the same bits (checked by a test).
pub fn prelude() -> String {
    let mut out = String::from(
        "// Generated by src/shaders.rs from the Rust constants; do not define these in WGSL.\n",
    );
    for (name, value) in CONSTANTS {
        let _ = match value {
            WgslValue::U32(v) => writeln!(out, "const {name}: u32 = {v}u;"),
            WgslValue::F32(v) => writeln!(out, "const {name}: f32 = {v:?}f;"),
        };
    }
    out
}

/// The composed source of shader `name` (`file`: its text): prelude,
/// common.wgsl, splat_common.wgsl for the splatters, then the file.
fn compose(name: &str, file: &str) -> String {
    let splat = if SPLATTERS.contains(&name) {
        format!("// ---- shaders/splat_common.wgsl\n{SPLAT_COMMON}\n")
    } else {
        String::new()
    };
    format!(
        "{}\n// ---- shaders/common.wgsl\n{COMMON}\n{splat}// ---- the shader\n{file}",
        prelude()
    )
}

/// The composed source of the shader named `name` (its file stem), as it
/// is compiled.
pub fn source(name: &str) -> Option<&'static str> {
    static COMPOSED: OnceLock<Vec<(&'static str, String)>> = OnceLock::new();
    COMPOSED
        .get_or_init(|| ALL.iter().map(|(n, s)| (*n, compose(n, s))).collect())
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, s)| s.as_str())
}

/// Parses and validates a WGSL module with naga; the error quotes the line
/// (of the composed source: prelude, common.wgsl, then the file).
pub fn validate(name: &str, source: &str) -> Result<naga::Module, String> {
    let path = format!("shaders/{name}.wgsl (composed)");
    let module = naga::front::wgsl::parse_str(source)
        .map_err(|e| e.emit_to_string_with_path(source, &path))?;
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .map_err(|e| e.emit_to_string_with_path(source, &path))?;
    Ok(module)
}

/// One member of a struct shared with WGSL, as Rust lays it out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Member {
    pub name: &'static str,
    pub offset: usize,
    pub size: usize,
}

/// A `#[repr(C)]` struct with a WGSL twin of the same name. Implemented by
/// [`wgsl_struct!`](crate::wgsl_struct); never by hand, so that the members cannot drift from
/// the definition.
pub trait WgslStruct: bytemuck::Pod {
    /// The struct's name, in Rust and in WGSL.
    const NAME: &'static str;
    /// Every member in declaration order.
    fn members() -> Vec<Member>;
}

/// Declares a `#[repr(C)]` struct shared with WGSL and implements
/// [`WgslStruct`] for it from the same tokens. Padding members are named
/// like their WGSL twins with a leading underscore (`_pad0` for `pad0`).
#[macro_export]
macro_rules! wgsl_struct {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $( $(#[$fmeta:meta])* $fvis:vis $field:ident : $ty:ty ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[repr(C)]
        $vis struct $name {
            $( $(#[$fmeta])* $fvis $field: $ty ),*
        }
        impl $crate::shaders::WgslStruct for $name {
            const NAME: &'static str = stringify!($name);
            fn members() -> Vec<$crate::shaders::Member> {
                vec![$($crate::shaders::Member {
                    name: stringify!($field),
                    offset: std::mem::offset_of!($name, $field),
                    size: std::mem::size_of::<$ty>(),
                }),*]
            }
        }
    };
}

/// The layout of a Rust twin, for comparison with naga's.
#[derive(Debug, Clone)]
pub struct RustLayout {
    pub name: &'static str,
    pub size: usize,
    pub members: Vec<Member>,
}

impl RustLayout {
    pub fn of<T: WgslStruct>() -> Self {
        Self {
            name: T::NAME,
            size: std::mem::size_of::<T>(),
            members: T::members(),
        }
    }
}

/// Every struct the host shares with a shader.
pub fn rust_twins() -> Vec<RustLayout> {
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

/// Compares `rust` with the struct of the same name in `module`: `Ok(false)`
/// when the module has no such struct, an error naming every difference
/// (size, member count, names, offsets, sizes) when they disagree.
pub fn compare_twin(module: &naga::Module, rust: &RustLayout) -> Result<bool, String> {
    let Some((_, ty)) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(rust.name))
    else {
        return Ok(false);
    };
    let naga::TypeInner::Struct { members, span } = &ty.inner else {
        return Err(format!("{} is not a struct in WGSL", rust.name));
    };
    let mut layouter = naga::proc::Layouter::default();
    layouter
        .update(module.to_ctx())
        .map_err(|e| format!("layout of {}: {e}", rust.name))?;
    let mut diffs = Vec::new();
    if *span as usize != rust.size {
        diffs.push(format!("size: WGSL {span}, Rust {}", rust.size));
    }
    if members.len() != rust.members.len() {
        diffs.push(format!(
            "{} members in WGSL, {} in Rust",
            members.len(),
            rust.members.len()
        ));
    }
    for (w, r) in members.iter().zip(&rust.members) {
        let wname = w.name.as_deref().unwrap_or("?");
        let wsize = layouter[w.ty].size as usize;
        if wname != r.name.trim_start_matches('_')
            || w.offset as usize != r.offset
            || wsize != r.size
        {
            diffs.push(format!(
                "WGSL {wname} at {} ({wsize} bytes) against Rust {} at {} ({} bytes)",
                w.offset, r.name, r.offset, r.size
            ));
        }
    }
    if diffs.is_empty() {
        Ok(true)
    } else {
        Err(format!("{}: {}", rust.name, diffs.join("; ")))
    }
}

/// WGSL structs bound as uniform or storage buffers (directly or as the
/// element of an array) that have no Rust twin in `twins`.
pub fn untwinned_buffer_structs(module: &naga::Module, twins: &[RustLayout]) -> Vec<String> {
    let mut out = Vec::new();
    for (_, var) in module.global_variables.iter() {
        if !matches!(
            var.space,
            naga::AddressSpace::Uniform | naga::AddressSpace::Storage { .. }
        ) {
            continue;
        }
        let mut ty = &module.types[var.ty];
        while let naga::TypeInner::Array { base, .. } = ty.inner {
            ty = &module.types[base];
        }
        if let (naga::TypeInner::Struct { .. }, Some(name)) = (&ty.inner, &ty.name) {
            if !twins.iter().any(|t| t.name == name) && !out.contains(name) {
                out.push(name.clone());
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn modules() -> Vec<(&'static str, naga::Module)> {
        ALL.iter()
            .map(|(name, _)| {
                let module =
                    validate(name, source(name).unwrap()).unwrap_or_else(|e| panic!("{e}"));
                (*name, module)
            })
            .collect()
    }

    #[test]
    fn every_shader_validates() {
        let failures: Vec<String> = ALL
            .iter()
            .filter_map(|(name, _)| validate(name, source(name).unwrap()).err())
            .collect();
        assert!(failures.is_empty(), "{}", failures.join("\n"));
    }

    #[test]
    fn every_wgsl_file_is_registered() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "wgsl") {
                let stem = path.file_stem().unwrap().to_str().unwrap().to_owned();
                assert!(
                    ["common", "splat_common"].contains(&stem.as_str()) || source(&stem).is_some(),
                    "shaders/{stem}.wgsl is not in shaders::ALL"
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
    fn the_prelude_holds_the_rust_values_bit_for_bit() {
        let module = validate("prelude", &prelude()).unwrap();
        for (name, value) in CONSTANTS {
            let (_, c) = module
                .constants
                .iter()
                .find(|(_, c)| c.name.as_deref() == Some(*name))
                .unwrap_or_else(|| panic!("{name} is not in the prelude"));
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
            assert!(same, "{name}: WGSL {got:?}, Rust {value:?}");
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
                    Err(e) => failures.push(format!("shaders/{name}.wgsl: {e}")),
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
                failures.push(format!("shaders/{name}.wgsl: {s} has no Rust twin"));
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
}
