/**
 * @file fuzz_filter.c
 * @brief libFuzzer target: att_filter_init with fuzzed settings, then att_filter_step with fuzzed samples,
 * for every kind, through the public att_filter API only (docs/robustness.md).
 *
 * Input: kind (1 + byte % 7), preset and dt, then up to 12 field mutations of the settings
 * (att_filter_settings_default + per-field writes of raw or special values), then up to 256 samples
 * (good motion, rest, raw floats, or a good sample with one fuzzed component), then a fixed recovery
 * sequence of good samples.
 *
 * Invariants, each with a name used in findings (kind:NAME):
 * - INIT_CHANGED    a refused init leaves the filter byte for byte as it was.
 * - FLAGS           the returned flags equal out.flags; att_filter_output repeats every field the step
 *                   marked valid (the other invariants are checked on att_filter_output's full record).
 * - STEPS           out.steps counts the steps (mod 2^32).
 * - Q_FINITE / Q_UNIT   unless a flag of FZ_INVALID says the output is not valid: q finite and
 *                   | |q| - 1 | <= FZ_Q_TOL; euler and gyro_bias finite (EULER_FINITE, BIAS_FINITE).
 * - COV_POSITIVE    kf/ekf/mekf, when valid: the four out.cov values finite and > 0.
 * - P_SPD           kf/ekf/mekf, when valid: the state covariance (kf: P = p I; ekf, mekf: the 6x6 matrix
 *                   of the packed upper triangle) is positive definite (Cholesky in double).
 * - EULER_RANGE     when valid: roll and yaw in [-pi, pi], pitch in [-pi/2, pi/2] (float32 pi, pi/2).
 * - BIAS_BOUND      ars/mars: every bias component within max(|bias_init|, gyro_range) (+ 1e-5 relative).
 * - NUMERIC_KEPT    a step flagged NUMERIC leaves q bit for bit as before the step.
 * - STUCK           the recovery contract (fz_recovery, tests/test_recovery.py): after the fuzzed samples,
 *                   good samples at rest (|a| = the kind's gravity): from the kind's n-th on, every one is
 *                   neither NUMERIC nor NOT_READY nor invalid, its output valid (FZ_HOLD more checked);
 *                   for a kind marked isolated (ekf) one of the first n is good and a later bad sample is
 *                   an isolated NUMERIC step (never two bad in a row, never NOT_READY). The same rule holds
 *                   during the roll below when it is a clean sample (gyro_range > 1 rad/s, accel_range >
 *                   1.01 g).
 * - FROZEN          then the attitude moves again: 16 samples of a 0.5 rad/s roll seen consistently by
 *                   gyro, accel and mag change q (checked when gyro_range > 1 rad/s, accel_range > 1.01 g,
 *                   the roll reaches 1e-3 rad and the rest detector does not take the roll for rest).
 * - RESET           att_filter_reset gives the output of a fresh init, and both step identically.
 *
 * Known findings (defects the filter owners know of, docs/robustness.md) can be tolerated by class:
 * ATT_FUZZ_KNOWN="kf:P_SPD,gyro:Q_FINITE" (or a file with one class per line, ATT_FUZZ_KNOWN=@path)
 * counts them instead of aborting (ATT_FUZZ_KNOWN="*": every class, for triage); ATT_FUZZ_FINDINGS=dir saves the first input of each class there.
 * Anything else aborts (a crash artifact for libFuzzer). ATT_FUZZ_BREAK_AT=N overwrites the filter with NaN
 * bytes before the N-th fuzzed sample: the self test that a broken filter is reported. ATT_FUZZ_BREAK_RECOVERY=N
 * (0-based) resets the filter before the N-th and every later good sample at rest and gives it a NaN accel:
 * the self test of STUCK (a filter left NOT_READY).
 */
#include <stdbool.h>
#include <stddef.h>

#include "attica/att_filter.h"
#include "fuzz_common.h"

#ifdef ATT_FLAG_OUTPUT_INVALID
#define FZ_INVALID ((uint32_t)ATT_FLAG_OUTPUT_INVALID)
#else
#define FZ_INVALID ((uint32_t)(ATT_FLAG_NOT_READY | ATT_FLAG_BAD_ARG))
#endif
#define FZ_Q_TOL 1e-5
#define FZ_HOLD 8 /* good samples at rest checked after a kind's recovery bound */
#define FZ_MAX_STEPS 256
#define FZ_G 9.80665f

/* --- the recovery contract (tests/test_recovery.py checks this table against its own) -------------- */

/** Within n good samples the output is good again; isolated: later a NUMERIC step may recur, never two
 * bad samples in a row; else every sample from the n-th on is good. */
typedef struct {
    unsigned n;
    bool isolated;
} fz_recovery_t;

static const fz_recovery_t fz_recovery[] = {
    [ATT_FILTER_NONE] = {2u, false},
    [ATT_FILTER_ARS] = {2u, false},
    [ATT_FILTER_MARS] = {2u, false},
    [ATT_FILTER_KF] = {2u, false},
    [ATT_FILTER_EKF] = {4u, true},
    [ATT_FILTER_GYRO] = {2u, false},
    [ATT_FILTER_TILT] = {2u, false},
    [ATT_FILTER_MEKF] = {2u, false},
};

/** Tracks the recovery contract over a run of good samples; true when the sample just stepped breaks it. */
typedef struct {
    fz_recovery_t rule;
    unsigned seen;      /* good samples stepped */
    unsigned first_ok;  /* the first whose output was good (1-based; 0: none yet) */
    bool last_bad;      /* the previous one's output was bad */
    char why[160];
} fz_recover_t;

