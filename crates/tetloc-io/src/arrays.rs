//! What results are written as, in every format: sampled values at their precision, the
//! names written beside them (`vtkValidPointMask`, `tet_id`), and an image's arrays. Below the
//! writers (`points`, `image`, `vtk`), which all name these.

use tetloc_core::error::{Error, Result};

/// The name of the 0/1 column (UInt8 array in VTK files) that says which points got an
/// answer: inside a cell, or within the boundary tolerance. VTK's probe filter names it so.
pub const VALID_MASK: &str = "vtkValidPointMask";

/// The columns and arrays that every table and point set of results has besides the values.
pub const RESULT_NAMES: [&str; 2] = ["tet_id", VALID_MASK];

/// An error when a sampled field's name is one of [`RESULT_NAMES`]: its column or array
/// would collide with theirs (in `.csv` as in `.vtu` and `.vtp`).
pub fn check_value_name(name: &str) -> Result<()> {
    if RESULT_NAMES.contains(&name) {
        return Err(Error::Invalid(format!(
            "the field '{name}' has the name of a column tetloc writes next to it ({}); rename the field",
            RESULT_NAMES.join(", ")
        )));
    }
    Ok(())
}

/// Sampled values at the precision they were interpolated in: f64 where the file's field is
/// f64 or f64 values were asked for, else f32.
#[derive(Clone, Copy, Debug)]
pub enum Values<'a> {
    F32(&'a [f32]),
    F64(&'a [f64]),
}

impl Values<'_> {
    pub fn len(&self) -> usize {
        match self {
            Values::F32(v) => v.len(),
            Values::F64(v) => v.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Value `i` as text: the shortest decimal that reads back to the same f32 or f64.
    pub(crate) fn text(&self, i: usize) -> String {
        match self {
            Values::F32(v) => v[i].to_string(),
            Values::F64(v) => v[i].to_string(),
        }
    }
}

/// One array of an image: a name and its components per point.
#[derive(Clone, Debug)]
pub struct ImageArray {
    pub name: String,
    pub n_components: usize,
}
