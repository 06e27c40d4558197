//! Query points in, ids and values out: .npy, .csv and raw little-endian arrays.
