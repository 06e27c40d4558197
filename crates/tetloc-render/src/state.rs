//! The view state: everything a viewer shows but the mesh, as one JSON document. The
//! browser viewer (`tetloc view`) exports it, `tetloc render --state view.json` renders the
//! same image offline, and `tetloc view --state view.json` opens it again.
//!
//! ```json
//! { "version": 1, "field": "temperature", "size": [512, 512],
//!   "camera": { "eye": [3, -4, 2], "target": [0, 0, 0], "up": [0, 0, 1], "zoom": 1 },
//!   "tf": { "colormap": "viridis", "colors": [], "space": "RGB",
//!           "opacity": [[0, 0, 0.5, 0], [1, 1, 0.5, 0]], "range": null, "scale": 8 },
//!   "step": null, "skip": true, "background": [0.1, 0.1, 0.1],
//!   "surface": null, "surface_color": [0.8, 0.8, 0.78], "time_step": 3 }
//! ```
//!
//! `time_step` (a series' step, 0-based) is written only when set.
//!
//! The camera is in the file's coordinates. `tf.colors` (ParaView's `RGBPoints` over the
//! normalised domain: `[x, r, g, b]`) replaces the named colormap when not empty, so an
//! imported ParaView preset travels inside the state: a state names no file, and a server
//! that reads states from clients opens none.

use crate::camera::{Camera, LookAt};
use crate::colorspace::ColorSpace;
use crate::error::{RenderError, Result};
use crate::options::{RenderOptions, SurfaceSpec, TfSpec};
use crate::tf::{Colormap, OpacityPoint, TransferFunction};
use serde::{Deserialize, Serialize};
use std::path::Path;
use tetloc_core::Mesh;

/// The version this code writes and reads.
pub const STATE_VERSION: u32 = 1;
/// Largest state file or message read, in bytes.
pub const MAX_STATE_BYTES: usize = 256 * 1024;
/// Most colour and opacity control points a state may hold.
pub const MAX_TF_POINTS: usize = 1024;
/// Largest image side a state may ask for.
pub const MAX_SIDE: u32 = 8192;

/// See the module's documentation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewState {
    pub version: u32,
    /// A scalar field or one component `NAME[i]` (the viewer adds `|NAME|` magnitudes).
    pub field: String,
    /// Width and height in pixels.
    pub size: [u32; 2],
    pub camera: CameraState,
    pub tf: TfState,
    /// Sampling step in mesh units; `null`: the mean tet size.
    #[serde(default)]
    pub step: Option<f32>,
    /// Empty-space skipping (exact: it changes no sample inside the mesh).
    #[serde(default = "yes")]
    pub skip: bool,
    /// sRGB, 0..1.
    pub background: [f32; 3],
    /// `"boundary"` (the mesh's boundary faces) or `null`.
    #[serde(default)]
    pub surface: Option<String>,
    #[serde(default = "default_surface_color")]
    pub surface_color: [f32; 3],
    /// The time step shown (0-based) of a series (an Exodus file with steps, a `.pvd`):
    /// `null` or absent, the first. Written only when set, so a snapshot's state is as before.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_step: Option<usize>,
}

fn yes() -> bool {
    true
}
fn default_surface_color() -> [f32; 3] {
    RenderOptions::default().surface_color
}

/// A camera placed by eye, target and up (file coordinates) and a zoom that narrows the
/// field of view.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraState {
    pub eye: [f64; 3],
    pub target: [f64; 3],
    pub up: [f64; 3],
    pub zoom: f32,
}

