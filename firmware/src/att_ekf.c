/**
 * @file att_ekf.c
 * @brief Euler-angle extended Kalman filter (see att_ekf.h). Mirrored by host/attica/reference/ekf.py.
 */
#include "att_fp.h"

#include "att_core.h"
#include "attica/att_ekf.h"
#include "attica/att_math.h"
#include "attica/att_sensor.h"

#define ATT_EKF_PI_F 0x1.921fb6p+1f
#define ATT_EKF_PIO2_F 0x1.921fb6p+0f
#define ATT_EKF_VAR_MAX 1000000.0f  /* upper limit of every variance setting, rad^2 */
#define ATT_EKF_PMAX_MIN 0.000001f  /* lower limit of p_max, rad^2 */
#define ATT_EKF_PIVOT_MIN 0x1p-12f  /* relative pivot margin of the positive definiteness test */
#define ATT_EKF_SHRINK 0x1.ff8p-1f  /* 1 - 2^-10: correlation shrink factor of the repair */

void att_ekf_settings_default(att_ekf_settings_t *settings, float dt)
{
    if (settings == NULL) {
        return;
    }
    settings->dt = dt;
    settings->q_phi = 0.03f;
    settings->q_theta = 0.03f;
    settings->q_psi = 1.0f;
    settings->r_phi = 3.0f;
    settings->r_theta = 3.0f;
    settings->p0 = 1.0f;
    settings->p_max = 1000000.0f;
    settings->gravity = 9.80665f;
    settings->accel_reject = 0.1f;
    settings->accel_range = 156.9064f; /* 16 g */
    settings->gyro_range = 34.906586f; /* 2000 deg/s */
    settings->cos_min = 0.001f;
    settings->init_from_accel = true;
    settings->euler_init.x = 0.0f;
    settings->euler_init.y = 0.0f;
    settings->euler_init.z = 0.0f;
    settings->noise_rates = true;
}

static bool att_ekf_var_ok(float v, bool zero_ok)
{
    return (zero_ok ? (v >= 0.0f) : (v > 0.0f)) && v <= ATT_EKF_VAR_MAX;
}

att_status_t att_ekf_settings_validate(const att_ekf_settings_t *s)
{
    bool ok;
    if (s == NULL) {
        return ATT_ERR_NULL;
    }
    /* NaN fails every comparison below */
    ok = att_i_in(s->dt, ATT_DT_MIN, ATT_DT_MAX) && att_ekf_var_ok(s->q_phi, true) &&
         att_ekf_var_ok(s->q_theta, true) && att_ekf_var_ok(s->q_psi, true) && att_ekf_var_ok(s->r_phi, false) &&
         att_ekf_var_ok(s->r_theta, false) && att_ekf_var_ok(s->p_max, false) && s->p_max >= ATT_EKF_PMAX_MIN &&
         s->p0 >= ATT_EKF_PMAX_MIN && s->p0 <= s->p_max && att_i_in(s->gravity, ATT_GRAVITY_MIN, ATT_GRAVITY_MAX) &&
         att_i_in(s->accel_reject, 0.0f, ATT_REJECT_MAX) && s->accel_range > s->gravity &&
         s->accel_range <= ATT_ACCEL_RANGE_MAX && s->gyro_range > 0.0f && s->gyro_range <= ATT_GYRO_RANGE_MAX &&
         s->cos_min > 0.0f && s->cos_min < 1.0f && att_i_bool_ok(&s->init_from_accel) &&
         att_i_bool_ok(&s->noise_rates) && att_i_in(s->euler_init.y, -ATT_EKF_PIO2_F, ATT_EKF_PIO2_F) &&
         att_i_in(s->euler_init.x, -8192.0f, 8192.0f) && att_i_in(s->euler_init.z, -8192.0f, 8192.0f);
    if (ok && s->noise_rates) {
        ok = att_ekf_var_ok(s->q_phi * s->dt, true) && att_ekf_var_ok(s->q_theta * s->dt, true) &&
             att_ekf_var_ok(s->q_psi * s->dt, true) && att_ekf_var_ok(s->r_phi / s->dt, false) &&
             att_ekf_var_ok(s->r_theta / s->dt, false) && s->r_phi / s->dt >= ATT_EKF_PMAX_MIN &&
             s->r_theta / s->dt >= ATT_EKF_PMAX_MIN;
    }
    return ok ? ATT_OK : ATT_ERR_SETTINGS;
}

