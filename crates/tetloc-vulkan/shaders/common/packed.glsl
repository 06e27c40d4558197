// Packed id arrays (src/packed.rs): field j holds bits j*BITS .. (j+1)*BITS of the words,
// least significant bit first. TL_PACKED_READER(name, WORD, BITS) defines `uint name(uint j)`
// over a word accessor `uint WORD(uint w)` (a function or macro of the array being read).
#ifndef TL_PACKED_GLSL
#define TL_PACKED_GLSL

// j * BITS may pass 32 bits (a billion fields of 26 bits), so the bit address is 64-bit.
#define TL_PACKED_READER(name, WORD, BITS)                                                \
    uint name(uint j) {                                                                    \
        uint hi, lo;                                                                       \
        umulExtended(j, BITS, hi, lo);                                                     \
        uint w = (hi << 27u) | (lo >> 5u), s = lo & 31u;                                   \
        uint v = WORD(w) >> s;                                                             \
        if (s + BITS > 32u) {                                                              \
            v |= WORD(w + 1u) << (32u - s);                                                \
        }                                                                                  \
        return BITS == 32u ? v : v & ((1u << BITS) - 1u);                                  \
    }

#endif
