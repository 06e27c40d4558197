//! One OpenFOAM file (`FoamFile` header, then the data), ascii or binary, gzip-compressed or
//! not: the tokens and lists the case reader needs. Errors are messages; the caller names the
//! file.

use std::collections::BTreeMap;

/// An OpenFOAM file's bytes and where reading is.
pub(crate) struct Foam {
    bytes: Vec<u8>,
    pos: usize,
    /// `format binary;`: lists hold raw little-endian numbers between their parentheses.
    binary: bool,
    /// Bytes of a label and a scalar in binary lists (`arch "LSB;label=32;scalar=64"`).
    label_bytes: usize,
    scalar_bytes: usize,
    /// The header's entries (`class`, `object`, `format`, ...).
    pub header: BTreeMap<String, String>,
}

type R<T> = Result<T, String>;

/// gzip's magic bytes.
const GZIP: &[u8] = &[0x1f, 0x8b];

impl Foam {
    /// Parses the header of `bytes` (inflated first when gzip-compressed).
    pub fn new(bytes: Vec<u8>) -> R<Foam> {
        let bytes = if bytes.starts_with(GZIP) { gunzip(&bytes)? } else { bytes };
        let mut f = Foam { bytes, pos: 0, binary: false, label_bytes: 4, scalar_bytes: 8, header: BTreeMap::new() };
        f.skip_space();
        if f.word()? != "FoamFile" {
            return Err("no FoamFile header: not an OpenFOAM file".into());
        }
        f.header = f.dictionary()?.into_iter().map(|(k, v)| (k, v.trim_matches('"').to_string())).collect();
        f.binary = f.header.get("format").is_some_and(|v| v == "binary");
        if let Some(arch) = f.header.get("arch") {
            for part in arch.split(';') {
                match part.split_once('=') {
                    Some(("label", "64")) => f.label_bytes = 8,
                    Some(("scalar", "32")) => f.scalar_bytes = 4,
                    _ => {}
                }
            }
        }
        Ok(f)
    }

    /// The header's `class` (`faceList`, `volScalarField`, ...).
    pub fn class(&self) -> &str {
        self.header.get("class").map_or("", String::as_str)
    }

    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    /// Skips white space and `//` and `/* */` comments.
    fn skip_space(&mut self) {
        loop {
            while self.peek().is_some_and(|c| c.is_ascii_whitespace()) {
                self.pos += 1;
            }
            let rest = &self.bytes[self.pos..];
            if rest.starts_with(b"//") {
                self.pos += rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
            } else if rest.starts_with(b"/*") {
                self.pos += rest.windows(2).position(|w| w == b"*/").map_or(rest.len(), |i| i + 2);
            } else {
                return;
            }
        }
    }

    fn at_end(&mut self) -> bool {
        self.skip_space();
        self.pos >= self.bytes.len()
    }

    fn where_(&self) -> String {
        let line = 1 + self.bytes[..self.pos.min(self.bytes.len())].iter().filter(|&&c| c == b'\n').count();
        format!("line {line}")
    }

    /// A word: up to white space or one of `;(){}[]`; a quoted string whole.
    pub fn word(&mut self) -> R<String> {
        self.skip_space();
        let start = self.pos;
        if self.peek() == Some(b'"') {
            let end = self.bytes[start + 1..].iter().position(|&c| c == b'"').ok_or("an unclosed string")?;
            self.pos = start + end + 2;
            return Ok(String::from_utf8_lossy(&self.bytes[start..self.pos]).into_owned());
        }
        while self.peek().is_some_and(|c| !c.is_ascii_whitespace() && !b";(){}[]".contains(&c)) {
            self.pos += 1;
        }
        if self.pos == start {
            return Err(match self.peek() {
                None => "the file ends where a word was expected".into(),
                Some(c) => format!("'{}' at {} where a word was expected", c as char, self.where_()),
            });
        }
        Ok(String::from_utf8_lossy(&self.bytes[start..self.pos]).into_owned())
    }

    fn expect(&mut self, c: u8) -> R<()> {
        self.skip_space();
        match self.peek() {
            Some(got) if got == c => {
                self.pos += 1;
                Ok(())
            }
            Some(got) => Err(format!("expected '{}' at {}, found '{}'", c as char, self.where_(), got as char)),
            None => Err(format!("expected '{}', found the end of the file (truncated?)", c as char)),
        }
    }

