/*
 * Consistent Overhead Byte Stuffing (Cheshire & Baker, 1999): removes every
 * 0x00 so that 0x00 can delimit frames unambiguously. Each block is a code
 * byte c (1..255) followed by c-1 non-zero bytes; c < 255 implies a zero
 * after the block, except at the very end of the frame.
 *
 * Copyright (c) 2026 the it2n authors. MIT licence (see LICENSE).
 */
#include "it2n_proto.h"

int it2n_cobs_encode(const uint8_t *src, size_t len, uint8_t *dst, size_t cap)
{
    size_t in, out = 1, code_at = 0;
    uint8_t code = 1;

    if (cap < 1u || len > (size_t)INT32_MAX / 2u)
        return IT2N_PROTO_ERR_NOSPACE;
    for (in = 0; in < len; in++) {
        if (src[in] != 0u) {
            if (out >= cap)
                return IT2N_PROTO_ERR_NOSPACE;
            dst[out++] = src[in];
            code++;
        }
        if (src[in] == 0u || code == 0xFFu) {
            /* A full block (254 data bytes) needs no implied zero; start a
             * new block only if more input follows or the byte was a zero. */
            dst[code_at] = code;
            if (src[in] != 0u && in + 1u == len)
                return (int)out;
            if (out >= cap)
                return IT2N_PROTO_ERR_NOSPACE;
            code_at = out++;
            code = 1;
        }
    }
    dst[code_at] = code;
    return (int)out;
}

int it2n_cobs_decode(const uint8_t *src, size_t len, uint8_t *dst, size_t cap)
{
    size_t in = 0, out = 0;

    if (len > (size_t)INT32_MAX)
        return IT2N_PROTO_ERR_NOSPACE;
    while (in < len) {
        uint8_t code = src[in++];
        uint8_t k;
        if (code == 0u || in + code - 1u > len)
            return IT2N_PROTO_ERR_COBS;
        for (k = 1; k < code; k++) {
            if (src[in] == 0u)
                return IT2N_PROTO_ERR_COBS;
            if (out >= cap)
                return IT2N_PROTO_ERR_NOSPACE;
            dst[out++] = src[in++];
        }
        if (code != 0xFFu && in < len) {
            if (out >= cap)
                return IT2N_PROTO_ERR_NOSPACE;
            dst[out++] = 0u;
        }
    }
    return (int)out;
}
