/**
 * @file att_host.h
 * @brief Host-only batch kernels for the Python binding: loop in C over numpy buffers (zero copy).
 *
 * Not part of the firmware; compiled with the same strict flags as the firmware.
 */
#ifndef ATT_HOST_H
#define ATT_HOST_H

#include "attica/att_filter.h"
#include "attica/att_math.h"

/* ATT_CDEF_BEGIN */
/** Scalar functions for att_host_map1: y[i] = fn(x[i]). */
enum {
    ATT_HOST_SIN = 0,
    ATT_HOST_COS = 1,
    ATT_HOST_ASIN = 2,
    ATT_HOST_ACOS = 3,
    ATT_HOST_SQRT = 4,
    ATT_HOST_WRAP_PI = 5
};
/** Vector/quaternion kernels for att_host_mapq. */
enum {
    ATT_HOST_QUAT_MUL = 0,        /**< in: a(4) b(4) -> out 4 */
    ATT_HOST_QUAT_NORMALIZE = 1,  /**< in: q(4) -> out 4 + ok(1) */
    ATT_HOST_QUAT_ROTATE = 2,     /**< in: q(4) v(3) -> out 3 */
    ATT_HOST_QUAT_FROM_EULER = 3, /**< in: e(3) -> out 4 */
    ATT_HOST_QUAT_TO_EULER = 4,   /**< in: q(4) -> out 3 */
    ATT_HOST_QUAT_TO_MATRIX = 5,  /**< in: q(4) -> out 9 */
    ATT_HOST_QUAT_FROM_ROTVEC = 6,/**< in: rv(3) -> out 4 */
    ATT_HOST_QUAT_FROM_AXIS_ANGLE = 7, /**< in: axis(3) angle(1) -> out 4 */
    ATT_HOST_VEC3_NORMALIZE = 8,  /**< in: v(3) -> out 3 + ok(1) */
    ATT_HOST_VEC3_CROSS = 9,      /**< in: a(3) b(3) -> out 3 */
    ATT_HOST_SENSOR_TILT = 10     /**< in: a(3) -> out 3 */
};
/** y[i] = fn(x[i]) for i < n; returns 0, or -1 for an unknown fn. */
int att_host_map1(int fn, const float *x, float *y, size_t n);
/** y[i] = atan2f(a[i], b[i]). */
void att_host_atan2(const float *a, const float *b, float *y, size_t n);
/** Row-wise kernel: in rows of in_width floats, out rows of out_width; -1 for bad fn/widths. */
int att_host_mapq(int fn, const float *in, size_t in_width, float *out, size_t out_width, size_t n);
/**
 * n steps of any filter: gyr, acc (n x 3); mag (n x 3) or NULL (absent); steps (n) the periods each row
 * advances (att_filter_step_n; its flags are the OR over them), or NULL for 1 each; out gets n records: the
 * per-step fields of att_filter_step, or with full != 0 the whole record of att_filter_output after
 * each step. With every > 0 and snaps != NULL, snaps[j] receives a copy of the filter state just before
 * step j * every (ceil(n / every) snapshots). moff (n) or NULL: att_filter_mag_offset after each step (the
 * hard-iron estimate of a mars or mekf; the caller checks the kind has one). Returns n, or 0 when f or an
 * input is NULL.
 */
size_t att_host_filter_run(att_filter_t *f, const float *gyr, const float *acc, const float *mag,
                           const uint32_t *steps, size_t n, att_output_t *out, int full, size_t every,
                           att_filter_t *snaps, att_mag_offset_t *moff);
/**
 * n steps of any filter, the lean batch: gyr, acc (n x 3); mag (n x 3) or NULL (absent); steps as for
 * att_host_filter_run (NULL: 1 each). q (n x 4)
 * gets the attitude after each step (w, x, y, z: the q of att_filter_output, bit for bit; the
 * Euler-state EKF's q is derived from its angles as att_filter_output does) and flags (n, or NULL)
 * the ATT_FLAG_* of each step. No output record is written. Returns n, or 0 when f, gyr, acc or q is
 * NULL (nothing done).
 */
size_t att_host_filter_run_q(att_filter_t *f, const float *gyr, const float *acc, const float *mag,
                             const uint32_t *steps, size_t n, float *q, uint32_t *flags);
/**
 * One step from nine floats (the Python binding's per-sample path: no sample struct to fill from
 * Python): gyr (rad/s), acc (m/s^2), mag (uT; zeros: absent), n periods (att_filter_step_n; 1 is
 * att_filter_step). full = 1: out is the whole att_filter_output after the step, its flags the
 * step's; 0: the step's fields (att_filter_step); 2: those and q always (the EKF's derived from its
 * angles as att_filter_output does). Returns the flags.
 */
uint32_t att_host_step9(att_filter_t *f, float gx, float gy, float gz, float ax, float ay, float az, float mx,
                        float my, float mz, uint32_t n, int full, att_output_t *out);
/* ATT_CDEF_END */

#endif /* ATT_HOST_H */