static void att_ekf_coeffs(att_ekf_t *f, const att_ekf_settings_t *settings)
{
    f->s = *settings;
    if (settings->noise_rates) {
        f->q_step[0] = settings->q_phi * settings->dt;
        f->q_step[1] = settings->q_theta * settings->dt;
        f->q_step[2] = settings->q_psi * settings->dt;
        f->r_step[0] = settings->r_phi / settings->dt;
        f->r_step[1] = settings->r_theta / settings->dt;
    } else {
        f->q_step[0] = settings->q_phi;
        f->q_step[1] = settings->q_theta;
        f->q_step[2] = settings->q_psi;
        f->r_step[0] = settings->r_phi;
        f->r_step[1] = settings->r_theta;
    }
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
    att_ekf_coeffs(f, settings);
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
        att_ekf_coeffs(f, settings);
    }
    return st;
}

static void att_ekf_p_diag(float P[3][3], float v)
{
    int i;
    int j;
    for (i = 0; i < 3; i++) {
        for (j = 0; j < 3; j++) {
            P[i][j] = (i == j) ? v : 0.0f;
        }
    }
}

static void att_ekf_p_copy(float dst[3][3], float src[3][3])
{
    int i;
    int j;
    for (i = 0; i < 3; i++) {
        for (j = 0; j < 3; j++) {
            dst[i][j] = src[i][j];
        }
    }
}

static bool att_ekf_p_finite(float P[3][3])
{
    int i;
    int j;
    for (i = 0; i < 3; i++) {
        for (j = 0; j < 3; j++) {
            if (!att_isfinitef(P[i][j])) {
                return false;
            }
        }
    }
    return true;
}

void att_ekf_reset(att_ekf_t *f)
{
    if (f == NULL) {
        return;
    }
    f->euler.x = att_wrap_pi(f->s.euler_init.x);
    f->euler.y = f->s.euler_init.y;
    f->euler.z = att_wrap_pi(f->s.euler_init.z);
    f->q = att_quat_from_euler(f->euler.x, f->euler.y, f->euler.z);
    att_ekf_p_diag(f->p, f->s.p0);
    f->initialised = !f->s.init_from_accel;
    f->steps = 0u;
    f->flags = 0u;
}

/*
 * Canonical Euler angles: theta wrapped to (-pi, pi] and, when beyond +-pi/2, mapped to the same
 * attitude (phi + pi, +-pi - theta, psi + pi); d(theta_new)/d(theta) = -1 flips the sign of P's
 * theta row and column. Then phi and psi are wrapped to (-pi, pi].
 */
static void att_ekf_canon(att_vec3_t *e, float P[3][3])
{
    bool flip = false;
    e->y = att_wrap_pi(e->y);
    if (e->y > ATT_EKF_PIO2_F) {
        e->y = ATT_EKF_PI_F - e->y;
        flip = true;
    } else if (e->y < -ATT_EKF_PIO2_F) {
        e->y = -ATT_EKF_PI_F - e->y;
        flip = true;
    }
    if (flip) {
        e->x = e->x + ATT_EKF_PI_F;
        e->z = e->z + ATT_EKF_PI_F;
        P[0][1] = -P[0][1];
        P[1][0] = -P[1][0];
        P[1][2] = -P[1][2];
        P[2][1] = -P[2][1];
    }
    e->x = att_wrap_pi(e->x);
    e->z = att_wrap_pi(e->z);
}

/* T = a b (3x3), each element ((a_i0 b_0j + a_i1 b_1j) + a_i2 b_2j). */
static void att_ekf_mul(float a[3][3], float b[3][3], float t[3][3])
{
    int i;
    int j;
    for (i = 0; i < 3; i++) {
        for (j = 0; j < 3; j++) {
            t[i][j] = (a[i][0] * b[0][j] + a[i][1] * b[1][j]) + a[i][2] * b[2][j];
        }
    }
}

/* Upper triangle of t m^T (j >= i), ((t_i0 m_j0 + t_i1 m_j1) + t_i2 m_j2), mirrored to the lower. */
static void att_ekf_mul_t_sym(float t[3][3], float m[3][3], float out[3][3])
{
    int i;
    int j;
    for (i = 0; i < 3; i++) {
        for (j = i; j < 3; j++) {
            out[i][j] = (t[i][0] * m[j][0] + t[i][1] * m[j][1]) + t[i][2] * m[j][2];
            out[j][i] = out[i][j];
        }
    }
}

/* Cap each variance at p_max by the congruence D P D, d_i = sqrt(p_max / P_ii) where P_ii > p_max. */
static bool att_ekf_cap(float P[3][3], float p_max)
{
    float d[3];
    bool capped = false;
    int i;
    int j;
    for (i = 0; i < 3; i++) {
        d[i] = 1.0f;
        if (P[i][i] > p_max) {
            d[i] = att_sqrtf(p_max / P[i][i]);
            capped = true;
        }
    }
    if (capped) {
        for (i = 0; i < 3; i++) {
            for (j = i; j < 3; j++) {
                P[i][j] = (P[i][j] * d[i]) * d[j];
                P[j][i] = P[i][j];
            }
        }
    }
    return capped;
}

