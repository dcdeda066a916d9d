/**
 * @file att_ekf.c
 * @brief Euler-angle EKF with gyro bias states (see att_ekf.h). Mirrored by host/attica/reference/ekf.py.
 *
 * P is the upper triangle of the symmetric 6x6 covariance, row by row: element (i, j), i <= j, at
 * att_ekf_ix[i][j] (the table is symmetric, so (j, i) finds the same element). Every sum below is
 * written out in a fixed order (the reference follows it term by term).
 */
#include "../../math/att_fp.h"

#include "../../core/att_core.h"
#include "../att_kinds.h"
#include "../att_yaw.h"
#include "att_ekf_checks.h"
#include "attica/att_ekf.h"
#include "attica/att_math.h"
#include "attica/att_sensor.h"

#define ATT_EKF_PI_F 0x1.921fb6p+1f
#define ATT_EKF_PIVOT_MIN 0x1p-12f           /* relative pivot margin of the positive definiteness test */
#define ATT_EKF_COLLAPSE 0x1p+12f            /* a roll or pitch variance this far above its noise: P conditioned */
#define ATT_EKF_SHRINK 0x1.ff8p-1f           /* 1 - 2^-10: correlation shrink factor of the repair */
#define ATT_EKF_SETTLED 0x1.47ae14p-7f       /* (0.1 rad)^2: the tilt error (sin^2) that ends the convergence phase */
#define ATT_EKF_BIAS_SOFT 0x1p-4f /* full bias gain up to a raw d^2 of 1/16, then (1/16) / d^2 */
#define ATT_EKF_COND_MASK 15u                /* P is conditioned every 16 steps (and ATT_EKF_COND_NOW) */
#define ATT_EKF_COND_NOW 0x80000000u         /* internal flag (prediction, tests of P): condition P this step */
/* Increments of an angle up to which sin/cos follow by angle addition (att_ekf_sincos_step) */
#define ATT_EKF_INC_MAX 0x1p-4f    /* 1/16 rad */
#define ATT_EKF_INC_S3 (-0x1.555556p-3f) /* -1/6 */
#define ATT_EKF_INC_S5 0x1.111112p-7f    /* 1/120 */
#define ATT_EKF_INC_C4 0x1.555556p-5f    /* 1/24 */

static const uint8_t att_ekf_ix[6][6] = {
    {0u, 1u, 2u, 3u, 4u, 5u},     {1u, 6u, 7u, 8u, 9u, 10u},    {2u, 7u, 11u, 12u, 13u, 14u},
    {3u, 8u, 12u, 15u, 16u, 17u}, {4u, 9u, 13u, 16u, 18u, 19u}, {5u, 10u, 14u, 17u, 19u, 20u}};

#define P_(p, i, j) ((p)[att_ekf_ix[(i)][(j)]])

/* The small loops over the covariance unrolled, so that the index table folds into constants. */
#if defined(__GNUC__)
#define ATT_EKF_PRAGMA(x) _Pragma(#x)
#define ATT_EKF_UNROLL ATT_EKF_PRAGMA(GCC unroll 8)
#else
#define ATT_EKF_UNROLL
#endif

void att_ekf_settings_default(att_ekf_settings_t *settings, float dt)
{
    if (settings == NULL) {
        return;
    }
    settings->dt = dt;
    settings->q_phi = 1e-3f;
    settings->q_theta = 1e-3f;
    settings->q_psi = 1e-3f;
    settings->q_bias = 1e-8f; /* a bias random walk of 1e-4 rad/s per sqrt(s) */
    settings->r_phi = 1e-4f;
    settings->r_theta = 1e-4f;
    settings->r_accel = 0.0f;
    settings->gate = 0.0f;
    settings->p0 = 1.0f;
    settings->p0_bias = 1e-4f;
    settings->p_max = 1000000.0f;
    settings->gravity = 9.80665f;
    settings->accel_reject = 0.0f;
    settings->accel_range = 156.9064f; /* 16 g */
    settings->gyro_range = 34.906586f; /* 2000 deg/s */
    settings->cos_min = 0.001f;
    settings->tau_acc_lp = 1.5f;
    settings->init_from_accel = true;
    settings->euler_init = att_i_vec3(0.0f, 0.0f, 0.0f);
    settings->bias_init = att_i_vec3(0.0f, 0.0f, 0.0f);
    settings->noise_rates = true;
    settings->recovery_time = 2.0f; /* s: as ars, mars, kf and mekf */
}

att_status_t att_ekf_settings_validate(const att_ekf_settings_t *s)
{
    bool ok;
    if (s == NULL) {
        return ATT_ERR_NULL;
    }
    ok = true ATT_EKF_CHECKS(ATT_CHECK_AND);
    return ok ? ATT_OK : ATT_ERR_SETTINGS;
}

/*
 * The coefficients of the recovery after a clipping gyro (att_ekf.h, step 3); after r_step and p_max.
 * The process noise k^2 r / (1 - k) is the one whose steady-state Kalman gain is k.
 */
static void att_ekf_rec_coeffs(att_ekf_coeffs_t *c, const att_ekf_settings_t *s)
{
    const float k = att_i_recovery_params(s->recovery_time, s->gyro_range, s->dt, &c->rec_n, &c->clip);
    c->q_rec[0] = (c->rec_n > 0u) ? att_i_recovery_q(k, c->r_step[0], c->p_max) : 0.0f;
    c->q_rec[1] = (c->rec_n > 0u) ? att_i_recovery_q(k, c->r_step[1], c->p_max) : 0.0f;
}

static void att_ekf_coeffs(att_ekf_coeffs_t *c, const att_ekf_settings_t *s)
{
    const float dq = s->noise_rates ? s->dt : 1.0f;
    const float dr = s->noise_rates ? s->dt : 1.0f;
    c->dt = s->dt;
    c->q_step[0] = s->q_phi * dq;
    c->q_step[1] = s->q_theta * dq;
    c->q_step[2] = s->q_psi * dq;
    c->q_step[3] = s->q_bias * dq;
    c->r_step[0] = s->r_phi / dr;
    c->r_step[1] = s->r_theta / dr;
    c->r_accel = s->r_accel;
    c->gate = s->gate;
    c->soft = s->gate * 0.25f;
    c->p0 = s->p0;
    c->p0_bias = s->p0_bias;
    c->p_max = s->p_max;
    c->gravity = s->gravity;
    c->accel_reject = s->accel_reject;
    c->accel_range2 = s->accel_range * s->accel_range;
    c->gyro_range = s->gyro_range;
    c->cos_min = s->cos_min;
    c->k_lp = (s->tau_acc_lp > 0.0f) ? s->dt / (s->tau_acc_lp + s->dt) : 0.0f;
    c->euler_init = att_i_vec3(att_wrap_pi(s->euler_init.x), s->euler_init.y, att_wrap_pi(s->euler_init.z));
    c->bias_init = s->bias_init;
    c->init_from_accel = s->init_from_accel;
    c->lp_on = c->k_lp > 0.0f;
    c->need_norm = s->r_accel > 0.0f || s->accel_reject > 0.0f;
    att_ekf_rec_coeffs(c, s);
}

att_status_t att_ekf_init(att_ekf_t *f, const att_ekf_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_ekf_settings_validate(settings);
    if (st != ATT_OK) {
        return st;
    }
    att_ekf_coeffs(&f->c, settings);
    att_ekf_reset(f);
    return ATT_OK;
}

att_status_t att_ekf_retune(att_ekf_t *f, const att_ekf_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_ekf_settings_validate(settings);
    if (st == ATT_OK) {
        att_ekf_coeffs(&f->c, settings);
        if (f->st.rec_left > f->c.rec_n) {
            f->st.rec_left = f->c.rec_n; /* a recovery no longer than the new recovery_time (0: ended) */
        }
    }
    return st;
}

