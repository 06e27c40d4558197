//! VTU writers: stub, replaced by the real writer.