/// The transfer function: colours, opacity curve, value range and opacity scale.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TfState {
    /// A built-in colormap (`viridis`, `plasma`, `coolwarm`, `grayscale`), or the name of
    /// the preset whose points `colors` holds.
    pub colormap: String,
    /// `[x, r, g, b]` over [0, 1], x ascending; empty: the built-in `colormap`.
    #[serde(default)]
    pub colors: Vec<[f32; 4]>,
    /// How `colors` interpolate (ParaView's names).
    #[serde(default = "rgb")]
    pub space: String,
    /// `[x, opacity, midpoint, sharpness]` over [0, 1], x ascending (ParaView's `Points`).
    pub opacity: Vec<[f32; 4]>,
    /// The values the function spans; `null`: the field's range.
    #[serde(default)]
    pub range: Option<[f32; 2]>,
    /// Optical depth across the bounds' diagonal of a value of opacity 1 (`--opacity`).
    pub scale: f32,
}

fn rgb() -> String {
    "RGB".into()
}

impl ViewState {
    /// The default view of `field` on `mesh`: `render`'s defaults, the camera fitted to the
    /// bounds as `render` fits it.
    pub fn new(mesh: &Mesh, field: &str, width: u32, height: u32) -> ViewState {
        let o = RenderOptions::default();
        let map = Colormap::Viridis;
        ViewState {
            version: STATE_VERSION,
            field: field.to_string(),
            size: [width, height],
            camera: CameraState::fitted(mesh, o.azimuth, o.elevation, o.zoom),
            tf: TfState {
                colormap: map.name().into(),
                colors: Vec::new(),
                space: rgb(),
                opacity: opacity_points(&TransferFunction::builtin(map).opacity),
                range: None,
                scale: o.opacity,
            },
            step: None,
            skip: true,
            background: o.background,
            surface: None,
            surface_color: o.surface_color,
            time_step: None,
        }
    }

    /// Parses a state; `path` names it in errors.
    pub fn parse(text: &str, path: &Path) -> Result<ViewState> {
        if text.len() > MAX_STATE_BYTES {
            return Err(RenderError::file(path, format!("a view state is at most {MAX_STATE_BYTES} bytes")));
        }
        let s: ViewState =
            serde_json::from_str(text).map_err(|e| RenderError::file(path, format!("not a view state: {e}")))?;
        s.validate().map_err(|e| RenderError::file(path, e.to_string()))?;
        Ok(s)
    }

    /// Reads a state file (`render --state`, `view --state`).
    pub fn load(path: &Path) -> Result<ViewState> {
        use std::io::Read;
        let file = std::fs::File::open(path).map_err(|e| RenderError::io(path, e))?;
        let mut text = String::new();
        // One byte past the limit tells a file that is too large, in bounded memory.
        file.take(MAX_STATE_BYTES as u64 + 1).read_to_string(&mut text).map_err(|e| RenderError::io(path, e))?;
        Self::parse(&text, path)
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a view state always serialises")
    }

