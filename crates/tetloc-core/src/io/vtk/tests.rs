//! Tests of the VTK readers and writers against the shared data.