static void att_ekf_p_diag(float *p, float angles, float bias)
{
    int i;
    for (i = 0; i < 21; i++) {
        p[i] = 0.0f;
    }
    p[0] = angles;
    p[6] = angles;
    p[11] = angles;
    p[15] = bias;
    p[18] = bias;
    p[20] = bias;
}

void att_ekf_reset(att_ekf_t *f)
{
    if (f == NULL) {
        return;
    }
    f->st.euler = f->c.euler_init;
    f->st.bias = f->c.bias_init;
    att_ekf_p_diag(f->st.p, f->c.p0, f->c.p0_bias);
    f->st.lp1 = att_i_vec3(0.0f, 0.0f, f->c.gravity);
    f->st.lp2 = f->st.lp1;
    f->st.lp_psi = f->st.euler.z;
    f->st.lp_ready = false;
    f->st.converging = false;
    f->st.lp_mean = false;
    f->st.recover = false;
    f->st.steps = 0u;
    f->st.flags = 0u;
    f->st.rec_left = 0u;
    f->st.rec_lp_n = 0u;
    f->st.initialised = !f->c.init_from_accel;
    f->st.head_known = false;
}

/* a outside (-pi, pi] wrapped: one step of 2 pi (exact split as att_wrap_pi), att_wrap_pi beyond. */
static ATT_NOINLINE float att_ekf_wrap_slow(float a)
{
    if (a > ATT_EKF_PI_F) {
        a = (a - 0x1.921fb6p+2f) - (-0x1.777a5cp-23f);
    } else if (a <= -ATT_EKF_PI_F) {
        a = (a + 0x1.921fb6p+2f) + (-0x1.777a5cp-23f);
    } else {
        return a; /* a == pi: within (-pi, pi] */
    }
    if (a > ATT_EKF_PI_F || a <= -ATT_EKF_PI_F) {
        a = att_wrap_pi(a);
    }
    return a;
}

/* Wrap a to (-pi, pi] (angles of a step: within it but for the small excursions of a step). */
static ATT_ALWAYS_INLINE float att_ekf_wrap(float a)
{
    /* one test for both ends: |a| >= pi (a == pi is within, the slow path returns it) */
    return (att_i_absf(a) >= ATT_EKF_PI_F) ? att_ekf_wrap_slow(a) : a;
}

/* theta beyond [-pi/2, pi/2] (or NaN): wrapped, and beyond pi/2 the equivalent attitude (phi + pi,
 * +-pi - theta, psi + pi; P's theta row and column change sign); phi, psi are wrapped by the caller. */
static ATT_ALWAYS_INLINE bool att_ekf_flip(att_vec3_t *e, float *p)
{
    e->y = att_ekf_wrap(e->y);
    if (e->y > ATT_EKF_PIO2_F || e->y < -ATT_EKF_PIO2_F) {
        e->y = ((e->y > 0.0f) ? ATT_EKF_PI_F : -ATT_EKF_PI_F) - e->y;
        e->x = e->x + ATT_EKF_PI_F;
        e->z = e->z + ATT_EKF_PI_F;
        p[1] = -p[1]; /* P(0,1) */
        p[8] = -p[8]; /* P(1,3) */
        p[9] = -p[9]; /* P(1,4) */
        p[10] = -p[10]; /* P(1,5) */
        return true;
    }
    return false;
}

/*
 * The angles of a stage canonical: theta into [-pi/2, pi/2] by the equivalent attitude (P's theta row
 * and column change sign), phi and psi wrapped. Returns true when the attitude was flipped. |theta| <=
 * pi/2 needs neither the wrap nor the flip: one test (att_ekf_flip does both otherwise).
 */
static ATT_ALWAYS_INLINE bool att_ekf_canon(att_vec3_t *e, float *p)
{
    bool flipped = false;
    if (!(att_i_absf(e->y) <= ATT_EKF_PIO2_F)) {
        flipped = att_ekf_flip(e, p);
    }
    e->x = att_ekf_wrap(e->x);
    e->z = att_ekf_wrap(e->z);
    return flipped;
}

/*
 * The angles e and the 16 carried elements of P (yaw's correlations, never written, are left to the
 * conditioning) are finite and every variance is > 0: one sum of them all is finite exactly when each is
 * (a finite sum of P below FLT_MAX stays finite when the canonical angles, |e_i| <= pi, are added: far
 * below half an ulp there), so one test covers both.
 */
static ATT_ALWAYS_INLINE bool att_ekf_usable(att_vec3_t e, const float *p)
{
    const float sum = ((((((((((((((((((p[0] + p[1]) + p[3]) + p[4]) + p[5]) + p[6]) + p[8]) + p[9]) + p[10]) +
                      p[11]) + p[15]) + p[16]) + p[17]) + p[18]) + p[19]) + p[20]) + e.x) + e.y) + e.z);
    return att_i_isfinitef(sum) && p[0] > 0.0f && p[6] > 0.0f && p[11] > 0.0f && p[15] > 0.0f && p[18] > 0.0f &&
           p[20] > 0.0f;
}

/* Positive definite with margin 2^-12 (att_core.h, att_i_pd6: the test float32 rounding cannot fool). */
static bool att_ekf_pd_ok(const float *p)
{
    return att_i_pd6(p, ATT_EKF_PIVOT_MIN);
}

/*
 * Conditioning (every 16 steps, at every step flagged GIMBAL or without an applied update, after an
 * increment beyond 1/16 rad, when the roll/pitch block is near singular): variances above p_max brought down by D P D (d_i = sqrt(p_max / P_ii));
 * if P then fails the test with margin, the correlations times 1 - 2^-10, or zero when that is not
 * enough. Returns ATT_FLAG_CLAMPED when it changed P.
 */
static ATT_NOINLINE uint32_t att_ekf_condition(float *p, float p_max, float pb_max)
{
    float dd[6];
    bool capped = false;
    int i;
    int j;
    ATT_EKF_UNROLL
    for (i = 0; i < 6; i++) {
        const float cap = (i < 3) ? p_max : pb_max;
        dd[i] = 1.0f;
        if (P_(p, i, i) > cap) {
            dd[i] = att_i_sqrtf(cap / P_(p, i, i));
            capped = true;
        }
    }
    if (capped) {
        for (i = 0; i < 6; i++) {
            for (j = i; j < 6; j++) {
                P_(p, i, j) = (P_(p, i, j) * dd[i]) * dd[j];
            }
        }
    }
    if (att_ekf_pd_ok(p)) {
        return capped ? ATT_FLAG_CLAMPED : 0u;
    }
    for (i = 0; i < 6; i++) {
        for (j = i + 1; j < 6; j++) {
            P_(p, i, j) = P_(p, i, j) * ATT_EKF_SHRINK;
        }
    }
    if (!att_ekf_pd_ok(p)) {
        for (i = 0; i < 6; i++) {
            for (j = i + 1; j < 6; j++) {
                P_(p, i, j) = 0.0f;
            }
        }
    }
    return ATT_FLAG_CLAMPED;
}

/*
 * P after a step whose covariance cannot be used (not finite, or a variance not positive: only from
 * adversarial states and settings; P is predicted and updated in place, so the one before is gone):
 * the start values, as att_ekf_reset. Returns ATT_FLAG_NUMERIC.
 */
static ATT_NOINLINE uint32_t att_ekf_p_restart(const att_ekf_coeffs_t *c, float *p)
{
    att_ekf_p_diag(p, c->p0, c->p0_bias);
    return ATT_FLAG_NUMERIC;
}

