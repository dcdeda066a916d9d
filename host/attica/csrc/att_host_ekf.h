/**
 * @file att_host_ekf.h
 * @brief Host-only batch kernel for the Euler EKF: many instances in lockstep over numpy buffers.
 *
 * Not part of the firmware; compiled with the same strict flags as the firmware.
 */
#ifndef ATT_HOST_EKF_H
#define ATT_HOST_EKF_H

#include "attica/att_ekf.h"

/* ATT_CDEF_BEGIN */
/**
 * steps x m EKF steps in lockstep: at step k instance i (f[i]) takes gyr/acc row k * m + i
 * (rad/s, m/s^2; rows of 3 floats). Per row the outputs get euler (3, rad), the bias (3, rad/s),
 * P (21: the packed upper triangle of att_ekf_state_t.p) and the flags; any output pointer may be
 * NULL. Returns the number of steps run (steps * m), or 0 when f, gyr or acc is NULL.
 */
size_t att_host_ekf_run(att_ekf_t *f, size_t m, const float *gyr, const float *acc, size_t steps,
                        float *euler, float *bias, float *cov, uint32_t *flags);
/* ATT_CDEF_END */

#endif /* ATT_HOST_EKF_H */
