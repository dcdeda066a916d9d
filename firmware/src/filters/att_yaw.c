/**
 * @file att_yaw.c
 * @brief The shared arithmetic of the kinds' yaw hooks (see att_yaw.h). Mirrored by reference/calib.py.
 */
#include "../math/att_fp.h"

#include "att_yaw.h"

bool att_yaw_turn(float yaw, float target, float gain, float *delta, float *s, float *c)
{
    *delta = att_wrap_pi(target - yaw) * gain;
    if (!att_i_isfinitef(*delta)) {
        return false;
    }
    att_i_sincosf(*delta, s, c);
    return true;
}

att_quat_t att_yaw_quat(att_quat_t q, float delta)
{
    float hs;
    float hc;
    att_quat_t out = q;
    att_i_sincosf(delta * 0.5f, &hs, &hc);
    (void)att_i_quat_normalize_bounded(att_i_quat_mul_z(hc, hs, q), &out);
    return out;
}

att_status_t att_yaw_q(att_quat_t *q, att_vec3_t *lp1, att_vec3_t *lp2, bool ready, float target, float gain,
                       float *s, float *c)
{
    float d;
    if (!ready) {
        return ATT_ERR_STATE;
    }
    if (!att_yaw_turn(att_i_yaw_of(*q), target, gain, &d, s, c)) {
        return ATT_ERR_STATE;
    }
    *lp1 = att_i_yaw_vec(*lp1, *c, *s);
    *lp2 = att_i_yaw_vec(*lp2, *c, *s);
    *q = att_yaw_quat(*q, d);
    return ATT_OK;
}