static bool recover_breaks(fz_recover_t *r, uint32_t flags)
{
    const uint32_t badf = (uint32_t)(ATT_FLAG_NUMERIC | ATT_FLAG_NOT_READY) | FZ_INVALID;
    const bool bad = (flags & badf) != 0u;
    bool broken = false;
    r->seen++;
    if (!bad && r->first_ok == 0u) {
        r->first_ok = r->seen;
    }
    if (!r->rule.isolated) {
        broken = bad && r->seen >= r->rule.n;
    } else if (r->first_ok == 0u) {
        broken = r->seen >= r->rule.n;
    } else if (bad) {
        broken = r->last_bad || (flags & ((uint32_t)ATT_FLAG_NOT_READY | FZ_INVALID)) != 0u;
    }
    if (broken) {
        snprintf(r->why, sizeof r->why, "flags %04x at good sample %u (recovery bound %u%s; first good output %u)",
                 flags, r->seen, r->rule.n, r->rule.isolated ? ", isolated NUMERIC allowed after" : "",
                 r->first_ok);
    }
    r->last_bad = bad;
    return broken;
}

/* --- settings fields ---------------------------------------------------------------------------- */

typedef enum { T_F32, T_U32, T_ENUM, T_BOOL } ftype_t;
typedef struct {
    const char *name;
    size_t off;
    ftype_t t;
} field_t;

#define FF(m, fld, t) {#fld, offsetof(att_filter_settings_t, m.fld), t}
#define FV(m, fld) FF(m, fld.x, T_F32), FF(m, fld.y, T_F32), FF(m, fld.z, T_F32)
#define FQ(m, fld) FF(m, fld.w, T_F32), FF(m, fld.x, T_F32), FF(m, fld.y, T_F32), FF(m, fld.z, T_F32)

static const field_t f_ars[] = {
    FF(ars, dt, T_F32), FF(ars, gain, T_F32), FF(ars, tau, T_F32), FF(ars, gain_c, T_F32),
    FF(ars, gravity, T_F32), FF(ars, accel_reject, T_F32), FF(ars, accel_range, T_F32),
    FF(ars, gyro_range, T_F32), FF(ars, bias_mode, T_ENUM), FF(ars, bias_n_max, T_U32), FV(ars, bias_init),
    FF(ars, rest_gyro, T_F32), FF(ars, rest_accel, T_F32), FF(ars, rest_time, T_F32),
    FF(ars, integration, T_ENUM), FF(ars, init_from_accel, T_BOOL), FQ(ars, q_init), FF(ars, tau_acc_lp, T_F32),
};
static const field_t f_mars[] = {
    FF(mars, dt, T_F32), FF(mars, alpha_acc, T_F32), FF(mars, alpha_mag, T_F32), FF(mars, tau_acc, T_F32),
    FF(mars, tau_mag, T_F32), FF(mars, mag_mode, T_ENUM), FF(mars, gravity, T_F32),
    FF(mars, accel_reject, T_F32), FF(mars, accel_range, T_F32), FF(mars, gyro_range, T_F32),
    FF(mars, mag_range, T_F32), FF(mars, mag_norm_reject, T_F32), FF(mars, mag_dip_reject, T_F32),
    FV(mars, bias_init), FF(mars, init_from_sensors, T_BOOL), FQ(mars, q_init), FV(mars, m0_init),
    FF(mars, integration, T_ENUM), FF(mars, tau_acc_lp, T_F32), FF(mars, bias_mode, T_ENUM),
    FF(mars, bias_n_max, T_U32), FF(mars, rest_gyro, T_F32), FF(mars, rest_accel, T_F32),
    FF(mars, rest_time, T_F32),
};
static const field_t f_kf[] = {
    FF(kf, dt, T_F32), FF(kf, q_noise, T_F32), FF(kf, r_noise, T_F32), FF(kf, r_accel, T_F32),
    FF(kf, gate, T_F32), FF(kf, p0, T_F32), FF(kf, gravity, T_F32), FF(kf, accel_reject, T_F32),
    FF(kf, accel_range, T_F32), FF(kf, gyro_range, T_F32), FF(kf, bias_mode, T_ENUM), FF(kf, bias_n_max, T_U32),
    FV(kf, bias_init), FF(kf, rest_gyro, T_F32), FF(kf, rest_accel, T_F32), FF(kf, rest_time, T_F32),
    FF(kf, tau_acc_lp, T_F32), FF(kf, init_from_accel, T_BOOL), FQ(kf, q_init), FF(kf, noise_rates, T_BOOL),
};
static const field_t f_ekf[] = {
    FF(ekf, dt, T_F32), FF(ekf, q_phi, T_F32), FF(ekf, q_theta, T_F32), FF(ekf, q_psi, T_F32),
    FF(ekf, q_bias, T_F32), FF(ekf, r_phi, T_F32), FF(ekf, r_theta, T_F32), FF(ekf, r_accel, T_F32),
    FF(ekf, gate, T_F32), FF(ekf, p0, T_F32), FF(ekf, p0_bias, T_F32), FF(ekf, p_max, T_F32),
    FF(ekf, gravity, T_F32), FF(ekf, accel_reject, T_F32), FF(ekf, accel_range, T_F32),
    FF(ekf, gyro_range, T_F32), FF(ekf, cos_min, T_F32), FF(ekf, tau_acc_lp, T_F32),
    FF(ekf, init_from_accel, T_BOOL), FV(ekf, euler_init), FV(ekf, bias_init), FF(ekf, noise_rates, T_BOOL),
};
static const field_t f_mekf[] = {
    FF(mekf, dt, T_F32), FF(mekf, gyro_noise, T_F32), FF(mekf, gyro_rate_noise, T_F32),
    FF(mekf, bias_noise, T_F32), FF(mekf, accel_noise, T_F32), FF(mekf, r_accel, T_F32), FF(mekf, gate, T_F32),
    FF(mekf, gate_recover, T_F32), FF(mekf, mag_noise, T_F32), FF(mekf, mag_gate, T_F32), FF(mekf, p0_att, T_F32),
    FF(mekf, p0_bias, T_F32), FF(mekf, p_max, T_F32), FF(mekf, gravity, T_F32), FF(mekf, accel_reject, T_F32),
    FF(mekf, accel_range, T_F32), FF(mekf, gyro_range, T_F32), FF(mekf, mag_range, T_F32),
    FF(mekf, mag_norm_reject, T_F32), FF(mekf, mag_dip_reject, T_F32), FF(mekf, tau_acc_lp, T_F32),
    FF(mekf, rest_noise, T_F32), FF(mekf, rest_gyro, T_F32), FF(mekf, rest_accel, T_F32),
    FF(mekf, rest_time, T_F32), FF(mekf, use_mag, T_BOOL), FF(mekf, init_from_sensors, T_BOOL),
    FQ(mekf, q_init), FV(mekf, m0_init), FV(mekf, bias_init), FF(mekf, gyro_scale_sd, T_F32),
    FF(mekf, gyro_scale_init, T_F32),
};
/*
 * Fields added after the first corpora (issue 23), in tables of their own: an input reaches them only with
 * bit 7 of its kind byte set (FZ_EXT), so every reproducer of tests/fuzz/regressions (kind bytes 0..6)
 * decodes as when it was found. ars_x .. mekf_x: the recoveries, mars's learnt reference and fast phase.
 * (kf's reproducer keeps a kind byte below 0x80 too: tests/test_fuzz.py.) The fields after a table's
 * first tier (the *_X_TIER1 first ones: mars's and mekf's declination, ekf's recovery, added after the
 * reproducers of F14 (mars, 0xd3) and of an ekf finding (0xff) were found with bit 7 set) are reached
 * only with the kind byte's top bits 101 (FZ_EXT2), so those reproducers too decode as when found.
 * ars's covariance model (gyro_noise, accel_noise) and mars's are in that second tier, and mekf's learnt
 * reference (mag_ref_tau, mag_new_time); mars's and mekf's hard-iron estimate (hard_iron_tau, hard_iron_rate);
 * mekf's low-pass before its first rest (tau_acc_lp_no_rest).
 */
