/**
 * @file att_hardiron.h
 * @brief Hard-iron offset estimated on the device, from rotation (mars and mekf, opt-in: hard_iron_tau).
 *
 * A magnetometer on a board reads m = R^T e + h: the earth field e (earth frame) seen in the sensor frame
 * plus the hard-iron offset h (uT, sensor frame) of the board's own magnetised parts. Between a keyframe
 * sample m_k and a later sample m, the gyro's rotation D (sensor frame at the keyframe to now,
 * integrated from the bias-corrected rate, independent of the attitude estimate and of any reference
 * field) gives m - D^T m_k = (I - D^T) h: linear in h, observable from rotation about two axes.
 * A magnetometer that samples the field a time lag L behind the gyro reads m(t - L) ~ m + L (w x m)
 * (a fixed earth field turns as -w x m in the sensor frame), which adds b L to that equation with
 * b = w x m - D^T (w_k x m_k) (w, w_k the rates at the two samples): L is estimated with h, so that the
 * lag (about 3.5 samples on BROAD's sensor) does not bias h when the rate changes within a pair.
 * A pair closes at the first mag sample after a rotation of 0.5 rad or after key_n steps (1 s, at most
 * 1024); a keyframe is dropped by a gyro sample that is not usable (invalid, or any |w_i| at the recovery's
 * clip level 0.98 gyro_range, also with recovery_time 0: a clipping gyro) and after 2 key_n steps without
 * a mag sample. Each pair adds its rows
 * [A b] (A = I - D^T) to the 4x4 information [A b]^T [A b] and [A b]^T y (y = m - D^T m_k) to the
 * information vector; both first decay by 1 - n dt / hard_iron_tau for the n steps of the pair (the
 * estimate's memory). h is solved with L eliminated (the Schur complement of the lag's entry; without
 * rate changes the 3x3 block alone). When the smallest eigenvalue of that 3x3 information is at least
 * ATT_HI_OBS, 1 (tested by the bound det / (trace / 2)^2; about eight pairs of 0.5 rad about each of two
 * axes), its solution, each axis within +-mag_range, is the target; the applied offset moves toward it
 * by at most hard_iron_rate (uT/s) per axis, so it never jumps and never moves while the offset is
 * unobservable (it starts at 0: the samples as they come). Pairs whose field norms (target removed)
 * differ by more than the owner's mag_norm_reject are skipped once the target is known (a field that
 * changed between the samples: a magnet passing). The filter subtracts the applied offset from every
 * valid mag sample (mars: before its sample checks, which then see the corrected sample; mekf: after
 * them, before its norm and dip tests). A retune that turns the estimate on or off, and a calibration
 * that changes the magnetometer's stage (att_filter_calibrate: its mag model or mounting, another frame
 * or scale), start it again from nothing; another convention, gyro or accel model keeps it. Mirrored by
 * host/attica/reference/hardiron.py. Units: uT, rad/s, s; the frame of the samples the kind sees: the
 * sensor frame without a calibration, else the body frame after the calibration stage's hard- and
 * soft-iron correction and mounting (att_filter.h, att_mag_offset_t; docs/calibration.md: folding it
 * into a calibration file's hard iron takes S^-1 R_mount^T offset, not the offset itself).
 */
#ifndef ATT_HARDIRON_H
#define ATT_HARDIRON_H

#include "attica/att_config.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** Coefficients of the on-device hard-iron estimate, derived from the owner's settings. */
typedef struct {
    float k_forget;  /**< decay of the sums per step, dt / hard_iron_tau (0: off) */
    float step_max;  /**< largest change of the applied offset per step and axis, hard_iron_rate dt, uT */
    float gate;      /**< relative norm difference above which a pair is skipped (mag_norm_reject; 0 = none) */
    float limit;     /**< bound of the target per axis, uT (mag_range) */
    uint32_t key_n;  /**< most steps of a keyframe pair (1 s, at least 1, at most 1024) */
    bool on;         /**< hard_iron_tau > 0: estimated and applied */
} att_hardiron_params_t;

/** State of the on-device hard-iron estimate. */
typedef struct {
    att_vec3_t offset;  /**< applied offset h, uT, sensor frame: subtracted from every valid mag sample */
    att_vec3_t target;  /**< least-squares estimate the offset moves toward, uT (when observable) */
    att_quat_t d;       /**< rotation from the sensor frame at the keyframe to the sensor frame now */
    att_vec3_t m_key;   /**< raw mag sample of the keyframe, uT, sensor frame */
    att_vec3_t w_key;   /**< bias-corrected rate at the keyframe, rad/s, sensor frame */
    float info[10];     /**< information of (h, L), packed upper triangle (xx xy xz xl yy yz yl zz zl ll) */
    float z[4];         /**< information vector of (h, L) */
    float lag;          /**< the lag L of the mag behind the gyro solved with the target, s (informational) */
    uint32_t key_steps; /**< steps since the keyframe, counting it (0 = no keyframe) */
    bool observable;    /**< target is a solution of information with smallest eigenvalue >= ATT_HI_OBS */
} att_hardiron_t;
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_HARDIRON_H */
