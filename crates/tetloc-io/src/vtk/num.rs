//! Typed numeric arrays as VTK files store them (any of ten element types), and their fast
//! conversion to tetloc's types. Arrays are normalised to little-endian bytes first, so the
//! conversions dispatch on the element type only.

use rayon::prelude::*;
use std::borrow::Cow;

/// Runs `$body` with `$T` bound to the Rust type of a [`NumType`].
macro_rules! with_type {
    ($ty:expr, $T:ident => $body:expr) => {
        // One arm a variant of this list, which pairs each with its Rust type.
        with_type!(@arms $ty, $T, $body;
            I8 i8, U8 u8, I16 i16, U16 u16, I32 i32, U32 u32, I64 i64, U64 u64, F32 f32, F64 f64)
    };
    (@arms $ty:expr, $T:ident, $body:expr; $($variant:ident $t:ty),*) => {
        match $ty {
            $(NumType::$variant => {
                type $T = $t;
                $body
            })*
        }
    };
}

/// The element types of VTK data arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum NumType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl NumType {
    pub fn size(self) -> usize {
        with_type!(self, T => T::SIZE)
    }

    pub fn is_float(self) -> bool {
        matches!(self, NumType::F32 | NumType::F64)
    }

    /// The `type` attribute of a VTK XML `DataArray`.
    pub fn from_xml(name: &str) -> Option<NumType> {
        Some(match name {
            "Int8" | "Char" => NumType::I8,
            "UInt8" => NumType::U8,
            "Int16" => NumType::I16,
            "UInt16" => NumType::U16,
            "Int32" => NumType::I32,
            "UInt32" => NumType::U32,
            "Int64" => NumType::I64,
            "UInt64" => NumType::U64,
            "Float32" => NumType::F32,
            "Float64" => NumType::F64,
            _ => return None,
        })
    }

    /// A data type name of the legacy format. `long` is 64-bit as VTK writes it on LP64
    /// systems; `vtkIdType` is written as 32-bit ints by VTK's legacy writer.
    pub fn from_legacy(name: &str) -> Option<NumType> {
        Some(match name.to_ascii_lowercase().as_str() {
            "char" | "signed_char" | "vtktypeint8" => NumType::I8,
            "unsigned_char" | "vtktypeuint8" => NumType::U8,
            "short" | "vtktypeint16" => NumType::I16,
            "unsigned_short" | "vtktypeuint16" => NumType::U16,
            "int" | "vtkidtype" | "vtktypeint32" => NumType::I32,
            "unsigned_int" | "vtktypeuint32" => NumType::U32,
            "long" | "long_long" | "vtktypeint64" => NumType::I64,
            "unsigned_long" | "unsigned_long_long" | "vtktypeuint64" => NumType::U64,
            "float" | "vtktypefloat32" => NumType::F32,
            "double" | "vtktypefloat64" => NumType::F64,
            _ => return None,
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            NumType::I8 => "Int8",
            NumType::U8 => "UInt8",
            NumType::I16 => "Int16",
            NumType::U16 => "UInt16",
            NumType::I32 => "Int32",
            NumType::U32 => "UInt32",
            NumType::I64 => "Int64",
            NumType::U64 => "UInt64",
            NumType::F32 => "Float32",
            NumType::F64 => "Float64",
        }
    }
}

#[derive(Debug)]
/// An array's values as little-endian bytes of `ty`. Borrowed straight from the file when
/// it can be (appended raw data), owned otherwise.
pub(crate) struct Array<'a> {
    pub ty: NumType,
    pub bytes: Cow<'a, [u8]>,
}

