//! Render options, one field per command-line option of `tetloc render`, and parsers for
//! the option strings that say exactly what is wrong with a bad one.

use crate::camera::LookAt;
use crate::error::{RenderError, Result};
use crate::surface::TriMesh;
use crate::tf::{Colormap, TransferFunction};
use std::path::PathBuf;

/// Where the transfer function comes from (`--tf NAME|FILE.json[#PRESET]`).
#[derive(Clone, Debug, PartialEq)]
pub enum TfSpec {
    Builtin(Colormap),
    /// A ParaView preset file; `preset` picks one by name, else the first.
    File {
        path: PathBuf,
        preset: Option<String>,
    },
    /// A transfer function built in code.
    Custom(TransferFunction),
}

impl TfSpec {
    /// A built-in colormap name, or a path to a `.json` preset file, optionally followed by
    /// `#Name` to pick a preset in a file that holds several.
    pub fn parse(s: &str) -> Result<TfSpec> {
        if let Some(map) = Colormap::from_name(s) {
            return Ok(TfSpec::Builtin(map));
        }
        let (file, preset) = match s.rsplit_once('#') {
            Some((f, p)) if f.to_ascii_lowercase().ends_with(".json") && !p.is_empty() => (f, Some(p.to_string())),
            _ => (s, None),
        };
        if file.to_ascii_lowercase().ends_with(".json") {
            return Ok(TfSpec::File { path: PathBuf::from(file), preset });
        }
        let names: Vec<&str> = Colormap::ALL.iter().map(|c| c.name()).collect();
        Err(RenderError::option(
            "--tf",
            s,
            format!("not a built-in colormap ({}) nor a ParaView preset file (FILE.json)", names.join(", ")),
        ))
    }

    /// The transfer function this names, reading the file if there is one.
    pub fn load(&self) -> Result<TransferFunction> {
        match self {
            TfSpec::Builtin(map) => Ok(TransferFunction::builtin(*map)),
            TfSpec::File { path, preset } => TransferFunction::load_paraview(path, preset.as_deref()),
            TfSpec::Custom(tf) => Ok(tf.clone()),
        }
    }
}

/// Opaque surface geometry (`--surface boundary|FILE`).
#[derive(Clone, Debug, PartialEq)]
pub enum SurfaceSpec {
    /// The mesh's own boundary faces.
    Boundary,
    /// An OBJ, STL or VTK legacy polydata file.
    File(PathBuf),
    /// Triangles already in memory (e.g. a generated shape's terrain, `--surface terrain`).
    Mesh(std::sync::Arc<TriMesh>),
}

impl SurfaceSpec {
    pub fn parse(s: &str) -> SurfaceSpec {
        if s == "boundary" {
            SurfaceSpec::Boundary
        } else {
            SurfaceSpec::File(PathBuf::from(s))
        }
    }
}

/// Everything that controls an image but the mesh, the field and the backend.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// `--size WxH`.
    pub width: u32,
    pub height: u32,
    /// `--view AZ,EL` in degrees: azimuth around +z (0 looks along +y), elevation above the
    /// xy plane. Ignored when `camera` is set.
    pub azimuth: f32,
    pub elevation: f32,
    /// `--zoom Z`: narrows the field of view by Z.
    pub zoom: f32,
    /// `--camera eye,target,up`: an explicit placement instead of the fitted view.
    pub camera: Option<LookAt>,
    /// `--step S` in mesh units; `None`: the mean tet size, (total volume / tets)^(1/3).
    pub step: Option<f32>,
    /// `--tf`.
    pub tf: TfSpec,
    /// `--range LO,HI`: the values the transfer function spans; `None`: the field's min and max.
    pub range: Option<(f32, f32)>,
    /// `--opacity K`: optical depth, across the bounds' diagonal, of a value whose
    /// transfer-function opacity is 1.
    pub opacity: f32,
    /// `--surface`.
    pub surface: Option<SurfaceSpec>,
    /// `--frames N`: an orbit of N frames, the azimuth advancing 360/N degrees a frame.
    pub frames: u32,
    /// Empty-space skipping; `--no-skip` turns it off (the paper's fixed stepping).
    pub skip: bool,
    /// sRGB background colour, 0..1.
    pub background: [f32; 3],
    /// sRGB base colour of surfaces, 0..1.
    pub surface_color: [f32; 3],
    /// Samples the marcher aims to hand the locator per batch: rays take several samples a
    /// round once few are left, so GPU backends keep getting large batches.
    pub batch_target: usize,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 1024,
            height: 1024,
            azimuth: 30.0,
            elevation: 25.0,
            zoom: 1.0,
            camera: None,
            step: None,
            tf: TfSpec::Builtin(Colormap::Viridis),
            range: None,
            opacity: 8.0,
            surface: None,
            frames: 1,
            skip: true,
            background: [0.1, 0.1, 0.1],
            surface_color: [0.8, 0.8, 0.78],
            batch_target: 1 << 20,
        }
    }
}

