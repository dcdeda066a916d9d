/**
 * @file att_step.h
 * @brief Private: the step entry points att_filter_step dispatches to.
 *
 * Each kind's step with the sample and output record of att_filter.h: the filter's inputs are read
 * and the per-step output fields (see att_output_t) written inside the kind's own translation unit,
 * where the updated state is still in registers (the three objects must not overlap, as for
 * att_filter_step). Same results as att_<kind>_step.
 */
#ifndef ATT_STEP_H
#define ATT_STEP_H

#include "attica/att_filter.h"

/** att_ars_step on in->gyr, in->acc; fills out (may be NULL) with q, gyro_bias, flags, steps. */
uint32_t att_ars_step_out(att_ars_t *restrict f, const att_sample_t *restrict in, att_output_t *restrict out);
/** att_mars_step on in->gyr, in->acc, in->mag; fills out (may be NULL) like att_ars_step_out. */
uint32_t att_mars_step_out(att_mars_t *restrict f, const att_sample_t *restrict in, att_output_t *restrict out);

/** att_kf_step on in->gyr, in->acc; fills out (may be NULL) like att_ars_step_out. */
uint32_t att_kf_step_out(att_kf_t *restrict f, const att_sample_t *restrict in, att_output_t *restrict out);

/** att_ekf_step on in->gyr, in->acc; fills out (may be NULL) with euler, gyro_bias, flags, steps. */
uint32_t att_ekf_step_out(att_ekf_t *restrict f, const att_sample_t *restrict in, att_output_t *restrict out);

/** att_mekf_step on in->gyr, in->acc, in->mag; fills out (may be NULL) like att_ars_step_out. */
uint32_t att_mekf_step_out(att_mekf_t *restrict f, const att_sample_t *restrict in, att_output_t *restrict out);

#endif /* ATT_STEP_H */