static const field_t f_ars_x[] = {
    FF(ars, recovery_time, T_F32), FF(ars, gyro_noise, T_F32), FF(ars, accel_noise, T_F32),
};
static const field_t f_mars_x[] = {
    FF(mars, mag_ref_tau, T_F32), FF(mars, mag_new_time, T_F32), FF(mars, tau_mag_fast, T_F32),
    FF(mars, tau_bias_mag, T_F32), FF(mars, recovery_time, T_F32), FF(mars, declination, T_F32),
    FF(mars, gyro_noise, T_F32), FF(mars, accel_noise, T_F32), FF(mars, mag_noise, T_F32),
    FF(mars, hard_iron_tau, T_F32), FF(mars, hard_iron_rate, T_F32),
};
#define FZ_MARS_X_TIER1 5u
static const field_t f_kf_x[] = {
    FF(kf, recovery_time, T_F32),
};
static const field_t f_mekf_x[] = {
    FF(mekf, recovery_time, T_F32), FF(mekf, declination, T_F32), FF(mekf, mag_ref_tau, T_F32),
    FF(mekf, mag_new_time, T_F32), FF(mekf, hard_iron_tau, T_F32), FF(mekf, hard_iron_rate, T_F32),
    FF(mekf, tau_acc_lp_no_rest, T_F32),
};
#define FZ_MEKF_X_TIER1 1u
static const field_t f_ekf_x[] = {
    FF(ekf, recovery_time, T_F32),
};
#define FZ_EKF_X_TIER1 0u
static const field_t f_gyro[] = {
    FF(gyro, dt, T_F32), FF(gyro, gyro_range, T_F32), FF(gyro, cos_min, T_F32), FV(gyro, euler_init),
};
static const field_t f_tilt[] = {
    FF(tilt, gravity, T_F32), FF(tilt, accel_range, T_F32), FF(tilt, normalise, T_BOOL),
};

typedef struct {
    const field_t *f; /* the first table */
    size_t n;
    const field_t *x; /* the later fields (FZ_EXT), or NULL */
    size_t nx;
    size_t nx1; /* the first nx1 of them: FZ_EXT alone; all nx: FZ_EXT and FZ_EXT2 */
} fields_t;

#define FZ_EXT 0x80u /* bit 7 of the kind byte: the later fields (their first tier) can be mutated too */
#define FZ_EXT2(b0) (((b0) & 0xE0u) == 0xA0u) /* top bits 101: every later field */

/* Field i of the first table, then of the later ones. */
static const field_t *field_at(const fields_t *fs, size_t i)
{
    return (i < fs->n) ? &fs->f[i] : &fs->x[i - fs->n];
}

