// Packed id arrays (src/packed.rs): field j holds bits j*BITS .. (j+1)*BITS of the words,
// least significant bit first, and every array ends in at least 4 words of padding.
//   TL_PACKED_READER(name, WORD, BITS)   defines `uint name(uint j)`, field j;
//   TL_PACKED4_READER(name, WORD, BITS)  defines `uvec4 name(uint i)`, fields 4i .. 4i + 3
// over a word accessor `uint WORD(uint w)` of the array being read. BITS is a specialization
// constant, so once a record is shifted to bit 0 its fields sit at constant places.
#ifndef TL_PACKED_GLSL
#define TL_PACKED_GLSL

// Bits p .. p + b of the 128 bits of a (p and b constant where it is called).
uint tl_bits128(uvec4 a, uint p, uint b) {
    uint q = p >> 5u, r = p & 31u;
    uint v = a[q] >> r;
    if (r + b > 32u) {
        v |= a[q + 1u] << (32u - r);
    }
    return b == 32u ? v : v & ((1u << b) - 1u);
}

// Where element j of `stride` bits starts: word w, bit s. j * stride may pass 32 bits (a
// billion fields of 26 bits), so the bit address is 64-bit (the writer, build/pack.comp, too).
void tl_packed_at(uint j, uint stride, out uint w, out uint s) {
    uint hi, lo;
    umulExtended(j, stride, hi, lo);
    w = (hi << 27u) | (lo >> 5u);
    s = lo & 31u;
}

#define TL_PACKED_READER(name, WORD, BITS)                                                \
    uint name(uint j) {                                                                    \
        uint w, s;                                                                         \
        tl_packed_at(j, BITS, w, s);                                                       \
        uint v = WORD(w) >> s;                                                             \
        if (s + BITS > 32u) {                                                              \
            v |= WORD(w + 1u) << (32u - s);                                                \
        }                                                                                  \
        return BITS == 32u ? v : v & ((1u << BITS) - 1u);                                  \
    }

// One record of four fields: its (up to) five words read at once and shifted to bit 0.
#define TL_PACKED4_READER(name, WORD, BITS)                                               \
    uvec4 name(uint i) {                                                                   \
        uint w, s;                                                                         \
        tl_packed_at(i, 4u * BITS, w, s);                                                  \
        uvec4 a = uvec4(WORD(w), WORD(w + 1u), WORD(w + 2u), WORD(w + 3u));               \
        if (s != 0u) {                                                                     \
            a = (a >> s) | (uvec4(a.yzw, WORD(w + 4u)) << (32u - s));                      \
        }                                                                                  \
        return uvec4(tl_bits128(a, 0u, BITS), tl_bits128(a, BITS, BITS),                  \
                     tl_bits128(a, 2u * BITS, BITS), tl_bits128(a, 3u * BITS, BITS));      \
    }

#endif
