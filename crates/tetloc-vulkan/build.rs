//! Compiles the GLSL shaders in `shaders/` to SPIR-V at build time with glslang; the crate
//! embeds the results with `include_bytes!` (see src/shaders.rs). Variants of one source
//! differ by `#define`s: `TL_F64` (the exact f64 fallback, for devices with shaderFloat64)
//! and the face kernel (`REP_FACES` / `SHARED_FACES`).

use glslang::include::{IncludeHandler, IncludeResult, IncludeType};
use glslang::{
    Compiler, CompilerOptions, ShaderInput, ShaderSource, ShaderStage, SourceLanguage, SpirvVersion, Target,
    VulkanVersion,
};
use std::path::{Path, PathBuf};

/// (output name, source file, stage, defines)
const SHADERS: &[(&str, &str, ShaderStage, &[&str])] = &[
    ("soft_bvh_f64", "soft_bvh.comp", ShaderStage::Compute, &["TL_F64"]),
    ("soft_bvh_f32", "soft_bvh.comp", ShaderStage::Compute, &[]),
    ("rt_rgen", "rt.rgen", ShaderStage::RayGeneration, &[]),
    ("march_f64", "march.comp", ShaderStage::Compute, &["TL_F64"]),
    ("march_f32", "march.comp", ShaderStage::Compute, &[]),
    ("march_rgen", "march.rgen", ShaderStage::RayGeneration, &[]),
    ("rt_rmiss", "rt.rmiss", ShaderStage::Miss, &[]),
    ("rt_bvh_rint_f64", "rt_bvh.rint", ShaderStage::Intersect, &["TL_F64"]),
    ("rt_bvh_rint_f32", "rt_bvh.rint", ShaderStage::Intersect, &[]),
    ("rt_bvh_rchit", "rt_bvh.rchit", ShaderStage::ClosestHit, &[]),
    ("rt_rep_rchit_f64", "rt_faces.rchit", ShaderStage::ClosestHit, &["REP_FACES", "TL_F64"]),
    ("rt_rep_rchit_f32", "rt_faces.rchit", ShaderStage::ClosestHit, &["REP_FACES"]),
    ("rt_shared_rchit_f64", "rt_faces.rchit", ShaderStage::ClosestHit, &["SHARED_FACES", "TL_F64"]),
    ("rt_shared_rchit_f32", "rt_faces.rchit", ShaderStage::ClosestHit, &["SHARED_FACES"]),
];

/// Resolves `#include "x"` against the shader directory.
struct Includes {
    dir: PathBuf,
}

impl IncludeHandler for Includes {
    fn include(&mut self, _ty: IncludeType, header: &str, _includer: &str, _depth: usize) -> Option<IncludeResult> {
        let path = self.dir.join(header);
        let data = std::fs::read_to_string(&path).ok()?;
        Some(IncludeResult { name: path.display().to_string(), data })
    }
}

fn main() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    println!("cargo:rerun-if-changed={}", dir.display());
    for sub in ["", "common"] {
        for e in std::fs::read_dir(dir.join(sub)).unwrap() {
            println!("cargo:rerun-if-changed={}", e.unwrap().path().display());
        }
    }
    let compiler = Compiler::acquire().expect("glslang initialisation failed");
    let options = CompilerOptions {
        source_language: SourceLanguage::GLSL,
        // Vulkan 1.2 with SPIR-V 1.4: the ray-tracing extension needs SPIR-V 1.4.
        target: Target::Vulkan { version: VulkanVersion::Vulkan1_2, spirv_version: SpirvVersion::SPIRV1_4 },
        version_profile: None,
        messages: glslang::ShaderMessage::DEFAULT,
    };
    let mut failed = false;
    for &(name, file, stage, defines) in SHADERS {
        let text = std::fs::read_to_string(dir.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        let source = ShaderSource::from(text);
        let defs: Vec<(&str, Option<&str>)> = defines.iter().map(|d| (*d, Some("1"))).collect();
        let mut includes = Includes { dir: dir.clone() };
        let compiled = ShaderInput::new(&source, stage, &options, Some(&defs), Some(&mut includes))
            .and_then(|input| compiler.create_shader(input))
            .and_then(|shader| shader.compile());
        match compiled {
            Ok(words) => {
                let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
                std::fs::write(out.join(format!("{name}.spv")), bytes).unwrap();
            }
            Err(e) => {
                eprintln!("{file} ({name}): {e}");
                println!("cargo:warning={file} ({name}): {e}");
                failed = true;
            }
        }
    }
    if failed {
        panic!("shader compilation failed (see the messages above)");
    }
}
