//! Output checks every command shares: no output is an input (every file an input reads,
//! pieces included: `mesh_arg::input_files`), and leftovers of an interrupted write of the
//! same output are named.

use anyhow::Result;
use tetloc_io::output::{self, FileArg};

/// [`output::check_distinct`], then a warning naming the stale temporaries (`.NAME.*.tmp`)
/// that an interrupted earlier write of each output left beside it.
pub fn check_distinct(inputs: &[FileArg], outputs: &[FileArg]) -> Result<()> {
    output::check_distinct(inputs, outputs)?;
    // Each look reads the output's folder: the first outputs of a long PNG series suffice.
    for o in outputs.iter().take(100) {
        let stale = output::stale_temporaries(o.path);
        if !stale.is_empty() {
            let names: Vec<String> = stale.iter().map(|p| p.display().to_string()).collect();
            eprintln!(
                "warning: {} {}: an interrupted earlier write left {} (not in use by this run; remove {})",
                o.name,
                o.path.display(),
                names.join(", "),
                if stale.len() == 1 { "it" } else { "them" }
            );
        }
    }
    Ok(())
}