impl<'a> Array<'a> {
    /// `bytes` in `big_endian` order become a little-endian array (one copy if swapped).
    pub fn from_bytes(ty: NumType, bytes: Cow<'a, [u8]>, big_endian: bool) -> Array<'a> {
        let s = ty.size();
        if !big_endian || s == 1 {
            return Array { ty, bytes };
        }
        let mut v = bytes.into_owned();
        v.par_chunks_mut(1 << 16).for_each(|c| c.chunks_exact_mut(s).for_each(|e| e.reverse()));
        Array { ty, bytes: Cow::Owned(v) }
    }

    pub fn len(&self) -> usize {
        self.bytes.len() / self.ty.size()
    }

    /// The i-th value as f64 (for error messages and small arrays).
    pub fn get_f64(&self, i: usize) -> f64 {
        with_type!(self.ty, T => T::get(&self.bytes, i).to_f64())
    }

    /// The i-th value as text, for error messages.
    pub fn show(&self, i: usize) -> String {
        self.get_i64(i).map_or_else(|| self.get_f64(i).to_string(), |v| v.to_string())
    }

    /// The i-th value as an integer, `None` for a float or a u64 beyond i64.
    pub fn get_i64(&self, i: usize) -> Option<i64> {
        with_type!(self.ty, T => T::get(&self.bytes, i).to_i64())
    }
}

/// One element type: read from little-endian bytes and convert.
pub(crate) trait Elem: Copy + Send + Sync + 'static {
    const SIZE: usize;
    fn read(b: &[u8]) -> Self;
    fn to_f32(self) -> f32;
    fn to_f64(self) -> f64;
    /// `None` for floats and for u64 values beyond i64.
    fn to_i64(self) -> Option<i64>;
    fn get(bytes: &[u8], i: usize) -> Self {
        Self::read(&bytes[i * Self::SIZE..(i + 1) * Self::SIZE])
    }
}

/// Element types; `to_i64` is the one conversion that differs between integers and floats.
macro_rules! impl_elem {
    ($to_i64:expr; $($t:ty),*) => {$(
        impl Elem for $t {
            const SIZE: usize = std::mem::size_of::<$t>();
            #[inline(always)]
            fn read(b: &[u8]) -> Self { <$t>::from_le_bytes(b.try_into().unwrap()) }
            #[inline(always)]
            fn to_f32(self) -> f32 { self as f32 }
            #[inline(always)]
            fn to_f64(self) -> f64 { self as f64 }
            #[inline(always)]
            fn to_i64(self) -> Option<i64> { ($to_i64)(self) }
        }
    )*};
}
// One conversion for every integer type: it can fail only for u64, so clippy's per-type lints do not apply.
#[allow(clippy::unnecessary_fallible_conversions, clippy::useless_conversion)]
mod int_elems {
    use super::*;
    impl_elem!(|v| i64::try_from(v).ok(); i8, u8, i16, u16, i32, u32, i64, u64);
}
impl_elem!(|_| None; f32, f64);

/// Maps each tuple of `N` values of `T` to one output value, in parallel. `f` rejects a tuple
/// with `None`; then the index of the first rejected tuple is returned. (`N` and `T` are
/// compile-time so that the inner loop has constant strides.)
fn map_tuples<T, const N: usize, U, F>(bytes: &[u8], f: F) -> Result<Vec<U>, usize>
where
    T: Elem,
    U: Copy + Default + Send + Sync,
    F: Fn([T; N]) -> Option<U> + Sync,
{
    const CHUNK: usize = 1 << 14;
    let tuple = |t: &[u8]| f(std::array::from_fn(|k| T::get(t, k)));
    let mut out = vec![U::default(); bytes.len() / (N * T::SIZE)];
    let ok = out.par_chunks_mut(CHUNK).zip(bytes.par_chunks(CHUNK * N * T::SIZE)).all(|(o, b)| {
        // No early exit inside a chunk: keeps the loop branch-light.
        let mut ok = true;
        for (x, t) in o.iter_mut().zip(b.chunks_exact(N * T::SIZE)) {
            match tuple(t) {
                Some(v) => *x = v,
                None => ok = false,
            }
        }
        ok
    });
    if ok {
        Ok(out)
    } else {
        // Error path only: find the first bad tuple sequentially.
        Err(bytes.chunks_exact(N * T::SIZE).position(|t| tuple(t).is_none()).unwrap_or(0))
    }
}

/// Every value as f32 (f64 rounds to nearest).
pub(crate) fn to_f32(a: &Array) -> Vec<f32> {
    with_type!(a.ty, T => map_tuples::<T, 1, _, _>(&a.bytes, |[v]| Some(v.to_f32())).unwrap_or_default())
}

/// Component `c` of every tuple of `ncomp` values, as f32.
pub(crate) fn component_f32(a: &Array, ncomp: usize, c: usize) -> Vec<f32> {
    fn go<T: Elem>(b: &[u8], ncomp: usize, c: usize) -> Vec<f32> {
        b.par_chunks_exact(ncomp * T::SIZE).map(|t| T::get(t, c).to_f32()).collect()
    }
    if ncomp == 1 {
        return to_f32(a);
    }
    with_type!(a.ty, T => go::<T>(&a.bytes, ncomp, c))
}