impl RenderOptions {
    /// Checks values that parse but cannot be rendered (for options set in code too).
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(RenderError::Invalid(m));
        if self.width == 0 || self.height == 0 {
            return bad(format!("image size {}x{}: both sides must be at least 1 pixel", self.width, self.height));
        }
        if !(self.zoom.is_finite() && self.zoom > 0.0) {
            return bad(format!("zoom {} must be a positive number", self.zoom));
        }
        if let Some(s) = self.step {
            if !(s.is_finite() && s > 0.0) {
                return bad(format!("step {s} must be a positive number"));
            }
        }
        if !(self.opacity.is_finite() && self.opacity >= 0.0) {
            return bad(format!("opacity {} must be a number ≥ 0", self.opacity));
        }
        if let Some((lo, hi)) = self.range {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return bad(format!("range {lo},{hi}: need finite LO < HI"));
            }
        }
        if self.frames == 0 {
            return bad("frames must be at least 1".into());
        }
        if self.batch_target == 0 {
            return bad("batch_target must be at least 1".into());
        }
        if let Some(look) = self.camera {
            if !look.is_usable() {
                return bad(format!(
                    "camera {look:?}: eye equals target, or up is zero or parallel to the view direction"
                ));
            }
        }
        if !self.azimuth.is_finite() || !self.elevation.is_finite() {
            return bad(format!("view {},{} must be finite", self.azimuth, self.elevation));
        }
        Ok(())
    }
}

/// `WxH` (or `N` for a square), e.g. `1024x768`.
pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let err = |m: &str| RenderError::option("--size", s, m);
    let (w, h) = match s.split_once(['x', 'X']) {
        Some((w, h)) => (w, h),
        None => (s, s),
    };
    let num = |v: &str| v.trim().parse::<u32>().map_err(|_| err("expected WIDTHxHEIGHT in pixels, e.g. 1024x768"));
    let (w, h) = (num(w)?, num(h)?);
    if w == 0 || h == 0 {
        return Err(err("both sides must be at least 1 pixel"));
    }
    if (w as u64) * (h as u64) > 1 << 28 {
        return Err(err("more than 2^28 pixels"));
    }
    Ok((w, h))
}

/// Comma-separated finite numbers, exactly `n` of them.
fn numbers(option: &'static str, s: &str, n: usize, layout: &str) -> Result<Vec<f32>> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| RenderError::option(option, s, format!("expected {layout}: {n} comma-separated numbers")))?;
    if v.len() != n {
        return Err(RenderError::option(option, s, format!("expected {layout}: {n} numbers, found {}", v.len())));
    }
    Ok(v)
}

/// `AZ,EL` in degrees; the elevation must be within ±90.
pub fn parse_view(s: &str) -> Result<(f32, f32)> {
    let v = numbers("--view", s, 2, "AZIMUTH,ELEVATION in degrees")?;
    if v[1].abs() > 90.0 {
        return Err(RenderError::option("--view", s, "elevation must be between -90 and 90 degrees"));
    }
    Ok((v[0], v[1]))
}

/// Largest camera coordinate taken (`--camera`, a state's camera): the camera squares
/// differences of coordinates in f32, which overflow beyond about 1e19.
pub const MAX_CAMERA_COORD: f64 = 1e18;

/// Whether a camera coordinate is finite and within [`MAX_CAMERA_COORD`].
pub fn camera_coordinate_ok(v: f64) -> bool {
    v.is_finite() && v.abs() <= MAX_CAMERA_COORD
}

/// `ex,ey,ez,tx,ty,tz,ux,uy,uz`: eye, target and up.
pub fn parse_camera(s: &str) -> Result<LookAt> {
    // A number that is not finite or too large is named (beyond f32, or overflowing in the
    // camera's arithmetic, it would read as no number, or as eye meeting target).
    const NAMES: [&str; 9] = ["ex", "ey", "ez", "tx", "ty", "tz", "ux", "uy", "uz"];
    for (text, name) in s.split(',').zip(NAMES) {
        if text.trim().parse::<f64>().is_ok_and(|v| !camera_coordinate_ok(v)) {
            let v = text.trim();
            let why = format!(
                "{name} = {v}: camera coordinates must be finite and at most {MAX_CAMERA_COORD:e} in magnitude"
            );
            return Err(RenderError::option("--camera", s, why));
        }
    }
    let v = numbers("--camera", s, 9, "eye,target,up (ex,ey,ez,tx,ty,tz,ux,uy,uz)")?;
    let look = LookAt { eye: [v[0], v[1], v[2]], target: [v[3], v[4], v[5]], up: [v[6], v[7], v[8]] };
    if !look.is_usable() {
        return Err(RenderError::option(
            "--camera",
            s,
            "eye equals target, or up is zero or parallel to the view direction",
        ));
    }
    Ok(look)
}

/// `LO,HI` with LO < HI.
pub fn parse_range(s: &str) -> Result<(f32, f32)> {
    let v = numbers("--range", s, 2, "LO,HI")?;
    if v[0] >= v[1] {
        return Err(RenderError::option("--range", s, "LO must be less than HI"));
    }
    Ok((v[0], v[1]))
}

/// A positive number (for `--zoom` and `--step`).
pub fn parse_positive(option: &'static str, s: &str) -> Result<f32> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(RenderError::option(option, s, "expected a positive number")),
    }
}