static fields_t fields_of(att_filter_kind_t kind)
{
    fields_t r = {NULL, 0u, NULL, 0u, 0u};
#define FZ_SET(arr) (r.f = (arr), r.n = sizeof(arr) / sizeof((arr)[0]))
#define FZ_SET_X(arr, tier1) (r.x = (arr), r.nx = sizeof(arr) / sizeof((arr)[0]), r.nx1 = (tier1))
    switch (kind) {
    case ATT_FILTER_ARS: FZ_SET(f_ars); FZ_SET_X(f_ars_x, 1u); break;
    case ATT_FILTER_MARS: FZ_SET(f_mars); FZ_SET_X(f_mars_x, FZ_MARS_X_TIER1); break;
    case ATT_FILTER_KF: FZ_SET(f_kf); FZ_SET_X(f_kf_x, 1u); break;
    case ATT_FILTER_EKF: FZ_SET(f_ekf); FZ_SET_X(f_ekf_x, FZ_EKF_X_TIER1); break;
    case ATT_FILTER_MEKF: FZ_SET(f_mekf); FZ_SET_X(f_mekf_x, FZ_MEKF_X_TIER1); break;
    case ATT_FILTER_GYRO: FZ_SET(f_gyro); break;
    default: FZ_SET(f_tilt); break;
    }
#undef FZ_SET
#undef FZ_SET_X
    return r;
}

static float get_f32(const att_filter_settings_t *s, const fields_t *fs, const char *name)
{
    size_t i;
    float v = 0.0f;
    for (i = 0; i < fs->n + fs->nx; ++i) {
        const field_t *fd = field_at(fs, i);
        if (strcmp(fd->name, name) == 0) {
            memcpy(&v, (const unsigned char *)s + fd->off, sizeof v);
        }
    }
    return v;
}

static void mutate(att_filter_settings_t *s, const field_t *fld, fz_reader_t *r)
{
    unsigned char *p = (unsigned char *)s + fld->off;
    switch (fld->t) {
    case T_F32: {
        float v = fz_float(r);
        memcpy(p, &v, sizeof v);
        break;
    }
    case T_BOOL: {
        bool b = (fz_u8(r) & 1u) != 0u;
        memcpy(p, &b, sizeof b);
        break;
    }
    case T_ENUM: {
        uint8_t sel = fz_u8(r);
        int v = (sel & 0x80u) ? (int)fz_u32(r) : (int)(sel & 7u); /* small values, sometimes any int */
        memcpy(p, &v, sizeof v);
        break;
    }
    default: {
        uint8_t sel = fz_u8(r);
        uint32_t v = (sel & 0x80u) ? fz_u32(r) : (uint32_t)1u << (sel & 31u);
        memcpy(p, &v, sizeof v);
        break;
    }
    }
}

/* --- known findings ----------------------------------------------------------------------------- */

static char g_known[4096];
static const char *g_findings_dir;
static const uint8_t *g_input;
static size_t g_input_size;
static unsigned long g_known_hits[64];
static char g_known_names[64][32];
static size_t g_known_n;

static void report_known(void)
{
    size_t i;
    for (i = 0; i < g_known_n; ++i) {
        fprintf(stderr, "attica fuzz: known finding %s: %lu inputs\n", g_known_names[i], g_known_hits[i]);
    }
}

static bool is_known(const char *cls)
{
    const char *p = g_known;
    size_t n = strlen(cls);
    if (strcmp(g_known, "*") == 0) {
        return true; /* triage: every class is counted, none aborts */
    }
    while ((p = strstr(p, cls)) != NULL) {
        bool start = (p == g_known) || p[-1] == ',' || p[-1] == '\n' || p[-1] == ' ';
        bool end = p[n] == '\0' || p[n] == ',' || p[n] == '\n' || p[n] == ' ' || p[n] == '\r';
        if (start && end) {
            return true;
        }
        p += n;
    }
    return false;
}

/** A violated invariant: abort, or (known class) count it and give up on this input. */
static void violation(att_filter_kind_t kind, const char *inv, const char *detail)
{
    char cls[64];
    size_t i;
    snprintf(cls, sizeof cls, "%s:%s", att_filter_name(kind), inv);
    if (!is_known(cls)) {
        FZ_FAIL("%s: %s", cls, detail);
    }
    for (i = 0; i < g_known_n && strcmp(g_known_names[i], cls) != 0; ++i) {
    }
    if (i == g_known_n && g_known_n < 64u) {
        snprintf(g_known_names[g_known_n], sizeof g_known_names[0], "%s", cls);
        g_known_n++;
        if (g_findings_dir != NULL) {
            char path[512];
            FILE *fh;
            snprintf(path, sizeof path, "%s/filter-%s-%s.bin", g_findings_dir, att_filter_name(kind), inv);
            fh = fopen(path, "rb");
            if (fh == NULL && (fh = fopen(path, "wb")) != NULL) {
                fwrite(g_input, 1u, g_input_size, fh);
                fprintf(stderr, "attica fuzz: first %s saved as %s (%s)\n", cls, path, detail);
            }
            if (fh != NULL) fclose(fh);
        }
    }
    if (i < 64u) g_known_hits[i]++;
}

/* --- checks ------------------------------------------------------------------------------------- */

typedef struct {
    att_filter_kind_t kind;
    const att_filter_settings_t *s;
    fields_t fs;
    bool failed; /* a known violation: stop this input */
} ctx_t;

#define FZ_VIOLATE(c, inv, ...)                                                                        \
    do {                                                                                               \
        char d_[400];                                                                                  \
        snprintf(d_, sizeof d_, __VA_ARGS__);                                                          \
        violation((c)->kind, inv, d_);                                                                 \
        (c)->failed = true;                                                                            \
        return;                                                                                        \
    } while (0)

static int g_verbose;
static long g_break_at = -1; /* ATT_FUZZ_BREAK_AT=N: self test, the state is overwritten with NaN bytes before step N */
static long g_break_recovery = -1; /* ATT_FUZZ_BREAK_RECOVERY=N: self test of STUCK, see the recovery loop */