/*
 * The one test of a step without an applied update, on the state it leaves (att_ekf_update tests its
 * own result): P that cannot be used restarts (att_ekf_p_restart); a usable P is conditioned this step
 * (ATT_EKF_COND_NOW). Without an update nothing bounds P: the prediction alone feeds the bias variance
 * into roll at a gain of dt tan(theta) per step, so near pitch 90 deg roll's variance runs beyond p_max
 * and its correlation with the bias beyond what float32 can carry within a few steps (F15: dt 0.5 s,
 * pitch 86 deg, accel samples unusable: roll's variance 3 -> 18,600 in 16 steps, P indefinite). The
 * conditioning keeps every variance within its cap and P positive definite with margin at every such
 * step; it costs less than the update it stands in for. The predicted angles are finite
 * (att_ekf_predict keeps them otherwise).
 */
static ATT_NOINLINE uint32_t att_ekf_check(const att_ekf_coeffs_t *c, att_ekf_state_t *st)
{
    return att_ekf_usable(st->euler, st->p) ? ATT_EKF_COND_NOW : att_ekf_p_restart(c, st->p);
}

/*
 * A prediction whose increments leave the wrap's range (adversarial rates, dt, cos_min, or a bias
 * estimate run beyond any gyro's range): the angles are kept by the caller; P, the bias and the stages
 * restart (the rotation was not followed, and a bias that left it could do so at every step:
 * docs/robustness.md F10). The bias restarts at bias_init, or at zero when the prediction already ran
 * with bias_init: a start value that itself takes the prediction out of the range (|w - b| dt / cos
 * beyond 8192 rad) is no gyro bias, and kept it would fail the prediction after every re-initialisation
 * (issue 26 R1). Returns ATT_FLAG_NUMERIC.
 */
static ATT_NOINLINE uint32_t att_ekf_out_of_range(const att_ekf_coeffs_t *c, att_ekf_state_t *st)
{
    const att_vec3_t b = st->bias;
    const att_vec3_t b0 = c->bias_init;
    const bool from_init = b.x == b0.x && b.y == b0.y && b.z == b0.z;
    st->lp_ready = false;
    st->bias = from_init ? att_i_vec3(0.0f, 0.0f, 0.0f) : b0;
    return att_ekf_p_restart(c, st->p);
}

/* sin and cos of roll and pitch (cos(theta) not guarded): of the state, or of the prediction */
typedef struct {
    float sphi;
    float cphi;
    float sth;
    float cth;
} att_ekf_trig_t;

/*
 * sin(d) and cos(d) of a small angle, |d| <= ATT_EKF_INC_MAX (1/16 rad), by the series
 * sin(d) = d + d^3 (-1/6 + d^2 / 120), cos(d) = 1 - d^2 (1/2 - d^2 / 24) (the next terms, d^7 / 5040 <
 * 4e-12 and d^6 / 720 < 9e-11, are far below half an ulp of 1).
 */
static ATT_ALWAYS_INLINE void att_ekf_sincos_small(float d, float *sd, float *cd)
{
    const float z = d * d;
    *sd = d + (d * z) * (ATT_EKF_INC_S3 + z * ATT_EKF_INC_S5);
    *cd = 1.0f - z * (0.5f - z * ATT_EKF_INC_C4);
}

/*
 * The low-pass stages (heading frame: the earth frame turned about z by a yaw, lp_psi) turned into the
 * estimate's heading frame, by d = psi - lp_psi (rad, |d| < 2 pi): x := c x + s y, y := c y - s x with
 * s = sin d, c = cos d (att_ekf_sincos_small for |d| <= 1/16 rad, else att_i_sincosf).
 * Done at each update, into the update's copies (kept only when it is applied; lp_psi := psi, the
 * predicted yaw: the update's own change of yaw and a flip are turned by the next update), not
 * at each step: between updates (accel rejected or missing) the stages are not used, and one turn by
 * the whole change keeps their norm (a turn per step would grow it by the rounding of c^2 + s^2, up to
 * 2e-8 per step at 0.02 rad/s of yaw rate).
 */
static ATT_ALWAYS_INLINE void att_ekf_turn(const att_ekf_state_t *st, att_vec3_t *lp1, att_vec3_t *lp2)
{
    const float d = st->euler.z - st->lp_psi;
    float sd;
    float cd;
    if (att_i_absf(d) <= ATT_EKF_INC_MAX) {
        att_ekf_sincos_small(d, &sd, &cd);
    } else {
        att_i_sincosf(d, &sd, &cd);
    }
    lp1->x = cd * st->lp1.x + sd * st->lp1.y;
    lp1->y = cd * st->lp1.y - sd * st->lp1.x;
    lp1->z = st->lp1.z;
    lp2->x = cd * st->lp2.x + sd * st->lp2.y;
    lp2->y = cd * st->lp2.y - sd * st->lp2.x;
    lp2->z = st->lp2.z;
}

/*
 * sin(a) and cos(a) of a = a0 + d (as rounded) from s0 = sin(a0), c0 = cos(a0): for |d| <=
 * ATT_EKF_INC_MAX (1/16 rad) by angle addition with att_ekf_sincos_small(d), else att_i_sincosf(a). The increments of a step are dt times the Euler
 * rates: within 1/16 rad up to 6.25 rad/s at 100 Hz (the midpoint up to 12.5 rad/s).
 */
static ATT_ALWAYS_INLINE void att_ekf_sincos_step(float a, float d, float s0, float c0, float *s, float *c)
{
    if (att_i_absf(d) <= ATT_EKF_INC_MAX) {
        float sd;
        float cd;
        att_ekf_sincos_small(d, &sd, &cd);
        *s = s0 * cd + c0 * sd;
        *c = c0 * cd - s0 * sd;
        return;
    }
    att_i_sincosf(a, s, c);
}

/*
 * sin(a) and cos(a) of the midpoint a = a0 + d to first order, s0 + c0 d and c0 - s0 d, for |d| <=
 * ATT_EKF_INC_MAX (an error of at most d^2 / 2 in the midpoint's rates: O(dt^2), so the midpoint rule
 * stays second order), else att_i_sincosf(a).
 */
static ATT_ALWAYS_INLINE void att_ekf_sincos_mid(float a, float d, float s0, float c0, float *s, float *c)
{
    if (att_i_absf(d) <= ATT_EKF_INC_MAX) {
        *s = s0 + c0 * d;
        *c = c0 - s0 * d;
        return;
    }
    att_i_sincosf(a, s, c);
}

/*
 * att_ekf_sincos_step's angle addition alone: for |d| <= ATT_EKF_INC_MAX into *s, *c (true), else
 * nothing (false: the caller evaluates sin/cos of the angle itself, as att_ekf_sincos_step does).
 */
static ATT_ALWAYS_INLINE bool att_ekf_sincos_add(float d, float s0, float c0, float *s, float *c)
{
    if (att_i_absf(d) <= ATT_EKF_INC_MAX) {
        att_ekf_sincos_step(0.0f, d, s0, c0, s, c);
        return true;
    }
    return false;
}

/*
 * The motion of a step with usable rates: the angles into *eo, P := F P F^T in place (Q not yet added;
 * every element of P is read before the first is written; Pbb does not change), the roll and pitch
 * increments into *dd; returns ATT_FLAG_GIMBAL when the cos(theta) guard was used. tr holds sin/cos of
 * the state's roll and pitch.
 */
