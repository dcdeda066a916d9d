/**
 * @file att_kf.c
 * @brief Linear quaternion Kalman filter (see att_kf.h). Mirrored by host/attica/reference/kf.py.
 *
 * Every matrix product is written as one fixed-order loop: s = a[i][0] * b[0][j], then
 * s = s + a[i][k] * b[k][j] for k = 1, 2, 3 (the sum starts from the first product, not from 0).
 */
#include "att_fp.h"

#include "att_core.h"
#include "attica/att_kf.h"
#include "attica/att_math.h"
#include "attica/att_sensor.h"

#define ATT_KF_NOISE_MIN 0x1.19799800p-40f /* 1e-12 */
#define ATT_KF_NOISE_MAX 0x1.d1a94a00p+39f /* 1e12 */

void att_kf_settings_default(att_kf_settings_t *settings, float dt)
{
    if (settings == NULL) {
        return;
    }
    settings->dt = dt;
    settings->q_noise = 1e-3f;
    settings->r_noise = 0.1f;
    settings->p0 = 1.0f;
    settings->gravity = 9.80665f;
    settings->accel_reject = 0.1f;
    settings->accel_range = 156.9064f; /* 16 g */
    settings->gyro_range = 34.906586f; /* 2000 deg/s */
    settings->yaw_mode = ATT_KF_YAW_STATE;
    settings->init_from_accel = true;
    settings->q_init = att_quat_identity();
    settings->noise_rates = true;
}

static bool att_kf_noise_valid(float v)
{
    return v >= ATT_KF_NOISE_MIN && v <= ATT_KF_NOISE_MAX; /* false for NaN */
}

att_status_t att_kf_settings_validate(const att_kf_settings_t *s)
{
    bool ok;
    if (s == NULL) {
        return ATT_ERR_NULL;
    }
    ok = att_i_in(s->dt, ATT_DT_MIN, ATT_DT_MAX) && att_i_in(s->gravity, ATT_GRAVITY_MIN, ATT_GRAVITY_MAX) &&
         att_i_in(s->accel_reject, 0.0f, ATT_REJECT_MAX) && s->accel_range > s->gravity &&
         s->accel_range <= ATT_ACCEL_RANGE_MAX && s->gyro_range > 0.0f && s->gyro_range <= ATT_GYRO_RANGE_MAX &&
         att_kf_noise_valid(s->q_noise) && att_kf_noise_valid(s->r_noise) && att_kf_noise_valid(s->p0) &&
         (s->yaw_mode == ATT_KF_YAW_STATE || s->yaw_mode == ATT_KF_YAW_ZERO) &&
         att_i_bool_ok(&s->init_from_accel) && att_i_bool_ok(&s->noise_rates) && att_i_quat_init_ok(s->q_init);
    if (ok && s->noise_rates) {
        ok = att_kf_noise_valid(s->q_noise * s->dt) && att_kf_noise_valid(s->r_noise / s->dt);
    }
    return ok ? ATT_OK : ATT_ERR_SETTINGS;
}

static void att_kf_coeffs(att_kf_t *f, const att_kf_settings_t *settings)
{
    f->s = *settings;
    f->q_step = settings->noise_rates ? settings->q_noise * settings->dt : settings->q_noise;
    f->r_step = settings->noise_rates ? settings->r_noise / settings->dt : settings->r_noise;
}

att_status_t att_kf_init(att_kf_t *f, const att_kf_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_kf_settings_validate(settings);
    if (st != ATT_OK) {
        return st;
    }
    att_kf_coeffs(f, settings);
    att_kf_reset(f);
    return ATT_OK;
}

att_status_t att_kf_retune(att_kf_t *f, const att_kf_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_kf_settings_validate(settings);
    if (st == ATT_OK) {
        att_kf_coeffs(f, settings);
    }
    return st;
}

void att_kf_reset(att_kf_t *f)
{
    int i;
    int j;
    if (f == NULL) {
        return;
    }
    (void)att_quat_normalize(f->s.q_init, &f->q);
    for (i = 0; i < 4; ++i) {
        for (j = 0; j < 4; ++j) {
            f->p[i][j] = (i == j) ? f->s.p0 : 0.0f;
        }
    }
    f->initialised = !f->s.init_from_accel;
    f->steps = 0u;
    f->flags = 0u;
}

/* out = a * b */
static void att_kf_mul(float a[4][4], float b[4][4], float out[4][4])
{
    int i;
    int j;
    int k;
    for (i = 0; i < 4; ++i) {
        for (j = 0; j < 4; ++j) {
            float s = a[i][0] * b[0][j];
            for (k = 1; k < 4; ++k) {
                s = s + a[i][k] * b[k][j];
            }
            out[i][j] = s;
        }
    }
}