/// Component `c` of every tuple of `ncomp` values as f64, for an f64 array some of whose
/// values do not round to f32 exactly (`None` otherwise: [`component_f32`] is the data).
pub(crate) fn component_f64(a: &Array, ncomp: usize, c: usize) -> Option<Vec<f64>> {
    if a.ty != NumType::F64 {
        return None;
    }
    let v = a.bytes.par_chunks_exact(ncomp * 8).map(|t| f64::get(t, c)).collect();
    tetloc_core::mesh::f64_if_needed(v)
}

/// Triples of values as f32 points.
pub(crate) fn to_points(a: &Array) -> Vec<[f32; 3]> {
    with_type!(a.ty, T => map_tuples::<T, 3, _, _>(&a.bytes, |t| Some(t.map(Elem::to_f32))).unwrap_or_default())
}

/// Triples of f64 values as points, when some value does not round to f32 exactly (`None`
/// for other types, or when [`to_points`] is the data exactly).
pub(crate) fn to_points64(a: &Array) -> Option<Vec<[f64; 3]>> {
    if a.ty != NumType::F64 {
        return None;
    }
    let pts = map_tuples::<f64, 3, _, _>(&a.bytes, Some).unwrap_or_default();
    crate::points64_if_needed(pts)
}

/// Integer values mapped through `f`, which returns `None` for values out of the caller's
/// range. On a float array or a rejected value: the index of the first bad value.
pub(crate) fn map_ints<U, F>(a: &Array, f: F) -> Result<Vec<U>, usize>
where
    U: Copy + Default + Send + Sync,
    F: Fn(i64) -> Option<U> + Sync,
{
    if a.ty.is_float() {
        return Err(0);
    }
    with_type!(a.ty, T => map_tuples::<T, 1, _, _>(&a.bytes, |[v]| v.to_i64().and_then(&f)))
}

/// Whether every value is an integer `v` at index `i` with `pred(i, v)`: a parallel check
/// that needs no converted copy.
pub(crate) fn all_ints(a: &Array, pred: impl Fn(usize, i64) -> bool + Sync) -> bool {
    fn go<T: Elem>(b: &[u8], pred: &(impl Fn(usize, i64) -> bool + Sync)) -> bool {
        const CHUNK: usize = 1 << 14;
        b.par_chunks(CHUNK * T::SIZE).enumerate().all(|(c, b)| {
            let mut ok = true;
            for (j, e) in b.chunks_exact(T::SIZE).enumerate() {
                ok &= T::read(e).to_i64().is_some_and(|v| pred(c * CHUNK + j, v));
            }
            ok
        })
    }
    !a.ty.is_float() && with_type!(a.ty, T => go::<T>(&a.bytes, &pred))
}

/// Point ids below `n_points`, grouped in `k`s (`k` = 1 or 4).
pub(crate) fn to_ids(a: &Array, n_points: usize) -> Result<Vec<u32>, usize> {
    // Ids must also fit u32; n_points <= u32::MAX is checked by Mesh::new.
    let n = n_points.min(u32::MAX as usize) as i64;
    map_ints(a, move |v| (0..n).contains(&v).then_some(v as u32))
}

