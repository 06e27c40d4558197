//! What `tetloc info --json` and Python's `Mesh.info()` report: one definition, so the two
//! cannot drift apart.

use super::faces::FaceStats;
use super::{Field, FieldLocation, Mesh, MeshInfo};
use serde::Serialize;

/// The mesh facts, its face counts and its fields with their value ranges.
#[derive(Clone, Debug, Serialize)]
pub struct MeshSummary<'a> {
    pub mesh: &'a MeshInfo,
    pub faces: FaceStats,
    pub fields: Vec<FieldSummary<'a>>,
}

/// A field's name, location, smallest and largest finite values (`None` when it has none),
/// and how many of its values are not finite (a range alone would hide them).
#[derive(Clone, Debug, Serialize)]
pub struct FieldSummary<'a> {
    pub name: &'a str,
    pub location: FieldLocation,
    pub min: Option<f32>,
    pub max: Option<f32>,
    /// Values that are NaN.
    pub n_nan: usize,
    /// Values that are +infinity.
    pub n_inf: usize,
    /// Values that are -infinity.
    pub n_neg_inf: usize,
}

impl FieldSummary<'_> {
    /// How many values are NaN or infinite.
    pub fn n_non_finite(&self) -> usize {
        self.n_nan + self.n_inf + self.n_neg_inf
    }

    /// `range LO .. HI`, then the non-finite values counted, for `info`'s text.
    pub fn describe_values(&self) -> String {
        let mut text = match (self.min, self.max) {
            (Some(lo), Some(hi)) => format!("range {lo} .. {hi}"),
            _ => "no finite values".to_string(),
        };
        if self.n_non_finite() > 0 {
            let counts: Vec<String> = [(self.n_nan, "NaN"), (self.n_inf, "+inf"), (self.n_neg_inf, "-inf")]
                .iter()
                .filter(|(n, _)| *n > 0)
                .map(|(n, what)| format!("{n} {what}"))
                .collect();
            text += &format!("; {} non-finite values ({})", self.n_non_finite(), counts.join(", "));
        }
        text
    }
}

impl Field {
    /// How many values are NaN, +infinity and -infinity.
    pub fn non_finite_counts(&self) -> (usize, usize, usize) {
        use rayon::prelude::*;
        self.values
            .par_iter()
            .filter(|v| !v.is_finite())
            .map(|&v| match v {
                f32::INFINITY => (0, 1, 0),
                f32::NEG_INFINITY => (0, 0, 1),
                _ => (1, 0, 0),
            })
            .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2))
    }

    /// The smallest and largest finite values, if there are any.
    pub fn finite_range(&self) -> Option<(f32, f32)> {
        self.values.iter().filter(|v| v.is_finite()).fold(None, |r, &v| match r {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
    }
}

impl Mesh {
    /// The summary of this mesh; computes the shared faces on first use.
    pub fn summary(&self) -> MeshSummary<'_> {
        let fields = self
            .fields
            .iter()
            .map(|f| {
                let (min, max) = f.finite_range().unzip();
                let (n_nan, n_inf, n_neg_inf) = f.non_finite_counts();
                FieldSummary { name: &f.name, location: f.location, min, max, n_nan, n_inf, n_neg_inf }
            })
            .collect();
        MeshSummary { mesh: &self.info, faces: self.faces().stats, fields }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_skip_non_finite_values() {
        let f = |values: Vec<f32>| Field { values64: None, name: "f".into(), location: FieldLocation::Vertex, values };
        assert_eq!(f(vec![2.0, f32::NAN, -1.0, f32::INFINITY, 0.5]).finite_range(), Some((-1.0, 2.0)));
        assert_eq!(f(vec![f32::NAN]).finite_range(), None);
        assert_eq!(f(vec![]).finite_range(), None);
    }

    /// Issue 29 item 13: a field of [0, NaN, inf, -inf] is not reported as "range 0 .. 0"
    /// alone: its non-finite values are counted.
    #[test]
    fn non_finite_values_are_counted() {
        let values = vec![0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
        let f = Field { values64: None, name: "f".into(), location: FieldLocation::Vertex, values };
        assert_eq!(f.non_finite_counts(), (2, 1, 1));
        let (min, max) = f.finite_range().unzip();
        let s = FieldSummary { name: "f", location: f.location, min, max, n_nan: 2, n_inf: 1, n_neg_inf: 1 };
        assert_eq!(s.describe_values(), "range 0 .. 0; 4 non-finite values (2 NaN, 1 +inf, 1 -inf)");
        let s = FieldSummary { min: None, max: None, n_inf: 0, n_neg_inf: 0, ..s };
        assert_eq!(s.describe_values(), "no finite values; 2 non-finite values (2 NaN)");
    }
}
