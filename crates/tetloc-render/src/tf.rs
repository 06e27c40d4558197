//! Transfer functions: field value → colour and opacity.
//!
//! A [`TransferFunction`] is a set of control points over the normalised domain [0, 1]:
//! colours in sRGB (as colormap tables and ParaView presets give them) interpolated in a
//! colour space, and opacities with ParaView's midpoint/sharpness shaping. The renderer
//! bakes it into a [`TfTable`] over the value range once per image and looks samples up
//! with linear filtering, like the paper's 1-D texture.

use crate::colorspace::{self, ColorSpace};
use crate::error::{RenderError, Result};
use serde_json::Value;
use std::path::Path;

/// The built-in colormaps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Colormap {
    Viridis,
    Plasma,
    /// Moreland's diverging "cool to warm" map (ParaView's default).
    Coolwarm,
    Grayscale,
}

impl Colormap {
    pub const ALL: [Colormap; 4] = [Colormap::Viridis, Colormap::Plasma, Colormap::Coolwarm, Colormap::Grayscale];

    pub fn name(self) -> &'static str {
        match self {
            Colormap::Viridis => "viridis",
            Colormap::Plasma => "plasma",
            Colormap::Coolwarm => "coolwarm",
            Colormap::Grayscale => "grayscale",
        }
    }

    pub fn from_name(name: &str) -> Option<Colormap> {
        let lower = name.to_ascii_lowercase();
        match lower.as_str() {
            "greyscale" | "gray" | "grey" => Some(Colormap::Grayscale),
            _ => Colormap::ALL.into_iter().find(|c| c.name() == lower),
        }
    }

    /// The colormap as a 256-entry sRGB table.
    pub fn table(self) -> Vec<[f32; 3]> {
        const N: usize = 256;
        let from_gradient = |g: colorous::Gradient| -> Vec<[f32; 3]> {
            (0..N)
                .map(|i| {
                    let c = g.eval_rational(i, N);
                    [c.r as f32 / 255.0, c.g as f32 / 255.0, c.b as f32 / 255.0]
                })
                .collect()
        };
        match self {
            Colormap::Viridis => from_gradient(colorous::VIRIDIS),
            Colormap::Plasma => from_gradient(colorous::PLASMA),
            // Moreland (2009): the two endpoint colours, interpolated through Msh space.
            Colormap::Coolwarm => {
                let (cool, warm) = ([0.230, 0.299, 0.754], [0.706, 0.016, 0.150]);
                (0..N)
                    .map(|i| colorspace::interpolate(ColorSpace::Diverging, cool, warm, i as f32 / (N - 1) as f32))
                    .collect()
            }
            Colormap::Grayscale => (0..N).map(|i| [i as f32 / (N - 1) as f32; 3]).collect(),
        }
    }
}

/// One opacity control point, as in ParaView's `Points` array: position, opacity, and the
/// midpoint and sharpness of the segment that starts here.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpacityPoint {
    pub x: f32,
    pub opacity: f32,
    pub midpoint: f32,
    pub sharpness: f32,
}

impl OpacityPoint {
    pub fn linear(x: f32, opacity: f32) -> OpacityPoint {
        OpacityPoint { x, opacity, midpoint: 0.5, sharpness: 0.0 }
    }
}

/// A transfer function over the normalised domain [0, 1].
#[derive(Clone, Debug, PartialEq)]
pub struct TransferFunction {
    pub name: String,
    /// Colour control points: position in [0, 1] (ascending) and sRGB colour in [0, 1].
    pub colors: Vec<(f32, [f32; 3])>,
    pub space: ColorSpace,
    /// Opacity control points, positions in [0, 1] ascending.
    pub opacity: Vec<OpacityPoint>,
}

