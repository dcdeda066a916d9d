/**
 * @file att_calib.c
 * @brief Input and output stages (see att_calib.h). Mirrored by host/attica/reference/calib.py.
 */
#include "../math/att_fp.h"

#include "att_calib_i.h"
#include "../core/att_core.h"
#include "../math/att_inline.h"
#include "attica/att_calib.h"
#include "attica/att_math.h"

#define ATT_CALIB_HALF_SQRT2 0x1.6a09e6p-1f /* 1/sqrt(2) rounded to float */
#define ATT_CALIB_ENTRY_MAX 1000.0f         /* |matrix entry|, |sensitivity| */
#define ATT_CALIB_GYRO_OFFSET_MAX 1000.0f   /* rad/s */
#define ATT_CALIB_ACCEL_OFFSET_MAX 10000.0f /* m/s^2 */
#define ATT_CALIB_MAG_OFFSET_MAX 100000.0f  /* uT */
#define ATT_CALIB_COND_MAX 3100.0f          /* Frobenius condition number ||A|| ||A^-1|| */
#define ATT_CALIB_DET_MIN 0x1p-60f          /* |det| below this: singular */
#define ATT_CALIB_Q2_LO 0.997f
#define ATT_CALIB_Q2_HI 1.003f

/* The 24 proper axis remaps: name i + 1 means body axis k = sign * sensor axis (characters 2k, 2k+1). */
static const char *const att_calib_remaps[ATT_CALIB_REMAPS] = {
    "+x+y+z", "+x-y-z", "-x+y-z", "-x-y+z", "+x+z-y", "+x-z+y", "-x+z+y", "-x-z-y",
    "+y+x-z", "+y-x+z", "-y+x+z", "-y-x-z", "+y+z+x", "+y-z-x", "-y+z-x", "-y-z+x",
    "+z+x+y", "+z-x-y", "-z+x-y", "-z-x+y", "+z+y-x", "+z-y+x", "-z+y+x", "-z-y-x"};

static const float att_calib_eye[9] = {1.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f};

void att_calib_settings_default(att_calib_settings_t *s)
{
    uint32_t i;
    if (s == NULL) {
        return;
    }
    for (i = 0u; i < 9u; i++) {
        s->gyro.misalignment[i] = att_calib_eye[i];
        s->accel.misalignment[i] = att_calib_eye[i];
        s->mag.soft_iron[i] = att_calib_eye[i];
    }
    s->gyro.sensitivity = att_i_vec3(1.0f, 1.0f, 1.0f);
    s->gyro.offset = att_i_vec3(0.0f, 0.0f, 0.0f);
    s->accel.sensitivity = s->gyro.sensitivity;
    s->accel.offset = s->gyro.offset;
    s->mag.hard_iron = s->gyro.offset;
    s->remap = 0u;
    s->mounting = att_i_quat_identity();
    s->convention = ATT_CONV_ENU;
    s->gravity = 9.80665f;
    s->accel_outputs = false;
}

/*
 * A matrix is accepted when its entries are finite with |m_ij| <= 1e3, |det| >= 2^-60 and the
 * Frobenius condition number ||M||_F ||adj M||_F / |det| is at most 3100 (tested squared, without
 * division: ||M||^2 ||adj M||^2 <= 3100^2 det^2). ||M||_F ||M^-1||_F <= 3 cond_2(M), so every matrix
 * with a 2-norm condition number below 1000 (the calibration file's limit) is accepted. No overflow:
 * ||M||^2 <= 9e6, ||adj M||^2 <= 3.6e13.
 */