static void dump_settings(att_filter_kind_t kind, const att_filter_settings_t *s, const fields_t *fs)
{
    size_t i;
    fprintf(stderr, "settings of %s:\n", att_filter_name(kind));
    for (i = 0; i < fs->n + fs->nx; ++i) {
        const field_t *fd = field_at(fs, i);
        const unsigned char *p = (const unsigned char *)s + fd->off;
        if (fd->t == T_F32) {
            float v;
            memcpy(&v, p, sizeof v);
            fprintf(stderr, "  %-16s %a (%.9g)\n", fd->name, (double)v, (double)v);
        } else if (fd->t == T_BOOL) {
            bool b;
            memcpy(&b, p, sizeof b);
            fprintf(stderr, "  %-16s %d\n", fd->name, (int)b);
        } else {
            uint32_t v;
            memcpy(&v, p, sizeof v);
            fprintf(stderr, "  %-16s %u\n", fd->name, v);
        }
    }
}

static bool spd(const double *a, int n)
{
    double l[36];
    int i;
    int j;
    int k;
    for (j = 0; j < n; ++j) {
        for (i = j; i < n; ++i) {
            double s = a[i * n + j];
            for (k = 0; k < j; ++k) s -= l[i * n + k] * l[j * n + k];
            if (i == j) {
                if (!(s > 0.0) || !isfinite(s)) return false;
                l[j * n + j] = sqrt(s);
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    return true;
}

/** The full covariance (n x n, double) of the filter state: kf P = p I, ekf and mekf the packed 6x6 upper
 * triangle. */
static int full_cov(const att_filter_t *f, att_filter_kind_t kind, double *a)
{
    int i;
    int j;
    if (kind == ATT_FILTER_KF) {
        for (i = 0; i < 16; ++i) a[i] = (i % 5 == 0) ? (double)f->u.kf.st.p : 0.0;
        return 4;
    }
    {
        const float *p = (kind == ATT_FILTER_MEKF) ? f->u.mekf.st.p : f->u.ekf.st.p;
        int k = 0;
        for (i = 0; i < 6; ++i) {
            for (j = i; j < 6; ++j) {
                a[i * 6 + j] = (double)p[k];
                a[j * 6 + i] = (double)p[k];
                ++k;
            }
        }
    }
    return 6;
}

static void check_cov(ctx_t *c, const att_filter_t *f, const att_output_t *o)
{
    double a[36];
    int n;
    int i;
    for (i = 0; i < 4; ++i) {
        if (!fz_finite(o->cov[i]) || !(o->cov[i] > 0.0f)) {
            FZ_VIOLATE(c, "COV_POSITIVE", "step %u: cov[%d] = %a", o->steps, i, (double)o->cov[i]);
        }
    }
    n = full_cov(f, c->kind, a);
    if (!spd(a, n)) {
        FZ_VIOLATE(c, "P_SPD", "step %u: P not positive definite (diag %a %a %a %a)", o->steps, a[0], a[n + 1],
                   a[2 * n + 2], a[3 * n + 3]);
    }
}

/* The MEKF's gyro scale estimate: |s| <= ATT_MEKF_SCALE_MAX, p_scale finite and >= 0, |V| finite and
 * within ATT_MEKF_SENS_MAX (after each step's limits). */
static void check_mekf_scale(ctx_t *c, const att_filter_t *f, const att_output_t *o)
{
    const att_mekf_state_t *st = &f->u.mekf.st;
    double n2 = 0.0;
    int i;
    for (i = 0; i < 6; ++i) {
        n2 += (double)st->scale_v[i] * st->scale_v[i];
    }
    if (!fz_finite(st->scale) || fabs((double)st->scale) > (double)ATT_MEKF_SCALE_MAX) {
        FZ_VIOLATE(c, "SCALE_BOUND", "step %u: gyro scale %a", o->steps, (double)st->scale);
    }
    if (!fz_finite(st->p_scale) || st->p_scale < 0.0f) {
        FZ_VIOLATE(c, "SCALE_VAR", "step %u: p_scale %a", o->steps, (double)st->p_scale);
    }
    if (!(sqrt(n2) <= (double)ATT_MEKF_SENS_MAX * (1.0 + 1e-5))) {
        FZ_VIOLATE(c, "SENS_BOUND", "step %u: |V| = %g", o->steps, sqrt(n2));
    }
}

static void check_valid_output(ctx_t *c, const att_filter_t *f, const att_output_t *o)
{
    double n2;
    if (!fz_finite(o->q.w) || !fz_finite(o->q.x) || !fz_finite(o->q.y) || !fz_finite(o->q.z)) {
        FZ_VIOLATE(c, "Q_FINITE", "step %u flags %04x: q = (%a, %a, %a, %a)", o->steps, o->flags, (double)o->q.w,
                   (double)o->q.x, (double)o->q.y, (double)o->q.z);
    }
    n2 = (double)o->q.w * o->q.w + (double)o->q.x * o->q.x + (double)o->q.y * o->q.y + (double)o->q.z * o->q.z;
    if (fabs(sqrt(n2) - 1.0) > FZ_Q_TOL) {
        FZ_VIOLATE(c, "Q_UNIT", "step %u flags %04x: |q| - 1 = %g", o->steps, o->flags, sqrt(n2) - 1.0);
    }
    if (!fz_finite(o->euler.x) || !fz_finite(o->euler.y) || !fz_finite(o->euler.z)) {
        FZ_VIOLATE(c, "EULER_FINITE", "step %u: euler (%a, %a, %a)", o->steps, (double)o->euler.x,
                   (double)o->euler.y, (double)o->euler.z);
    }
    if (fabs((double)o->euler.y) > (double)1.57079637f || fabs((double)o->euler.x) > (double)3.14159274f ||
        fabs((double)o->euler.z) > (double)3.14159274f) {
        FZ_VIOLATE(c, "EULER_RANGE", "step %u flags %04x: euler (%.9g, %.9g, %.9g) outside [-pi, pi] x [-pi/2, pi/2] x [-pi, pi]",
                   o->steps, o->flags, (double)o->euler.x, (double)o->euler.y, (double)o->euler.z);
    }
    if (!fz_finite(o->gyro_bias.x) || !fz_finite(o->gyro_bias.y) || !fz_finite(o->gyro_bias.z)) {
        FZ_VIOLATE(c, "BIAS_FINITE", "step %u: bias (%a, %a, %a)", o->steps, (double)o->gyro_bias.x,
                   (double)o->gyro_bias.y, (double)o->gyro_bias.z);
    }
    if (c->kind == ATT_FILTER_ARS || c->kind == ATT_FILTER_MARS) {
        double range = (double)get_f32(c->s, &c->fs, "gyro_range");
        double b0[3] = {(double)get_f32(c->s, &c->fs, "bias_init.x"), (double)get_f32(c->s, &c->fs, "bias_init.y"),
                        (double)get_f32(c->s, &c->fs, "bias_init.z")};
        double b[3] = {(double)o->gyro_bias.x, (double)o->gyro_bias.y, (double)o->gyro_bias.z};
        int i;
        for (i = 0; i < 3; ++i) {
            double lim = fabs(b0[i]) > range ? fabs(b0[i]) : range;
            if (fabs(b[i]) > lim * (1.0 + 1e-5)) {
                FZ_VIOLATE(c, "BIAS_BOUND", "step %u: bias[%d] = %g beyond %g", o->steps, i, b[i], lim);
            }
        }
    }
    if (c->kind == ATT_FILTER_KF || c->kind == ATT_FILTER_EKF || c->kind == ATT_FILTER_MEKF) {
        check_cov(c, f, o);
    }
    if (c->kind == ATT_FILTER_MEKF) {
        check_mekf_scale(c, f, o);
    }
}

static bool same_floats(const float *a, const float *b, int n)
{
    int i;
    for (i = 0; i < n; ++i) {
        if (fz_float_bits(a[i]) != fz_float_bits(b[i]) && !(a[i] != a[i] && b[i] != b[i])) return false;
    }
    return true;
}

/** The fields a holds (a->valid) are in b, bit for bit (NaN equals NaN), and so are flags and steps. */
static bool same_output(const att_output_t *a, const att_output_t *b)
{
    if ((a->valid & ~b->valid) != 0u) return false;
    if ((a->valid & ATT_OUT_Q) != 0u) {
        const float qa[4] = {a->q.w, a->q.x, a->q.y, a->q.z};
        const float qb[4] = {b->q.w, b->q.x, b->q.y, b->q.z};
        if (!same_floats(qa, qb, 4)) return false;
    }
    if ((a->valid & ATT_OUT_EULER) != 0u) {
        const float ea[3] = {a->euler.x, a->euler.y, a->euler.z};
        const float eb[3] = {b->euler.x, b->euler.y, b->euler.z};
        if (!same_floats(ea, eb, 3)) return false;
    }
    if ((a->valid & ATT_OUT_BIAS) != 0u) {
        const float ba[3] = {a->gyro_bias.x, a->gyro_bias.y, a->gyro_bias.z};
        const float bb[3] = {b->gyro_bias.x, b->gyro_bias.y, b->gyro_bias.z};
        if (!same_floats(ba, bb, 3)) return false;
    }
    if ((a->valid & ATT_OUT_COV) != 0u && !same_floats(a->cov, b->cov, 4)) return false;
    return a->flags == b->flags && a->steps == b->steps;
}

/** One step and its per-step invariants. */
static uint32_t step(ctx_t *c, att_filter_t *f, const att_sample_t *in, att_output_t *prev, att_output_t *o)
{
    att_output_t again;
    uint32_t flags = att_filter_step(f, in, o);
    c->failed = false;
    if (g_verbose) {
        fprintf(stderr, "step %u: gyr (%a %a %a) acc (%a %a %a) mag (%a %a %a) -> flags %04x q (%.9g %.9g %.9g %.9g) "
                "cov (%g %g %g %g) bias (%g %g %g)\n", o->steps, (double)in->gyr.x, (double)in->gyr.y,
                (double)in->gyr.z, (double)in->acc.x, (double)in->acc.y, (double)in->acc.z, (double)in->mag.x,
                (double)in->mag.y, (double)in->mag.z, flags, (double)o->q.w, (double)o->q.x, (double)o->q.y,
                (double)o->q.z, (double)o->cov[0], (double)o->cov[1], (double)o->cov[2], (double)o->cov[3],
                (double)o->gyro_bias.x, (double)o->gyro_bias.y, (double)o->gyro_bias.z);
    }
    if (flags != o->flags) {
        violation(c->kind, "FLAGS", "returned flags differ from out.flags");
        c->failed = true;
        return flags;
    }
    att_filter_output(f, &again);
    if (again.valid != (uint32_t)ATT_OUT_ALL || !same_output(o, &again)) {
        violation(c->kind, "FLAGS", "att_filter_output differs from the step's output");
        c->failed = true;
        return flags;
    }
    *o = again; /* the full record from here on */
    if (o->steps != prev->steps + 1u) {
        violation(c->kind, "STEPS", "steps did not count");
        c->failed = true;
        return flags;
    }
    if ((flags & ATT_FLAG_NUMERIC) != 0u && memcmp(&o->q, &prev->q, sizeof o->q) != 0) {
        char d[200];
        snprintf(d, sizeof d, "step %u: NUMERIC but q changed (%a, %a, %a, %a) -> (%a, %a, %a, %a)", o->steps,
                 (double)prev->q.w, (double)prev->q.x, (double)prev->q.y, (double)prev->q.z, (double)o->q.w,
                 (double)o->q.x, (double)o->q.y, (double)o->q.z);
        violation(c->kind, "NUMERIC_KEPT", d);
        c->failed = true;
        return flags;
    }
    if ((flags & FZ_INVALID) == 0u) {
        check_valid_output(c, f, o);
    }
    *prev = *o;
    return flags;
}

/* |a| of the good samples: the kind's gravity (below its accel_range by the settings contract, also for a
   normalising tilt, which then ignores the norm: FZ_G there could be beyond a valid accel_range, F13) */
static float gravity_of(const ctx_t *c)
{
    if (c->kind == ATT_FILTER_GYRO) return FZ_G;
    return get_f32(c->s, &c->fs, "gravity");
}

static att_sample_t rest_sample(float g)
{
    att_sample_t s;
    s.gyr.x = 0.0f;
    s.gyr.y = 0.0f;
    s.gyr.z = 0.0f;
    s.acc.x = 0.0f;
    s.acc.y = 0.0f;
    s.acc.z = g;
    s.mag.x = 0.0f;
    s.mag.y = 20.0f;
    s.mag.z = -40.0f;
    return s;
}

static void read_sample(fz_reader_t *r, att_sample_t *s, float g)
{
    uint8_t mode = fz_u8(r);
    *s = rest_sample(g);
    if (mode < 0x40u) { /* good motion: small rates, accel near gravity, field near the reference */
        s->gyr.x = (float)(int8_t)fz_u8(r) / 32.0f;
        s->gyr.y = (float)(int8_t)fz_u8(r) / 32.0f;
        s->gyr.z = (float)(int8_t)fz_u8(r) / 32.0f;
        s->acc.x += (float)(int8_t)fz_u8(r) / 16.0f;
        s->acc.y += (float)(int8_t)fz_u8(r) / 16.0f;
        s->acc.z += (float)(int8_t)fz_u8(r) / 16.0f;
        s->mag.x += (float)(int8_t)fz_u8(r) / 4.0f;
        s->mag.y += (float)(int8_t)fz_u8(r) / 4.0f;
        s->mag.z += (float)(int8_t)fz_u8(r) / 4.0f;
    } else if (mode < 0x80u) {
        /* rest */
    } else if (mode < 0xC0u) { /* anything */
        float *v = &s->gyr.x;
        int i;
        for (i = 0; i < 9; ++i) v[i] = fz_float(r);
    } else { /* a good sample with one bad component */
        float *v = &s->gyr.x;
        v[(mode - 0xC0u) % 9u] = fz_float(r);
    }
}

/* --- entry -------------------------------------------------------------------------------------- */

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    const char *k = getenv("ATT_FUZZ_KNOWN");
    (void)argc;
    (void)argv;
    g_known[0] = '\0';
    if (k != NULL && k[0] == '@') {
        FILE *fh = fopen(k + 1, "rb");
        if (fh != NULL) {
            size_t n = fread(g_known, 1u, sizeof g_known - 1u, fh);
            g_known[n] = '\0';
            fclose(fh);
        }
        /* lines starting with '#' are comments: blank them */
        {
            char *p = g_known;
            while (p && *p) {
                if (*p == '#') {
                    while (*p && *p != '\n') *p++ = ' ';
                }
                p = strchr(p, '\n');
                if (p) ++p;
            }
        }
    } else if (k != NULL) {
        snprintf(g_known, sizeof g_known, "%s", k);
    }
    g_findings_dir = getenv("ATT_FUZZ_FINDINGS");
    g_verbose = getenv("ATT_FUZZ_VERBOSE") != NULL;
    if (getenv("ATT_FUZZ_BREAK_AT") != NULL) g_break_at = strtol(getenv("ATT_FUZZ_BREAK_AT"), NULL, 10);
    if (getenv("ATT_FUZZ_BREAK_RECOVERY") != NULL) {
        g_break_recovery = strtol(getenv("ATT_FUZZ_BREAK_RECOVERY"), NULL, 10);
    }
    atexit(report_known);
    return 0;
}

static const float dts[] = {0.0035f, 0.01f, 0.001f, 0.1f, 1.0f, 0.0001f, 0.02f, 0.5f};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_reader_t r;
    att_filter_kind_t kind;
    att_filter_settings_t s;
    att_filter_t f;
    att_filter_t before;
    att_output_t prev;
    att_output_t o;
    ctx_t c;
    uint8_t b0;
    uint8_t b1;
    size_t nsel;
    float dt;
    size_t nmut;
    size_t i;
    att_status_t st;
    float g;

    if (size > 4096u) return -1;
    g_input = data;
    g_input_size = size;
    fz_init(&r, data, size);
    b0 = fz_u8(&r);
    kind = (att_filter_kind_t)(1 + b0 % 7u);
    b1 = fz_u8(&r);
    dt = (b1 & 0x10u) ? fz_float(&r) : dts[(b1 >> 5) & 7u];
    if (att_filter_settings_preset(kind, (b1 & 1u) ? ATT_PRESET_SEED : ATT_PRESET_DEFAULT, dt, &s) != ATT_OK) {
        FZ_FAIL("settings_preset refused kind %d", (int)kind);
    }
    c.kind = kind;
    c.s = &s;
    c.fs = fields_of(kind);
    c.failed = false;
    nmut = (size_t)((b1 >> 1) & 7u) + ((b1 & 0x08u) ? 5u : 0u);
    nsel = c.fs.n + (((b0 & FZ_EXT) != 0u) ? (FZ_EXT2(b0) ? c.fs.nx : c.fs.nx1) : 0u);
    for (i = 0; i < nmut; ++i) {
        mutate(&s, field_at(&c.fs, fz_u8(&r) % nsel), &r);
    }

    if (g_verbose) dump_settings(kind, &s, &c.fs);
    memset(&f, 0xA5, sizeof f);
    before = f;
    st = att_filter_init(&f, kind, &s);
    if (st != ATT_OK) {
        if (g_verbose) fprintf(stderr, "init refused: %d\n", (int)st);
        if (memcmp(&f, &before, sizeof f) != 0) violation(kind, "INIT_CHANGED", "refused init changed f");
        return 0;
    }
    att_filter_output(&f, &prev);

    g = gravity_of(&c);
    {
        size_t nsteps = (size_t)fz_u8(&r);
        for (i = 0; i < nsteps && fz_left(&r) > 0u; ++i) {
            att_sample_t in;
            read_sample(&r, &in, g);
            if ((long)i == g_break_at) memset(&f.u, 0xFF, sizeof f.u);
            (void)step(&c, &f, &in, &prev, &o);
            if (c.failed) return 0;
        }
    }

    /* recovery: good samples at rest (the recovery contract), then the attitude must move again */
    {
        att_sample_t in = rest_sample(g);
        uint32_t flags = 0u;
        fz_recover_t rec;
        memset(&rec, 0, sizeof rec);
        rec.rule = fz_recovery[kind];
        for (i = 0; i < rec.rule.n + FZ_HOLD; ++i) {
            if (g_break_recovery >= 0 && (long)i >= g_break_recovery) {
                /* self test: a filter that never recovers, as seen from outside (reset before every
                   sample, whose accel is NaN: NOT_READY at every step) */
                att_sample_t broken = in;
                broken.acc.x = NAN;
                att_filter_reset(&f);
                att_filter_output(&f, &prev);
                flags = step(&c, &f, &broken, &prev, &o);
            } else {
                flags = step(&c, &f, &in, &prev, &o);
            }
            if (c.failed) return 0;
            if (recover_breaks(&rec, flags)) {
                char d[240];
                snprintf(d, sizeof d, "at rest (|a| = %a): %s", (double)g, rec.why);
                violation(kind, "STUCK", d);
                return 0;
            }
        }
        if ((flags & (ATT_FLAG_NUMERIC | ATT_FLAG_NOT_READY | FZ_INVALID)) == 0u) {
            check_valid_output(&c, &f, &o);
            if (c.failed) return 0;
        }
        {
            /* a roll at 0.5 rad/s seen consistently by gyro, accel and mag: whatever the gains, q moves */
            float range = (kind == ATT_FILTER_TILT) ? 1e30f : get_f32(&s, &c.fs, "gyro_range");
            float dtk = (kind == ATT_FILTER_TILT) ? 0.01f : get_f32(&s, &c.fs, "dt");
            float arange = (kind == ATT_FILTER_GYRO) ? 1e30f : get_f32(&s, &c.fs, "accel_range");
            att_quat_t q0 = o.q;
            uint32_t seen = 0u;
            double phi = 0.0;
            const bool clean = range > 1.0f && arange > g * 1.01f; /* the roll's samples are valid */
            rec.seen = rec.rule.n; /* recovered: from here on the rule after the bound */
            for (i = 0; i < 16; ++i) {
                uint32_t fl;
                phi += 0.5 * (double)dtk;
                in.gyr.x = 0.5f;
                in.acc.y = (float)((double)g * sin(phi));
                in.acc.z = (float)((double)g * cos(phi));
                in.mag.y = (float)(20.0 * cos(phi) - 40.0 * sin(phi));
                in.mag.z = (float)(-20.0 * sin(phi) - 40.0 * cos(phi));
                fl = step(&c, &f, &in, &prev, &o);
                seen |= fl;
                if (c.failed) return 0;
                if (clean && recover_breaks(&rec, fl)) {
                    char d[240];
                    snprintf(d, sizeof d, "during a 0.5 rad/s roll (dt %a), after recovering: %s", (double)dtk, rec.why);
                    violation(kind, "STUCK", d);
                    return 0;
                }
            }
            if (range > 1.0f && arange > g * 1.01f && phi >= 1e-3 && (seen & ATT_FLAG_AT_REST) == 0u &&
                memcmp(&q0, &o.q, sizeof q0) == 0) {
                char d[200];
                snprintf(d, sizeof d, "16 steps of a 0.5 rad/s roll (dt %a, %g rad) did not change q; flags %04x",
                         (double)dtk, phi, seen);
                violation(kind, "FROZEN", d);
                return 0;
            }
        }
    }

    /* reset == fresh init, and both step alike */
    {
        att_filter_t fresh;
        att_output_t a;
        att_output_t b;
        att_sample_t in = rest_sample(g);
        FZ_CHECK(att_filter_init(&fresh, kind, &s) == ATT_OK, "second init with the same settings refused");
        att_filter_reset(&f);
        att_filter_output(&f, &a);
        att_filter_output(&fresh, &b);
        if (!same_output(&a, &b)) {
            violation(kind, "RESET", "output after reset differs from a fresh init");
            return 0;
        }
        in.gyr.x = 0.25f;
        (void)att_filter_step(&f, &in, &a);
        (void)att_filter_step(&fresh, &in, &b);
        if (a.valid != b.valid || !same_output(&a, &b)) {
            violation(kind, "RESET", "first step after reset differs from a fresh filter's");
            return 0;
        }
        att_filter_output(&f, &a);
        att_filter_output(&fresh, &b);
        if (!same_output(&a, &b)) {
            violation(kind, "RESET", "first step after reset differs from a fresh filter's");
            return 0;
        }
    }
    return 0;
}
