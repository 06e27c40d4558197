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
//! `tetloc render` options map one to one onto [`RenderOptions`] fields, each with a parser
//! that names the option and the problem in its error:
//!
//! | option | field | parser |
//! |---|---|---|
//! | `--size WxH` | `width`, `height` | [`parse_size`] |
//! | `--view AZ,EL` | `azimuth`, `elevation` | [`parse_view`] |
//! | `--zoom Z` | `zoom` | [`parse_positive`]`("--zoom", ..)` |
//! | `--camera eye,target,up` | `camera` | [`parse_camera`] |
//! | `--step S` | `step` | [`parse_positive`]`("--step", ..)` |
//! | `--tf NAME\|FILE.json[#PRESET]` | `tf` | [`TfSpec::parse`] |
//! | `--range LO,HI` | `range` | [`parse_range`] |
//! | `--opacity K` | `opacity` | [`parse_opacity`] |
//! | `--surface boundary\|FILE` | `surface` | [`SurfaceSpec::parse`] |
//! | `--frames N` | `frames` | [`parse_frames`] |
//! | `--no-skip` | `skip = false` | |
//! | `--background COLOR` | `background` | [`parse_color`] |
//! | `--fps` | | [`measure_fps`] with the chosen locator |
//!
//! [`render_to_file`] writes one PNG, numbered PNGs for an orbit, or a GIF (by the output's
//! extension); [`FrameStats`] and [`FpsReport`] print as one line each.
//!
//! Frames are rendered by a [`Marcher`]: the host marcher over any locator, which batches
//! every round's samples for `locator.sample`, or (feature `vulkan`, on by default)
//! [`GpuMarcher`], which runs the whole march on the GPU with a tetloc-vulkan kernel.
//!
//! Beyond the paper: empty-space skipping over a conservative occupancy grid (on by
//! default, exact: the same samples inside the mesh as without it), ParaView colormap
//! presets, surfaces from OBJ/STL/VTK files, orbits as PNG series or GIF.

pub mod camera;
pub mod colorspace;
mod error;
#[cfg(feature = "vulkan")]
mod gpu;
pub mod image;
mod options;
mod output;
mod render;
pub mod skip;
pub mod state;
pub mod surface;
pub mod tf;
mod vec;

pub use camera::{Camera, LookAt, Ray};
pub use error::{RenderError, Result};
#[cfg(feature = "vulkan")]
pub use gpu::GpuMarcher;
pub use image::{psnr, GifWriter, Image};
pub use options::{
    parse_camera, parse_color, parse_frames, parse_opacity, parse_positive, parse_range, parse_size, parse_view,
    RenderOptions, SurfaceSpec, TfSpec,
};
pub use output::{
    check_outputs, compare_locators, frame_path, measure_fps, render_to_file, Comparison, FpsReport, RenderReport,
};
pub use render::{FrameStats, HostMarcher, Marcher, Renderer, OPACITY_CUTOFF};
pub use state::{CameraState, TfState, ViewState};
pub use tf::{Colormap, TransferFunction};