impl TransferFunction {
    /// A built-in colormap with the default opacity ramp (0 at the low end, 1 at the high end).
    pub fn builtin(map: Colormap) -> TransferFunction {
        let table = map.table();
        let n = table.len();
        TransferFunction {
            name: map.name().to_string(),
            colors: table.into_iter().enumerate().map(|(i, c)| (i as f32 / (n - 1) as f32, c)).collect(),
            space: ColorSpace::Rgb,
            opacity: default_opacity_ramp(),
        }
    }

    /// The same colours with one opacity everywhere (used for closed-form checks).
    pub fn with_constant_opacity(mut self, opacity: f32) -> TransferFunction {
        self.opacity = vec![OpacityPoint::linear(0.0, opacity), OpacityPoint::linear(1.0, opacity)];
        self
    }

    /// Reads a ParaView colormap preset file (an array of preset objects, or one object).
    /// `preset` picks one by `Name`; without it the first preset is used.
    pub fn load_paraview(path: &Path, preset: Option<&str>) -> Result<TransferFunction> {
        let text = std::fs::read_to_string(path).map_err(|e| RenderError::io(path, e))?;
        Self::parse_paraview(&text, path, preset)
    }

    /// Parses a ParaView preset held in memory; `path` only names it in errors.
    pub fn parse_paraview(text: &str, path: &Path, preset: Option<&str>) -> Result<TransferFunction> {
        let bad = |msg: String| RenderError::file(path, msg);
        let json: Value = serde_json::from_str(text)
            .map_err(|e| bad(format!("not valid JSON (line {}, column {}): {e}", e.line(), e.column())))?;
        let presets: Vec<&Value> = match &json {
            Value::Array(a) => a.iter().collect(),
            Value::Object(_) => vec![&json],
            _ => return Err(bad("expected a ParaView colormap preset: a JSON object or an array of objects".into())),
        };
        if presets.is_empty() {
            return Err(bad("the file holds no presets (an empty array)".into()));
        }
        for (i, p) in presets.iter().enumerate() {
            if !p.is_object() {
                return Err(bad(format!("preset #{i} is not a JSON object")));
            }
        }
        let name_of = |p: &Value| p.get("Name").and_then(Value::as_str).map(str::to_string);
        let chosen = match preset {
            None => presets[0],
            Some(want) => presets.iter().copied().find(|p| name_of(p).as_deref() == Some(want)).ok_or_else(|| {
                let names: Vec<String> = presets.iter().filter_map(|p| name_of(p)).map(|n| format!("'{n}'")).collect();
                bad(format!(
                    "no preset named '{want}' (the file has: {})",
                    if names.is_empty() { "no named presets".into() } else { names.join(", ") }
                ))
            })?,
        };
        let name = name_of(chosen).unwrap_or_else(|| "unnamed".to_string());
        let bad = |msg: String| RenderError::file(path, format!("preset '{name}': {msg}"));

        let space = match chosen.get("ColorSpace") {
            None => ColorSpace::Rgb,
            Some(v) => {
                let s = v.as_str().ok_or_else(|| bad("ColorSpace is not a string".into()))?;
                ColorSpace::from_paraview(s)
                    .ok_or_else(|| bad(format!("unknown ColorSpace '{s}' (known: {})", ColorSpace::KNOWN)))?
            }
        };
        let rgb = match chosen.get("RGBPoints") {
            Some(v) => numbers(v, "RGBPoints").map_err(bad)?,
            None if chosen.get("IndexedColors").is_some() => {
                return Err(bad("indexed (categorical) presets are not supported: no RGBPoints".into()))
            }
            None => return Err(bad("no RGBPoints array".into())),
        };
        let groups = groups_of_4(&rgb, "RGBPoints", "x,r,g,b").map_err(bad)?;
        for (i, g) in groups.iter().enumerate() {
            if let Some(c) = g[1..].iter().find(|c| !(0.0..=1.0).contains(*c)) {
                return Err(bad(format!("RGBPoints point {i} has colour component {c}, outside 0..1")));
            }
        }
        let xs = normalise(&groups, "RGBPoints").map_err(bad)?;
        let colors = groups.iter().zip(xs).map(|(g, x)| (x, [g[1] as f32, g[2] as f32, g[3] as f32])).collect();

        let opacity = match chosen.get("Points") {
            None => default_opacity_ramp(),
            Some(v) => {
                let pts = numbers(v, "Points").map_err(bad)?;
                let groups = groups_of_4(&pts, "Points", "x,opacity,midpoint,sharpness").map_err(bad)?;
                for (i, g) in groups.iter().enumerate() {
                    if let Some(c) = g[1..].iter().find(|c| !(0.0..=1.0).contains(*c)) {
                        return Err(bad(format!(
                            "Points point {i}: opacity, midpoint and sharpness must be in 0..1, found {c}"
                        )));
                    }
                }
                let xs = normalise(&groups, "Points").map_err(bad)?;
                groups
                    .iter()
                    .zip(xs)
                    .map(|(g, x)| OpacityPoint {
                        x,
                        opacity: g[1] as f32,
                        midpoint: g[2] as f32,
                        sharpness: g[3] as f32,
                    })
                    .collect()
            }
        };
        Ok(TransferFunction { name, colors, space, opacity })
    }

