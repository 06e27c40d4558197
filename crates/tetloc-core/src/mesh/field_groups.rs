//! Fields of k components. The mesh stores scalar fields; a file's k-component array is read
//! as the k fields `NAME[0]` … `NAME[k-1]` (in this order, next to each other), and the
//! writers turn such runs back into one k-component array. A [`FieldGroup`] is one such
//! array: a scalar field, or the components of a vector.
//!
//! **Naming, in every command:** `v` is the whole array (all its components), `v[1]` one
//! component of it (a scalar). Commands that sample whole arrays (resample, probe) take both;
//! commands that need one scalar (locate, render) take a scalar field or a component and say
//! which components a vector has; trace's `--vector` takes a whole 3-component vector.

use crate::error::{Error, Result};
use crate::mesh::{Field, FieldLocation, Mesh};

/// One array as files see it: a name, where it lives and its scalar components in order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldGroup {
    pub name: String,
    pub location: FieldLocation,
    /// The mesh's scalar fields, one per component: `[name]`, or `NAME[0]`, `NAME[1]`, ….
    pub components: Vec<String>,
    /// Whether some component has f64 data (`Field::values64`): probed as f64, written as
    /// Float64 (as VTK's probe keeps the source array's type).
    pub f64: bool,
}

impl FieldGroup {
    pub fn n_components(&self) -> usize {
        self.components.len()
    }

    /// The component names as `&str`, for [`crate::BatchLocator::sample_many`].
    pub fn component_refs(&self) -> Vec<&str> {
        self.components.iter().map(String::as_str).collect()
    }
}

/// The field named `name` in `fields`: a scalar field of that name, the run `NAME[0]` …
/// `NAME[k-1]` (k ≥ 2) of a vector, or one component `NAME[i]` of a vector (a one-component
/// group). Errors list the arrays there are.
pub fn resolve_in(fields: &[Field], name: &str) -> Result<FieldGroup> {
    let groups = groups_of(fields);
    if let Some(g) = groups.iter().find(|g| g.name == name) {
        return Ok(g.clone());
    }
    if let Some(f) = fields.iter().find(|f| f.name == name) {
        let components = vec![f.name.clone()];
        return Ok(FieldGroup { name: f.name.clone(), location: f.location, components, f64: f.values64.is_some() });
    }
    Err(Error::NoSuchField {
        name: name.to_string(),
        available: if fields.is_empty() {
            "none".to_string()
        } else {
            groups.iter().map(describe).collect::<Vec<_>>().join(", ")
                + if groups.iter().any(|g| g.n_components() > 1) { "; a component as NAME[i]" } else { "" }
        },
    })
}

/// The scalar field to sample for `name` (commands that sample one value a point: locate,
/// render): a scalar field, or one component `NAME[i]` of a vector; a whole vector is an
/// error that names its components.
pub fn resolve_scalar(fields: &[Field], name: &str) -> Result<String> {
    let g = resolve_in(fields, name)?;
    match g.components.as_slice() {
        [one] => Ok(one.clone()),
        all => Err(Error::Invalid(format!(
            "'{name}' is a vector of {} components, and this samples one value a point: name a component, {}",
            all.len(),
            all.iter().map(|c| format!("'{c}'")).collect::<Vec<_>>().join(", ")
        ))),
    }
}

/// The arrays named by `names` (each as in [`resolve_in`]), for commands that write one array
/// each (resample, probe): a name given twice, or one that `reserved` output arrays take
/// (`vtkValidPointMask`), is an error. With no names, every array of the mesh except those
/// named as reserved ones (a probe's `vtkValidPointMask`: the output gets a new one).
pub fn resolve_outputs(fields: &[Field], names: &[String], reserved: &[&str]) -> Result<Vec<FieldGroup>> {
    if names.is_empty() {
        return Ok(groups_of(fields).into_iter().filter(|g| !reserved.contains(&g.name.as_str())).collect());
    }
    let mut out: Vec<FieldGroup> = Vec::with_capacity(names.len());
    for name in names {
        if reserved.contains(&name.as_str()) {
            return Err(Error::Invalid(format!(
                "the field '{name}': the output has an array of that name of its own; rename the field"
            )));
        }
        let g = resolve_in(fields, name)?;
        if out.iter().any(|o| o.name == g.name) {
            return Err(Error::Invalid(format!("the field '{name}' is named twice")));
        }
        out.push(g);
    }
    Ok(out)
}

/// [`resolve_in`] over a mesh's fields.
pub fn resolve(mesh: &Mesh, name: &str) -> Result<FieldGroup> {
    resolve_in(&mesh.fields, name)
}

/// Every array of a mesh, in file order: runs `NAME[0]` … `NAME[k-1]` (k ≥ 2, one location)
/// become one group; every other field is a scalar group of its own.
pub fn groups(mesh: &Mesh) -> Vec<FieldGroup> {
    groups_of(&mesh.fields)
}