    /// The text up to the next `;` at this level (brackets balanced), which is consumed.
    fn until_semicolon(&mut self) -> R<String> {
        let start = self.pos;
        let mut depth = 0i32;
        while let Some(c) = self.peek() {
            self.pos += 1;
            match c {
                b'(' | b'[' | b'{' => depth += 1,
                b')' | b']' | b'}' => depth -= 1,
                b';' if depth <= 0 => return Ok(String::from_utf8_lossy(&self.bytes[start..self.pos - 1]).into_owned()),
                _ => {}
            }
        }
        Err("the file ends inside an entry (a missing ';')".into())
    }

    /// Skips top-level entries up to the one named `key`; `false` when the file has none.
    pub fn seek_entry(&mut self, key: &str) -> R<bool> {
        while !self.at_end() {
            let w = self.word()?;
            if w == key {
                return Ok(true);
            }
            self.skip_space();
            if self.peek() == Some(b'{') {
                // A sub-dictionary (`boundaryField { ... }`): skip it whole.
                let mut depth = 0;
                while let Some(c) = self.peek() {
                    self.pos += 1;
                    match c {
                        b'{' => depth += 1,
                        b'}' => {
                            depth -= 1;
                            if depth == 0 {
                                break;
                            }
                        }
                        _ => {}
                    }
                }
            } else {
                self.until_semicolon()?;
            }
        }
        Ok(false)
    }

    /// A flat dictionary `{ key value; ... }`: its entries, values trimmed.
    fn dictionary(&mut self) -> R<BTreeMap<String, String>> {
        self.expect(b'{')?;
        let mut entries = BTreeMap::new();
        loop {
            self.skip_space();
            if self.peek() == Some(b'}') {
                self.pos += 1;
                return Ok(entries);
            }
            let key = self.word()?;
            entries.insert(key, self.until_semicolon()?.trim().to_string());
        }
    }

    /// A list's length, and whether it is given as `N{value}` (every entry the same).
    fn count(&mut self, what: &str) -> R<usize> {
        let w = self.word()?;
        let n: usize = w.parse().map_err(|_| format!("{what}: '{w}' at {} is not a list length", self.where_()))?;
        // Every entry takes at least a byte: a larger count is a lie, refused before allocating.
        if n > self.bytes.len() {
            return Err(format!("{what}: a list of {n} entries in a file of {} bytes", self.bytes.len()));
        }
        Ok(n)
    }

    /// The raw bytes of a binary list of `n` items of `size` bytes, parentheses consumed.
    fn binary_block(&mut self, n: usize, size: usize, what: &str) -> R<&[u8]> {
        self.expect(b'(')?;
        let len = n.checked_mul(size).ok_or_else(|| format!("{what}: {n} entries overflow"))?;
        let start = self.pos;
        if self.bytes.len() - start < len + 1 {
            return Err(format!("{what}: {n} binary entries run past the end of the file (truncated?)"));
        }
        self.pos += len;
        self.expect(b')')?;
        Ok(&self.bytes[start..start + len])
    }

    fn number(&mut self, what: &str) -> R<f64> {
        let w = self.word()?;
        w.parse().map_err(|_| format!("{what}: '{w}' at {} is not a number", self.where_()))
    }

    fn label(&mut self, what: &str) -> R<i64> {
        let w = self.word()?;
        w.parse().map_err(|_| format!("{what}: '{w}' at {} is not a label", self.where_()))
    }

    /// A `List<label>`: `N (a b ...)` or `N{a}`; binary lists hold raw labels.
    pub fn labels(&mut self, what: &str) -> R<Vec<i64>> {
        let n = self.count(what)?;
        self.skip_space();
        if self.peek() == Some(b'{') {
            self.pos += 1;
            let v = self.label(what)?;
            self.expect(b'}')?;
            return Ok(vec![v; n]);
        }
        if self.binary {
            let size = self.label_bytes;
            let raw = self.binary_block(n, size, what)?;
            return Ok(raw
                .chunks_exact(size)
                .map(|c| match size {
                    8 => i64::from_le_bytes(c.try_into().unwrap()),
                    _ => i64::from(i32::from_le_bytes(c.try_into().unwrap())),
                })
                .collect());
        }
        self.expect(b'(')?;
        let v = (0..n).map(|_| self.label(what)).collect::<R<Vec<_>>>()?;
        self.expect(b')')?;
        Ok(v)
    }