    /// sRGB colour at normalised position `u` (clamped to [0, 1]).
    pub fn color_at(&self, u: f32) -> [f32; 3] {
        let u = u.clamp(0.0, 1.0);
        let pts = &self.colors;
        let i = pts.partition_point(|p| p.0 <= u);
        if i == 0 {
            return pts[0].1;
        }
        if i == pts.len() {
            return pts[i - 1].1;
        }
        let (a, b) = (pts[i - 1], pts[i]);
        if self.space == ColorSpace::Step || b.0 <= a.0 {
            return a.1;
        }
        colorspace::interpolate(self.space, a.1, b.1, (u - a.0) / (b.0 - a.0))
    }

    /// Opacity at normalised position `u` (clamped to [0, 1]).
    pub fn opacity_at(&self, u: f32) -> f32 {
        let u = u.clamp(0.0, 1.0);
        let pts = &self.opacity;
        let i = pts.partition_point(|p| p.x <= u);
        if i == 0 {
            return pts[0].opacity;
        }
        if i == pts.len() {
            return pts[i - 1].opacity;
        }
        let (a, b) = (pts[i - 1], pts[i]);
        if b.x <= a.x {
            return a.opacity;
        }
        shaped_segment(a, b.opacity, (u - a.x) / (b.x - a.x))
    }

    /// Bakes the function over the value range `[lo, hi]` into a lookup table.
    pub fn bake(&self, lo: f32, hi: f32) -> TfTable {
        const N: usize = 1024;
        let entries = (0..N)
            .map(|i| {
                let u = i as f32 / (N - 1) as f32;
                let c = self.color_at(u).map(colorspace::srgb_to_linear);
                [c[0], c[1], c[2], self.opacity_at(u)]
            })
            .collect();
        let inv = if hi > lo { 1.0 / (hi - lo) } else { 0.0 };
        TfTable { entries, lo, inv_range: inv }
    }
}

/// Opacity 0 at the low end of the range rising linearly to 1 at the high end.
fn default_opacity_ramp() -> Vec<OpacityPoint> {
    vec![OpacityPoint::linear(0.0, 0.0), OpacityPoint::linear(1.0, 1.0)]
}

