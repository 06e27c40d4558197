//! The binary blocks of VTK XML files: base64 text, the size header, zlib compression.
//!
//! A block is `[header][data]`. Uncompressed, the header is the data's byte count;
//! compressed (vtkZLibDataCompressor) it is `[#blocks][block size][last block size]
//! [compressed size of each block]` followed by the zlib streams. Header ints are UInt32 or
//! UInt64 (`header_type`), in the file's byte order.

use base64::Engine;
use rayon::prelude::*;
use std::borrow::Cow;

/// Attributes of `<VTKFile>` that say how blocks are laid out.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Layout {
    pub header64: bool,
    pub zlib: bool,
    pub big_endian: bool,
}

impl Layout {
    fn header_size(self) -> usize {
        if self.header64 {
            8
        } else {
            4
        }
    }

    /// The header int at `buf[at..]`, if the bytes are there.
    fn header_int(self, buf: &[u8], at: usize) -> Option<u64> {
        let b = buf.get(at..at.checked_add(self.header_size())?)?;
        Some(match (self.header64, self.big_endian) {
            (true, false) => u64::from_le_bytes(b.try_into().unwrap()),
            (true, true) => u64::from_be_bytes(b.try_into().unwrap()),
            (false, false) => u32::from_le_bytes(b.try_into().unwrap()) as u64,
            (false, true) => u32::from_be_bytes(b.try_into().unwrap()) as u64,
        })
    }
}

/// Decodes base64 text, ignoring whitespace. Padded pieces may follow each other: VTK
/// encodes a compressed array's header and its data separately.
pub(crate) fn base64_decode(text: &[u8]) -> Result<Vec<u8>, String> {
    let clean: Vec<u8> = text.iter().copied().filter(|c| !c.is_ascii_whitespace()).collect();
    let mut out = Vec::with_capacity(clean.len() / 4 * 3);
    let mut rest = &clean[..];
    while !rest.is_empty() {
        let end = match rest.iter().position(|&c| c == b'=') {
            Some(p) => p + rest[p..].iter().take_while(|&&c| c == b'=').count(),
            None => rest.len(),
        };
        base64::engine::general_purpose::STANDARD
            .decode_vec(&rest[..end], &mut out)
            .map_err(|e| format!("invalid base64 data: {e}"))?;
        rest = &rest[end..];
    }
    Ok(out)
}

/// The byte count the block at `buf[at..]` declares (inflated, when compressed): for arrays
/// whose length only their block gives (the polyhedra's faces).
pub(crate) fn declared_bytes(buf: &[u8], at: usize, layout: Layout) -> Result<usize, String> {
    let hs = layout.header_size();
    let int = |i: usize| {
        layout.header_int(buf, at + i * hs).ok_or_else(|| format!("block at offset {at} runs past the end of the data"))
    };
    let bytes = if !layout.zlib {
        int(0)?
    } else {
        let (n_blocks, block_size, last_size) = (int(0)?, int(1)?, int(2)?);
        match n_blocks {
            0 => 0,
            n => (n - 1).saturating_mul(block_size).saturating_add(if last_size == 0 { block_size } else { last_size }),
        }
    };
    // Never more than the data could inflate to (read_block checks the rest).
    let limit = (buf.len() as u64).saturating_mul(1100).saturating_add(1024);
    usize::try_from(bytes)
        .ok()
        .filter(|&b| b as u64 <= limit)
        .ok_or_else(|| format!("block at offset {at} declares {bytes} bytes: more than the file can hold"))
}

