//! What the readers' and writers' unit tests share: tetloc-testdata's data folder and test
//! meshes (core's usual test grid among them).

pub(crate) use tetloc_testdata::{jittered_grid, require_data, written_files, KuhnGrid};