/// ParaView's (vtkPiecewiseFunction's) segment shape: the midpoint moves where the value is
/// halfway; sharpness goes from linear (0) through a Hermite curve to a step (1).
fn shaped_segment(a: OpacityPoint, y1: f32, f: f32) -> f32 {
    let (y0, m, s) = (a.opacity, a.midpoint.clamp(1e-5, 1.0 - 1e-5), a.sharpness);
    let x = if f < m { 0.5 * f / m } else { 0.5 + 0.5 * (f - m) / (1.0 - m) };
    if s > 0.99 {
        return if x < 0.5 { y0 } else { y1 };
    }
    if s < 0.01 {
        return y0 + (y1 - y0) * x;
    }
    // Sharper segments flatten near the ends and steepen through the middle.
    let x =
        if x < 0.5 { 0.5 * (2.0 * x).powf(1.0 + 10.0 * s) } else { 1.0 - 0.5 * (2.0 * (1.0 - x)).powf(1.0 + 10.0 * s) };
    let (x2, x3) = (x * x, x * x * x);
    let (h1, h2, h3, h4) = (2.0 * x3 - 3.0 * x2 + 1.0, -2.0 * x3 + 3.0 * x2, x3 - 2.0 * x2 + x, x3 - x2);
    let slope = (1.0 - s) * (y1 - y0);
    (h1 * y0 + h2 * y1 + h3 * slope + h4 * slope).clamp(y0.min(y1), y0.max(y1))
}

fn numbers(v: &Value, what: &str) -> Result<Vec<f64>, String> {
    let arr = v.as_array().ok_or_else(|| format!("{what} is not an array"))?;
    arr.iter()
        .enumerate()
        .map(|(i, x)| match x.as_f64() {
            Some(f) if f.is_finite() => Ok(f),
            _ => Err(format!("{what}[{i}] is {x}, not a finite number")),
        })
        .collect()
}

// `is_multiple_of` is newer than the workspace's rust-version (1.80).
#[allow(clippy::manual_is_multiple_of)]
fn groups_of_4(v: &[f64], what: &str, layout: &str) -> Result<Vec<[f64; 4]>, String> {
    if v.is_empty() || v.len() % 4 != 0 {
        return Err(format!("{what} has {} numbers; expected groups of {layout} (a non-zero multiple of 4)", v.len()));
    }
    Ok(v.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect())
}

/// Maps control-point positions onto [0, 1] (presets are rescaled to the data range, as in
/// ParaView); positions must not decrease.
fn normalise(groups: &[[f64; 4]], what: &str) -> Result<Vec<f32>, String> {
    for (i, w) in groups.windows(2).enumerate() {
        if w[1][0] < w[0][0] {
            return Err(format!(
                "{what} positions must not decrease: point {} is at {} after {}",
                i + 1,
                w[1][0],
                w[0][0]
            ));
        }
    }
    let (lo, hi) = (groups[0][0], groups[groups.len() - 1][0]);
    Ok(groups.iter().map(|g| if hi > lo { ((g[0] - lo) / (hi - lo)) as f32 } else { 0.0 }).collect())
}

/// A baked transfer function: 1024 entries of linear RGB and opacity over a value range.
#[derive(Clone, Debug)]
pub struct TfTable {
    pub(crate) entries: Vec<[f32; 4]>,
    pub(crate) lo: f32,
    /// 1 / (hi − lo); 0 for an empty range, which maps every value to the table's start.
    pub(crate) inv_range: f32,
}

impl TfTable {
    /// The same table with each opacity `o` replaced by the alpha of a step whose optical
    /// depth is `o · depth`: 1 − exp(−o · depth).
    pub fn with_step_alpha(mut self, depth: f32) -> TfTable {
        for e in &mut self.entries {
            e[3] = 1.0 - (-e[3] * depth).exp();
        }
        self
    }