    fn scalar_of(size: usize, c: &[u8]) -> f64 {
        match size {
            4 => f64::from(f32::from_le_bytes(c.try_into().unwrap())),
            _ => f64::from_le_bytes(c.try_into().unwrap()),
        }
    }

    /// A list of `k`-component values (`k = 1`: scalars `N (a b ...)`; else `N ((x y z) ...)`),
    /// flat; or `N{value}`.
    pub fn values(&mut self, k: usize, what: &str) -> R<Vec<f64>> {
        let n = self.count(what)?;
        self.skip_space();
        if self.peek() == Some(b'{') {
            self.pos += 1;
            let v = self.value(k, what)?;
            self.expect(b'}')?;
            return Ok((0..n).flat_map(|_| v.iter().copied()).collect());
        }
        if self.binary {
            let size = self.scalar_bytes;
            let raw = self.binary_block(n, k * size, what)?;
            return Ok(raw.chunks_exact(size).map(|c| Foam::scalar_of(size, c)).collect());
        }
        self.expect(b'(')?;
        let mut out = Vec::with_capacity(n * k);
        for _ in 0..n {
            out.extend(self.value(k, what)?);
        }
        self.expect(b')')?;
        Ok(out)
    }

    /// One value of `k` components: `a`, or `(x y z)`.
    pub fn value(&mut self, k: usize, what: &str) -> R<Vec<f64>> {
        if k == 1 {
            return Ok(vec![self.number(what)?]);
        }
        self.expect(b'(')?;
        let v = (0..k).map(|_| self.number(what)).collect::<R<Vec<_>>>()?;
        self.expect(b')')?;
        Ok(v)
    }

    /// A `faceList` (`N (4(a b c d) ...)`) or a `faceCompactList` (offsets, then the flat
    /// point labels): face ends and point labels.
    pub fn faces(&mut self) -> R<(Vec<u64>, Vec<i64>)> {
        let what = "faces";
        if self.class() == "faceCompactList" {
            let offsets = self.labels("face offsets")?;
            let labels = self.labels("face points")?;
            if offsets.first().is_some_and(|&o| o != 0) {
                return Err("the face offsets do not start at 0".into());
            }
            let mut ends = Vec::with_capacity(offsets.len().saturating_sub(1));
            for w in offsets.windows(2) {
                match (u64::try_from(w[0]), u64::try_from(w[1])) {
                    (Ok(a), Ok(b)) if a <= b && b <= labels.len() as u64 => ends.push(b),
                    _ => return Err(format!("face offsets {} then {} do not fit {} labels", w[0], w[1], labels.len())),
                }
            }
            if ends.last().is_some_and(|&e| e != labels.len() as u64) {
                return Err(format!("the face offsets end before the {} labels do", labels.len()));
            }
            return Ok((ends, labels));
        }
        let n = self.count(what)?;
        self.expect(b'(')?;
        let (mut ends, mut labels) = (Vec::with_capacity(n), Vec::new());
        for _ in 0..n {
            labels.extend(self.labels(what)?);
            ends.push(labels.len() as u64);
        }
        self.expect(b')')?;
        Ok((ends, labels))
    }

    /// A `polyBoundaryMesh`: each patch's name, type, first face and face count.
    pub fn patches(&mut self) -> R<Vec<Patch>> {
        let n = self.count("boundary")?;
        self.expect(b'(')?;
        let mut out = Vec::with_capacity(n);
        for _ in 0..n {
            let name = self.word()?;
            let entries = self.dictionary()?;
            let int = |k: &str| -> R<usize> {
                entries
                    .get(k)
                    .and_then(|v| v.parse().ok())
                    .ok_or_else(|| format!("patch '{name}': no {k} (or not a count)"))
            };
            out.push(Patch {
                ty: entries.get("type").cloned().unwrap_or_default(),
                n_faces: int("nFaces")?,
                start: int("startFace")?,
                name,
            });
        }
        self.expect(b')')?;
        Ok(out)
    }
}