    /// Checks every number, so that a state from a file or a client cannot ask for what
    /// cannot be rendered.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(RenderError::Invalid(m));
        if self.version != STATE_VERSION {
            return bad(format!("view state version {} (this tetloc reads {STATE_VERSION})", self.version));
        }
        let [w, h] = self.size;
        if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
            return bad(format!("size {w}x{h}: each side must be 1..{MAX_SIDE} pixels"));
        }
        let c = &self.camera;
        for (name, v) in [("eye", c.eye), ("target", c.target), ("up", c.up)] {
            if let Some((i, x)) = v.iter().enumerate().find(|(_, &x)| !crate::options::camera_coordinate_ok(x)) {
                return bad(format!(
                    "camera.{name}[{i}] = {x:e}: camera coordinates must be finite and at most {:e} in magnitude",
                    crate::options::MAX_CAMERA_COORD
                ));
            }
        }
        if !(c.zoom.is_finite() && c.zoom > 0.0) {
            return bad(format!("camera.zoom = {}: must be a positive number", c.zoom));
        }
        let t = &self.tf;
        if Colormap::from_name(&t.colormap).is_none() && t.colors.is_empty() {
            return bad(format!("tf: '{}' is not a built-in colormap and no colors are given", t.colormap));
        }
        if ColorSpace::from_paraview(&t.space).is_none() {
            return bad(format!("tf: unknown colour space '{}' (known: {})", t.space, ColorSpace::KNOWN));
        }
        check_points("tf.colors", &t.colors, 0)?;
        check_points("tf.opacity", &t.opacity, 1)?;
        if let Some([lo, hi]) = t.range {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return bad(format!("tf.range {lo},{hi}: need finite LO < HI"));
            }
        }
        if !(t.scale.is_finite() && t.scale >= 0.0) {
            return bad(format!("tf.scale {} must be a number ≥ 0", t.scale));
        }
        if let Some(s) = self.step {
            if !(s.is_finite() && s > 0.0) {
                return bad(format!("step {s} must be a positive number"));
            }
        }
        for (name, rgb) in [("background", self.background), ("surface_color", self.surface_color)] {
            if rgb.iter().any(|c| !(0.0..=1.0).contains(c)) {
                return bad(format!("{name} {rgb:?}: components must be in 0..1"));
            }
        }
        if let Some(s) = &self.surface {
            if s != "boundary" {
                return bad(format!("surface '{s}': a view state shows the mesh's boundary or nothing"));
            }
        }
        self.render_options().and_then(|o| o.validate())
    }

    /// The transfer function the state describes.
    pub fn transfer_function(&self) -> Result<TransferFunction> {
        let t = &self.tf;
        let mut tf = match (t.colors.is_empty(), Colormap::from_name(&t.colormap)) {
            (true, Some(map)) => TransferFunction::builtin(map),
            (true, None) => return Err(RenderError::Invalid(format!("tf: unknown colormap '{}'", t.colormap))),
            (false, _) => TransferFunction {
                name: t.colormap.clone(),
                colors: t.colors.iter().map(|p| (p[0], [p[1], p[2], p[3]])).collect(),
                space: ColorSpace::from_paraview(&t.space)
                    .ok_or_else(|| RenderError::Invalid(format!("tf: unknown colour space '{}'", t.space)))?,
                opacity: Vec::new(),
            },
        };
        tf.opacity = t
            .opacity
            .iter()
            .map(|p| OpacityPoint { x: p[0], opacity: p[1], midpoint: p[2], sharpness: p[3] })
            .collect();
        Ok(tf)
    }

    /// The options `tetloc render` renders this state with.
    pub fn render_options(&self) -> Result<RenderOptions> {
        let c = &self.camera;
        let f32s = |v: [f64; 3]| v.map(|x| x as f32);
        Ok(RenderOptions {
            width: self.size[0],
            height: self.size[1],
            zoom: c.zoom,
            camera: Some(LookAt { eye: f32s(c.eye), target: f32s(c.target), up: f32s(c.up) }),
            step: self.step,
            tf: TfSpec::Custom(self.transfer_function()?),
            range: self.tf.range.map(|[lo, hi]| (lo, hi)),
            opacity: self.tf.scale,
            surface: self.surface.as_ref().map(|_| SurfaceSpec::Boundary),
            skip: self.skip,
            background: self.background,
            surface_color: self.surface_color,
            ..RenderOptions::default()
        })
    }
}

impl CameraState {
    /// `render`'s fitted camera (azimuth and elevation in degrees around the bounds' centre)
    /// in the file's coordinates.
    pub fn fitted(mesh: &Mesh, azimuth: f32, elevation: f32, zoom: f32) -> CameraState {
        let i = &mesh.info;
        let cam = Camera::fitted(i.bounds_min, i.bounds_max, azimuth, elevation, zoom, 1, 1);
        let target: [f32; 3] = std::array::from_fn(|k| 0.5 * (i.bounds_min[k] + i.bounds_max[k]));
        CameraState {
            eye: i.frame.to_file(cam.eye),
            target: i.frame.to_file(target),
            up: cam.up().map(f64::from),
            zoom,
        }
    }
}