/// [`groups`] over a list of fields (what writers hold).
pub fn groups_of(fields: &[Field]) -> Vec<FieldGroup> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < fields.len() {
        let k = run_length(fields, i);
        let f = &fields[i];
        let name = if k > 1 { base_name(&f.name).unwrap_or(&f.name).to_string() } else { f.name.clone() };
        out.push(FieldGroup {
            name,
            location: f.location,
            components: fields[i..i + k].iter().map(|f| f.name.clone()).collect(),
            f64: fields[i..i + k].iter().any(|f| f.values64.is_some()),
        });
        i += k;
    }
    out
}

/// The name in `'NAME' (k components, per vertex)` form for error messages.
fn describe(g: &FieldGroup) -> String {
    let loc = match g.location {
        FieldLocation::Vertex => "point",
        FieldLocation::Cell => "cell",
    };
    match g.n_components() {
        1 => format!("'{}' ({loc})", g.name),
        k => format!("'{}' ({loc}, {k} components)", g.name),
    }
}

/// `NAME` of `NAME[0]`.
fn base_name(name: &str) -> Option<&str> {
    name.strip_suffix("[0]").filter(|b| !b.is_empty())
}

/// How many fields from `i` on form the run `NAME[0]`, `NAME[1]`, … (1 when `fields[i]` does
/// not start a run of at least two).
fn run_length(fields: &[Field], i: usize) -> usize {
    let Some(base) = base_name(&fields[i].name) else { return 1 };
    let location = fields[i].location;
    let k = fields[i..]
        .iter()
        .enumerate()
        .take_while(|(c, f)| f.location == location && f.name == format!("{base}[{c}]"))
        .count();
    if k >= 2 {
        k
    } else {
        1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field(name: &str, location: FieldLocation) -> Field {
        Field { values64: None, name: name.into(), location, values: vec![] }
    }

    #[test]
    fn runs_of_components_group_and_lone_ones_do_not() {
        use FieldLocation::{Cell, Vertex};
        let fields = [
            field("v[0]", Vertex),
            field("v[1]", Vertex),
            field("v[2]", Vertex),
            field("f", Vertex),
            field("c[0]", Cell), // a lone `[0]` is a scalar named so
            field("w[0]", Vertex),
            field("w[1]", Cell), // another location: not the same array
            field("[0]", Vertex),
            field("[1]", Vertex),
        ];
        let g = groups_of(&fields);
        let names: Vec<(&str, usize)> = g.iter().map(|g| (g.name.as_str(), g.n_components())).collect();
        assert_eq!(names, [("v", 3), ("f", 1), ("c[0]", 1), ("w[0]", 1), ("w[1]", 1), ("[0]", 1), ("[1]", 1)]);
        assert_eq!(g[0].components, ["v[0]", "v[1]", "v[2]"]);
        assert_eq!(resolve_in(&fields, "v").unwrap().components.len(), 3);
        assert_eq!(resolve_in(&fields, "c[0]").unwrap().components, ["c[0]"]);
        let e = resolve_in(&fields, "nope").unwrap_err().to_string();
        assert!(e.contains("'nope'") && e.contains("'v' (point, 3 components)") && e.contains("'f' (point)"), "{e}");
    }

    /// Issue 29 item 18: `v` is the whole vector and `v[1]` one component, wherever a command
    /// can use them; names given twice and reserved output names are refused.
    #[test]
    fn one_naming_rule() {
        use FieldLocation::Vertex;
        let fields = [field("v[0]", Vertex), field("v[1]", Vertex), field("v[2]", Vertex), field("f", Vertex)];
        assert_eq!(resolve_in(&fields, "v[1]").unwrap().components, ["v[1]"]);
        assert_eq!(resolve_in(&fields, "v[1]").unwrap().name, "v[1]");
        assert_eq!(resolve_scalar(&fields, "v[2]").unwrap(), "v[2]");
        assert_eq!(resolve_scalar(&fields, "f").unwrap(), "f");
        let e = resolve_scalar(&fields, "v").unwrap_err().to_string();
        assert!(e.contains("'v' is a vector of 3 components") && e.contains("'v[0]', 'v[1]', 'v[2]'"), "{e}");
        let e = resolve_in(&fields, "w").unwrap_err().to_string();
        assert!(e.contains("a component as NAME[i]"), "{e}");
        let names = |n: &[&str]| n.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let got = resolve_outputs(&fields, &names(&["v", "v[1]", "f"]), &["vtkValidPointMask"]).unwrap();
        assert_eq!(got.iter().map(|g| g.n_components()).collect::<Vec<_>>(), [3, 1, 1]);
        let e = resolve_outputs(&fields, &names(&["f", "f"]), &[]).unwrap_err().to_string();
        assert!(e.contains("the field 'f' is named twice"), "{e}");
        let mut with_mask = fields.to_vec();
        with_mask.push(field("vtkValidPointMask", Vertex));
        let e = resolve_outputs(&with_mask, &names(&["vtkValidPointMask"]), &["vtkValidPointMask"]).unwrap_err();
        assert!(e.to_string().contains("rename the field"), "{e}");
        let all = resolve_outputs(&with_mask, &[], &["vtkValidPointMask"]).unwrap();
        assert_eq!(all.iter().map(|g| g.name.as_str()).collect::<Vec<_>>(), ["v", "f"]);
    }
}
