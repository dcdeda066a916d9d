/**
 * @file att_yaw.h
 * @brief Private: the arithmetic of the kinds' yaw hooks (att_<kind>_yaw_to): small inline helpers and
 * the two functions of att_yaw.c.
 *
 * A heading set or update turns the attitude about the earth vertical by the wrapped difference
 * between the target yaw and the current one, times a gain; the earth-frame memories of a kind
 * (accel low-pass stages, reference fields) turn with it. Compiled only with firmware/cflags.txt;
 * mirrored by reference/calib.py (the heading part).
 */
#ifndef ATT_YAW_H
#define ATT_YAW_H

#include "../math/att_inline.h"

#include "attica/att_math.h"

/** The ZYX yaw (rad, ENU) of a unit quaternion. */
static inline float att_i_yaw_of(att_quat_t q)
{
    return att_atan2f(2.0f * (q.w * q.z + q.x * q.y), 1.0f - 2.0f * (q.y * q.y + q.z * q.z));
}

/**
 * The turn from yaw toward target (rad) by the fraction gain of the wrapped difference: *delta and
 * its sine and cosine. False when the difference is not finite (an Euler yaw outside the wrap's domain).
 * (att_yaw.c: one copy for every kind.)
 */
bool att_yaw_turn(float yaw, float target, float gain, float *delta, float *s, float *c);

/** q turned by delta (rad) about the earth z axis, normalised (q itself when that fails). */
att_quat_t att_yaw_quat(att_quat_t q, float delta);

/**
 * The yaw hook of a kind whose state is a quaternion q with two earth-frame accel low-pass stages:
 * ATT_ERR_STATE when not ready (no valid sample yet) or the turn is not finite; else q, lp1 and lp2
 * turned, *s and *c the sine and cosine of the turn (for the kind's other earth-frame memories).
 */
att_status_t att_yaw_q(att_quat_t *q, att_vec3_t *lp1, att_vec3_t *lp2, bool ready, float target, float gain,
                       float *s, float *c);

/** v turned by the angle with cosine c and sine s about the earth z axis. */
static inline att_vec3_t att_i_yaw_vec(att_vec3_t v, float c, float s)
{
    return att_i_vec3(c * v.x - s * v.y, s * v.x + c * v.y, v.z);
}

#endif /* ATT_YAW_H */