/* out = a * b^T */
static void att_kf_mul_bt(float a[4][4], float b[4][4], float out[4][4])
{
    int i;
    int j;
    int k;
    for (i = 0; i < 4; ++i) {
        for (j = 0; j < 4; ++j) {
            float s = a[i][0] * b[j][0];
            for (k = 1; k < 4; ++k) {
                s = s + a[i][k] * b[j][k];
            }
            out[i][j] = s;
        }
    }
}

/* out = (m + m^T) / 2, elementwise; bitwise symmetric because + commutes. */
static void att_kf_symmetrise(float m[4][4], float out[4][4])
{
    int i;
    int j;
    for (i = 0; i < 4; ++i) {
        for (j = 0; j < 4; ++j) {
            out[i][j] = (m[i][j] + m[j][i]) * 0.5f;
        }
    }
}

static bool att_kf_all_finite(const float x[4], float p[4][4])
{
    int i;
    int j;
    bool ok = true;
    for (i = 0; i < 4; ++i) {
        ok = ok && att_isfinitef(x[i]);
        for (j = 0; j < 4; ++j) {
            ok = ok && att_isfinitef(p[i][j]);
        }
    }
    return ok;
}

/* x := A x, P := sym(A P A^T + Q) with A = I + dt/2 Omega(w). */
static void att_kf_predict(const att_kf_t *f, att_vec3_t gyr, float x[4], float p[4][4])
{
    const float h = f->s.dt * 0.5f;
    const float hp = h * gyr.x;
    const float hq = h * gyr.y;
    const float hr = h * gyr.z;
    float a[4][4];
    float t[4][4];
    float u[4][4];
    float xn[4];
    int i;
    int k;
    a[0][0] = 1.0f;
    a[0][1] = -hp;
    a[0][2] = -hq;
    a[0][3] = -hr;
    a[1][0] = hp;
    a[1][1] = 1.0f;
    a[1][2] = hr;
    a[1][3] = -hq;
    a[2][0] = hq;
    a[2][1] = -hr;
    a[2][2] = 1.0f;
    a[2][3] = hp;
    a[3][0] = hr;
    a[3][1] = hq;
    a[3][2] = -hp;
    a[3][3] = 1.0f;
    for (i = 0; i < 4; ++i) {
        float s = a[i][0] * x[0];
        for (k = 1; k < 4; ++k) {
            s = s + a[i][k] * x[k];
        }
        xn[i] = s;
    }
    for (i = 0; i < 4; ++i) {
        x[i] = xn[i];
    }
    att_kf_mul(a, p, t);
    att_kf_mul_bt(t, a, u);
    for (i = 0; i < 4; ++i) {
        u[i][i] = u[i][i] + f->q_step;
    }
    att_kf_symmetrise(u, p);
}

/*
 * Measurement update with H = I. Returns false (x, p untouched) when the Cholesky factorisation of
 * S = P + R fails or the result is not finite.
 */
static bool att_kf_update(const att_kf_t *f, const float z[4], float x[4], float p[4][4])
{
    const float r = f->r_step;
    float l[4][4];
    float k[4][4];
    float m[4][4];
    float t[4][4];
    float u[4][4];
    float kk[4][4];
    float y[4];
    float w[4];
    float e[4];
    float xn[4];
    float pn[4][4];
    int i;
    int j;
    int c;
    int n;

    /* Cholesky S = L L^T, S = P + r I (lower triangle of L only) */
    for (j = 0; j < 4; ++j) {
        float d = p[j][j] + r;
        for (n = 0; n < j; ++n) {
            d = d - l[j][n] * l[j][n];
        }
        if (!(d > 0.0f) || !att_isfinitef(d)) {
            return false;
        }
        l[j][j] = att_sqrtf(d);
        for (i = j + 1; i < 4; ++i) {
            float v = p[i][j];
            for (n = 0; n < j; ++n) {
                v = v - l[i][n] * l[j][n];
            }
            l[i][j] = v / l[j][j];
        }
    }

    /* K = P S^-1: row c of K is S^-1 (column c of P), as S and P are symmetric */
    for (c = 0; c < 4; ++c) {
        for (i = 0; i < 4; ++i) {
            float v = p[i][c];
            for (n = 0; n < i; ++n) {
                v = v - l[i][n] * y[n];
            }
            y[i] = v / l[i][i];
        }
        for (i = 3; i >= 0; --i) {
            float v = y[i];
            for (n = i + 1; n < 4; ++n) {
                v = v - l[n][i] * w[n];
            }
            w[i] = v / l[i][i];
        }
        for (i = 0; i < 4; ++i) {
            k[c][i] = w[i];
        }
    }

    /* x := x + K (z - x) */
    for (i = 0; i < 4; ++i) {
        e[i] = z[i] - x[i];
    }
    for (i = 0; i < 4; ++i) {
        float s = k[i][0] * e[0];
        for (n = 1; n < 4; ++n) {
            s = s + k[i][n] * e[n];
        }
        xn[i] = x[i] + s;
    }

    /* Joseph form P := (I - K) P (I - K)^T + r K K^T, symmetrised */
    for (i = 0; i < 4; ++i) {
        for (j = 0; j < 4; ++j) {
            m[i][j] = (i == j) ? 1.0f - k[i][j] : -k[i][j];
        }
    }
    att_kf_mul(m, p, t);
    att_kf_mul_bt(t, m, u);
    att_kf_mul_bt(k, k, kk);
    for (i = 0; i < 4; ++i) {
        for (j = 0; j < 4; ++j) {
            u[i][j] = u[i][j] + r * kk[i][j];
        }
    }
    att_kf_symmetrise(u, pn);

    if (!att_kf_all_finite(xn, pn)) {
        return false;
    }
    for (i = 0; i < 4; ++i) {
        x[i] = xn[i];
        for (j = 0; j < 4; ++j) {
            p[i][j] = pn[i][j];
        }
    }
    return true;
}

