/**
 * @file att_soak.c
 * @brief Soak test of every filter kind through the public att_filter API (docs/robustness.md).
 *
 *     att_soak [--steps N] [--kind KIND] [--seed S] [--known CLASS,CLASS...] [--break-at STEP]
 *
 * Per kind, N steps (default 1e8) with the default settings at 1/285.714 s over a simulated sensor:
 * the true attitude turns through alternating phases of rest (0.5 .. 3 s), motion (rates up to
 * 3 rad/s about a random axis, 1 .. 10 s) and bad samples (1 .. 20 steps of NaN, +-Inf, 1e30, zero,
 * saturated 200 m/s^2 / 40 rad/s, FLT_MAX in one or all components of gyro, accel or mag). Gyro carries a
 * constant bias of 0.01 rad/s per axis, accel and mag the true gravity and field in the sensor frame.
 *
 * Invariants (a violation prints its class kind:NAME; classes given with --known are counted only):
 * - Q_UNIT     every step whose flags have no bit of SOAK_INVALID: q finite, | |q| - 1 | <= SOAK_Q_TOL.
 * - COV        kf/ekf, valid steps: out.cov diagonal finite and > 0; every 4096th step the whole state
 *              covariance is symmetric and positive definite (Cholesky in double).
 * - BIAS       ars/mars: |bias_i| <= 0.5 rad/s (the true bias is 0.01 rad/s; a bias learnt from motion or
 *              bad samples would exceed it).
 * - STEPS      out.steps counts every step (mod 2^32; the wrap itself is tested in tests/test_soak.py).
 * - STUCK      after every bad burst, within SOAK_RECOVER good samples the flags have no NUMERIC and no
 *              NOT_READY bit and q is valid.
 * - FROZEN     during every motion phase q changes (no stuck state).
 * --break-at STEP overwrites the filter state with NaN bytes at that step: a self test that the
 * invariants fire. Prints one line per kind: steps, bad samples injected, bursts, violations, max | |q| - 1 |, seconds.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "attica/att_filter.h"

#ifdef ATT_FLAG_OUTPUT_INVALID
#define SOAK_INVALID ((uint32_t)ATT_FLAG_OUTPUT_INVALID)
#else
#define SOAK_INVALID ((uint32_t)(ATT_FLAG_NOT_READY | ATT_FLAG_BAD_ARG))
#endif
#define SOAK_Q_TOL 1e-6
#define SOAK_RECOVER 8
#define SOAK_DT 0.0035f
#define SOAK_G 9.80665

static uint64_t g_rng = 0x9E3779B97F4A7C15ull;

static uint64_t rnd(void)
{
    g_rng ^= g_rng << 13;
    g_rng ^= g_rng >> 7;
    g_rng ^= g_rng << 17;
    return g_rng;
}

static double urand(void)
{
    return (double)(rnd() >> 11) * (1.0 / 9007199254740992.0);
}

typedef struct {
    double w, x, y, z;
} dq_t;

static dq_t dq_mul(dq_t a, dq_t b)
{
    dq_t r;
    r.w = a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z;
    r.x = a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y;
    r.y = a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x;
    r.z = a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w;
    return r;
}

/** v_sensor = q^-1 v_earth q (q sensor-to-earth). */
static void to_sensor(dq_t q, const double e[3], double s[3])
{
    dq_t v = {0.0, e[0], e[1], e[2]};
    dq_t qc = {q.w, -q.x, -q.y, -q.z};
    dq_t r = dq_mul(dq_mul(qc, v), q);
    s[0] = r.x;
    s[1] = r.y;
    s[2] = r.z;
}

static char g_known[1024];
static unsigned long g_viol[6][8];
static const char *inv_names[8] = {"Q_UNIT", "COV", "BIAS", "STEPS", "STUCK", "FROZEN", "", ""};
static int g_unknown;
static unsigned long long g_break_at; /* --break-at: self test, the state is overwritten with NaN there */

static void violation(att_filter_kind_t kind, int inv, unsigned long long step, const char *detail)
{
    char cls[48];
    snprintf(cls, sizeof cls, "%s:%s", att_filter_name(kind), inv_names[inv]);
    if (g_viol[kind - 1][inv]++ == 0) {
        int known = strstr(g_known, cls) != NULL;
        fprintf(stderr, "att_soak: %s %s at step %llu: %s\n", known ? "known finding" : "VIOLATION", cls, step, detail);
        if (!known) g_unknown = 1;
    }
}