/// A block's data: borrowed from `buf` when uncompressed. `at` is where its header starts;
/// `expected` is the byte count that the array must have. Errors are messages to be
/// prefixed with the array's name.
pub(crate) fn read_block(buf: &[u8], at: usize, layout: Layout, expected: usize) -> Result<Cow<'_, [u8]>, String> {
    let hs = layout.header_size();
    let past_end = || format!("block at offset {at} runs past the end of the data (truncated file?)");
    if !layout.zlib {
        let n = layout.header_int(buf, at).ok_or_else(past_end)?;
        let start = at + hs;
        if n > (buf.len() - start) as u64 {
            return Err(format!(
                "block at offset {at} declares {n} bytes but only {} follow (truncated file?)",
                buf.len() - start
            ));
        }
        if n != expected as u64 {
            return Err(format!("block at offset {at} holds {n} bytes, expected {expected}"));
        }
        return Ok(Cow::Borrowed(&buf[start..start + expected]));
    }

    let int = |i: usize| layout.header_int(buf, at + i * hs).ok_or_else(past_end);
    let (n_blocks, block_size, last_size) = (int(0)?, int(1)?, int(2)?);
    // The block sizes must be in the file before anything is believed or allocated.
    let n_blocks_max = (buf.len().saturating_sub(at) / hs) as u64;
    if n_blocks > n_blocks_max {
        return Err(format!("compressed block at offset {at} declares {n_blocks} blocks: more than the file can hold"));
    }
    let nb = n_blocks as usize;
    let sizes: Vec<u64> = (0..nb).map(|k| int(3 + k)).collect::<Result<_, _>>()?;
    if last_size > block_size || (nb > 0 && block_size == 0) {
        return Err(format!("compressed block at offset {at}: bad block sizes {block_size} / last {last_size}"));
    }
    let total = match nb {
        0 => Some(0),
        _ => (n_blocks - 1)
            .checked_mul(block_size)
            .and_then(|t| t.checked_add(if last_size == 0 { block_size } else { last_size })),
    };
    if total != Some(expected as u64) {
        return Err(format!(
            "compressed block at offset {at} inflates to {} bytes, expected {expected}",
            total.map_or("too many".to_string(), |t| t.to_string())
        ));
    }
    let mut ranges = Vec::with_capacity(nb);
    let mut pos = at + hs * (3 + nb);
    for (k, &cs) in sizes.iter().enumerate() {
        if cs > (buf.len().saturating_sub(pos)) as u64 {
            return Err(past_end());
        }
        let raw = if k + 1 == nb && last_size != 0 { last_size } else { block_size };
        // zlib cannot inflate more than ~1032:1: refuse claims that would make us allocate
        // far more than the file could ever produce.
        if raw > cs.saturating_mul(1100).saturating_add(1024) {
            return Err(format!("compressed block at offset {at}: {cs} bytes cannot inflate to {raw}"));
        }
        ranges.push(pos..pos + cs as usize);
        pos += cs as usize;
    }
    let mut out = vec![0u8; expected];
    out.par_chunks_mut(block_size.max(1) as usize).zip(ranges).enumerate().try_for_each(|(k, (dst, src))| {
        let mut z = flate2::Decompress::new(true);
        let bad = |why: &str| format!("compressed block at offset {at}, part {k}: {why}");
        match z.decompress(&buf[src], dst, flate2::FlushDecompress::Finish) {
            Ok(flate2::Status::StreamEnd) if z.total_out() == dst.len() as u64 => Ok(()),
            Ok(_) => Err(bad("zlib data does not inflate to the size its header gives")),
            Err(e) => Err(bad(&format!("corrupt zlib data ({e})"))),
        }
    })?;
    Ok(Cow::Owned(out))
}

/// Compresses `data` as VTK zlib blocks of `block_size` bytes, with UInt64 header ints:
/// header and data in one buffer (the writers stream theirs: `write.rs`).
#[cfg(test)]
pub(crate) fn zlib_block(data: &[u8], block_size: usize) -> Vec<u8> {
    let parts: Vec<Vec<u8>> = data.par_chunks(block_size).map(zlib_compress).collect();
    let mut out = zlib_header(data.len(), block_size, parts.iter().map(Vec::len));
    for p in &parts {
        out.extend_from_slice(p);
    }
    out
}

