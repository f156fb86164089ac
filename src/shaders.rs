//! The crate's WGSL shaders, compiled into the binary with `include_str!`
//! and validated by naga (a unit test checks every one without a GPU).

/// Every shader under `shaders/`, by file stem. Add new files here.
pub const ALL: &[(&str, &str)] = &[
    ("selftest", include_str!("../shaders/selftest.wgsl")),
    ("splat", include_str!("../shaders/splat.wgsl")),
    (
        "splat_resolve",
        include_str!("../shaders/splat_resolve.wgsl"),
    ),
    ("harris", include_str!("../shaders/harris.wgsl")),
    ("ncc", include_str!("../shaders/ncc.wgsl")),
];

/// The source of the shader named `name` (its file stem).
pub fn source(name: &str) -> Option<&'static str> {
    ALL.iter().find(|(n, _)| *n == name).map(|(_, s)| *s)
}

/// Parses and validates a WGSL module with naga; the error names the line.
pub fn validate(name: &str, source: &str) -> Result<naga::Module, String> {
    let module = naga::front::wgsl::parse_str(source)
        .map_err(|e| e.emit_to_string_with_path(source, &format!("shaders/{name}.wgsl")))?;
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .map_err(|e| e.emit_to_string_with_path(source, &format!("shaders/{name}.wgsl")))?;
    Ok(module)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shader_validates() {
        let failures: Vec<String> = ALL
            .iter()
            .filter_map(|(name, src)| validate(name, src).err())
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
                    source(&stem).is_some(),
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
}