/// Parses whitespace-separated numbers as `ty` into a little-endian array: all of them
/// (`count` None) or exactly `count`. Returns the array and the number of bytes consumed.
/// On error: a message naming the bad token.
pub(crate) fn parse_ascii(text: &[u8], ty: NumType, count: Option<usize>) -> Result<(Array<'static>, usize), String> {
    let size = ty.size();
    // A value takes at least two bytes of text (digit and separator): never trust `count`
    // for the allocation.
    let cap = count.unwrap_or(usize::MAX).min(text.len() / 2 + 1);
    let mut out: Vec<u8> = Vec::with_capacity(cap * size);
    let mut pos = 0;
    let mut n = 0;
    while !matches!(count, Some(c) if n >= c) {
        while pos < text.len() && text[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if pos == text.len() {
            break;
        }
        let start = pos;
        while pos < text.len() && !text[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let tok = &text[start..pos];
        let bad = || {
            format!("value {n}: '{}' is not a valid {}", String::from_utf8_lossy(&tok[..tok.len().min(40)]), ty.name())
        };
        let s = std::str::from_utf8(tok).map_err(|_| bad())?;
        macro_rules! push_int {
            ($t:ty) => {{
                let v: $t = match s.parse::<$t>() {
                    Ok(v) => v,
                    // Some writers print integral values of int arrays as floats ("3.0").
                    Err(_) => {
                        let f: f64 = s.parse().map_err(|_| bad())?;
                        if f.fract() != 0.0 || f < <$t>::MIN as f64 || f > <$t>::MAX as f64 {
                            return Err(bad());
                        }
                        f as $t
                    }
                };
                out.extend_from_slice(&v.to_le_bytes());
            }};
        }
        match ty {
            NumType::I8 => push_int!(i8),
            NumType::U8 => push_int!(u8),
            NumType::I16 => push_int!(i16),
            NumType::U16 => push_int!(u16),
            NumType::I32 => push_int!(i32),
            NumType::U32 => push_int!(u32),
            NumType::I64 => push_int!(i64),
            NumType::U64 => push_int!(u64),
            NumType::F32 => out.extend_from_slice(&s.parse::<f32>().map_err(|_| bad())?.to_le_bytes()),
            NumType::F64 => out.extend_from_slice(&s.parse::<f64>().map_err(|_| bad())?.to_le_bytes()),
        }
        n += 1;
    }
    if let Some(c) = count {
        if n < c {
            return Err(format!("expected {c} values, found only {n} before the end of the data"));
        }
    }
    Ok((Array { ty, bytes: Cow::Owned(out) }, pos))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arr(ty: NumType, bytes: Vec<u8>) -> Array<'static> {
        Array { ty, bytes: Cow::Owned(bytes) }
    }

    #[test]
    fn big_endian_is_swapped() {
        let a = Array::from_bytes(NumType::I32, Cow::Owned(vec![0, 0, 1, 2, 0xff, 0xff, 0xff, 0xfe]), true);
        assert_eq!(map_ints(&a, Some).unwrap(), vec![258i64, -2]);
        let d = Array::from_bytes(NumType::F64, Cow::Owned(1.5f64.to_be_bytes().to_vec()), true);
        assert_eq!(to_f32(&d), vec![1.5]);
    }

    #[test]
    fn conversions() {
        let f: Vec<u8> = [1.0f64, 2.0, 3.0, 4.0, 5.0, 6.0].iter().flat_map(|v| v.to_le_bytes()).collect();
        let a = arr(NumType::F64, f);
        assert_eq!(to_points(&a), vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(component_f32(&a, 3, 1), vec![2.0, 5.0]);
        assert_eq!(component_f32(&a, 2, 1), vec![2.0, 4.0, 6.0]);
        assert_eq!(map_ints(&a, Some), Err(0), "floats are no ids");
        assert!(!all_ints(&a, |_, _| true));

        let ids: Vec<u8> = [0i64, 5, 7, -1].iter().flat_map(|v| v.to_le_bytes()).collect();
        let a = arr(NumType::I64, ids);
        assert_eq!(to_ids(&a, 8), Err(3), "negative id");
        assert_eq!(to_ids(&a, 7), Err(2), "id beyond the points");
        assert!(all_ints(&a, |i, v| v == [0, 5, 7, -1][i]));
        assert!(!all_ints(&a, |i, v| i < 3 && v >= 0));
        let big = arr(NumType::U64, u64::MAX.to_le_bytes().to_vec());
        assert_eq!(big.get_i64(0), None);
        assert_eq!(to_ids(&big, 10), Err(0));
    }

    #[test]
    fn ascii() {
        let (a, used) = parse_ascii(b"  1 -2\n3e0 4.0 x", NumType::I16, Some(4)).unwrap();
        assert_eq!(map_ints(&a, Some).unwrap(), vec![1i64, -2, 3, 4]);
        assert_eq!(used, 14);
        assert!(parse_ascii(b"1 2 x", NumType::F32, None).unwrap_err().contains("'x'"));
        assert!(parse_ascii(b"300", NumType::U8, None).is_err());
        assert!(parse_ascii(b"1.5", NumType::I32, None).is_err());
        assert!(parse_ascii(b"1 2", NumType::F64, Some(3)).unwrap_err().contains("only 2"));
        // A huge declared count allocates by the text, not by the claim.
        assert!(parse_ascii(b"1 2", NumType::F64, Some(1 << 60)).is_err());
        let (f, _) = parse_ascii(b"0.1 nan -inf", NumType::F32, None).unwrap();
        let v = to_f32(&f);
        assert_eq!(v[0], 0.1f32);
        assert!(v[1].is_nan() && v[2] == f32::NEG_INFINITY);
    }
}