static ATT_ALWAYS_INLINE uint32_t att_ekf_propagate(const att_ekf_coeffs_t *c, att_ekf_state_t *st, att_vec3_t w,
                                                    const att_ekf_trig_t *tr, att_vec3_t *eo, float dd[2],
                                                    att_ekf_trig_t *tp, bool *added)
{
    const float dt = c->dt;
    const float sphi = tr->sphi;
    const float cphi = tr->cphi;
    const float sth = tr->sth;
    float cth = tr->cth;
    float tth;
    float sec;
    float u;
    float v;
    float a00;
    float a01;
    float a10;
    float b00;
    float b01;
    float b02;
    float b11;
    float b12;
    float uu[2][3];
    float ww[2][2];
    float *pn = st->p;
    const float *p = st->p;
    att_vec3_t e;
    uint32_t flags = 0u;
    int i;
    int j;
    if (att_i_absf(cth) < c->cos_min) {
        cth = (cth < 0.0f) ? -c->cos_min : c->cos_min;
        flags = ATT_FLAG_GIMBAL;
    }
    tth = sth / cth;
    sec = 1.0f / cth;
    /* the kinematics by the midpoint rule: rates at the start give the midpoint angles, the rates
     * there the step (second order: first-order Euler steps drift at the rates of fast rotation); the
     * midpoint's sin/cos by angle addition from the start's (att_ekf_sincos_step) */
    {
        float sm;
        float cm;
        float stm;
        float ctm;
        float ttm;
        float secm;
        const float hdt = dt * 0.5f;
        const float dxh = (w.x + sphi * tth * w.y + cphi * tth * w.z) * hdt;
        const float dyh = (cphi * w.y - sphi * w.z) * hdt;
        att_ekf_sincos_mid(st->euler.x + dxh, dxh, sphi, cphi, &sm, &cm);
        att_ekf_sincos_mid(st->euler.y + dyh, dyh, sth, tr->cth, &stm, &ctm);
        if (att_i_absf(ctm) < c->cos_min) {
            ctm = (ctm < 0.0f) ? -c->cos_min : c->cos_min;
        }
        ttm = stm / ctm;
        secm = 1.0f / ctm;
        dd[0] = (w.x + sm * ttm * w.y + cm * ttm * w.z) * dt;
        dd[1] = (cm * w.y - sm * w.z) * dt;
        e.x = st->euler.x + dd[0];
        e.y = st->euler.y + dd[1];
        e.z = st->euler.z + (sm * secm * w.y + cm * secm * w.z) * dt;
    }
    /* sin/cos of the predicted roll and pitch by angle addition (before P: fewer values live across
     * it); an increment beyond 1/16 rad leaves them to att_ekf_predict (from the wrapped angle) */
    *added = att_ekf_sincos_add(dd[0], sphi, cphi, &tp->sphi, &tp->cphi) &&
             att_ekf_sincos_add(dd[1], sth, tr->cth, &tp->sth, &tp->cth);
    u = sphi * w.y + cphi * w.z;
    v = cphi * w.y - sphi * w.z;
    /* A: the roll and pitch rows of I + dt J (A00 = a00, A11 = 1, A02 = A12 = 0) */
    a00 = 1.0f + dt * (v * tth);
    a01 = dt * (u * sec * sec);
    a10 = -(dt * u);
    /* B: the roll and pitch rows of -dt E */
    b00 = -dt;
    b01 = -(dt * (sphi * tth));
    b02 = -(dt * (cphi * tth));
    b11 = -(dt * cphi);
    b12 = dt * sphi;
    /* W = A Paa over roll and pitch (read before any element of P is written); yaw's row of P is not
     * carried (its correlations stay zero): F's yaw column is zero in the rows of roll and pitch and H
     * does not see yaw, so that row never reaches roll, pitch or the bias */
    ATT_EKF_UNROLL
    for (j = 0; j < 2; j++) {
        const float r0j = P_(p, 0, j);
        const float r1j = P_(p, 1, j);
        ww[0][j] = a00 * r0j + a01 * r1j;
        ww[1][j] = a10 * r0j + r1j;
    }
    /* U = A Pab, V = B Pbb, the new Pab N = U + V, column by column in place (roll and pitch rows) */
    ATT_EKF_UNROLL
    for (j = 0; j < 3; j++) {
        const float p0j = P_(p, 0, 3 + j);
        const float p1j = P_(p, 1, 3 + j);
        const float q0j = P_(p, 3, 3 + j);
        const float q1j = P_(p, 4, 3 + j);
        const float q2j = P_(p, 5, 3 + j);
        uu[0][j] = a00 * p0j + a01 * p1j;
        uu[1][j] = a10 * p0j + p1j;
        P_(pn, 0, 3 + j) = uu[0][j] + ((b00 * q0j + b01 * q1j) + b02 * q2j);
        P_(pn, 1, 3 + j) = uu[1][j] + (b11 * q1j + b12 * q2j);
    }
    /* the new roll/pitch block = A Paa A^T (row i of W A^T) + N B^T (X) + (U B^T)^T (Y), (i, j >= i) */
    ATT_EKF_UNROLL
    for (i = 0; i < 2; i++) {
        const float w0 = ww[i][0];
        const float w1 = ww[i][1];
        const float n0 = P_(pn, i, 3);
        const float n1 = P_(pn, i, 4);
        const float n2 = P_(pn, i, 5);
        float t[2];
        float x[2];
        t[0] = w0 * a00 + w1 * a01;
        t[1] = w0 * a10 + w1;
        x[0] = (n0 * b00 + n1 * b01) + n2 * b02;
        x[1] = n1 * b11 + n2 * b12;
        ATT_EKF_UNROLL
        for (j = i; j < 2; j++) {
            const float u1 = uu[j][1];
            const float u2 = uu[j][2];
            const float yji = (i == 0) ? ((uu[j][0] * b00 + u1 * b01) + u2 * b02) : (u1 * b11 + u2 * b12);
            P_(pn, i, j) = (t[j] + x[j]) + yji;
        }
    }
    *eo = e;
    return flags;
}

/* sin/cos of the predicted roll and pitch when att_ekf_propagate left them: directly after a flip, else
 * as att_ekf_sincos_step (an increment beyond 1/16 rad: from the wrapped angle). */
static ATT_ALWAYS_INLINE void att_ekf_predict_trig(att_vec3_t e, const float *dd, const att_ekf_trig_t *t0,
                                              att_ekf_trig_t *tr, bool flipped)
{
    if (flipped) {
        att_i_sincosf(e.x, &tr->sphi, &tr->cphi);
        att_i_sincosf(e.y, &tr->sth, &tr->cth);
    } else {
        att_ekf_sincos_step(e.x, dd[0], t0->sphi, t0->cphi, &tr->sphi, &tr->cphi);
        att_ekf_sincos_step(e.y, dd[1], t0->sth, t0->cth, &tr->sth, &tr->cth);
    }
}

/*
 * Prediction of the angles and of P, in place (out of line: its frame is not the update's); returns
 * its flags. Without usable rates the angles are kept and F = I (the bias did not enter the
 * prediction): P := P + Q. Taken unless its angles leave the wrap's range (adversarial rates, dt and
 * cos_min: then the angles are kept, P restarts, the stages restart: an unmeasured rotation); tested
 * with the update's result, or by att_ekf_check when no update is applied. tr: sin/cos of the roll and
 * pitch for the update.
 */
