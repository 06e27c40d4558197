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

/// A field's name, location, and smallest and largest finite values (`None` when it has none).
#[derive(Clone, Debug, Serialize)]
pub struct FieldSummary<'a> {
    pub name: &'a str,
    pub location: FieldLocation,
    pub min: Option<f32>,
    pub max: Option<f32>,
}

impl Field {
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
                FieldSummary { name: &f.name, location: f.location, min, max }
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
}