/*
 * Positive definite with margin: the pivots of P = L D L^T satisfy d_0 > 0 and d_i > ATT_EKF_PIVOT_MIN
 * P_ii (i = 1, 2), i.e. no angle is almost a linear function of the angles before it.
 */
static bool att_ekf_pd_ok(float P[3][3])
{
    const float d0 = P[0][0];
    const float l10 = P[1][0] / d0;
    const float d1 = P[1][1] - l10 * P[1][0];
    const float l20 = P[2][0] / d0;
    const float e21 = P[2][1] - l20 * P[1][0];
    const float l21 = e21 / d1;
    const float d2 = (P[2][2] - l20 * P[2][0]) - l21 * e21;
    return d0 > 0.0f && d1 > ATT_EKF_PIVOT_MIN * P[1][1] && d2 > ATT_EKF_PIVOT_MIN * P[2][2];
}

/* Off-diagonal elements times s. */
static void att_ekf_shrink(float P[3][3], float s)
{
    P[0][1] = P[0][1] * s;
    P[1][0] = P[0][1];
    P[0][2] = P[0][2] * s;
    P[2][0] = P[0][2];
    P[1][2] = P[1][2] * s;
    P[2][1] = P[1][2];
}

/*
 * Keep P usable: not finite or a variance not > 0 gives ATT_FLAG_NUMERIC (the caller discards the
 * stage). Otherwise variances above p_max are capped, and when P is not positive definite with
 * margin the correlations are shrunk by the factor ATT_EKF_SHRINK, or dropped when that is not
 * enough (ATT_FLAG_CLAMPED).
 */
static uint32_t att_ekf_condition(float P[3][3], float p_max)
{
    uint32_t flags = 0u;
    if (!att_ekf_p_finite(P) || !(P[0][0] > 0.0f) || !(P[1][1] > 0.0f) || !(P[2][2] > 0.0f)) {
        return ATT_FLAG_NUMERIC;
    }
    if (att_ekf_cap(P, p_max)) {
        flags |= ATT_FLAG_CLAMPED;
    }
    if (!att_ekf_pd_ok(P)) {
        flags |= ATT_FLAG_CLAMPED;
        att_ekf_shrink(P, ATT_EKF_SHRINK);
        if (!att_ekf_pd_ok(P)) {
            att_ekf_shrink(P, 0.0f);
        }
    }
    return flags;
}

/* Prediction x := x + dt E w, P := A P A^T + Q (A at the state before). Returns flags. */
static uint32_t att_ekf_predict(att_ekf_t *f, att_vec3_t w, bool gyro_ok)
{
    const float dt = f->s.dt;
    const float sphi = att_sinf(f->euler.x);
    const float cphi = att_cosf(f->euler.x);
    const float sth = att_sinf(f->euler.y);
    float cth = att_cosf(f->euler.y);
    float tth;
    float sec;
    float u;
    float v;
    float a[3][3];
    float t[3][3];
    float pp[3][3];
    att_vec3_t e;
    uint32_t cond;
    uint32_t flags = 0u;
    if (att_absf(cth) < f->s.cos_min) {
        cth = (cth < 0.0f) ? -f->s.cos_min : f->s.cos_min;
        if (gyro_ok) {
            flags |= ATT_FLAG_GIMBAL;
        }
    }
    tth = sth / cth;
    sec = 1.0f / cth;
    e.x = f->euler.x + (w.x + sphi * tth * w.y + cphi * tth * w.z) * dt;
    e.y = f->euler.y + (cphi * w.y - sphi * w.z) * dt;
    e.z = f->euler.z + (sphi / cth * w.y + cphi / cth * w.z) * dt;
    u = sphi * w.y + cphi * w.z;
    v = cphi * w.y - sphi * w.z;
    a[0][0] = 1.0f + dt * (v * tth);
    a[0][1] = dt * (u * sec * sec);
    a[0][2] = 0.0f;
    a[1][0] = -(dt * u);
    a[1][1] = 1.0f;
    a[1][2] = 0.0f;
    a[2][0] = dt * (v * sec);
    a[2][1] = dt * (u * sec * tth);
    a[2][2] = 1.0f;
    att_ekf_mul(a, f->p, t);
    att_ekf_mul_t_sym(t, a, pp);
    pp[0][0] = pp[0][0] + f->q_step[0];
    pp[1][1] = pp[1][1] + f->q_step[1];
    pp[2][2] = pp[2][2] + f->q_step[2];
    att_ekf_canon(&e, pp);
    cond = att_ekf_condition(pp, f->s.p_max);
    if (!att_vec3_isfinite(e) || (cond & ATT_FLAG_NUMERIC) != 0u) {
        return flags | ATT_FLAG_NUMERIC; /* prediction discarded */
    }
    flags |= cond;
    f->euler = e;
    att_ekf_p_copy(f->p, pp);
    return flags;
}