static bool att_calib_matrix_ok(const float m[9])
{
    float c[9];
    float det;
    float n2 = 0.0f;
    float a2 = 0.0f;
    uint32_t i;
    for (i = 0u; i < 9u; i++) {
        if (!att_i_in(m[i], -ATT_CALIB_ENTRY_MAX, ATT_CALIB_ENTRY_MAX)) {
            return false;
        }
    }
    c[0] = m[4] * m[8] - m[5] * m[7];
    c[1] = m[2] * m[7] - m[1] * m[8];
    c[2] = m[1] * m[5] - m[2] * m[4];
    c[3] = m[5] * m[6] - m[3] * m[8];
    c[4] = m[0] * m[8] - m[2] * m[6];
    c[5] = m[2] * m[3] - m[0] * m[5];
    c[6] = m[3] * m[7] - m[4] * m[6];
    c[7] = m[1] * m[6] - m[0] * m[7];
    c[8] = m[0] * m[4] - m[1] * m[3];
    det = (m[0] * c[0] + m[1] * c[3]) + m[2] * c[6];
    if (!(att_i_absf(det) >= ATT_CALIB_DET_MIN)) {
        return false;
    }
    for (i = 0u; i < 9u; i++) {
        n2 = n2 + m[i] * m[i];
        a2 = a2 + c[i] * c[i];
    }
    return (n2 * a2) <= (ATT_CALIB_COND_MAX * ATT_CALIB_COND_MAX) * (det * det);
}

static bool att_calib_scale_ok(att_vec3_t s)
{
    return s.x > 0.0f && s.x <= ATT_CALIB_ENTRY_MAX && s.y > 0.0f && s.y <= ATT_CALIB_ENTRY_MAX && s.z > 0.0f &&
           s.z <= ATT_CALIB_ENTRY_MAX;
}

static bool att_calib_mounting_ok(const att_calib_settings_t *s)
{
    float q2;
    if (s->remap != 0u) {
        return true; /* the remap gives the mounting */
    }
    q2 = s->mounting.w * s->mounting.w + s->mounting.x * s->mounting.x + s->mounting.y * s->mounting.y +
         s->mounting.z * s->mounting.z;
    return att_i_quat_isfinite(s->mounting) && att_i_in(q2, ATT_CALIB_Q2_LO, ATT_CALIB_Q2_HI);
}

static bool att_calib_convention_ok(att_convention_t c)
{
    return c == ATT_CONV_ENU || c == ATT_CONV_NED || c == ATT_CONV_NWU;
}

/*
 * The settings contract of the stages, one line per condition in the order they are tested:
 *     C(code, name, ok, lo, hi, rule, unit)
 * code the att_calib_error_t of the line, the rest as in the kinds' tables (att_core.h).
 * att_calib_settings_check returns the code of the first line that fails, att_calib_settings_rule lists
 * them (the host's tables, help and docs), att_node_settings_check names the field: one list.
 */
