//! tetloc-render: a sample-based volume ray marcher for tetrahedral meshes, after section
//! 6.3 of Wald et al., "RTX Beyond Ray Tracing" (HPG 2019), that samples through any
//! [`tetloc_core::BatchLocator`] — the CPU locator or a GPU kernel.
//!
//! ```no_run
//! # use std::sync::Arc;
//! # fn demo(mesh: Arc<tetloc_core::Mesh>) -> tetloc_render::Result<()> {
//! use tetloc_render::{render_to_file, RenderOptions, Renderer};
//! let opts = RenderOptions { width: 512, height: 512, ..Default::default() };
//! let renderer = Renderer::new(mesh.clone(), "temperature", &opts)?;
//! let mut cpu = tetloc_core::CpuLocator::new(mesh);
//! let report = render_to_file(&renderer, &mut cpu, "out.png".as_ref())?;
//! println!("{} samples", report.total().samples);
//! # Ok(()) }
//! ```
//!
//! Beyond the paper: empty-space skipping over a conservative occupancy grid (on by
//! default, exact: the same samples inside the mesh as without it), ParaView colormap
//! presets, surfaces from OBJ/STL/VTK files, orbits as PNG series or GIF.

pub mod camera;
pub mod colorspace;
mod error;
pub mod image;
mod options;
mod output;
mod render;
pub mod skip;
pub mod surface;
pub mod testmesh;
pub mod tf;
mod vec;

pub use camera::{Camera, LookAt, Ray};
pub use error::{RenderError, Result};
pub use image::{psnr, Image};
pub use options::{
    parse_camera, parse_color, parse_frames, parse_opacity, parse_positive, parse_range, parse_size, parse_view,
    RenderOptions, SurfaceSpec, TfSpec,
};
pub use output::{compare_locators, frame_path, measure_fps, render_to_file, Comparison, FpsReport, RenderReport};
pub use render::{FrameStats, Renderer, OPACITY_CUTOFF};
pub use tf::{Colormap, TransferFunction};
