//! Synthetic meshes shaped like the paper's data sets.
