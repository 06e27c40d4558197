//! Writes the GLSL side of the Rust/GLSL interface (`interface.glsl`, from src/interface.rs),
//! compiles the shaders in `shaders/` to SPIR-V with glslang, and writes the shader table
//! (`shaders.rs`: one constant per shader, with its f32 and f64 variants) that src/shaders.rs
//! includes, all from the one list below. Variants of one source differ by `#define`s:
//! `TL_F64` (the exact f64 fallback, for devices with shaderFloat64) and the face kernel
//! (`REP_FACES` / `SHARED_FACES`).

use glslang::include::{IncludeHandler, IncludeResult, IncludeType};
use glslang::{
    Compiler, CompilerOptions, ShaderInput, ShaderSource, ShaderStage, SourceLanguage, SpirvVersion, Target,
    VulkanVersion,
};
use std::fmt::Write;
use std::path::{Path, PathBuf};

#[allow(dead_code)] // build.rs needs only `glsl()`; the library uses the rest
mod interface {
    include!("src/interface.rs");
}

/// A shader as the library names it: source, stage, defines, and whether it has an f64
/// variant (`TL_F64` defined) besides the pure-f32 one.
struct Shader {
    name: &'static str,
    file: &'static str,
    stage: ShaderStage,
    defines: &'static [&'static str],
    f64: bool,
}

const fn shader(name: &'static str, file: &'static str, stage: ShaderStage, f64: bool) -> Shader {
    Shader { name, file, stage, defines: &[], f64 }
}

const SHADERS: &[Shader] = &[
    // soft-bvh (compute) and the volume marcher on it.
    shader("SOFT_BVH", "soft_bvh.comp", ShaderStage::Compute, true),
    shader("MARCH", "march.comp", ShaderStage::Compute, true),
    shader("STREAM", "stream.comp", ShaderStage::Compute, true),
    shader("HINTED", "hinted.comp", ShaderStage::Compute, true),
    shader("MEMPROBE", "memprobe.comp", ShaderStage::Compute, false),
    // Weights applied to many steps' fields (locate once, interpolate many: src/weights.rs).
    shader("WEIGHTS", "weights.comp", ShaderStage::Compute, true),
    // Query ordering (a counting sort along the Morton curve) before a locate launch.
    shader("ORDER", "order.comp", ShaderStage::Compute, false),
    // The GPU build of soft-bvh's structure (src/build).
    shader("BUILD_SORT", "build/sort.comp", ShaderStage::Compute, false),
    shader("BUILD_SCAN", "build/scan.comp", ShaderStage::Compute, false),
    shader("BUILD_HIERARCHY", "build/hierarchy.comp", ShaderStage::Compute, false),
    shader("BUILD_GRID", "build/grid.comp", ShaderStage::Compute, false),
    shader("BUILD_GRID_STARTS", "build/grid_starts.comp", ShaderStage::Compute, true),
    shader("BUILD_NEIGHBORS", "build/neighbors.comp", ShaderStage::Compute, false),
    shader("BUILD_PACK", "build/pack.comp", ShaderStage::Compute, false),
    // The ray-tracing kernels: ray generation (locate, march) and miss shared, hit groups per kernel.
    shader("RT_RGEN", "rt.rgen", ShaderStage::RayGeneration, true),
    shader("MARCH_RGEN", "march.rgen", ShaderStage::RayGeneration, true),
    shader("RT_RMISS", "rt.rmiss", ShaderStage::Miss, false),
    shader("RT_BVH_RINT", "rt_bvh.rint", ShaderStage::Intersect, true),
    shader("RT_BVH_RCHIT", "rt_bvh.rchit", ShaderStage::ClosestHit, false),
    Shader { defines: &["REP_FACES"], ..shader("RT_REP_RCHIT", "rt_faces.rchit", ShaderStage::ClosestHit, true) },
    Shader { defines: &["SHARED_FACES"], ..shader("RT_SHARED_RCHIT", "rt_faces.rchit", ShaderStage::ClosestHit, true) },
];

/// Resolves `#include "x"` against the shader directory, then OUT_DIR (the generated interface).
struct Includes {
    dirs: [PathBuf; 2],
}

impl IncludeHandler for Includes {
    fn include(&mut self, _ty: IncludeType, header: &str, _includer: &str, _depth: usize) -> Option<IncludeResult> {
        self.dirs.iter().find_map(|dir| {
            let path = dir.join(header);
            let data = std::fs::read_to_string(&path).ok()?;
            Some(IncludeResult { name: path.display().to_string(), data })
        })
    }
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("shaders");
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    println!("cargo:rerun-if-changed={}", root.join("src/interface.rs").display());
    println!("cargo:rerun-if-changed={}", dir.display());
    for sub in ["", "common", "build"] {
        for e in std::fs::read_dir(dir.join(sub)).unwrap() {
            println!("cargo:rerun-if-changed={}", e.unwrap().path().display());
        }
    }
    std::fs::write(out.join("interface.glsl"), interface::glsl()).unwrap();

    let compiler = Compiler::acquire().expect("glslang initialisation failed");
    let options = CompilerOptions {
        source_language: SourceLanguage::GLSL,
        // Vulkan 1.2 with SPIR-V 1.4: the ray-tracing extension needs SPIR-V 1.4.
        target: Target::Vulkan { version: VulkanVersion::Vulkan1_2, spirv_version: SpirvVersion::SPIRV1_4 },
        version_profile: None,
        messages: glslang::ShaderMessage::DEFAULT,
    };
    let mut failed = false;
    let mut table = String::from("// Generated by build.rs from its shader list.\n");
    for s in SHADERS {
        let text = std::fs::read_to_string(dir.join(s.file)).unwrap_or_else(|e| panic!("{}: {e}", s.file));
        let source = ShaderSource::from(text);
        let variants: &[(&str, bool)] = if s.f64 { &[("_f64", true), ("_f32", false)] } else { &[("", false)] };
        for &(suffix, f64) in variants {
            let spv = format!("{}{suffix}.spv", s.name.to_lowercase());
            let mut defs: Vec<(&str, Option<&str>)> = s.defines.iter().map(|d| (*d, Some("1"))).collect();
            if f64 {
                defs.push(("TL_F64", Some("1")));
            }
            let mut includes = Includes { dirs: [dir.clone(), out.clone()] };
            let compiled = ShaderInput::new(&source, s.stage, &options, Some(&defs), Some(&mut includes))
                .and_then(|input| compiler.create_shader(input))
                .and_then(|shader| shader.compile());
            match compiled {
                Ok(words) => {
                    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
                    std::fs::write(out.join(&spv), bytes).unwrap();
                }
                Err(e) => {
                    eprintln!("{} ({spv}): {e}", s.file);
                    println!("cargo:warning={} ({spv}): {e}", s.file);
                    failed = true;
                }
            }
        }
        let spirv = |suffix: &str| {
            format!("include_bytes!(concat!(env!(\"OUT_DIR\"), \"/{}{suffix}.spv\"))", s.name.to_lowercase())
        };
        let value = if s.f64 {
            format!("Shader::Precision {{ f64: {}, f32: {} }}", spirv("_f64"), spirv("_f32"))
        } else {
            format!("Shader::One({})", spirv(""))
        };
        let defines: String = s.defines.iter().map(|d| format!(" with {d}")).collect();
        writeln!(table, "/// `shaders/{}`{defines}.\npub(crate) const {}: Shader = {value};", s.file, s.name).unwrap();
    }
    if failed {
        panic!("shader compilation failed (see the messages above)");
    }
    std::fs::write(out.join("shaders.rs"), table).unwrap();
}