static ATT_NOINLINE uint32_t att_ekf_predict(const att_ekf_coeffs_t *c, att_ekf_state_t *st, att_vec3_t w,
                                             bool gyro_ok, att_ekf_trig_t *tr)
{
    float *pn = st->p;
    att_vec3_t e;
    uint32_t flags = 0u;
    float dd[2] = {0.0f, 0.0f};
    att_ekf_trig_t t0;
    bool flipped;
    bool added = false;
    att_i_sincosf(st->euler.x, &t0.sphi, &t0.cphi);
    att_i_sincosf(st->euler.y, &t0.sth, &t0.cth);
    if (gyro_ok) {
        flags = att_ekf_propagate(c, st, w, &t0, &e, dd, tr, &added);
    } else {
        e = st->euler;
        att_ekf_sincos_step(e.x, 0.0f, t0.sphi, t0.cphi, &tr->sphi, &tr->cphi);
        att_ekf_sincos_step(e.y, 0.0f, t0.sth, t0.cth, &tr->sth, &tr->cth);
        added = true;
    }
    P_(pn, 0, 0) = P_(pn, 0, 0) + c->q_step[0];
    P_(pn, 1, 1) = P_(pn, 1, 1) + c->q_step[1];
    P_(pn, 2, 2) = P_(pn, 2, 2) + c->q_step[2];
    P_(pn, 3, 3) = P_(pn, 3, 3) + c->q_step[3];
    P_(pn, 4, 4) = P_(pn, 4, 4) + c->q_step[3];
    P_(pn, 5, 5) = P_(pn, 5, 5) + c->q_step[3];
    if (st->rec_left > 0u) {
        /* a recovery (step 3): roll and pitch follow the accelerometer with its gain */
        P_(pn, 0, 0) = P_(pn, 0, 0) + c->q_rec[0];
        P_(pn, 1, 1) = P_(pn, 1, 1) + c->q_rec[1];
    }
    flipped = att_ekf_canon(&e, pn);
    if (!att_i_isfinitef((e.x + e.y) + e.z)) {
        return flags | att_ekf_out_of_range(c, st); /* no update follows (tr unused) */
    }
    /* sin/cos of the predicted roll and pitch for the update: by angle addition from the increments
     * (as wrapped: the same sin/cos; done in att_ekf_propagate), directly after a flip to the
     * equivalent attitude or for an increment beyond 1/16 rad */
    if (flipped || !added) {
        att_ekf_predict_trig(e, dd, &t0, tr, flipped);
        if (!added) {
            /* a roll or pitch increment beyond 1/16 rad: F is far from I (fast rotation, a long dt),
             * and P may lose positive definiteness to rounding before the next 16th step */
            flags |= ATT_EKF_COND_NOW;
        }
    }
    st->euler = e;
    return flags;
}

/* |a| / g - 1 of a usable accel sample (|a|^2 as att_i_sensor_check_accel2 computes it). */
static ATT_ALWAYS_INLINE float att_ekf_norm_error(const att_ekf_coeffs_t *c, att_vec3_t acc)
{
    return att_i_sqrtf(att_i_vec3_dot(acc, acc)) / c->gravity - 1.0f;
}

/*
 * The applied update: the stages (lp := lp + eps x lp with eps_z = 0, in the heading frame of the
 * predicted yaw, lp_psi: the next update turns them on from there, through this one's change of yaw and
 * any flip), the angles and the bias.
 */
static ATT_ALWAYS_INLINE void att_ekf_commit(const att_ekf_coeffs_t *c, att_ekf_state_t *st, att_vec3_t e,
                                             att_vec3_t lp1, att_vec3_t lp2, float epx, float epy, bool ready,
                                             const float db3[3])
{
    if (c->lp_on) {
        st->lp1 = att_i_vec3(lp1.x + epy * lp1.z, lp1.y - epx * lp1.z, lp1.z + (epx * lp1.y - epy * lp1.x));
        st->lp2 = att_i_vec3(lp2.x + epy * lp2.z, lp2.y - epx * lp2.z, lp2.z + (epx * lp2.y - epy * lp2.x));
        st->lp_psi = st->euler.z;
        st->lp_ready = ready;
        st->converging = !ready;
    }
    st->euler = e;
    st->bias.x = st->bias.x + db3[0];
    st->bias.y = st->bias.y + db3[1];
    st->bias.z = st->bias.z + db3[2];
}

/* What the gain and covariance step of an update takes: the innovation, R and S^-1, the soft factors. */
typedef struct {
    float y0;  /**< innovation of roll (the tilt error about x over cos(theta)), rad */
    float y1;  /**< innovation of pitch, rad */
    float yb0; /**< the raw sample's innovation (the bias states measure against it): roll, rad */
    float yb1; /**< pitch, rad */
    float r0;  /**< R of roll, rad^2 */
    float r1;  /**< R of pitch, rad^2 */
    float t0;  /**< det P2 + r1 P00 */
    float t1;  /**< det P2 + r0 P11 */
    float inv; /**< 1 / det S */
    float i00; /**< S^-1 (symmetric) */
    float i01;
    float i11;
    float fk;  /**< the gate's soft factor (1: the whole update) */
    float fb;  /**< the bias states' factor */
} att_ekf_innov_t;

/*
 * K = P H^T S^-1 (columns k0, k1; row i: k0_i = P_i0 i00 + P_i1 i01, k1_i = P_i0 i01 + P_i1 i11): the
 * updated roll and pitch into e (x, y), the bias change into db3, P in place.
 * P := P - K S K^T without cancellation in the rows of roll and pitch: (I - K H) P there is
 * R S^-1 P (rows 0, 1), so P2 := R S^-1 P2 = [r0 (det P2 + r1 P00), r0 r1 P01; ., r1 (det P2 + r0
 * P11)] / det S (positive definite) and P(0:2, j) := R (K^T)(:, j); the rest P - K (H P). In place,
 * one row i = 2..5 of the gain at a time: row i of the block reads P_0j, P_1j for j >= i only, so
 * P_0i, P_1i are written after it (soft: every element P + fk (P_update - P)).
 */
static ATT_ALWAYS_INLINE void att_ekf_gain(att_ekf_state_t *st, const att_ekf_innov_t *v, att_vec3_t *e, float db3[3])
{
    const float *p = st->p;
    float *pn = st->p;
    int i;
    int j;
    const bool soft = v->fk < 1.0f;
    float kb0[3];
    float kb1[3];
    float n00;
    float n01;
    float n11;
    float k00;
    float k10;
    float k01;
    float k11;
    k00 = P_(p, 0, 0) * v->i00 + P_(p, 0, 1) * v->i01;
    k10 = P_(p, 0, 0) * v->i01 + P_(p, 0, 1) * v->i11;
    k01 = P_(p, 1, 0) * v->i00 + P_(p, 1, 1) * v->i01;
    k11 = P_(p, 1, 0) * v->i01 + P_(p, 1, 1) * v->i11;
    e->x = st->euler.x + (k00 * v->y0 + k10 * v->y1) * v->fk;
    e->y = st->euler.y + (k01 * v->y0 + k11 * v->y1) * v->fk;
    ATT_EKF_UNROLL
    for (i = 3; i < 6; i++) {
        const float k0 = P_(p, i, 0) * v->i00 + P_(p, i, 1) * v->i01;
        const float k1 = P_(p, i, 0) * v->i01 + P_(p, i, 1) * v->i11;
        const float o0 = P_(p, 0, i);
        const float o1 = P_(p, 1, i);
        kb0[i - 3] = k0;
        kb1[i - 3] = k1;
        ATT_EKF_UNROLL
        for (j = i; j < 6; j++) {
            const float old = P_(pn, i, j);
            const float nw = old - (k0 * P_(p, 0, j) + k1 * P_(p, 1, j));
            P_(pn, i, j) = soft ? old + v->fk * (nw - old) : nw;
        }
        P_(pn, 0, i) = soft ? o0 + v->fk * (v->r0 * k0 - o0) : v->r0 * k0;
        P_(pn, 1, i) = soft ? o1 + v->fk * (v->r1 * k1 - o1) : v->r1 * k1;
    }
    n00 = (v->r0 * v->inv) * v->t0;
    n01 = ((v->r0 * v->r1) * v->inv) * P_(p, 0, 1);
    n11 = (v->r1 * v->inv) * v->t1;
    if (soft) {
        n00 = P_(p, 0, 0) + v->fk * (n00 - P_(p, 0, 0));
        n01 = P_(p, 0, 1) + v->fk * (n01 - P_(p, 0, 1));
        n11 = P_(p, 1, 1) + v->fk * (n11 - P_(p, 1, 1));
    }
    pn[0] = n00;
    pn[1] = n01;
    pn[6] = n11;
    db3[0] = (kb0[0] * v->yb0 + kb1[0] * v->yb1) * v->fb;
    db3[1] = (kb0[1] * v->yb0 + kb1[1] * v->yb1) * v->fb;
    db3[2] = (kb0[2] * v->yb0 + kb1[2] * v->yb1) * v->fb;
}