/* Update with z = accel tilt, H = [I2 0]; Joseph form. Returns flags. */
static uint32_t att_ekf_update(att_ekf_t *f, att_vec3_t acc)
{
    const att_vec3_t z = att_sensor_tilt(acc);
    const float y0 = att_wrap_pi(z.x - f->euler.x);
    const float y1 = att_wrap_pi(z.y - f->euler.y);
    const float s00 = f->p[0][0] + f->r_step[0];
    const float s01 = f->p[0][1];
    const float s11 = f->p[1][1] + f->r_step[1];
    const float det = s00 * s11 - s01 * s01;
    float i00;
    float i01;
    float i11;
    float k[3][2];
    float m[3][3];
    float t[3][3];
    float pn[3][3];
    att_vec3_t e;
    uint32_t cond;
    int i;
    int j;
    if (!(det > 0.0f) || !att_isfinitef(det)) {
        return ATT_FLAG_NUMERIC;
    }
    i00 = s11 / det;
    i01 = -s01 / det;
    i11 = s00 / det;
    for (i = 0; i < 3; i++) {
        k[i][0] = f->p[i][0] * i00 + f->p[i][1] * i01;
        k[i][1] = f->p[i][0] * i01 + f->p[i][1] * i11;
    }
    e.x = f->euler.x + (k[0][0] * y0 + k[0][1] * y1);
    e.y = f->euler.y + (k[1][0] * y0 + k[1][1] * y1);
    e.z = f->euler.z + (k[2][0] * y0 + k[2][1] * y1);
    /* M = I - K H */
    for (i = 0; i < 3; i++) {
        m[i][0] = ((i == 0) ? 1.0f : 0.0f) - k[i][0];
        m[i][1] = ((i == 1) ? 1.0f : 0.0f) - k[i][1];
        m[i][2] = (i == 2) ? 1.0f : 0.0f;
    }
    att_ekf_mul(m, f->p, t);
    att_ekf_mul_t_sym(t, m, pn);
    /* + K R K^T */
    for (i = 0; i < 3; i++) {
        for (j = i; j < 3; j++) {
            pn[i][j] = pn[i][j] + ((k[i][0] * f->r_step[0]) * k[j][0] + (k[i][1] * f->r_step[1]) * k[j][1]);
            pn[j][i] = pn[i][j];
        }
    }
    att_ekf_canon(&e, pn);
    cond = att_ekf_condition(pn, f->s.p_max);
    if (!att_vec3_isfinite(e) || (cond & ATT_FLAG_NUMERIC) != 0u) {
        return ATT_FLAG_NUMERIC; /* update discarded */
    }
    f->euler = e;
    att_ekf_p_copy(f->p, pn);
    return cond;
}

uint32_t att_ekf_step(att_ekf_t *f, att_vec3_t gyr, att_vec3_t acc)
{
    uint32_t flags;
    uint32_t accel_flags;
    float norm;
    float e;
    bool gyro_ok;
    bool accel_ok;
    att_vec3_t w;
    if (f == NULL) {
        return ATT_FLAG_BAD_ARG;
    }
    flags = att_sensor_check_gyro(gyr, f->s.gyro_range);
    gyro_ok = (flags == 0u);
    accel_flags = att_sensor_check_accel(acc, f->s.accel_range, &norm);
    accel_ok = (accel_flags == 0u);
    flags |= accel_flags;
    e = norm / f->s.gravity - 1.0f;
    if (accel_ok && f->s.accel_reject > 0.0f && att_absf(e) > f->s.accel_reject) {
        flags |= ATT_FLAG_ACCEL_REJECTED;
    }

    if (!f->initialised) {
        if (accel_ok) {
            const att_vec3_t t = att_sensor_tilt(acc);
            f->euler.x = att_wrap_pi(t.x); /* atan2 may give -pi */
            f->euler.y = t.y;
            f->euler.z = 0.0f;
            f->q = att_quat_from_euler(f->euler.x, f->euler.y, 0.0f);
            f->initialised = true;
            flags |= ATT_FLAG_INITIALISED;
        } else {
            flags |= ATT_FLAG_NOT_READY;
        }
        f->steps = f->steps + 1u;
        f->flags = flags;
        return flags;
    }

    if (gyro_ok) {
        w = gyr;
    } else {
        w.x = 0.0f; /* time passes without rate information: state kept, P := P + Q */
        w.y = 0.0f;
        w.z = 0.0f;
    }
    flags |= att_ekf_predict(f, w, gyro_ok);
    if (accel_ok && (flags & ATT_FLAG_ACCEL_REJECTED) == 0u) {
        flags |= att_ekf_update(f, acc);
    }
    f->q = att_quat_from_euler(f->euler.x, f->euler.y, f->euler.z);
    f->steps = f->steps + 1u;
    f->flags = flags;
    return flags;
}
