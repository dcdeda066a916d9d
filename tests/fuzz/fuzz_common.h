/**
 * @file fuzz_common.h
 * @brief Shared pieces of the attica fuzz targets (tests/fuzz, docs/robustness.md): a byte reader that
 * turns the fuzzer's input into values, float helpers, and the report/abort policy.
 *
 * Test code only: it may use double and libc (the firmware may not).
 */
#ifndef ATT_FUZZ_COMMON_H
#define ATT_FUZZ_COMMON_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/** Reads values from the fuzzer's bytes; past the end every read returns zeros. */
typedef struct {
    const uint8_t *p;
    size_t n;
    size_t i;
} fz_reader_t;

static inline void fz_init(fz_reader_t *r, const uint8_t *data, size_t size)
{
    r->p = data;
    r->n = size;
    r->i = 0u;
}

static inline size_t fz_left(const fz_reader_t *r)
{
    return r->n - r->i;
}

static inline uint8_t fz_u8(fz_reader_t *r)
{
    return (r->i < r->n) ? r->p[r->i++] : (uint8_t)0u;
}

static inline uint16_t fz_u16(fz_reader_t *r)
{
    uint16_t lo = fz_u8(r);
    uint16_t hi = fz_u8(r);
    return (uint16_t)(lo | (uint16_t)(hi << 8));
}

static inline uint32_t fz_u32(fz_reader_t *r)
{
    uint32_t v = 0u;
    int k;
    for (k = 0; k < 4; ++k) {
        v |= (uint32_t)fz_u8(r) << (8 * k);
    }
    return v;
}

static inline float fz_bits_to_float(uint32_t bits)
{
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

static inline uint32_t fz_float_bits(float f)
{
    uint32_t b;
    memcpy(&b, &f, sizeof b);
    return b;
}

/** Floats that break arithmetic: the classes a sensor or a bus can deliver. */
static const uint32_t fz_special_bits[] = {
    0x00000000u, /* 0 */
    0x80000000u, /* -0 */
    0x7FC00000u, /* quiet NaN */
    0xFFC00001u, /* negative NaN with payload */
    0x7F800001u, /* signalling NaN */
    0x7F800000u, /* +Inf */
    0xFF800000u, /* -Inf */
    0x7F7FFFFFu, /* FLT_MAX */
    0xFF7FFFFFu, /* -FLT_MAX */
    0x00800000u, /* FLT_MIN */
    0x00000001u, /* smallest denormal */
    0x80000001u, /* -smallest denormal */
    0x007FFFFFu, /* largest denormal */
    0x3F800000u, /* 1 */
    0xBF800000u, /* -1 */
    0x3F800001u, /* 1 + ulp */
    0x3F7FFFFFu, /* 1 - ulp/2 */
    0x411CE80Au, /* 9.80665 */
    0x7149F2CAu, /* 1e30 */
    0xF149F2CAu, /* -1e30 */
    0x5F000000u, /* 2^63 */
    0x4B000000u, /* 2^23 */
    0x46FFFE00u, /* 32767 */
    0x3FC90FDBu, /* pi/2 */
    0xBFC90FDBu, /* -pi/2 */
    0x40490FDBu, /* pi */
    0x2EDBE6FFu, /* 1e-10 */
    0x49742400u, /* 1e6 */
};
#define FZ_N_SPECIAL (sizeof fz_special_bits / sizeof fz_special_bits[0])

/** A float chosen by the input: raw bits (selector < 0xC0) or a special value. */
static inline float fz_float(fz_reader_t *r)
{
    uint8_t sel = fz_u8(r);
    if (sel < 0xC0u) {
        return fz_bits_to_float(fz_u32(r));
    }
    return fz_bits_to_float(fz_special_bits[(size_t)(sel - 0xC0u) % FZ_N_SPECIAL]);
}

static inline int fz_finite(float x)
{
    return (fz_float_bits(x) & 0x7F800000u) != 0x7F800000u;
}

/** Print a violated invariant and abort (libFuzzer then saves the input as a crash artifact). */
#define FZ_FAIL(...)                                                                                   \
    do {                                                                                               \
        fprintf(stderr, "attica fuzz invariant violated (%s:%d): ", __FILE__, __LINE__);               \
        fprintf(stderr, __VA_ARGS__);                                                                  \
        fprintf(stderr, "\n");                                                                         \
        abort();                                                                                       \
    } while (0)

#define FZ_CHECK(cond, ...)                                                                            \
    do {                                                                                               \
        if (!(cond)) {                                                                                 \
            FZ_FAIL(__VA_ARGS__);                                                                      \
        }                                                                                              \
    } while (0)

#endif /* ATT_FUZZ_COMMON_H */