/// One boundary patch.
#[derive(Clone, Debug)]
pub(crate) struct Patch {
    pub name: String,
    pub ty: String,
    pub start: usize,
    pub n_faces: usize,
}

/// Inflates a gzip file (bounded: no more than zlib's largest ratio allows).
fn gunzip(bytes: &[u8]) -> R<Vec<u8>> {
    use std::io::Read;
    let limit = (bytes.len() as u64).saturating_mul(1100).saturating_add(1024);
    let mut out = Vec::new();
    flate2::read::MultiGzDecoder::new(bytes)
        .take(limit)
        .read_to_end(&mut out)
        .map_err(|e| format!("corrupt gzip data ({e})"))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn foam(class: &str, format: &str, body: &[u8]) -> Foam {
        let mut b = format!("FoamFile\n{{\n    version 2.0;\n    format {format};\n    class {class};\n    arch \"LSB;label=32;scalar=64\";\n}}\n// comment\n/* block */\n").into_bytes();
        b.extend_from_slice(body);
        Foam::new(b).unwrap()
    }

    #[test]
    fn ascii_lists() {
        let mut f = foam("labelList", "ascii", b"3\n(\n0 1\n2\n)\n");
        assert_eq!(f.labels("owner").unwrap(), vec![0, 1, 2]);
        let mut f = foam("vectorField", "ascii", b"2((0 0 1) (1 2 3.5e0))");
        assert_eq!(f.values(3, "points").unwrap(), vec![0., 0., 1., 1., 2., 3.5]);
        let mut f = foam("faceList", "ascii", b"2(3(0 1 2) 4(1 2 3 4))");
        assert_eq!(f.faces().unwrap(), (vec![3, 7], vec![0, 1, 2, 1, 2, 3, 4]));
        let mut f = foam("labelList", "ascii", b"4{7}");
        assert_eq!(f.labels("owner").unwrap(), vec![7; 4]);
    }

    #[test]
    fn binary_lists() {
        let mut body = b"2\n(".to_vec();
        body.extend([5i32, 9].iter().flat_map(|v| v.to_le_bytes()));
        body.extend(b")\n");
        assert_eq!(foam("labelList", "binary", &body).labels("owner").unwrap(), vec![5, 9]);
        let mut body = b"1(".to_vec();
        body.extend([1.5f64, 2.0, -3.0].iter().flat_map(|v| v.to_le_bytes()));
        body.extend(b")");
        assert_eq!(foam("vectorField", "binary", &body).values(3, "points").unwrap(), vec![1.5, 2.0, -3.0]);
        // A faceCompactList: offsets then labels.
        let mut body = b"3(".to_vec();
        body.extend([0i32, 3, 7].iter().flat_map(|v| v.to_le_bytes()));
        body.extend(b")\n7(");
        body.extend([0i32, 1, 2, 1, 2, 3, 4].iter().flat_map(|v| v.to_le_bytes()));
        body.extend(b")");
        assert_eq!(foam("faceCompactList", "binary", &body).faces().unwrap(), (vec![3, 7], vec![0, 1, 2, 1, 2, 3, 4]));
        // Truncated: an error, not a panic.
        let mut f = foam("labelList", "binary", b"5(abc");
        assert!(f.labels("owner").unwrap_err().contains("past the end"));
    }

    #[test]
    fn entries_and_patches() {
        let mut f = foam(
            "volScalarField",
            "ascii",
            b"dimensions [0 0 0 0 0 0 0];\nsub { a 1; b { c 2; } }\ninternalField uniform 3;\nboundaryField { }",
        );
        assert!(f.seek_entry("internalField").unwrap());
        assert_eq!(f.word().unwrap(), "uniform");
        assert_eq!(f.value(1, "x").unwrap(), vec![3.0]);
        let mut f =
            foam("polyBoundaryMesh", "ascii", b"1(walls { type wall; inGroups 1(wall); nFaces 6; startFace 10; })");
        let p = f.patches().unwrap();
        assert_eq!((p[0].name.as_str(), p[0].ty.as_str(), p[0].start, p[0].n_faces), ("walls", "wall", 10, 6));
        assert!(Foam::new(b"hello".to_vec()).is_err());
    }
}
