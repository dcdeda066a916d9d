/**
 * @file att_bias.h
 * @brief Gyro bias by capped running mean with a rest detector, shared by att_ars and att_mars.
 *
 * At rest when |w - b| < rest_gyro and ||a| - g| < rest_accel for rest_n consecutive samples.
 * Running mean b := (n b + w) / (n + 1), n capped at n_max, updated for every valid gyro sample
 * (ATT_BIAS_RUNNING) or only at rest (ATT_BIAS_AT_REST). Units: rad/s, m/s^2; sensor frame.
 */
#ifndef ATT_BIAS_H
#define ATT_BIAS_H

#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** How a gyro bias estimate is maintained. */
typedef enum {
    ATT_BIAS_OFF = 0,      /**< b = 0 */
    ATT_BIAS_FROZEN = 1,   /**< b = bias_init, never updated */
    ATT_BIAS_RUNNING = 2,  /**< running mean of every valid gyro sample (KITECH literal) */
    ATT_BIAS_AT_REST = 3   /**< running mean of samples taken while at rest */
} att_bias_mode_t;

/** Parameters of one bias update (taken from the owning filter's settings). */
typedef struct {
    att_bias_mode_t mode; /**< estimation mode */
    uint32_t n_max;       /**< cap on n in the running mean, 1 .. 2^24 */
    uint32_t rest_n;      /**< consecutive samples at rest needed */
    float rest_gyro;      /**< rest threshold on |w - b|, rad/s */
    float rest_accel;     /**< rest threshold on ||a| - g|, m/s^2 */
    float gravity;        /**< g, m/s^2 */
} att_bias_params_t;

/**
 * One rest-detector and bias update. bias (rad/s, sensor frame), n and rest_count are the owner's
 * state; gyr is the raw gyro sample, gyro_ok/accel_ok its validity, norm = |a| (m/s^2).
 * Returns ATT_FLAG_AT_REST and/or ATT_FLAG_BIAS_UPDATED.
 */
uint32_t att_bias_step(const att_bias_params_t *p, att_vec3_t *bias, uint32_t *n, uint32_t *rest_count,
                       att_vec3_t gyr, bool gyro_ok, bool accel_ok, float norm);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_BIAS_H */
