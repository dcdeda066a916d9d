/**
 * @file att_bias.h
 * @brief Gyro bias by capped running mean with a rest detector, shared by att_ars and att_mars.
 *
 * At rest when |w - b| < rest_gyro and ||a| - g| < rest_accel for rest_n consecutive samples, tested
 * on squares (|w - b|^2 < rest_gyro^2 and (g - rest_accel)^2 < |a|^2 < (g + rest_accel)^2, no square
 * roots). In ATT_BIAS_AT_REST mode the gate follows n: while n = 0 the running mean has not started (its
 * first sample replaces b, whether 0 or bias_init), so b is taken for the gyro's unknown turn-on bias and
 * the gyro test is |w - b|^2 < rest_gyro^2 + ATT_BIAS_UNKNOWN2: 3 standard deviations per axis of a
 * turn-on bias of 0.01 rad/s per axis (as the mekf's p0_bias and its rest gate), so that a still gyro
 * with a bias near or above rest_gyro (a consumer gyro's 2 deg/s per axis) is seen at rest. From the
 * first sample of the mean on (n > 0, also after a retune that keeps n) the test is rest_gyro^2 again;
 * rest_gyro^2 = 0 means no rest in either case.
 * Running mean b := (n b + w) / (n + 1), n capped at n_max, updated for every valid gyro sample
 * (ATT_BIAS_RUNNING) or only at rest (ATT_BIAS_AT_REST); valid is what the filter integrates, so a
 * reading at the rail (beyond gyro_range, within twice it: att_types.h ATT_FLAG_GYRO_RANGE) enters a
 * running mean too (it is never at rest). Units: rad/s, m/s^2; sensor frame.
 */
#ifndef ATT_BIAS_H
#define ATT_BIAS_H

#include "attica/att_config.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** The rest gate's widening before the first rest sample: 9 x 3 x (0.01 rad/s)^2 = 2.7e-3 (rad/s)^2. */
#define ATT_BIAS_UNKNOWN2 0x1.61e4f8p-9f

/* ATT_CDEF_BEGIN */
/** How a gyro bias estimate is maintained. */
typedef enum {
    ATT_BIAS_OFF = 0,      /**< b = 0 */
    ATT_BIAS_FROZEN = 1,   /**< b = bias_init, never updated */
    ATT_BIAS_RUNNING = 2,  /**< running mean of every valid gyro sample (KITECH literal) */
    ATT_BIAS_AT_REST = 3   /**< running mean of samples taken while at rest */
} att_bias_mode_t;

/** Parameters of the rest detector and bias update: att_bias_params_set derives them (fill them only with it:
    a struct filled by hand would miss fields added later, such as rest_first2). */
typedef struct {
    att_bias_mode_t mode; /**< estimation mode */
    uint32_t n_max;       /**< cap on n in the running mean, 1 .. 2^24 */
    uint32_t rest_n;      /**< consecutive samples at rest needed */
    float rest_gyro2;     /**< rest_gyro^2, (rad/s)^2: at rest needs |w - b|^2 below it (n > 0) ... */
    float acc2_lo;        /**< ... and |a|^2 above (g - rest_accel)^2, (m/s^2)^2 ... */
    float acc2_hi;        /**< ... and below (g + rest_accel)^2, (m/s^2)^2 */
    float rest_first2;    /**< the gyro gate while n = 0: rest_gyro^2 + ATT_BIAS_UNKNOWN2 in AT_REST mode with
                               rest_gyro^2 > 0, else rest_gyro^2, (rad/s)^2 */
} att_bias_params_t;

/**
 * Parameters from settings: rest thresholds rest_gyro (rad/s), rest_accel (m/s^2, <= gravity) and
 * rest_time (s), gravity g (m/s^2), sample period dt (s); rest_n = ceil(rest_time / dt).
 */
void att_bias_params_set(att_bias_params_t *p, att_bias_mode_t mode, uint32_t n_max, float rest_gyro,
                         float rest_accel, float rest_time, float gravity, float dt);

/**
 * One rest-detector and bias update. bias (rad/s, sensor frame), n and rest_count are the owner's
 * state; gyr is the raw gyro sample, gyro_ok/accel_ok its validity, acc_norm2 = |a|^2 ((m/s^2)^2).
 * The gyro gate is rest_first2 while *n = 0, else rest_gyro2 (above). Returns ATT_FLAG_AT_REST and/or
 * ATT_FLAG_BIAS_UPDATED.
 */
uint32_t att_bias_step(const att_bias_params_t *p, att_vec3_t *bias, uint32_t *n, uint32_t *rest_count,
                       att_vec3_t gyr, bool gyro_ok, bool accel_ok, float acc_norm2);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_BIAS_H */