/* Measurement quaternion from the accelerometer tilt and the yaw of the predicted state x. */
static void att_kf_measurement(const att_kf_t *f, att_vec3_t acc, const float x[4], float z[4])
{
    att_quat_t xq;
    att_quat_t xu;
    att_quat_t zq;
    att_vec3_t t;
    float psi = 0.0f;
    float dot;
    xq.w = x[0];
    xq.x = x[1];
    xq.y = x[2];
    xq.z = x[3];
    if (f->s.yaw_mode == ATT_KF_YAW_STATE) {
        (void)att_quat_normalize(xq, &xu); /* identity (yaw 0) if it fails */
        psi = att_quat_to_euler(xu).z;
    }
    t = att_sensor_tilt(acc);
    zq = att_quat_from_euler(t.x, t.y, psi);
    dot = zq.w * x[0] + zq.x * x[1] + zq.y * x[2] + zq.z * x[3];
    if (dot < 0.0f) {
        zq.w = -zq.w;
        zq.x = -zq.x;
        zq.y = -zq.y;
        zq.z = -zq.z;
    }
    z[0] = zq.w;
    z[1] = zq.x;
    z[2] = zq.y;
    z[3] = zq.z;
}

uint32_t att_kf_step(att_kf_t *f, att_vec3_t gyr, att_vec3_t acc)
{
    uint32_t flags;
    uint32_t accel_flags;
    float norm;
    float e;
    float n2;
    bool gyro_ok;
    bool accel_ok;
    bool ok;
    float x[4];
    float z[4];
    float p[4][4];
    att_quat_t xq;
    att_quat_t qn;
    int i;
    int j;
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
            f->q = att_quat_from_euler(t.x, t.y, 0.0f);
            (void)att_quat_normalize(f->q, &f->q);
            f->initialised = true;
            flags |= ATT_FLAG_INITIALISED;
        } else {
            flags |= ATT_FLAG_NOT_READY;
        }
        f->steps = f->steps + 1u;
        f->flags = flags;
        return flags;
    }

    x[0] = f->q.w;
    x[1] = f->q.x;
    x[2] = f->q.y;
    x[3] = f->q.z;
    for (i = 0; i < 4; ++i) {
        for (j = 0; j < 4; ++j) {
            p[i][j] = f->p[i][j];
        }
    }

    /* prediction; an unusable gyro sample leaves x as it is but still adds Q */
    if (gyro_ok) {
        att_kf_predict(f, gyr, x, p);
    } else {
        for (i = 0; i < 4; ++i) {
            p[i][i] = p[i][i] + f->q_step;
        }
    }

    /* measurement update */
    if (accel_ok && (flags & ATT_FLAG_ACCEL_REJECTED) == 0u) {
        att_kf_measurement(f, acc, x, z);
        if (!att_kf_update(f, z, x, p)) {
            flags |= ATT_FLAG_NUMERIC; /* predicted x and P kept */
        }
    }

    /* normalisation x := x / |x|, P := P / |x|^2 */
    xq.w = x[0];
    xq.x = x[1];
    xq.y = x[2];
    xq.z = x[3];
    n2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3];
    ok = att_quat_normalize(xq, &qn);
    for (i = 0; i < 4; ++i) {
        for (j = 0; j < 4; ++j) {
            p[i][j] = p[i][j] / n2;
        }
    }
    x[0] = qn.w;
    x[1] = qn.x;
    x[2] = qn.y;
    x[3] = qn.z;
    if (ok && att_kf_all_finite(x, p)) {
        f->q = qn;
        for (i = 0; i < 4; ++i) {
            for (j = 0; j < 4; ++j) {
                f->p[i][j] = p[i][j];
            }
        }
    } else {
        flags |= ATT_FLAG_NUMERIC; /* keep the state from before the step */
    }
    f->steps = f->steps + 1u;
    f->flags = flags;
    return flags;
}
