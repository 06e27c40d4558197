//! Exclusive prefix sums over the build's scan buffer (`shaders/build/scan.comp`): chunks of
//! SCAN_CHUNK values scanned by one workgroup each, the chunks' totals scanned the same way
//! (recursively, after the values), then added back. The grand total lands after the values.

use super::{Builder, Groups, SCAN};
use crate::device::{Device, Recording};
use crate::error::VkResult;
use crate::interface::*;
use crate::pipeline::Spec;

/// Words of scan buffer that a scan of `n` values needs (values, total, and the sums' levels).
pub(super) fn words(n: u64) -> u64 {
    let chunk = SCAN_CHUNK as u64;
    if n <= chunk {
        n + 1
    } else {
        n + 1 + words(n.div_ceil(chunk))
    }
}

pub(super) fn prepare(b: &mut Builder, dev: &mut Device) -> VkResult<()> {
    b.prepare(dev, SCAN, &[BUILD_SCAN_LOCAL, BUILD_SCAN_ADD], &Spec::default())
}

/// Records the scan of the `n` (> 0) values from word `at`; ends with a barrier.
pub(super) fn record(b: &Builder, r: &Recording, n: u32, at: u32) {
    let chunks = n.div_ceil(SCAN_CHUNK);
    let none = [[0.0; 4]; 2];
    if chunks == 1 {
        b.record(r, SCAN, BUILD_SCAN_LOCAL, [n, at, 0, 1], none, Groups::Workgroups(1));
    } else {
        let sums = at + n + 1;
        b.record(r, SCAN, BUILD_SCAN_LOCAL, [n, at, sums, 0], none, Groups::Workgroups(chunks as u64));
        r.barrier();
        record(b, r, chunks, sums);
        b.record(r, SCAN, BUILD_SCAN_ADD, [n, at, sums, 0], none, Groups::Items(n as u64));
    }
    r.barrier();
}