/// Adds a scalar field `|NAME|` (per vertex or per cell, as the vector) for every vector
/// field of `mesh` that has none: how the viewer and `render --state` colour by a vector's
/// magnitude. Returns the names added.
pub fn add_magnitudes(mesh: &mut Mesh) -> Vec<String> {
    use rayon::prelude::*;
    let mut added = Vec::new();
    for g in tetloc_core::mesh::field_groups::groups_of(&mesh.fields) {
        let name = format!("|{}|", g.name);
        if g.n_components() < 2 || mesh.fields.iter().any(|f| f.name == name) {
            continue;
        }
        let comps: Vec<&[f32]> =
            g.components.iter().filter_map(|c| mesh.field(c).ok()).map(|f| f.values.as_slice()).collect();
        let n = comps[0].len();
        let values = (0..n).into_par_iter().map(|i| comps.iter().map(|c| c[i] * c[i]).sum::<f32>().sqrt()).collect();
        mesh.fields.push(tetloc_core::Field::new(name.clone(), g.location, values));
        added.push(name);
    }
    added
}

/// ParaView's `Points` layout of opacity control points.
fn opacity_points(points: &[OpacityPoint]) -> Vec<[f32; 4]> {
    points.iter().map(|p| [p.x, p.opacity, p.midpoint, p.sharpness]).collect()
}

