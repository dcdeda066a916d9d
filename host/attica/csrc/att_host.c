/**
 * @file att_host.c
 * @brief Host-only batch kernels (see att_host.h).
 */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

#include "att_host.h"

#include "attica/att_sensor.h"

#if defined(__GNUC__)
#define ATT_HOST_INLINE inline __attribute__((always_inline))
#else
#define ATT_HOST_INLINE inline
#endif

static att_vec3_t att_host_v3(const float *p)
{
    att_vec3_t v;
    v.x = p[0];
    v.y = p[1];
    v.z = p[2];
    return v;
}

static att_quat_t att_host_q(const float *p)
{
    att_quat_t q;
    q.w = p[0];
    q.x = p[1];
    q.y = p[2];
    q.z = p[3];
    return q;
}

static void att_host_put_v3(float *p, att_vec3_t v)
{
    p[0] = v.x;
    p[1] = v.y;
    p[2] = v.z;
}

static void att_host_put_q(float *p, att_quat_t q)
{
    p[0] = q.w;
    p[1] = q.x;
    p[2] = q.y;
    p[3] = q.z;
}

int att_host_map1(int fn, const float *x, float *y, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        switch (fn) {
        case ATT_HOST_SIN:
            y[i] = att_sinf(x[i]);
            break;
        case ATT_HOST_COS:
            y[i] = att_cosf(x[i]);
            break;
        case ATT_HOST_ASIN:
            y[i] = att_asinf(x[i]);
            break;
        case ATT_HOST_ACOS:
            y[i] = att_acosf(x[i]);
            break;
        case ATT_HOST_SQRT:
            y[i] = att_sqrtf(x[i]);
            break;
        case ATT_HOST_WRAP_PI:
            y[i] = att_wrap_pi(x[i]);
            break;
        default:
            return -1;
        }
    }
    return 0;
}

void att_host_atan2(const float *a, const float *b, float *y, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        y[i] = att_atan2f(a[i], b[i]);
    }
}

static const size_t att_host_widths[][2] = {
    {8u, 4u}, {4u, 5u}, {7u, 3u}, {3u, 4u}, {4u, 3u}, {4u, 9u},
    {3u, 4u}, {4u, 4u}, {3u, 4u}, {6u, 3u}, {3u, 3u},
};

int att_host_mapq(int fn, const float *in, size_t in_width, float *out, size_t out_width, size_t n)
{
    size_t i;
    if (fn < 0 || fn > ATT_HOST_SENSOR_TILT || att_host_widths[fn][0] != in_width ||
        att_host_widths[fn][1] != out_width) {
        return -1;
    }
    for (i = 0; i < n; i++) {
        const float *p = in + i * in_width;
        float *o = out + i * out_width;
        bool ok;
        att_quat_t q;
        att_vec3_t v;
        switch (fn) {
        case ATT_HOST_QUAT_MUL:
            att_host_put_q(o, att_quat_mul(att_host_q(p), att_host_q(p + 4)));
            break;
        case ATT_HOST_QUAT_NORMALIZE:
            ok = att_quat_normalize(att_host_q(p), &q);
            att_host_put_q(o, q);
            o[4] = ok ? 1.0f : 0.0f;
            break;
        case ATT_HOST_QUAT_ROTATE:
            att_host_put_v3(o, att_quat_rotate(att_host_q(p), att_host_v3(p + 4)));
            break;
        case ATT_HOST_QUAT_FROM_EULER:
            att_host_put_q(o, att_quat_from_euler(p[0], p[1], p[2]));
            break;
        case ATT_HOST_QUAT_TO_EULER:
            att_host_put_v3(o, att_quat_to_euler(att_host_q(p)));
            break;
        case ATT_HOST_QUAT_TO_MATRIX:
            att_quat_to_matrix(att_host_q(p), o);
            break;
        case ATT_HOST_QUAT_FROM_ROTVEC:
            att_host_put_q(o, att_quat_from_rotvec(att_host_v3(p)));
            break;
        case ATT_HOST_QUAT_FROM_AXIS_ANGLE:
            att_host_put_q(o, att_quat_from_axis_angle(att_host_v3(p), p[3]));
            break;
        case ATT_HOST_VEC3_NORMALIZE:
            ok = att_vec3_normalize(att_host_v3(p), &v);
            att_host_put_v3(o, v);
            o[3] = ok ? 1.0f : 0.0f;
            break;
        case ATT_HOST_VEC3_CROSS:
            att_host_put_v3(o, att_vec3_cross(att_host_v3(p), att_host_v3(p + 3)));
            break;
        default: /* ATT_HOST_SENSOR_TILT */
            att_host_put_v3(o, att_sensor_tilt(att_host_v3(p)));
            break;
        }
    }
    return 0;
}

/* The sample buffer of a batch loop: mag zero (absent) unless the loop reads a mag array. */
static void att_host_sample_clear(att_sample_t *in)
{
    in->gyr.x = 0.0f;
    in->gyr.y = 0.0f;
    in->gyr.z = 0.0f;
    in->acc = in->gyr;
    in->mag = in->gyr;
}