/// `--opacity K`, a number ≥ 0.
pub fn parse_opacity(s: &str) -> Result<f32> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(RenderError::option("--opacity", s, "expected a number ≥ 0")),
    }
}

/// `--frames N`, at least 1.
pub fn parse_frames(s: &str) -> Result<u32> {
    match s.trim().parse::<u32>() {
        Ok(v) if v >= 1 => Ok(v),
        _ => Err(RenderError::option("--frames", s, "expected a whole number ≥ 1")),
    }
}

/// A colour as `#rrggbb` or `r,g,b` in 0..1 (sRGB).
pub fn parse_color(option: &'static str, s: &str) -> Result<[f32; 3]> {
    if let Some(hex) = s.strip_prefix('#') {
        if hex.len() == 6 {
            if let Ok(v) = u32::from_str_radix(hex, 16) {
                return Ok([(v >> 16) & 255, (v >> 8) & 255, v & 255].map(|c| c as f32 / 255.0));
            }
        }
        return Err(RenderError::option(option, s, "expected #rrggbb"));
    }
    let v = numbers(option, s, 3, "#rrggbb or r,g,b")?;
    if v.iter().any(|c| !(0.0..=1.0).contains(c)) {
        return Err(RenderError::option(option, s, "r,g,b components must be in 0..1"));
    }
    Ok([v[0], v[1], v[2]])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn msg<T: std::fmt::Debug>(r: Result<T>) -> String {
        r.unwrap_err().to_string()
    }

    #[test]
    fn sizes() {
        assert_eq!(parse_size("1024x768").unwrap(), (1024, 768));
        assert_eq!(parse_size("64").unwrap(), (64, 64));
        assert!(msg(parse_size("0x512")).contains("--size '0x512': both sides must be at least 1 pixel"));
        assert!(msg(parse_size("wide")).contains("expected WIDTHxHEIGHT"));
        assert!(msg(parse_size("100000x100000")).contains("2^28"));
    }

    #[test]
    fn views_cameras_ranges() {
        assert_eq!(parse_view("45,-10").unwrap(), (45.0, -10.0));
        assert!(msg(parse_view("45")).contains("found 1"));
        assert!(msg(parse_view("0,91")).contains("between -90 and 90"));
        let c = parse_camera("0,0,5, 0,0,0, 0,1,0").unwrap();
        assert_eq!(c.eye, [0.0, 0.0, 5.0]);
        assert!(msg(parse_camera("0,0,5,0,0,0,0,0,1")).contains("parallel"));
        assert!(msg(parse_camera("1,2,3")).contains("9 numbers"));
        assert_eq!(parse_range("-1,2.5").unwrap(), (-1.0, 2.5));
        assert!(msg(parse_range("2,1")).contains("LO must be less than HI"));
        assert!(msg(parse_range("a,b")).contains("--range 'a,b'"));
        assert!(msg(parse_range("nan,1")).contains("--range"));
        assert!(msg(parse_positive("--zoom", "0")).contains("--zoom '0': expected a positive number"));
        assert_eq!(parse_opacity("0").unwrap(), 0.0);
        assert!(parse_frames("0").is_err());
        assert_eq!(parse_color("--background", "#ff8000").unwrap(), [1.0, 128.0 / 255.0, 0.0]);
        assert_eq!(parse_color("--background", "0,0.5,1").unwrap(), [0.0, 0.5, 1.0]);
        assert!(msg(parse_color("--background", "#ff80")).contains("#rrggbb"));
    }

    #[test]
    fn tf_and_surface_specs() {
        assert_eq!(TfSpec::parse("plasma").unwrap(), TfSpec::Builtin(Colormap::Plasma));
        assert_eq!(TfSpec::parse("maps/a.json").unwrap(), TfSpec::File { path: "maps/a.json".into(), preset: None });
        assert_eq!(
            TfSpec::parse("maps/a.json#Cool to Warm").unwrap(),
            TfSpec::File { path: "maps/a.json".into(), preset: Some("Cool to Warm".into()) }
        );
        let e = msg(TfSpec::parse("jet"));
        assert!(e.contains("--tf 'jet'") && e.contains("viridis, plasma, coolwarm, grayscale"), "{e}");
        assert_eq!(SurfaceSpec::parse("boundary"), SurfaceSpec::Boundary);
        assert_eq!(SurfaceSpec::parse("coast.stl"), SurfaceSpec::File("coast.stl".into()));
    }

    #[test]
    fn validate_catches_what_code_can_set() {
        assert!(RenderOptions::default().validate().is_ok());
        let zero = RenderOptions { width: 0, ..Default::default() };
        assert!(msg(zero.validate()).contains("image size 0x1024"));
        assert!(RenderOptions { step: Some(-1.0), ..Default::default() }.validate().is_err());
        assert!(RenderOptions { range: Some((1.0, 1.0)), ..Default::default() }.validate().is_err());
        assert!(RenderOptions { frames: 0, ..Default::default() }.validate().is_err());
        assert!(RenderOptions { opacity: f32::NAN, ..Default::default() }.validate().is_err());
    }
}