#define ATT_CALIB_MATRIX_RULE "finite, |entries| <= 1e3, |det| >= 2^-60, Frobenius condition number <= 3100"
#define ATT_CALIB_CHECKS(C)                                                                                   \
    C(ATT_CALIB_ERR_GYRO_MATRIX, "calib.gyro.misalignment", att_calib_matrix_ok(s->gyro.misalignment), 0.0f,   \
      ATT_CALIB_COND_MAX, ATT_CALIB_MATRIX_RULE, "")                                                          \
    C(ATT_CALIB_ERR_GYRO_SENSITIVITY, "calib.gyro.sensitivity", att_calib_scale_ok(s->gyro.sensitivity), 0.0f, \
      ATT_CALIB_ENTRY_MAX, "each component in (0, 1e3]", "")                                                  \
    C(ATT_CALIB_ERR_GYRO_OFFSET, "calib.gyro.offset", att_i_vec3_within(s->gyro.offset, ATT_CALIB_GYRO_OFFSET_MAX), \
      -ATT_CALIB_GYRO_OFFSET_MAX, ATT_CALIB_GYRO_OFFSET_MAX, "each component in [-1e3, 1e3]", "rad/s")        \
    C(ATT_CALIB_ERR_ACCEL_MATRIX, "calib.accel.misalignment", att_calib_matrix_ok(s->accel.misalignment), 0.0f, \
      ATT_CALIB_COND_MAX, ATT_CALIB_MATRIX_RULE, "")                                                          \
    C(ATT_CALIB_ERR_ACCEL_SENSITIVITY, "calib.accel.sensitivity", att_calib_scale_ok(s->accel.sensitivity),    \
      0.0f, ATT_CALIB_ENTRY_MAX, "each component in (0, 1e3]", "")                                            \
    C(ATT_CALIB_ERR_ACCEL_OFFSET, "calib.accel.offset",                                                       \
      att_i_vec3_within(s->accel.offset, ATT_CALIB_ACCEL_OFFSET_MAX), -ATT_CALIB_ACCEL_OFFSET_MAX,            \
      ATT_CALIB_ACCEL_OFFSET_MAX, "each component in [-1e4, 1e4]", "m/s^2")                                   \
    C(ATT_CALIB_ERR_MAG_MATRIX, "calib.mag.soft_iron", att_calib_matrix_ok(s->mag.soft_iron), 0.0f,           \
      ATT_CALIB_COND_MAX, ATT_CALIB_MATRIX_RULE, "")                                                          \
    C(ATT_CALIB_ERR_MAG_OFFSET, "calib.mag.hard_iron", att_i_vec3_within(s->mag.hard_iron, ATT_CALIB_MAG_OFFSET_MAX), \
      -ATT_CALIB_MAG_OFFSET_MAX, ATT_CALIB_MAG_OFFSET_MAX, "each component in [-1e5, 1e5]", "uT")             \
    C(ATT_CALIB_ERR_REMAP, "calib.remap", s->remap <= ATT_CALIB_REMAPS, 0.0f, (float)ATT_CALIB_REMAPS,         \
      "[0, 24] (0: the mounting quaternion)", "")                                                             \
    C(ATT_CALIB_ERR_MOUNTING, "calib.mounting", att_calib_mounting_ok(s), ATT_CALIB_Q2_LO, ATT_CALIB_Q2_HI,    \
      "when remap is 0: finite, |mounting|^2 in [0.997, 1.003]", "")                                          \
    C(ATT_CALIB_ERR_CONVENTION, "calib.convention", att_calib_convention_ok(s->convention), 0.0f, 2.0f,        \
      "ENU (0), NED (1) or NWU (2)", "")                                                                      \
    C(ATT_CALIB_ERR_GRAVITY, "calib.gravity", att_i_in(s->gravity, ATT_GRAVITY_MIN, ATT_GRAVITY_MAX),          \
      ATT_GRAVITY_MIN, ATT_GRAVITY_MAX, "[1, 100]", "m/s^2")                                                  \
    C(ATT_CALIB_ERR_FLAG, "calib.accel_outputs", att_i_bool_ok(&s->accel_outputs), 0.0f, 1.0f, "0 or 1 (bool)", "")

#define ATT_CALIB_CHECK_CODE(code, name, ok, lo, hi, rule, unit)                                              \
    if (!(ok)) {                                                                                              \
        return code;                                                                                          \
    }
#define ATT_CALIB_CHECK_RULE(code, name, ok, lo, hi, rule, unit) ATT_CHECK_RULE(name, ok, lo, hi, rule, unit)

att_calib_error_t att_calib_settings_check(const att_calib_settings_t *s)
{
    if (s == NULL) {
        return ATT_CALIB_ERR_NULL;
    }
    ATT_CALIB_CHECKS(ATT_CALIB_CHECK_CODE)
    return ATT_CALIB_OK;
}

att_status_t att_calib_settings_rule(const att_calib_settings_t *s, uint32_t index, att_settings_error_t *out)
{
    uint32_t line = 0u;
    (void)att_i_settings_end(out);
    if (s == NULL || out == NULL) {
        return ATT_ERR_NULL;
    }
    ATT_CALIB_CHECKS(ATT_CALIB_CHECK_RULE)
    return att_i_settings_end(out);
}

att_status_t att_calib_settings_validate(const att_calib_settings_t *s)
{
    const att_calib_error_t e = att_calib_settings_check(s);
    if (e == ATT_CALIB_OK) {
        return ATT_OK;
    }
    return (e == ATT_CALIB_ERR_NULL) ? ATT_ERR_NULL : ATT_ERR_SETTINGS;
}