    /// Linear RGB and opacity (or step alpha) for a field value, linearly filtered; values outside the range clamp.
    #[inline]
    pub fn lookup(&self, v: f32) -> [f32; 4] {
        let n = self.entries.len();
        let u = ((v - self.lo) * self.inv_range).clamp(0.0, 1.0) * (n - 1) as f32;
        let i = (u as usize).min(n - 2);
        let f = u - i as f32;
        let (a, b) = (self.entries[i], self.entries[i + 1]);
        std::array::from_fn(|k| a[k] + (b[k] - a[k]) * f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<TransferFunction> {
        TransferFunction::parse_paraview(text, Path::new("maps/test.json"), None)
    }

    fn err(text: &str) -> String {
        parse(text).unwrap_err().to_string()
    }

    #[test]
    fn builtin_tables_have_256_distinct_ramps() {
        for map in Colormap::ALL {
            let t = map.table();
            assert_eq!(t.len(), 256);
            // A real map is not a two-stop ramp: some interior entry leaves the straight line.
            let (a, b) = (t[0], t[255]);
            let off_line = t.iter().enumerate().any(|(i, c)| {
                let f = i as f32 / 255.0;
                (0..3).any(|k| (c[k] - (a[k] + (b[k] - a[k]) * f)).abs() > 0.02)
            });
            assert_eq!(off_line, map != Colormap::Grayscale, "{}", map.name());
        }
        // Viridis starts dark purple and ends yellow.
        let v = Colormap::Viridis.table();
        assert!(v[0][2] > v[0][1] && v[255][0] > 0.9 && v[255][2] < 0.2);
        // Cool to warm passes through a light grey in the middle.
        let c = Colormap::Coolwarm.table();
        let mid = c[128];
        assert!(mid.iter().all(|&x| x > 0.8 && x < 0.9), "{mid:?}");
    }

    #[test]
    fn names_parse() {
        assert_eq!(Colormap::from_name("Viridis"), Some(Colormap::Viridis));
        assert_eq!(Colormap::from_name("grey"), Some(Colormap::Grayscale));
        assert_eq!(Colormap::from_name("jet"), None);
    }

    #[test]
    fn paraview_preset_is_rescaled_and_interpolated() {
        let tf = parse(
            r#"[{"Name": "Two", "ColorSpace": "RGB",
                 "RGBPoints": [-1, 0, 0, 1,  1, 1, 0, 0],
                 "Points": [-1, 0, 0.5, 0,  1, 0.8, 0.5, 0]}]"#,
        )
        .unwrap();
        assert_eq!(tf.name, "Two");
        let c = tf.color_at(0.5);
        assert!((c[0] - 0.5).abs() < 1e-6 && (c[2] - 0.5).abs() < 1e-6);
        assert!((tf.opacity_at(0.25) - 0.2).abs() < 1e-6);
        assert!((tf.opacity_at(2.0) - 0.8).abs() < 1e-6, "clamped above the range");
    }

    #[test]
    fn single_object_and_named_presets() {
        let one = parse(r#"{"Name": "Solo", "RGBPoints": [0, 1, 1, 1, 1, 0, 0, 0]}"#).unwrap();
        assert_eq!(one.name, "Solo");
        assert_eq!(one.opacity, default_opacity_ramp());
        let two = r#"[{"Name": "A", "RGBPoints": [0, 1, 0, 0, 1, 1, 0, 0]},
                      {"Name": "B", "RGBPoints": [0, 0, 1, 0, 1, 0, 1, 0]}]"#;
        let b = TransferFunction::parse_paraview(two, Path::new("x.json"), Some("B")).unwrap();
        assert_eq!(b.color_at(0.3), [0.0, 1.0, 0.0]);
        let e = TransferFunction::parse_paraview(two, Path::new("x.json"), Some("C")).unwrap_err().to_string();
        assert!(e.contains("x.json") && e.contains("no preset named 'C'") && e.contains("'A', 'B'"), "{e}");
    }

    #[test]
    fn sharpness_one_is_a_step_and_midpoint_moves_the_half_value() {
        let step = OpacityPoint { x: 0.0, opacity: 0.0, midpoint: 0.5, sharpness: 1.0 };
        assert_eq!(shaped_segment(step, 1.0, 0.4), 0.0);
        assert_eq!(shaped_segment(step, 1.0, 0.6), 1.0);
        let early = OpacityPoint { midpoint: 0.2, sharpness: 0.0, ..step };
        assert!((shaped_segment(early, 1.0, 0.2) - 0.5).abs() < 1e-6);
        let smooth = OpacityPoint { sharpness: 0.5, ..step };
        let mid = shaped_segment(smooth, 1.0, 0.5);
        assert!((mid - 0.5).abs() < 1e-5 && shaped_segment(smooth, 1.0, 0.1) < 0.1);
    }