/* The start's running mean ends at this count at the latest (its float exact; a k_lp below 2^-24). */
#define ATT_EKF_MEAN_N_MAX 0x1000000u

/*
 * The low-pass stages' step with sample vv: during a recovery and after the start (lp_mean) at the gain
 * of the running mean (att_i_recovery_lp_gain, down to k_lp / 4, where the start's mean ends, or at
 * ATT_EKF_MEAN_N_MAX updates), else k_lp. The count is of the updates computed: a sample the gate then
 * rejects (on outside a recovery) counts without entering the stages.
 */
static ATT_ALWAYS_INLINE void att_ekf_lowpass(const att_ekf_coeffs_t *c, att_ekf_state_t *st, att_vec3_t vv,
                                              att_vec3_t *lp1, att_vec3_t *lp2)
{
    float k = c->k_lp;
    float k2 = k;
    if (st->rec_left > 0u || st->lp_mean) {
        k = att_i_recovery_lp_gain2(&st->rec_lp_n, c->k_lp, &k2);
        st->lp_mean = st->lp_mean && k2 > c->k_lp && st->rec_lp_n < ATT_EKF_MEAN_N_MAX;
    }
    att_i_lowpass2(vv, k, k2, lp1, lp2);
}

/*
 * The measurement of an update: the specific force in the heading frame of the prediction (the earth
 * frame turned by its yaw: R_y(theta) R_x(phi) a) into *va, and the direction the update measures: the
 * low-passed one when the stages are on (their copies turned and stepped in *lp1, *lp2; *ready: they
 * run), else va.
 */
static ATT_ALWAYS_INLINE att_vec3_t att_ekf_measurement(const att_ekf_coeffs_t *c, att_ekf_state_t *st,
                                                        att_vec3_t acc, const att_ekf_trig_t *tr,
                                                        att_vec3_t *va, att_vec3_t *lp1, att_vec3_t *lp2,
                                                        bool *ready)
{
    const float sphi = tr->sphi;
    const float cphi = tr->cphi;
    const float sth = tr->sth;
    const float cth = tr->cth;
    att_vec3_t vv;
    vv.x = cth * acc.x + (sth * sphi) * acc.y + (sth * cphi) * acc.z;
    vv.y = cphi * acc.y - sphi * acc.z;
    vv.z = (-sth) * acc.x + (cth * sphi) * acc.y + (cth * cphi) * acc.z;
    *va = vv;
    *ready = st->lp_ready;
    if (c->lp_on) {
        att_ekf_turn(st, lp1, lp2); /* the stages in the predicted heading frame */
        if (!*ready) {
            /* not started: a sample within 0.1 rad of the estimate's gravity starts the stages, from
             * that gravity (0, 0, g) after a reset or an unusable gyro sample (a right estimate kept: no
             * pull onto one noisy sample), from the sample at the end of the convergence phase (no
             * residual error left in the stages); otherwise the raw sample is the measurement */
            const float h2 = va->x * va->x + va->y * va->y;
            *ready = va->z > 0.0f && h2 < ATT_EKF_SETTLED * (h2 + va->z * va->z);
            *lp1 = (*ready && !st->converging) ? att_i_vec3(0.0f, 0.0f, c->gravity) : *va;
            *lp2 = *lp1;
            st->lp_mean = false; /* restarted from a sample or the estimate: the start's mean is over */
        }
        att_ekf_lowpass(c, st, vv, lp1, lp2);
        vv = *lp2;
    }
    return vv;
}

/*
 * Update with the roll and pitch of the low-passed gravity, P in place (out of line: its frame is not
 * the prediction's); returns its flags: the measurement, the innovation, R, S^-1 and the gate, the
 * gain and covariance, the pure tilt correction, the commit. Not applied (no direction, det S not
 * usable, outside the gate): the prediction kept. An update whose result cannot be used is discarded
 * (ATT_FLAG_NUMERIC): the predicted angles and bias kept, P restarted (att_ekf_p_restart).
 */