/* Remap r (1 .. 24) as body axis k = (sign[k] set ? -1 : 1) * sensor axis axis[k]. */
static void att_calib_remap_axes(uint32_t r, uint32_t axis[3], uint32_t sign[3])
{
    const char *name = att_calib_remaps[r - 1u];
    uint32_t k;
    for (k = 0u; k < 3u; k++) {
        sign[k] = (name[(size_t)2u * k] == '-') ? 0x80000000u : 0u;
        axis[k] = (uint32_t)(name[2u * k + 1u] - 'x');
    }
}

static bool att_calib_is_eye(const float m[9])
{
    uint32_t i;
    for (i = 0u; i < 9u; i++) {
        if (m[i] != att_calib_eye[i]) {
            return false;
        }
    }
    return true;
}

/*
 * Fold one sensor's model X = M diag(s) (m, s; o the offset) and the mounting into its stage: the
 * mounting is a remap (r > 0: rows permuted and negated, exact) or the rotation matrix rm (r == 0).
 */
static void att_calib_fold(att_calib_stage_t *st, const float m[9], att_vec3_t s, att_vec3_t o, uint32_t r,
                           const float rm[9], bool mount_identity)
{
    float x[9];
    const float sv[3] = {s.x, s.y, s.z};
    uint32_t i;
    uint32_t j;
    const bool model_identity = att_calib_is_eye(m) && s.x == 1.0f && s.y == 1.0f && s.z == 1.0f &&
                                o.x == 0.0f && o.y == 0.0f && o.z == 0.0f;
    st->mode = 0u;
    st->o = o;
    for (i = 0u; i < 3u; i++) {
        st->axis[i] = i;
        st->sign[i] = 0u;
        for (j = 0u; j < 3u; j++) {
            x[3u * i + j] = m[3u * i + j] * sv[j];
        }
    }
    if (r > 0u) {
        att_calib_remap_axes(r, st->axis, st->sign);
    }
    st->perm = (st->axis[0] == 0u) ? ((st->axis[1] == 1u) ? 0u : 1u)
                                   : ((st->axis[0] == 1u) ? ((st->axis[1] == 0u) ? 2u : 3u)
                                                          : ((st->axis[1] == 0u) ? 4u : 5u));
    if (model_identity && mount_identity) {
        for (i = 0u; i < 9u; i++) {
            st->a[i] = att_calib_eye[i];
        }
        return;
    }
    if (model_identity && r > 0u) {
        st->mode = 1u;
        for (i = 0u; i < 9u; i++) {
            st->a[i] = 0.0f;
        }
        for (i = 0u; i < 3u; i++) {
            st->a[3u * i + st->axis[i]] = (st->sign[i] != 0u) ? -1.0f : 1.0f;
        }
        return;
    }
    st->mode = 2u;
    for (i = 0u; i < 3u; i++) {
        for (j = 0u; j < 3u; j++) {
            if (r > 0u) {
                const float v = x[3u * st->axis[i] + j];
                st->a[3u * i + j] = (st->sign[i] != 0u) ? -v : v;
            } else if (mount_identity) {
                st->a[3u * i + j] = x[3u * i + j];
            } else {
                st->a[3u * i + j] = (rm[(size_t)3u * i] * x[j] + rm[3u * i + 1u] * x[3u + j]) + rm[3u * i + 2u] * x[6u + j];
            }
        }
    }
}

