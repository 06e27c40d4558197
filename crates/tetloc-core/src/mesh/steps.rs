//! Time steps: a mesh whose fields change in time while its geometry does not (ParaView's
//! time steps). Each step's fields are read when they are asked for, one step at a time, so
//! memory stays bounded for any number of steps.

use super::Field;
use crate::error::{Error, Result};

/// Where each step's fields come from: a file format's reader.
pub trait StepFields: Send + Sync {
    /// The fields of step `k` (`k` < the number of steps): the mesh's names, locations and
    /// lengths, with that step's values.
    fn read(&self, k: usize) -> Result<Vec<Field>>;

    /// The fields of step `k` named in `names` (the others may be left unread): what a reader
    /// that can skip arrays does faster. By default, [`Self::read`]'s, filtered.
    fn read_named(&self, k: usize, names: &[String]) -> Result<Vec<Field>> {
        Ok(self.read(k)?.into_iter().filter(|f| names.contains(&f.name)).collect())
    }
}

/// A mesh's time steps: their times, and their fields read a step at a time.
pub struct TimeSteps {
    /// The file (or series) the steps come from; used in error messages.
    pub source: String,
    /// Each step's time, ascending.
    pub times: Vec<f64>,
    fields: Box<dyn StepFields>,
}

impl std::fmt::Debug for TimeSteps {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "TimeSteps({}, {} steps)", self.source, self.times.len())
    }
}

impl TimeSteps {
    pub fn new(source: impl Into<String>, times: Vec<f64>, fields: Box<dyn StepFields>) -> TimeSteps {
        TimeSteps { source: source.into(), times, fields }
    }

    pub fn len(&self) -> usize {
        self.times.len()
    }

    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// An error unless `k` names a step.
    pub fn check(&self, k: usize) -> Result<()> {
        check_step(&self.source, self.len(), k)
    }

    /// The fields of step `k`, read now.
    pub fn fields(&self, k: usize) -> Result<Vec<Field>> {
        self.check(k)?;
        self.fields.read(k)
    }

    /// The fields of step `k` named in `names`, read now (a name the step lacks is left out).
    pub fn fields_named(&self, k: usize, names: &[String]) -> Result<Vec<Field>> {
        self.check(k)?;
        self.fields.read_named(k, names)
    }

    /// The field `name` of step `k` (an error that lists the step's fields when it has none of
    /// that name).
    pub fn field(&self, name: &str, k: usize) -> Result<Field> {
        if let Some(f) = self.fields_named(k, &[name.to_string()])?.into_iter().find(|f| f.name == name) {
            return Ok(f);
        }
        let fields = self.fields(k)?;
        let available = fields.iter().map(|f| format!("'{}'", f.name)).collect::<Vec<_>>().join(", ");
        Err(Error::NoSuchField {
            name: name.to_string(),
            available: if available.is_empty() { "none".into() } else { available },
        })
    }
}

/// An error unless `k` names one of `n` steps of `source` (none: it has no time steps).
pub fn check_step(source: &str, n: usize, k: usize) -> Result<()> {
    match n {
        0 => Err(no_steps(source, k)),
        n if k >= n => {
            Err(Error::Invalid(format!("time step {k} is out of range: {source} has {n} steps (0 to {})", n - 1)))
        }
        _ => Ok(()),
    }
}

/// The error for step `k` of `source`, a single snapshot.
pub fn no_steps(source: &str, k: usize) -> Error {
    Error::Invalid(format!("{source} has no time steps (a single snapshot): there is no step {k}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::FieldLocation;

    struct Ramp;
    impl StepFields for Ramp {
        fn read(&self, k: usize) -> Result<Vec<Field>> {
            Ok(vec![Field::new("f", FieldLocation::Vertex, vec![k as f32; 3])])
        }
    }

    /// Steps are read when asked, by index; out of range and unknown names are clear errors.
    #[test]
    fn steps_read_on_demand_and_refuse_bad_indices() {
        let s = TimeSteps::new("ramp.pvd", vec![0.0, 0.5, 1.0], Box::new(Ramp));
        assert_eq!(s.fields(2).unwrap()[0].values, [2.0; 3]);
        assert_eq!(s.field("f", 1).unwrap().values, [1.0; 3]);
        let e = s.fields(3).unwrap_err().to_string();
        assert!(
            e.contains("time step 3 is out of range") && e.contains("3 steps (0 to 2)") && e.contains("ramp.pvd"),
            "{e}"
        );
        assert!(s.field("g", 0).unwrap_err().to_string().contains("'f'"));
        assert!(check_step("one.vtu", 0, 0).unwrap_err().to_string().contains("no time steps"));
    }
}
