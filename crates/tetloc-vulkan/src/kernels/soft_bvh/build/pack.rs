//! Packs the built neighbours or leaf prims into an id array of fewer bits a field
//! (`src/packed.rs`, `shaders/build/pack.comp`), for the `compact` and `small` layouts.

use super::{structure, Builder, Groups, PACK};
use crate::device::{Device, Split};
use crate::error::VkResult;
use crate::interface::*;
use crate::memory::Buffer;
use crate::packed;
use crate::pipeline::Spec;

/// What a pack pass reads.
pub(super) enum Source<'a> {
    /// The tets' four neighbours (each + 1), `bits` a field.
    Neighbors(&'a Split),
    /// The leaf prims.
    Prims(&'a Buffer),
}

/// `source` packed at `bits` bits a field, in one buffer named `name`.
pub(super) fn run(b: &mut Builder, dev: &mut Device, source: Source, bits: u32, name: &str) -> VkResult<Buffer> {
    let (pass, fields, spec) = match source {
        Source::Neighbors(nb) => {
            b.bind_split(B_BUILD_NEIGHBORS, Some(nb), dev.unbound());
            (BUILD_PACK_NEIGHBORS, 4 * b.n_tets as u64, Spec::default().set(sc::NEIGHBOR_BITS, bits))
        }
        Source::Prims(p) => {
            b.bind(B_PRIMS, p);
            (BUILD_PACK_PRIMS, b.n as u64, Spec::default().set(sc::PRIM_BITS, bits))
        }
    };
    let out = structure(dev, name, 4 * packed::words(fields, bits))?;
    b.bind(B_PACKED, &out);
    b.prepare(dev, PACK, &[pass], &spec)?;
    dev.run(|r| {
        super::fill(r, &out, 0, out.size, 0);
        r.barrier();
        b.record(r, PACK, pass, [fields as u32, 0, 0, 0], [[0.0; 4]; 2], Groups::Items(fields));
    })?;
    b.bind(B_PACKED, dev.unbound());
    b.bind(B_PRIMS, dev.unbound());
    b.bind_split(B_BUILD_NEIGHBORS, None, dev.unbound());
    Ok(out)
}