/* Row i of the input arrays into in, in place (mag NULL: in->mag is left as it is, zero). */
static ATT_HOST_INLINE void att_host_sample_load(att_sample_t *in, const float *gyr, const float *acc,
                                                 const float *mag, size_t i)
{
    const float *g = gyr + 3u * i;
    const float *a = acc + 3u * i;
    in->gyr.x = g[0];
    in->gyr.y = g[1];
    in->gyr.z = g[2];
    in->acc.x = a[0];
    in->acc.y = a[1];
    in->acc.z = a[2];
    if (mag != NULL) {
        const float *m = mag + 3u * i;
        in->mag.x = m[0];
        in->mag.y = m[1];
        in->mag.z = m[2];
    }
}

/* Steps i0 .. i1 - 1 into the records out[i0 .. i1 - 1]; steps (or NULL: 1 each) periods per row; moff
 * (or NULL) gets att_filter_mag_offset after each step. */
static void att_host_run_records(att_filter_t *f, att_sample_t *in, const float *gyr, const float *acc,
                                 const float *mag, const uint32_t *steps, size_t i0, size_t i1,
                                 att_output_t *out, int full, att_mag_offset_t *moff)
{
    size_t i;
    if (steps == NULL && moff == NULL) {
        for (i = i0; i < i1; i++) {
            att_host_sample_load(in, gyr, acc, mag, i);
            (void)att_filter_step(f, in, out + i);
            if (full != 0) {
                att_filter_output(f, out + i);
            }
        }
        return;
    }
    for (i = i0; i < i1; i++) {
        uint32_t flags;
        att_host_sample_load(in, gyr, acc, mag, i);
        flags = att_filter_step_n(f, in, (steps != NULL) ? steps[i] : 1u, out + i);
        if (full != 0) {
            att_filter_output(f, out + i);
            out[i].flags = flags; /* the OR over the n steps, as att_filter_step_n reports it */
        }
        if (moff != NULL) {
            (void)att_filter_mag_offset(f, moff + i);
        }
    }
}

size_t att_host_filter_run(att_filter_t *f, const float *gyr, const float *acc, const float *mag,
                           const uint32_t *steps, size_t n, att_output_t *out, int full, size_t every,
                           att_filter_t *snaps, att_mag_offset_t *moff)
{
    size_t i;
    att_sample_t in;
    if (f == NULL || gyr == NULL || acc == NULL || out == NULL) {
        return 0u;
    }
    att_host_sample_clear(&in);
    if (snaps == NULL || every == 0u) {
        att_host_run_records(f, &in, gyr, acc, mag, steps, 0u, n, out, full, moff);
        return n;
    }
    /* a snapshot, then a run of every steps without a test per step */
    for (i = 0u; i < n; i += every) {
        const size_t end = (n - i > every) ? i + every : n;
        snaps[i / every] = *f;
        att_host_run_records(f, &in, gyr, acc, mag, steps, i, end, out, full, moff);
    }
    return n;
}

size_t att_host_filter_run_q(att_filter_t *f, const float *gyr, const float *acc, const float *mag,
                             const uint32_t *steps, size_t n, float *q, uint32_t *flags)
{
    size_t i;
    att_sample_t in;
    att_output_t o;
    if (f == NULL || gyr == NULL || acc == NULL || q == NULL) {
        return 0u;
    }
    att_host_sample_clear(&in);
    for (i = 0u; i < n; i++) {
        float *qi = q + 4u * i;
        att_host_sample_load(&in, gyr, acc, mag, i);
        if (steps == NULL) {
            (void)att_filter_step(f, &in, &o);
        } else {
            (void)att_filter_step_n(f, &in, steps[i], &o);
        }
        if ((o.valid & ATT_OUT_Q) == 0u) {
            /* the Euler-state EKF: q on request, exactly as att_filter_output derives it */
            o.q = att_quat_from_euler(o.euler.x, o.euler.y, o.euler.z);
        }
        qi[0] = o.q.w;
        qi[1] = o.q.x;
        qi[2] = o.q.y;
        qi[3] = o.q.z;
        if (flags != NULL) {
            flags[i] = o.flags;
        }
    }
    return n;
}

uint32_t att_host_step9(att_filter_t *f, float gx, float gy, float gz, float ax, float ay, float az, float mx,
                        float my, float mz, uint32_t n, int full, att_output_t *out)
{
    att_sample_t in;
    uint32_t flags;
    in.gyr.x = gx;
    in.gyr.y = gy;
    in.gyr.z = gz;
    in.acc.x = ax;
    in.acc.y = ay;
    in.acc.z = az;
    in.mag.x = mx;
    in.mag.y = my;
    in.mag.z = mz;
    flags = (n == 1u) ? att_filter_step(f, &in, out) : att_filter_step_n(f, &in, n, out);
    if (out == NULL || (flags & (uint32_t)ATT_FLAG_BAD_ARG) != 0u) {
        return flags;
    }
    if (full == 1) {
        att_filter_output(f, out);
        out->flags = flags;
    } else if (full == 2 && (out->valid & ATT_OUT_Q) == 0u) {
        /* the Euler-state EKF: q as att_filter_output derives it (as att_host_filter_run_q) */
        out->q = att_quat_from_euler(out->euler.x, out->euler.y, out->euler.z);
        out->valid |= ATT_OUT_Q;
    }
    return flags;
}
