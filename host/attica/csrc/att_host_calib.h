/**
 * @file att_host_calib.h
 * @brief Host-only batch kernels of the input/output stages (att_calib.h) for the Python binding.
 *
 * Not part of the firmware; compiled with the same strict flags as the firmware.
 */
#ifndef ATT_HOST_CALIB_H
#define ATT_HOST_CALIB_H

#include "attica/att_calib.h"
#include "attica/att_filter.h"

/* ATT_CDEF_BEGIN */
/** att_calib_apply on n samples in place: gyr, acc, mag (n x 3 each, float32). */
void att_host_calib_apply(const att_calib_t *c, float *gyr, float *acc, float *mag, size_t n);
/**
 * n steps of f (att_filter_step) recording after each step the whole att_filter_output in out[i] and
 * the att_filter_accel fields in accel (n x 10 words: gravity, linear, earth, valid). mag may be NULL.
 * Returns n, or 0 when an argument is NULL.
 */
size_t att_host_filter_run_accel(att_filter_t *f, const float *gyr, const float *acc, const float *mag, size_t n,
                                 att_output_t *out, float *accel);
/* ATT_CDEF_END */

#endif /* ATT_HOST_CALIB_H */