static ATT_NOINLINE uint32_t att_ekf_update(const att_ekf_coeffs_t *c, att_ekf_state_t *st, att_vec3_t acc,
                                            const att_ekf_trig_t *tr)
{
    /* (|a| / g - 1)^2 for the noise growth (computed here: no float lives across the prediction) */
    const float er = c->need_norm ? att_ekf_norm_error(c, acc) : 0.0f;
    const float e2 = c->need_norm ? er * er : 0.0f;
    const float *p = st->p;
    const float sth = tr->sth;
    const float cth = tr->cth;
    float cg;
    float cw;
    float cx;
    float cy;
    float n;
    float ex;
    float ey;
    float y0;
    float y1;
    float sec;
    float fa;
    float r0;
    float r1;
    float pp;
    float dp;
    uint32_t cond = 0u;
    float t0;
    float t1;
    float det;
    float inv;
    float yb0;
    float yb1;
    float fb;
    bool ready;
    float i00;
    float i01;
    float i11;
    float d2;
    float fk = 1.0f;
    float db3[3];
    float *pn = st->p;
    att_vec3_t lp1 = st->lp1; /* the update's copies of the stages (turned below when on) */
    att_vec3_t lp2 = st->lp2;
    att_vec3_t vv;
    att_vec3_t va;
    att_vec3_t e;
    float epx; /* the correction's rotation in the heading frame, rad: x, y (its z is 0) */
    float epy;
    vv = att_ekf_measurement(c, st, acc, tr, &va, &lp1, &lp2, &ready);
    if (!att_i_align_up(vv, &cw, &cx, &cy, &n)) {
        return att_ekf_check(c, st); /* no direction: no update */
    }
    (void)cw;
    /* the tilt error e (heading frame) and the roll and pitch that remove it */
    ex = 2.0f * cx;
    ey = 2.0f * cy;
    cg = cth;
    if (att_i_absf(cg) < c->cos_min) {
        cg = (cg < 0.0f) ? -c->cos_min : c->cos_min;
    }
    sec = 1.0f / cg;
    y0 = ex * sec;
    y1 = ey;
    /* the same for the raw sample, to first order (e = (v_y, -v_x) / |v|): the bias states measure
     * against it (their gain averages over minutes; the lag of the stages would hide the bias) */
    {
        const float in = 1.0f / n;
        const float ax = va.y * in;
        const float ay = -(va.x * in);
        yb0 = ax * sec;
        yb1 = ay;
    }
    /* R: the tilt error has the same noise about both horizontal axes; its roll is (..) / cos(theta), so
     * the roll noise is r_phi / cos^2(theta) (roll is not observable at +-90 deg pitch) */
    fa = 1.0f + c->r_accel * e2;
    r1 = c->r_step[1] * fa;
    r0 = (c->r_step[0] * fa) * (sec * sec);
    /* a prior roll or pitch variance more than 2^12 times its measurement noise collapses by that factor
     * in this update, and the rounding of the bias rows (P - K H P) can leave P indefinite (F18: 1e6
     * against 2e-4 with a bias variance of 1e6): P conditioned after the update */
    if (P_(p, 0, 0) > ATT_EKF_COLLAPSE * r0 || P_(p, 1, 1) > ATT_EKF_COLLAPSE * r1) {
        cond = ATT_EKF_COND_NOW;
    }
    /* det S = det P2 + r1 P00 + r0 P11 + r0 r1 (P2 = P[0:2,0:2], det P2 >= 0): > 0 by construction.
     * det P2 within the pivot margin of singular (F12: P00 P11 - P01^2 not above 2^-12 P00 P11, a
     * correlation of roll and pitch beyond 1 - 2^-13 in magnitude, or not finite): P conditioned after
     * the update; only then can det P2 be below 0 (or NaN), taken as 0 (dp > 2^-12 P00 P11 >= 0 else).
     * float32 cannot carry such a block: a roll variance left at p_max (an initialisation at the gimbal,
     * roll unobservable there) feeds pitch through F's coupling until the correlation is within 1e-8 of
     * -1, and the rounding of the update makes P indefinite; the update cannot make it closer to
     * singular (det / (P00 P11) does not decrease in an update). */
    pp = P_(p, 0, 0) * P_(p, 1, 1);
    dp = pp - P_(p, 0, 1) * P_(p, 0, 1);
    if (!(dp > ATT_EKF_PIVOT_MIN * pp)) {
        cond = ATT_EKF_COND_NOW;
        dp = (dp > 0.0f) ? dp : 0.0f;
    }
    t0 = dp + r1 * P_(p, 0, 0);
    t1 = dp + r0 * P_(p, 1, 1);
    det = (t0 + r0 * P_(p, 1, 1)) + r0 * r1;
    if (!(det > 0.0f) || !att_i_isfinitef(det)) {
        return ATT_FLAG_NUMERIC | att_ekf_check(c, st); /* not applied: the prediction kept */
    }
    inv = 1.0f / det;
    i00 = (P_(p, 1, 1) + r1) * inv;
    i01 = -P_(p, 0, 1) * inv;
    i11 = (P_(p, 0, 0) + r0) * inv;
    d2 = y0 * (i00 * y0 + i01 * y1) + y1 * (i01 * y0 + i11 * y1);
    if (c->gate > 0.0f && st->rec_left == 0u) { /* the gate is off during a recovery */
        if (d2 > c->gate) {
            return ATT_FLAG_ACCEL_REJECTED | att_ekf_check(c, st); /* outside the gate: not applied */
        }
        if (d2 > c->soft) {
            fk = c->soft / d2; /* the innovation covariance inflated so that d^2 = gate / 4 */
        }
    }
    {
        const float db = yb0 * (i00 * yb0 + i01 * yb1) + yb1 * (i01 * yb0 + i11 * yb1);
        fb = (db > ATT_EKF_BIAS_SOFT) ? (ATT_EKF_BIAS_SOFT / db) * fk : fk;
    }
    {
        const att_ekf_innov_t v = {y0, y1, yb0, yb1, r0, r1, t0, t1, inv, i00, i01, i11, fk, fb};
        att_ekf_gain(st, &v, &e, db3);
    }
    /* The correction is a pure tilt rotation: the measurement carries no heading, so the change of the
     * angles must not turn the estimate about the vertical. A change (dphi, dtheta, dpsi) rotates the
     * heading frame by (cos(theta) dphi, dtheta, dpsi - sin(theta) dphi): yaw follows roll by
     * dpsi = sin(theta) dphi (its row of P is not carried: no gain of its own), and the rotation of the
     * correction in the heading frame, for the low-pass stages, is (cos(theta) dphi, dtheta, 0). */
    {
        const float dphi = e.x - st->euler.x;
        epx = dphi * cth;
        epy = e.y - st->euler.y;
        e.z = st->euler.z + sth * dphi;
    }
    (void)att_ekf_canon(&e, pn);
    if (!att_ekf_usable(e, pn)) {
        return att_ekf_p_restart(c, pn); /* update discarded: the predicted angles and bias kept */
    }
    att_ekf_commit(c, st, e, lp1, lp2, epx, epy, ready, db3);
    return cond;
}

/*
 * With the conditioning of P (every 16 steps, GIMBAL, large increments, steps without an applied update,
 * a near singular roll/pitch block): the bias estimate limited to +-gyro_range per axis
 * (ATT_FLAG_CLAMPED when that acts; NaN: bias_init). A gyro cannot read a bias beyond its range; a bias
 * variance far beyond any gyro's (a fuzzed q_bias) could push the estimate there (docs/robustness.md
 * F10). Off the normal step: at most 15 steps pass with such a bias.
 */
static ATT_NOINLINE uint32_t att_ekf_bias_limit(const att_ekf_coeffs_t *c, att_ekf_state_t *st)
{
    const float m = c->gyro_range;
    const att_vec3_t b = st->bias;
    att_vec3_t l;
    if ((att_i_absf(b.x) + att_i_absf(b.y)) + att_i_absf(b.z) <= m) {
        return 0u; /* the usual case (NaN fails the test) */
    }
    l = att_i_vec3(att_i_clampf(b.x, -m, m), att_i_clampf(b.y, -m, m), att_i_clampf(b.z, -m, m));
    if (!att_i_isfinitef((l.x + l.y) + l.z)) {
        l = c->bias_init;
    }
    st->bias = l;
    return (l.x != b.x || l.y != b.y || l.z != b.z) ? ATT_FLAG_CLAMPED : 0u;
}

/*
 * First valid accel sample: roll and pitch from it, yaw 0; the low-pass stages start from it (heading
 * frame: the sample turned by roll and pitch). After a step flagged NUMERIC (recover) the same from the
 * next usable sample, with the yaw kept and P restarted (p0, p0_bias): the failed step kept the state
 * from before it, which with a constant sample would fail again at every step (issue 26 R1), while the
 * attitude of the sample cannot (its innovation is zero).
 */
static ATT_NOINLINE void att_ekf_start(const att_ekf_coeffs_t *c, att_ekf_state_t *st, att_vec3_t acc)
{
    const att_vec3_t t = att_sensor_tilt(acc);
    const float yaw = st->recover ? st->euler.z : 0.0f;
    att_quat_t q;
    if (st->recover) {
        att_ekf_p_diag(st->p, c->p0, c->p0_bias);
        st->recover = false;
    }
    st->euler = att_i_vec3(att_wrap_pi(t.x), t.y, yaw); /* atan2 may give -pi */
    (void)att_i_quat_normalize_bounded(att_quat_from_euler(st->euler.x, st->euler.y, 0.0f), &q);
    st->lp1 = att_i_quat_rotate(q, acc);
    st->lp2 = st->lp1;
    st->lp_psi = yaw;
    st->lp_ready = true;
    st->converging = false;
    st->lp_mean = c->lp_on; /* the stages take the running mean of the samples since this one */
    st->rec_lp_n = 1u;
    st->initialised = true;
}