att_status_t att_calib_init(att_calib_t *c, const att_calib_settings_t *s)
{
    att_calib_t t;
    float rm[9];
    att_quat_t q;
    bool mount_identity;
    const att_vec3_t zero = att_i_vec3(0.0f, 0.0f, 0.0f);
    const att_vec3_t ones = att_i_vec3(1.0f, 1.0f, 1.0f);
    const att_status_t st = att_calib_settings_validate(s);
    if (c == NULL) {
        return ATT_ERR_NULL;
    }
    if (st != ATT_OK) {
        return st;
    }
    t.convention = s->convention;
    t.gravity = s->gravity;
    if (s->remap == 0u) {
        (void)att_i_quat_normalize(s->mounting, &q); /* cannot fail: |q|^2 checked */
        att_quat_to_matrix(q, rm);
        mount_identity = att_calib_is_eye(rm);
    } else {
        att_quat_to_matrix(att_i_quat_identity(), rm);
        mount_identity = (s->remap == 1u);
    }
    att_calib_fold(&t.gyr, s->gyro.misalignment, s->gyro.sensitivity, s->gyro.offset, s->remap, rm,
                   mount_identity);
    att_calib_fold(&t.acc, s->accel.misalignment, s->accel.sensitivity, s->accel.offset, s->remap, rm,
                   mount_identity);
    att_calib_fold(&t.mag, s->mag.soft_iron, ones, s->mag.hard_iron, s->remap, rm, mount_identity);
    t.active = 0u;
    if ((t.gyr.mode | t.acc.mode | t.mag.mode) != 0u) {
        t.active |= ATT_CALIB_ACTIVE_INPUT;
    }
    if (s->convention != ATT_CONV_ENU) {
        t.active |= ATT_CALIB_ACTIVE_CONV;
    }
    if (s->accel_outputs) {
        t.active |= ATT_CALIB_ACTIVE_ACC;
    }
    t.acc_body = zero;
    t.have_acc = false;
    *c = t;
    return ATT_OK;
}

void att_calib_apply(const att_calib_t *c, att_vec3_t *gyr, att_vec3_t *acc, att_vec3_t *mag)
{
    if (c == NULL || gyr == NULL || acc == NULL || mag == NULL) {
        return;
    }
    att_i_calib_apply(c, gyr, acc, mag, gyr, acc, mag);
}

att_quat_t att_calib_quat_to(att_quat_t q, att_convention_t conv)
{
    const float a = ATT_CALIB_HALF_SQRT2;
    if (conv == ATT_CONV_NED) {
        return att_i_quat((-q.x - q.y) * a, (q.w + q.z) * a, (q.w - q.z) * a, (q.y - q.x) * a);
    }
    if (conv == ATT_CONV_NWU) {
        return att_i_quat((q.w + q.z) * a, (q.x + q.y) * a, (q.y - q.x) * a, (q.z - q.w) * a);
    }
    return q;
}

att_vec3_t att_calib_vec_to(att_vec3_t v, att_convention_t conv)
{
    if (conv == ATT_CONV_NED) {
        return att_i_vec3(v.y, v.x, -v.z);
    }
    if (conv == ATT_CONV_NWU) {
        return att_i_vec3(v.y, -v.x, v.z);
    }
    return v;
}

uint32_t att_calib_remap_parse(const char *name)
{
    uint32_t r;
    uint32_t i;
    if (name == NULL) {
        return 0u;
    }
    for (r = 0u; r < ATT_CALIB_REMAPS; r++) {
        const char *t = att_calib_remaps[r];
        for (i = 0u; i < 6u && name[i] == t[i]; i++) {
        }
        if (i == 6u && name[6] == '\0') {
            return r + 1u;
        }
    }
    return 0u;
}

const char *att_calib_remap_name(uint32_t remap)
{
    if (remap < 1u || remap > ATT_CALIB_REMAPS) {
        return NULL;
    }
    return att_calib_remaps[remap - 1u];
}