    #[test]
    fn step_and_lab_spaces() {
        let tf = parse(r#"{"ColorSpace": "Step", "RGBPoints": [0, 1, 0, 0,  0.5, 0, 1, 0,  1, 0, 0, 1]}"#).unwrap();
        assert_eq!(tf.color_at(0.49), [1.0, 0.0, 0.0]);
        assert_eq!(tf.color_at(0.51), [0.0, 1.0, 0.0]);
        let lab = parse(r#"{"ColorSpace": "Lab", "RGBPoints": [0, 0, 0, 0,  1, 1, 1, 1]}"#).unwrap();
        let g = lab.color_at(0.5);
        // Half way in lightness is brighter than half way in sRGB numbers.
        assert!(g[0] > 0.45 && (g[0] - g[1]).abs() < 1e-3, "{g:?}");
    }

    #[test]
    fn malformed_files_say_what_is_wrong() {
        let cases = [
            ("[{\"Name\": ", "not valid JSON (line 1"),
            ("42", "a JSON object or an array"),
            ("[]", "no presets"),
            ("[3]", "preset #0 is not a JSON object"),
            (r#"{"Name": "N"}"#, "preset 'N': no RGBPoints"),
            (r#"{"Name": "N", "IndexedColors": [1, 0, 0]}"#, "indexed (categorical)"),
            (r#"{"RGBPoints": "red"}"#, "RGBPoints is not an array"),
            (r#"{"RGBPoints": [0, 1, 0]}"#, "RGBPoints has 3 numbers"),
            (r#"{"RGBPoints": [0, 1, 0, "x"]}"#, "RGBPoints[3] is \"x\""),
            (r#"{"RGBPoints": [1, 1, 0, 0, 0, 0, 0, 0]}"#, "must not decrease"),
            (r#"{"RGBPoints": [0, 255, 0, 0]}"#, "outside 0..1"),
            (r#"{"ColorSpace": "XYZ", "RGBPoints": [0, 1, 0, 0]}"#, "unknown ColorSpace 'XYZ'"),
            (r#"{"RGBPoints": [0, 1, 0, 0], "Points": [0, 2, 0.5, 0]}"#, "Points point 0"),
            (r#"{"RGBPoints": [0, 1, 0, 0], "Points": [0, 1]}"#, "Points has 2 numbers"),
        ];
        for (text, want) in cases {
            let e = err(text);
            assert!(e.starts_with("maps/test.json: ") && e.contains(want), "{text}: {e}");
        }
        let missing = TransferFunction::load_paraview(Path::new("/nonexistent/cmap.json"), None).unwrap_err();
        assert!(missing.to_string().contains("/nonexistent/cmap.json"), "{missing}");
    }

    #[test]
    fn baked_table_maps_the_range_and_clamps() {
        let tf = TransferFunction::builtin(Colormap::Grayscale);
        let t = tf.bake(10.0, 20.0);
        assert_eq!(t.lookup(10.0), [0.0, 0.0, 0.0, 0.0]);
        assert_eq!(t.lookup(5.0), [0.0, 0.0, 0.0, 0.0]);
        let top = t.lookup(25.0);
        assert!(top.iter().all(|&x| (x - 1.0).abs() < 1e-6));
        let mid = t.lookup(15.0);
        assert!((mid[3] - 0.5).abs() < 1e-3, "opacity ramp is linear in value");
        assert!((mid[0] - colorspace::srgb_to_linear(0.5)).abs() < 2e-3, "colours are linearised");
    }
}
