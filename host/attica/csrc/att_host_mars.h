/**
 * @file att_host_mars.h
 * @brief Host-only batch kernel for the 9-axis complementary filter (loops in C over numpy buffers).
 *
 * Not part of the firmware; compiled with the same strict flags as the firmware.
 */
#ifndef ATT_HOST_MARS_H
#define ATT_HOST_MARS_H

#include "attica/att_mars.h"

/* ATT_CDEF_BEGIN */
/**
 * n MARS steps: gyr, acc, mag (n x 3, sensor frame; mag NULL = absent), quat out (n x 4), flags out (n);
 * m0 out (n x 3, earth-frame reference field after each step) may be NULL.
 * Returns n, or 0 when f, gyr, acc, quat or flags is NULL.
 */
size_t att_host_mars_run(att_mars_t *f, const float *gyr, const float *acc, const float *mag, size_t n,
                         float *quat, float *m0, uint32_t *flags);
/* ATT_CDEF_END */

#endif /* ATT_HOST_MARS_H */
