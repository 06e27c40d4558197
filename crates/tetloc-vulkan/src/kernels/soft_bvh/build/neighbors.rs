//! The tets' face neighbours (`shaders/build/neighbors.comp`), as `Mesh::neighbors`: every
//! face (4 a tet) counted and scattered into a bucket of its smallest vertex (a counting sort
//! through the scan), then matched with the faces of the same vertices in its bucket; a face
//! of three or more tets links only the first two (in order of 4 tet + face), as the CPU's
//! sort does. Work per face is its bucket's size (about 24 faces a vertex in a tet mesh).

use super::{scan, Builder, Groups, NEIGHBORS};
use crate::device::{Device, Split};
use crate::error::VkResult;
use crate::interface::*;
use crate::kernels::Inputs;
use crate::memory::{Buffer, MemKind};
use crate::pipeline::Spec;

pub(super) fn run(b: &mut Builder, dev: &mut Device, input: &Inputs, scan_buf: &Buffer) -> VkResult<Split> {
    let n = b.n_tets as u64;
    let points = input.mesh.points.len() as u32;
    let faces = b.split(dev, MemKind::Scratch, "build faces", 4 * n, 12)?;
    let out = b.split(dev, MemKind::Structure, "tet neighbours", n, 16)?;
    b.bind_split(B_BUILD_FACES, Some(&faces), dev.unbound());
    b.bind_split(B_BUILD_NEIGHBORS, Some(&out), dev.unbound());
    b.prepare(dev, NEIGHBORS, &[BUILD_NB_COUNT, BUILD_NB_SCATTER, BUILD_NB_MATCH], &Spec::default())?;
    scan::prepare(b, dev)?;
    let f = (4 * n) as u32;
    let none = [[0.0; 4]; 2];
    dev.run(|r| {
        super::fill(r, scan_buf, 0, 4 * points as u64, 0);
        r.barrier();
        b.record(r, NEIGHBORS, BUILD_NB_COUNT, [f, 0, 0, 0], none, Groups::Items(f as u64));
        r.barrier();
        scan::record(b, r, points, 0);
        b.record(r, NEIGHBORS, BUILD_NB_SCATTER, [f, 0, 0, 0], none, Groups::Items(f as u64));
        r.barrier();
        b.record(r, NEIGHBORS, BUILD_NB_MATCH, [f, 0, 0, 0], none, Groups::Items(f as u64));
    })?;
    b.bind_split(B_BUILD_FACES, None, dev.unbound());
    b.bind_split(B_BUILD_NEIGHBORS, None, dev.unbound());
    drop(faces);
    Ok(out)
}
