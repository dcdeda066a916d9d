/**
 * @file att_host_kf.h
 * @brief Host-only batch kernel for the linear quaternion KF (tests, tools); not part of the firmware.
 */
#ifndef ATT_HOST_KF_H
#define ATT_HOST_KF_H

#include "attica/att_kf.h"

/* ATT_CDEF_BEGIN */
/**
 * Step m independent filters f[0..m-1] through `steps` samples each, in lockstep.
 * gyr, acc: steps x m x 3 floats (rad/s, m/s^2, sensor frame; sample t of filter j at (t*m + j)*3).
 * Outputs after every step: quat steps x m x 4 (w,x,y,z), p steps x m (the variance, P = p I; may be
 * NULL), flags steps x m. Returns steps * m, or 0 when a required pointer is NULL.
 */
size_t att_host_kf_run(att_kf_t *f, size_t m, const float *gyr, const float *acc, size_t steps, float *quat,
                       float *p, uint32_t *flags);
/* ATT_CDEF_END */

#endif /* ATT_HOST_KF_H */