/// Control points: at most [`MAX_TF_POINTS`], at least `min`, x ascending in [0, 1], values in 0..1.
fn check_points(name: &str, points: &[[f32; 4]], min: usize) -> Result<()> {
    let bad = |m: String| Err(RenderError::Invalid(format!("{name}: {m}")));
    if points.len() < min || points.len() > MAX_TF_POINTS {
        return bad(format!("{} points (need {min}..{MAX_TF_POINTS})", points.len()));
    }
    for (i, p) in points.iter().enumerate() {
        if p.iter().any(|v| !(0.0..=1.0).contains(v)) {
            return bad(format!("point {i} {p:?}: every number must be in 0..1"));
        }
        if i > 0 && p[0] < points[i - 1][0] {
            return bad(format!("point {i}: positions must ascend"));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use tetloc_testdata::testmesh;

    fn cube() -> Mesh {
        testmesh::cube(3, 2.0, 1.0)
    }

    #[test]
    fn round_trips_through_json() {
        let mesh = cube();
        let mut s = ViewState::new(&mesh, "f", 64, 48);
        s.tf.colors = vec![[0.0, 0.0, 0.0, 1.0], [1.0, 1.0, 0.5, 0.0]];
        s.tf.colormap = "my preset".into();
        s.tf.range = Some([-1.0, 3.5]);
        s.step = Some(0.01);
        s.surface = Some("boundary".into());
        let text = s.to_json();
        let back = ViewState::parse(&text, Path::new("v.json")).unwrap();
        assert_eq!(back, s);
        let o = back.render_options().unwrap();
        assert_eq!((o.width, o.height, o.range, o.step), (64, 48, Some((-1.0, 3.5)), Some(0.01)));
        assert_eq!(o.surface, Some(SurfaceSpec::Boundary));
        let tf = back.transfer_function().unwrap();
        assert_eq!(tf.color_at(1.0), [1.0, 0.5, 0.0]);
        assert_eq!(tf.opacity_at(0.5), 0.5);
    }

    /// A state with no step writes no `time_step` (a snapshot's state is as before, and reads
    /// in an older tetloc); a step round-trips; a state without the key shows the first step.
    #[test]
    fn the_time_step_is_written_only_when_set() {
        let mut s = ViewState::new(&cube(), "f", 8, 8);
        assert!(!s.to_json().contains("time_step"));
        s.time_step = Some(3);
        let text = s.to_json();
        assert!(text.contains("\"time_step\": 3"), "{text}");
        assert_eq!(ViewState::parse(&text, Path::new("v.json")).unwrap().time_step, Some(3));
        let old = text.replace(",\n  \"time_step\": 3", "");
        assert!(!old.contains("time_step"), "{old}");
        assert_eq!(ViewState::parse(&old, Path::new("v.json")).unwrap().time_step, None);
        let e = ViewState::parse(&text.replace("\"time_step\": 3", "\"time_step\": -1"), Path::new("n.json"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("n.json: not a view state"), "{e}");
    }

    #[test]
    fn the_default_state_renders_what_render_renders() {
        let mesh = std::sync::Arc::new(cube());
        let s = ViewState::new(&mesh, "f", 40, 30);
        let from_state = crate::Renderer::new(mesh.clone(), "f", &s.render_options().unwrap()).unwrap();
        let plain = RenderOptions { width: 40, height: 30, ..Default::default() };
        let from_options = crate::Renderer::new(mesh.clone(), "f", &plain).unwrap();
        let mut cpu = tetloc_core::CpuLocator::new(mesh);
        let (a, _) = from_state.render(&mut cpu, &from_state.camera(0)).unwrap();
        let (b, _) = from_options.render(&mut cpu, &from_options.camera(0)).unwrap();
        let db = crate::psnr(&a, &b).unwrap();
        assert!(db >= 50.0, "the fitted camera in file coordinates gives render's image: {db:.1} dB");
    }

    #[test]
    fn magnitudes_of_vectors() {
        use tetloc_core::{Field, FieldLocation};
        let mut mesh = cube();
        let n = mesh.points.len();
        for (k, v) in [3.0f32, 4.0].into_iter().enumerate() {
            mesh.fields.push(Field::new(format!("v[{k}]"), FieldLocation::Vertex, vec![v; n]));
        }
        assert_eq!(add_magnitudes(&mut mesh), vec!["|v|".to_string()]);
        assert_eq!(mesh.field("|v|").unwrap().values, vec![5.0; n]);
        assert!(add_magnitudes(&mut mesh).is_empty(), "added once");
    }

    #[test]
    fn bad_states_name_the_problem() {
        let mesh = cube();
        let good = ViewState::new(&mesh, "f", 8, 8);
        let text = |f: &dyn Fn(&mut ViewState)| {
            let mut s = good.clone();
            f(&mut s);
            let e = ViewState::parse(&serde_json::to_string(&s).unwrap(), Path::new("s.json")).unwrap_err();
            e.to_string()
        };
        assert!(text(&|s| s.version = 2).contains("s.json: view state version 2"));
        assert!(text(&|s| s.size = [0, 8]).contains("size 0x8"));
        assert!(text(&|s| s.camera.zoom = -1.0).contains("camera.zoom"));
        // Coordinates beyond f32's camera arithmetic (a client's PUT as a file's): named.
        assert!(text(&|s| s.camera.eye[2] = 1e30).contains("camera.eye[2] = 1e30"));
        assert!(text(&|s| s.camera.up[0] = -1e19).contains("camera.up[0] = -1e19"));
        assert!(text(&|s| s.tf.colormap = "jet".into()).contains("'jet' is not a built-in colormap"));
        assert!(text(&|s| s.tf.opacity.clear()).contains("tf.opacity: 0 points"));
        assert!(text(&|s| s.tf.opacity[1][0] = -0.5).contains("tf.opacity: point 1"));
        assert!(text(&|s| s.tf.range = Some([2.0, 1.0])).contains("tf.range"));
        assert!(text(&|s| s.surface = Some("/etc/passwd".into())).contains("boundary or nothing"));
        assert!(text(&|s| s.background = [2.0, 0.0, 0.0]).contains("background"));
        let along = |s: &mut ViewState| s.camera.up = std::array::from_fn(|k| s.camera.target[k] - s.camera.eye[k]);
        assert!(text(&along).contains("camera"), "up along the view");
        let e = ViewState::parse("{\"version\": 1, \"extra\": 1}", Path::new("x.json")).unwrap_err().to_string();
        assert!(e.starts_with("x.json: not a view state"), "{e}");
        let huge = " ".repeat(MAX_STATE_BYTES + 1);
        assert!(ViewState::parse(&huge, Path::new("h.json")).unwrap_err().to_string().contains("at most"));
    }
}