/* One step (out of line, as the prediction and the update below it: three frames, not one). */
static ATT_NOINLINE uint32_t att_ekf_update_step(att_ekf_t *f, att_vec3_t gyr, att_vec3_t acc)
{
    const att_ekf_coeffs_t *c;
    att_ekf_state_t *st;
    uint32_t flags;
    uint32_t accel_flags;
    float n2;
    bool gyro_ok;
    bool accel_ok;
    att_vec3_t w;
    att_vec3_t e0;
    att_ekf_trig_t tr;
    if (f == NULL) {
        return ATT_FLAG_BAD_ARG;
    }
    c = &f->c;
    st = &f->st;
    flags = att_i_sensor_check_gyro(gyr, c->gyro_range);
    gyro_ok = att_i_gyro_usable(gyr, c->gyro_range, flags);
    accel_flags = att_i_sensor_check_accel2(acc, c->accel_range2, &n2);
    accel_ok = (accel_flags == 0u);
    flags |= accel_flags;
    if (accel_ok && c->accel_reject > 0.0f && att_i_absf(att_ekf_norm_error(c, acc)) > c->accel_reject) {
        flags |= ATT_FLAG_ACCEL_REJECTED;
    }
    if (!st->initialised) {
        if (accel_ok) {
            att_ekf_start(c, st, acc);
            flags |= ATT_FLAG_INITIALISED;
        } else {
            flags |= ATT_FLAG_NOT_READY;
        }
        st->steps = st->steps + 1u;
        st->flags = flags;
        return flags;
    }
    (void)att_i_recovery_step(gyr, c->clip, c->rec_n, &st->rec_left, &st->rec_lp_n); /* step 3 */
    if (st->rec_left > 0u) {
        flags |= ATT_FLAG_INITIALISED;
        if (st->rec_left == c->rec_n) {
            st->head_known = false; /* a clipping sample: the yaw lost rotation too (the output's cov[2]) */
        }
    }
    if (!gyro_ok) {
        st->lp_ready = false; /* an unmeasured rotation: the stages (estimate's heading frame) are stale */
    }
    w = gyro_ok ? att_i_vec3_sub(gyr, st->bias) : att_i_vec3(0.0f, 0.0f, 0.0f);
    e0 = st->euler;
    flags |= att_ekf_predict(c, st, w, gyro_ok, &tr);
    if (accel_ok && (flags & (ATT_FLAG_ACCEL_REJECTED | ATT_FLAG_NUMERIC)) == 0u) {
        flags |= att_ekf_update(c, st, acc, &tr); /* tests the state it leaves (att_ekf_check) */
    } else {
        flags |= att_ekf_check(c, st);
    }
    if ((flags & ATT_FLAG_NUMERIC) != 0u) {
        /* NUMERIC: the attitude from before the step (P restarted if it was unusable); the next usable
         * accel sample re-initialises roll and pitch (att_ekf_start), not ready until then */
        st->euler = e0;
        st->initialised = false;
        st->recover = true;
        st->head_known = false; /* the rotation of this step and of the waiting ones is lost (cov[2]) */
    }
    if ((st->steps & ATT_EKF_COND_MASK) == 0u || (flags & (ATT_FLAG_GIMBAL | ATT_EKF_COND_NOW)) != 0u ||
        st->rec_left > 0u) {
        /* during a recovery (step 3) too: its process noise moves P fast, and with a large bias variance
         * the update's rounding can leave it indefinite (F17) */
        /* near gimbal lock F grows as 1 / cos(theta), after a large increment it is far from I, and a
         * near singular roll/pitch block cannot take rounding (F12), and without an update nothing bounds
         * P (att_ekf_check, F15): P is conditioned at once */
        /* the bias variances capped at gyro_range^2 too (a bias beyond the range is no estimate), never
         * below their start value p0_bias (a tiny range's square underflows) */
        const float r2 = c->gyro_range * c->gyro_range;
        const float rb = (r2 > c->p0_bias) ? r2 : c->p0_bias;
        flags = (flags & ~ATT_EKF_COND_NOW) | att_ekf_condition(st->p, c->p_max, (rb < c->p_max) ? rb : c->p_max) |
                att_ekf_bias_limit(c, st);
    }
    st->steps = st->steps + 1u;
    st->flags = flags;
    return flags;
}

uint32_t att_ekf_step_out(att_ekf_t *restrict f, const att_sample_t *restrict in, att_output_t *restrict out)
{
    const uint32_t flags = att_ekf_update_step(f, in->gyr, in->acc);
    if (out != NULL) {
        out->euler = f->st.euler;
        out->gyro_bias = f->st.bias;
        out->flags = flags;
        out->steps = f->st.steps;
        out->valid = ATT_OUT_EULER | ATT_OUT_BIAS;
    }
    return flags;
}

uint32_t att_ekf_step(att_ekf_t *f, att_vec3_t gyr, att_vec3_t acc)
{
    if (f == NULL) {
        return ATT_FLAG_BAD_ARG;
    }
    return att_ekf_update_step(f, gyr, acc);
}

/* --- hooks of the kind table (att_kinds.h) ------------------------------------------------- */

void att_ekf_preset(att_ekf_settings_t *s, att_preset_t preset, float dt)
{
    att_ekf_settings_default(s, dt);
    if (preset == ATT_PRESET_SEED) {
        s->q_phi = 0.0001f;
        s->q_theta = 0.0001f;
        s->q_psi = 0.1f;
        s->q_bias = 1e-12f; /* the notes' filter had no bias states: they stay at 0 */
        s->p0_bias = 1e-12f;
        s->r_phi = 6.0f;
        s->r_theta = 6.0f;
        s->r_accel = 0.0f;
        s->gate = 0.0f;
        s->accel_reject = 0.1f;
        s->tau_acc_lp = 0.0f;
        s->noise_rates = false;
        s->recovery_time = 0.0f;
    }
}

float att_ekf_period(const att_ekf_settings_t *s)
{
    return s->dt;
}

void att_ekf_output(const att_ekf_t *f, att_output_t *out)
{
    const float *p = f->st.p; /* packed upper triangle: the diagonal at 0, 6, 11, 15, 18, 20 */
    out->euler = f->st.euler; /* the state: q is derived on request */
    out->gyro_bias = f->st.bias;
    out->flags = f->st.flags;
    out->steps = f->st.steps;
    out->valid = ATT_OUT_EULER | ATT_OUT_BIAS;
    out->cov[0] = p[0]; /* phi, theta, psi; then the mean bias variance */
    out->cov[1] = p[6];
    out->cov[2] = (f->st.head_known && p[11] < ATT_COV_UNKNOWN) ? p[11] : ATT_COV_UNKNOWN; /* yaw: unobserved */
    out->cov[3] = ((p[15] + p[18]) + p[20]) * 0x1.555556p-2f;
}

att_heading_t att_ekf_heading_kind(const att_ekf_t *f)
{
    (void)f;
    return ATT_HEADING_UPDATE;
}

att_status_t att_ekf_yaw_to(att_ekf_t *f, float target, float gain)
{
    float d;
    float s;
    float c;
    const float yaw = f->st.euler.z;
    if (!f->st.initialised) {
        return ATT_ERR_STATE;
    }
    if (!att_yaw_turn(yaw, target, gain, &d, &s, &c)) {
        return ATT_ERR_STATE; /* a yaw outside the wrap domain */
    }
    f->st.lp1 = att_i_yaw_vec(f->st.lp1, c, s);
    f->st.lp2 = att_i_yaw_vec(f->st.lp2, c, s);
    f->st.euler.z = (gain == 1.0f) ? target : att_wrap_pi(yaw + d);
    if (gain == 1.0f) {
        f->st.p[11] = f->c.q_step[2]; /* a set heading: exact, one step's noise (> 0: P's test), cov[2] */
        f->st.head_known = true;
    }
    return ATT_OK;
}

bool att_ekf_set_gain(att_ekf_settings_t *s, att_gain_t gain, float value)
{
    if (gain != ATT_GAIN_EKF_R) {
        return false;
    }
    s->r_phi = value;
    s->r_theta = value;
    return true;
}