const char *att_calib_error_name(att_calib_error_t e)
{
    switch (e) {
    case ATT_CALIB_OK:
        return "ok";
    case ATT_CALIB_ERR_NULL:
        return "NULL settings";
    case ATT_CALIB_ERR_GYRO_MATRIX:
        return "gyro misalignment (not finite, |m| > 1e3, singular or ill-conditioned)";
    case ATT_CALIB_ERR_GYRO_SENSITIVITY:
        return "gyro sensitivity (outside (0, 1e3])";
    case ATT_CALIB_ERR_GYRO_OFFSET:
        return "gyro offset (not finite or > 1e3 rad/s)";
    case ATT_CALIB_ERR_ACCEL_MATRIX:
        return "accel misalignment (not finite, |m| > 1e3, singular or ill-conditioned)";
    case ATT_CALIB_ERR_ACCEL_SENSITIVITY:
        return "accel sensitivity (outside (0, 1e3])";
    case ATT_CALIB_ERR_ACCEL_OFFSET:
        return "accel offset (not finite or > 1e4 m/s^2)";
    case ATT_CALIB_ERR_MAG_MATRIX:
        return "mag soft-iron (not finite, |m| > 1e3, singular or ill-conditioned)";
    case ATT_CALIB_ERR_MAG_OFFSET:
        return "mag hard-iron (not finite or > 1e5 uT)";
    case ATT_CALIB_ERR_REMAP:
        return "remap (not 0 .. 24)";
    case ATT_CALIB_ERR_MOUNTING:
        return "mounting quaternion (not finite or not unit)";
    case ATT_CALIB_ERR_CONVENTION:
        return "convention (not ENU, NED, NWU)";
    case ATT_CALIB_ERR_GRAVITY:
        return "gravity (outside [1, 100] m/s^2)";
    case ATT_CALIB_ERR_FLAG:
        return "accel_outputs (not a bool)";
    default:
        return "?";
    }
}

/* The float slot of field index (see att_calib_field_set), NULL for the integer fields and beyond. */
static float *att_calib_field_slot(att_calib_settings_t *s, uint32_t index)
{
    att_vec3_t *v = NULL;
    uint32_t k = 0u;
    if (index < 9u) {
        return &s->gyro.misalignment[index];
    }
    if (index >= 15u && index < 24u) {
        return &s->accel.misalignment[index - 15u];
    }
    if (index >= 30u && index < 39u) {
        return &s->mag.soft_iron[index - 30u];
    }
    if (index < 15u) {
        v = (index < 12u) ? &s->gyro.sensitivity : &s->gyro.offset;
        k = (index - 9u) % 3u;
    } else if (index < 30u) {
        v = (index < 27u) ? &s->accel.sensitivity : &s->accel.offset;
        k = (index - 24u) % 3u;
    } else if (index < 42u) {
        v = &s->mag.hard_iron;
        k = index - 39u;
    } else if (index < 46u) {
        float *q[4];
        q[0] = &s->mounting.w;
        q[1] = &s->mounting.x;
        q[2] = &s->mounting.y;
        q[3] = &s->mounting.z;
        return q[index - 42u];
    } else if (index == 48u) {
        return &s->gravity;
    } else {
        return NULL;
    }
    return (k == 0u) ? &v->x : ((k == 1u) ? &v->y : &v->z);
}

bool att_calib_field_set(att_calib_settings_t *s, uint32_t index, float value)
{
    float *slot;
    uint32_t u;
    if (s == NULL || index >= ATT_CALIB_FIELDS) {
        return false;
    }
    slot = att_calib_field_slot(s, index);
    if (slot != NULL) {
        *slot = value;
        return true;
    }
    if (!(value >= 0.0f && value <= 16777216.0f)) {
        return false; /* NaN, negative or too large for the exact conversion */
    }
    u = (uint32_t)value;
    if ((float)u != value) {
        return false;
    }
    if (index == 46u) {
        s->remap = u;
    } else if (index == 47u) {
        s->convention = (att_convention_t)u; /* validated by the settings check */
    } else {
        if (u > 1u) {
            return false;
        }
        s->accel_outputs = (u == 1u);
    }
    return true;
}

bool att_calib_field_get(const att_calib_settings_t *s, uint32_t index, float *value)
{
    att_calib_settings_t t;
    float *slot;
    if (s == NULL || value == NULL || index >= ATT_CALIB_FIELDS) {
        return false;
    }
    t = *s;
    slot = att_calib_field_slot(&t, index);
    if (slot != NULL) {
        *value = *slot;
    } else if (index == 46u) {
        *value = (float)(s->remap & 0xFFFFFFu);
    } else if (index == 47u) {
        *value = (float)((uint32_t)s->convention & 0xFFFFFFu);
    } else {
        *value = s->accel_outputs ? 1.0f : 0.0f;
    }
    return true;
}
