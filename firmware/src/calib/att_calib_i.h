/**
 * @file att_calib_i.h
 * @brief Private: the per-sample input stage of att_calib.h as static inline functions (compiled only
 * with firmware/cflags.txt), shared by att_calib.c (att_calib_apply) and att_filter.c (the step).
 */
#ifndef ATT_CALIB_I_H
#define ATT_CALIB_I_H

#include "../math/att_inline.h"

#include "attica/att_calib.h"

/** The IEEE-754 bits of x. */
static inline uint32_t att_i_calib_bits(float x)
{
    union {
        float f;
        uint32_t u;
    } t;
    t.f = x;
    return t.u;
}

/** The float with bits u. */
static inline float att_i_calib_float(uint32_t u)
{
    union {
        float f;
        uint32_t u;
    } t;
    t.u = u;
    return t.f;
}

/**
 * One sensor's stage from *in to *out (may be the same): affine v = A (raw - o) in the order
 * (a0 dx + a1 dy) + a2 dz; a signed permutation (the sign bit flipped, exact, no arithmetic); or a copy.
 * Mirrored by reference/calib.Stage.apply.
 */
static ATT_ALWAYS_INLINE void att_i_calib_stage(const att_calib_stage_t *st, const att_vec3_t *in, att_vec3_t *out)
{
    if (st->mode == 2u) {
        const float dx = in->x - st->o.x;
        const float dy = in->y - st->o.y;
        const float dz = in->z - st->o.z;
        out->x = (st->a[0] * dx + st->a[1] * dy) + st->a[2] * dz;
        out->y = (st->a[3] * dx + st->a[4] * dy) + st->a[5] * dz;
        out->z = (st->a[6] * dx + st->a[7] * dy) + st->a[8] * dz;
    } else if (st->mode == 1u) {
        const uint32_t x = att_i_calib_bits(in->x);
        const uint32_t y = att_i_calib_bits(in->y);
        const uint32_t z = att_i_calib_bits(in->z);
        uint32_t a;
        uint32_t b;
        uint32_t c;
        switch (st->perm) {
        case 0u:
            a = x;
            b = y;
            c = z;
            break;
        case 1u:
            a = x;
            b = z;
            c = y;
            break;
        case 2u:
            a = y;
            b = x;
            c = z;
            break;
        case 3u:
            a = y;
            b = z;
            c = x;
            break;
        case 4u:
            a = z;
            b = x;
            c = y;
            break;
        default:
            a = z;
            b = y;
            c = x;
            break;
        }
        out->x = att_i_calib_float(a ^ st->sign[0]);
        out->y = att_i_calib_float(b ^ st->sign[1]);
        out->z = att_i_calib_float(c ^ st->sign[2]);
    } else {
        *out = *in;
    }
}

/**
 * The zero mag vector (+-0 components): "no sample", passed on unchanged. A NaN component needs no test:
 * the affine stage makes every component NaN (0 * NaN = NaN), the permutation keeps it.
 */
static inline bool att_i_calib_mag_zero(const att_vec3_t *m)
{
    return ((att_i_calib_bits(m->x) | att_i_calib_bits(m->y) | att_i_calib_bits(m->z)) << 1) == 0u;
}

/** The input stage: gyr, acc, mag of *in calibrated into *out (may be the same). */
static ATT_ALWAYS_INLINE void att_i_calib_apply(const att_calib_t *c, const att_vec3_t *gi, const att_vec3_t *ai,
                                                const att_vec3_t *mi, att_vec3_t *go, att_vec3_t *ao, att_vec3_t *mo)
{
    att_i_calib_stage(&c->gyr, gi, go);
    att_i_calib_stage(&c->acc, ai, ao);
    if (c->mag.mode != 0u && !att_i_calib_mag_zero(mi)) {
        att_i_calib_stage(&c->mag, mi, mo);
    } else {
        *mo = *mi;
    }
}

#endif /* ATT_CALIB_I_H */