static int spd(const double *a, int n)
{
    double l[36];
    int i, j, k;
    for (j = 0; j < n; ++j) {
        for (i = j; i < n; ++i) {
            double s = a[i * n + j];
            for (k = 0; k < j; ++k) s -= l[i * n + k] * l[j * n + k];
            if (i == j) {
                if (!(s > 0.0) || !isfinite(s)) return 0;
                l[j * n + j] = sqrt(s);
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    return 1;
}

/** The state covariance (kf: P = p I; ekf: the packed 6x6 upper triangle) is positive definite. */
static int cov_ok(const att_filter_t *f)
{
    double a[36];
    int i, j, k = 0;
    if (f->kind == ATT_FILTER_KF) {
        for (i = 0; i < 16; ++i) a[i] = (i % 5 == 0) ? (double)f->u.kf.st.p : 0.0;
        return spd(a, 4);
    }
    for (i = 0; i < 6; ++i) {
        for (j = i; j < 6; ++j) {
            a[i * 6 + j] = (double)f->u.ekf.st.p[k];
            a[j * 6 + i] = (double)f->u.ekf.st.p[k];
            ++k;
        }
    }
    return spd(a, 6);
}

static float bad_value(void)
{
    static const float v[] = {NAN, INFINITY, -INFINITY, 1e30f, -1e30f, 0.0f, 3.40282347e38f, 200.0f, 40.0f};
    return v[rnd() % (sizeof v / sizeof v[0])];
}

typedef struct {
    unsigned long long steps, bad_samples, bursts, motions;
    double max_qerr;
} result_t;

static result_t soak(att_filter_kind_t kind, unsigned long long n_steps)
{
    att_filter_settings_t s;
    att_filter_t f;
    att_output_t o;
    result_t res;
    dq_t q = {1.0, 0.0, 0.0, 0.0};
    dq_t dqs = {1.0, 0.0, 0.0, 0.0};
    double rate[3] = {0.0, 0.0, 0.0};
    const double g_e[3] = {0.0, 0.0, SOAK_G};
    const double m_e[3] = {0.0, 20.0, -40.0};
    unsigned long long k = 0;
    int phase = 0; /* 0 rest, 1 motion, 2 bad */
    unsigned long long left = 100;
    unsigned long long since_bad = 1000000;
    int motion_moved = 1;
    att_quat_t q_phase_start = {1.0f, 0.0f, 0.0f, 0.0f};
    uint32_t last_steps = 0;
    memset(&res, 0, sizeof res);
    if (att_filter_settings_default(kind, SOAK_DT, &s) != ATT_OK || att_filter_init(&f, kind, &s) != ATT_OK) {
        fprintf(stderr, "att_soak: cannot init %s\n", att_filter_name(kind));
        exit(2);
    }
    for (k = 0; k < n_steps; ++k) {
        att_sample_t in;
        double a[3], m[3];
        uint32_t flags;
        int valid;
        if (left == 0) { /* next phase */
            if (phase == 1 && !motion_moved) violation(kind, 5, k, "q did not change during a motion phase");
            if (phase == 2) {
                since_bad = 0;
                res.bursts++;
            }
            phase = (phase == 2 || (phase == 1 && (rnd() & 3u) != 0u)) ? 0 : (phase == 0 ? 1 : 2);
            if (phase == 0 && (rnd() & 3u) == 0u) phase = 2;
            if (phase == 0) {
                left = (unsigned long long)(143.0 + urand() * 714.0);
                rate[0] = rate[1] = rate[2] = 0.0;
            } else if (phase == 1) {
                double ax[3] = {urand() - 0.5, urand() - 0.5, urand() - 0.5};
                double nrm = sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2]) + 1e-9;
                double w = 0.2 + urand() * 2.8;
                double h;
                int i;
                left = (unsigned long long)(286.0 + urand() * 2571.0);
                for (i = 0; i < 3; ++i) rate[i] = w * ax[i] / nrm;
                h = 0.5 * w * (double)SOAK_DT;
                dqs.w = cos(h);
                dqs.x = sin(h) * ax[0] / nrm;
                dqs.y = sin(h) * ax[1] / nrm;
                dqs.z = sin(h) * ax[2] / nrm;
                motion_moved = 0;
                q_phase_start = o.q;
                res.motions++;
            } else {
                left = 1 + rnd() % 20u;
            }
        }
        left--;
        if (phase == 1) {
            double nq;
            q = dq_mul(q, dqs);
            nq = sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
            q.w /= nq;
            q.x /= nq;
            q.y /= nq;
            q.z /= nq;
        }
        to_sensor(q, g_e, a);
        to_sensor(q, m_e, m);
        in.gyr.x = (float)(rate[0] + 0.01);
        in.gyr.y = (float)(rate[1] + 0.01);
        in.gyr.z = (float)(rate[2] + 0.01);
        in.acc.x = (float)a[0];
        in.acc.y = (float)a[1];
        in.acc.z = (float)a[2];
        in.mag.x = (float)m[0];
        in.mag.y = (float)m[1];
        in.mag.z = (float)m[2];
        if (phase == 2) {
            float *v = &in.gyr.x;
            unsigned what = (unsigned)(rnd() % 4u);
            if (what == 3u) {
                int i;
                for (i = 0; i < 9; ++i) v[i] = bad_value();
            } else {
                v[what * 3u + (unsigned)(rnd() % 3u)] = bad_value();
            }
            res.bad_samples++;
        }
        if (g_break_at != 0u && k == g_break_at) memset(&f.u, 0xFF, sizeof f.u);
        flags = att_filter_step(&f, &in, &o);
        att_filter_output(&f, &o); /* every field (the step fills only the per-step ones) */
        if (o.steps != last_steps + 1u) violation(kind, 3, k, "steps did not count");
        last_steps = o.steps;
        valid = (flags & SOAK_INVALID) == 0u;
        if (valid) {
            double n2 = (double)o.q.w * o.q.w + (double)o.q.x * o.q.x + (double)o.q.y * o.q.y + (double)o.q.z * o.q.z;
            double e = fabs(sqrt(n2) - 1.0);
            if (!(e <= SOAK_Q_TOL)) {
                char d[160];
                snprintf(d, sizeof d, "| |q| - 1 | = %g, flags %04x", e, flags);
                violation(kind, 0, k, d);
            } else if (e > res.max_qerr) {
                res.max_qerr = e;
            }
            if (kind == ATT_FILTER_KF || kind == ATT_FILTER_EKF) {
                int i;
                for (i = 0; i < 4; ++i) {
                    if (!(o.cov[i] > 0.0f) || !isfinite(o.cov[i])) violation(kind, 1, k, "cov diagonal not > 0");
                }
                if ((k & 4095u) == 0u && !cov_ok(&f)) violation(kind, 1, k, "P not symmetric positive definite");
            }
            if (kind == ATT_FILTER_ARS || kind == ATT_FILTER_MARS) {
                if (!(fabsf(o.gyro_bias.x) <= 0.5f && fabsf(o.gyro_bias.y) <= 0.5f && fabsf(o.gyro_bias.z) <= 0.5f)) {
                    char d[120];
                    snprintf(d, sizeof d, "bias (%g, %g, %g)", (double)o.gyro_bias.x, (double)o.gyro_bias.y,
                             (double)o.gyro_bias.z);
                    violation(kind, 2, k, d);
                }
            }
        }
        if (phase != 2) {
            since_bad++;
            if (since_bad == SOAK_RECOVER && ((flags & (ATT_FLAG_NUMERIC | ATT_FLAG_NOT_READY)) != 0u || !valid)) {
                char d[80];
                snprintf(d, sizeof d, "flags %04x %d good samples after a bad burst", flags, SOAK_RECOVER);
                violation(kind, 4, k, d);
            }
        }
        if (phase == 1 && memcmp(&o.q, &q_phase_start, sizeof o.q) != 0) motion_moved = 1;
    }
    res.steps = k;
    return res;
}

int main(int argc, char **argv)
{
    unsigned long long n = 100000000ull;
    const char *only = NULL;
    int i;
    int kind;
    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--steps") == 0 && i + 1 < argc) {
            n = strtoull(argv[++i], NULL, 10);
        } else if (strcmp(argv[i], "--kind") == 0 && i + 1 < argc) {
            only = argv[++i];
        } else if (strcmp(argv[i], "--seed") == 0 && i + 1 < argc) {
            g_rng = strtoull(argv[++i], NULL, 10) * 0x9E3779B97F4A7C15ull + 1u;
        } else if (strcmp(argv[i], "--break-at") == 0 && i + 1 < argc) {
            g_break_at = strtoull(argv[++i], NULL, 10);
        } else if (strcmp(argv[i], "--known") == 0 && i + 1 < argc) {
            snprintf(g_known, sizeof g_known, "%s", argv[++i]);
        } else {
            fprintf(stderr, "usage: att_soak [--steps N] [--kind KIND] [--seed S] [--known CLASS,...]\n");
            return 2;
        }
    }
    for (kind = ATT_FILTER_ARS; kind <= ATT_FILTER_TILT; ++kind) {
        result_t r;
        clock_t t0;
        double sec;
        unsigned long total = 0;
        int inv;
        if (only != NULL && strcmp(only, att_filter_name((att_filter_kind_t)kind)) != 0) continue;
        t0 = clock();
        r = soak((att_filter_kind_t)kind, n);
        sec = (double)(clock() - t0) / CLOCKS_PER_SEC;
        for (inv = 0; inv < 8; ++inv) total += g_viol[kind - 1][inv];
        printf("att_soak: %-4s steps %llu, bad samples %llu in %llu bursts, %llu motion phases, violations %lu, "
               "max | |q| - 1 | %.3g, %.1f s\n",
               att_filter_name((att_filter_kind_t)kind), r.steps, r.bad_samples, r.bursts, r.motions, total, r.max_qerr,
               sec);
        fflush(stdout);
    }
    if (g_unknown) {
        printf("att_soak: FAILED (violations outside --known)\n");
        return 1;
    }
    printf("att_soak: OK\n");
    return 0;
}