/// One block as a zlib stream.
pub(crate) fn zlib_compress(block: &[u8]) -> Vec<u8> {
    use std::io::Write;
    // Level 3: measured on a 10M-tet grid, as small as the default level and much faster;
    // zlib-rs's level 1 gave a 70 % larger file.
    let mut z = flate2::write::ZlibEncoder::new(Vec::with_capacity(block.len() / 2), flate2::Compression::new(3));
    z.write_all(block).expect("writing to a Vec");
    z.finish().expect("writing to a Vec")
}

/// The UInt64 header of `n_bytes` compressed in blocks of `block_size`: the block count, the
/// block size, the last block's size (0 when full) and each block's compressed size.
pub(crate) fn zlib_header(n_bytes: usize, block_size: usize, sizes: impl ExactSizeIterator<Item = usize>) -> Vec<u8> {
    let mut out = Vec::with_capacity(8 * (3 + sizes.len()));
    for v in [sizes.len(), block_size, n_bytes % block_size].into_iter().chain(sizes) {
        out.extend_from_slice(&(v as u64).to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const LE64: Layout = Layout { header64: true, zlib: false, big_endian: false };

    #[test]
    fn base64_pieces() {
        assert_eq!(base64_decode(b"AQID\nBA==").unwrap(), vec![1, 2, 3, 4]);
        // Two padded pieces back to back, as VTK writes a compressed header and its data.
        assert_eq!(base64_decode(b"AQ==AgM=").unwrap(), vec![1, 2, 3]);
        assert!(base64_decode(b"AQ=").is_err());
        assert!(base64_decode(b"A*==").is_err());
    }

    #[test]
    fn raw_blocks() {
        let mut buf = 4u64.to_le_bytes().to_vec();
        buf.extend_from_slice(&[9, 8, 7, 6]);
        assert_eq!(&*read_block(&buf, 0, LE64, 4).unwrap(), &[9, 8, 7, 6]);
        assert!(read_block(&buf, 0, LE64, 3).unwrap_err().contains("expected 3"));
        assert!(read_block(&buf[..7], 0, LE64, 4).unwrap_err().contains("truncated"));
        assert!(read_block(&buf, 5, LE64, 4).is_err());
        let be = Layout { header64: false, zlib: false, big_endian: true };
        assert_eq!(&*read_block(&[0, 0, 0, 1, 5], 0, be, 1).unwrap(), &[5]);
        // A header claiming an enormous size is an error, not an allocation.
        let mut huge = u64::MAX.to_le_bytes().to_vec();
        huge.push(0);
        assert!(read_block(&huge, 0, LE64, 1 << 40).is_err());
    }

    #[test]
    fn zlib_round_trip() {
        let z = Layout { zlib: true, ..LE64 };
        let data: Vec<u8> = (0..100_000u32).flat_map(|i| (i / 7).to_le_bytes()).collect();
        for bs in [1 << 10, 1 << 15, data.len(), data.len() + 5] {
            let blk = zlib_block(&data, bs);
            assert_eq!(&*read_block(&blk, 0, z, data.len()).unwrap(), &data[..]);
            assert!(read_block(&blk, 0, z, data.len() - 1).is_err());
            assert!(read_block(&blk[..blk.len() - 1], 0, z, data.len()).is_err());
        }
        let empty = zlib_block(&[], 1 << 10);
        assert!(read_block(&empty, 0, z, 0).unwrap().is_empty());
        // A block claiming to inflate 10 bytes into a gigabyte.
        let mut bomb = Vec::new();
        for v in [1u64, 1 << 30, 0, 10] {
            bomb.extend_from_slice(&v.to_le_bytes());
        }
        bomb.extend_from_slice(&[0; 10]);
        assert!(read_block(&bomb, 0, z, 1 << 30).unwrap_err().contains("cannot inflate"));
    }
}
