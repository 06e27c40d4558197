//! Cache hints: they change no value, only when a later access of the memory arrives. A CPU
//! loop that stores into memory gone cold since its last visit (a particle's arrays, visited
//! once a leg) waits for each line before the stores behind it can finish; a hint issued some
//! work before lets that wait overlap the work.

/// Bytes of a cache line on the CPUs we run on (x86-64; most Arm cores too).
const LINE: usize = 64;

/// Asks the cache for the line holding `x`.
#[inline(always)]
pub(crate) fn line_of<T>(x: &T) {
    hint((x as *const T).cast());
}

/// Asks the cache for the lines that the next `n` items pushed onto `v` will take (those
/// within its capacity; nothing when it has none to spare).
#[inline(always)]
pub(crate) fn next_pushes<T>(v: &Vec<T>, n: usize) {
    let n = n.min(v.capacity() - v.len());
    let bytes = n * std::mem::size_of::<T>();
    if bytes == 0 {
        return;
    }
    let start: *const u8 = v.as_ptr().wrapping_add(v.len()).cast();
    for offset in (0..bytes).step_by(LINE) {
        hint(start.wrapping_add(offset));
    }
    // The last byte: a range not aligned to lines may end on one more line.
    hint(start.wrapping_add(bytes - 1));
}

#[inline(always)]
fn hint(p: *const u8) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch hint reads nothing into the program and never faults, whatever the
    // address.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.cast())
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hint changes nothing it is given: a vector's items, length and capacity, whether it
    /// has spare room or none (an empty vector's dangling pointer included).
    #[test]
    fn hints_change_nothing() {
        let mut v: Vec<[f64; 3]> = Vec::new();
        next_pushes(&v, 4);
        v.reserve_exact(10);
        v.push([1.0, 2.0, 3.0]);
        next_pushes(&v, 100);
        line_of(&v[0]);
        assert_eq!((v.len(), v.capacity(), v[0]), (1, 10, [1.0, 2.0, 3.0]));
        v.extend(std::iter::repeat_n([0.0; 3], 9));
        next_pushes(&v, 1);
        assert_eq!((v.len(), v.capacity()), (10, 10));
    }
}
