/**
 * @file att_bench.c
 * @brief Step a filter N times on synthetic deterministic inputs (for instruction counts and stack).
 *
 * Usage: att_bench KIND[+STAGE] N [stack]     KIND: a filter name of att_filter_name (ars, gyro, tilt, ...)
 *
 * STAGE (att_calib.h; a comma-separated list) enables input/output stages: gyro, accel, mag (models),
 * remap ("+y-x+z"), quat (a mounting quaternion), all (gyro + accel + mag models and the quaternion
 * mounting), ned (output convention), accout (acceleration outputs kept; att_filter_accel is then called
 * after every step, so that its cost on request can be counted too).
 *
 * Runs att_filter_step N times with default settings (dt = 0.01 s) through the unified interface and
 * prints a checksum of the outputs. tools/attica_dev/bench.py runs it under valgrind --tool=callgrind
 * with --toggle-collect=att_filter_step for two values of N and divides the difference in
 * instructions by the difference in N, which removes start-up and initialisation costs;
 * tools/attica_dev/cycles.py counts every instruction of every att_filter_step call in a QEMU trace.
 * With "stack" (Arm targets), every call is probed instead and the deepest is printed as
 * "stack KIND BYTES" (bytes below the caller's stack pointer, att_bench_common.h).
 *
 * Inputs: the stream of att_bench_common.h, which the peers' drivers (att_peer_fusion.c,
 * att_peer_vqf.cpp) get too. Test harness: plain C99 + stdio.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "att_bench_common.h"
#include "attica/att_filter.h"

static void bench_att_sample(unsigned long i, att_sample_t *s)
{
    float g[3];
    float a[3];
    float m[3];
    bench_sample(i, g, a, m);
    s->gyr.x = g[0];
    s->gyr.y = g[1];
    s->gyr.z = g[2];
    s->acc.x = a[0];
    s->acc.y = a[1];
    s->acc.z = a[2];
    s->mag.x = m[0];
    s->mag.y = m[1];
    s->mag.z = m[2];
}

/* Non-identity settings for the stage named by stage added to c; false for an unknown name. */
static bool bench_stage(const char *stage, att_calib_settings_t *c)
{
    static const float m[9] = {1.01f, 0.02f, -0.01f, -0.015f, 0.99f, 0.005f, 0.01f, -0.02f, 1.02f};
    int i;
    int all = strcmp(stage, "all") == 0;
    if (all || strcmp(stage, "gyro") == 0) {
        for (i = 0; i < 9; i++) c->gyro.misalignment[i] = m[i];
        c->gyro.sensitivity.x = 1.02f;
        c->gyro.offset.z = 0.01f;
    }
    if (all || strcmp(stage, "accel") == 0) {
        for (i = 0; i < 9; i++) c->accel.misalignment[i] = m[8 - i];
        c->accel.sensitivity.y = 0.98f;
        c->accel.offset.x = 0.1f;
    }
    if (all || strcmp(stage, "mag") == 0) {
        for (i = 0; i < 9; i++) c->mag.soft_iron[i] = m[i];
        c->mag.hard_iron.y = 12.0f;
    }
    if (all || strcmp(stage, "quat") == 0) {
        c->mounting.w = 0.92387953f;
        c->mounting.z = 0.38268343f;
    }
    if (strcmp(stage, "remap") == 0) c->remap = att_calib_remap_parse("+y-x+z");
    if (strcmp(stage, "ned") == 0) c->convention = ATT_CONV_NED;
    if (strcmp(stage, "accout") == 0) c->accel_outputs = true;
    return all || strcmp(stage, "remap") == 0 || strcmp(stage, "ned") == 0 || strcmp(stage, "accout") == 0 ||
           strcmp(stage, "gyro") == 0 || strcmp(stage, "accel") == 0 || strcmp(stage, "mag") == 0 ||
           strcmp(stage, "quat") == 0;
}

/* Settings with every stage of the comma-separated list (e.g. "gyro,accel"); false for an unknown one. */
static bool bench_stages(const char *list, att_calib_settings_t *c)
{
    char one[16];
    size_t len = 0u;
    att_calib_settings_default(c);
    for (;; list++) {
        if (*list == ',' || *list == '\0') {
            one[len] = '\0';
            if (!bench_stage(one, c)) return false;
            len = 0u;
            if (*list == '\0') return true;
        } else if (len + 1u < sizeof one) {
            one[len++] = *list;
        }
    }
}

#if BENCH_HAVE_STACK
/* noinline: top is this function's own stack pointer, the step's depth is measured below it */
__attribute__((noinline)) static uint32_t bench_probe(att_filter_t *f, const att_sample_t *s, att_output_t *o,
                                                      uint32_t *flags)
{
    volatile uint32_t *top = bench_stack_paint();
    *flags = att_filter_step(f, s, o);
    return bench_stack_used(top);
}
#endif

int main(int argc, char **argv)
{
    att_filter_settings_t settings;
    att_filter_t f;
    att_output_t out;
    att_sample_t s;
    unsigned long n;
    unsigned long i;
    uint32_t sum = 0u;
    uint32_t deepest = 0u;
    int k;
    int stack = 0;
    att_filter_kind_t kind = ATT_FILTER_NONE;
    char *end = NULL;
    const char *stage = NULL;
    char name[16];
    bool accout = false;
    att_accel_t acc;
    if (argc == 4 && strcmp(argv[3], "stack") == 0) {
        stack = 1;
    } else if (argc != 3) {
        fprintf(stderr, "usage: att_bench KIND N [stack]\n");
        return 1;
    }
    {
        const char *plus = strchr(argv[1], '+');
        size_t len = (plus != NULL) ? (size_t)(plus - argv[1]) : strlen(argv[1]);
        if (len >= sizeof name) len = sizeof name - 1u;
        memcpy(name, argv[1], len);
        name[len] = '\0';
        if (plus != NULL) stage = plus + 1;
    }
    for (k = 1; k < 64; k++) {
        if (strcmp(att_filter_name((att_filter_kind_t)k), name) == 0) {
            kind = (att_filter_kind_t)k;
        }
    }
    n = strtoul(argv[2], &end, 10);
    if (end == NULL || *end != '\0') {
        fprintf(stderr, "att_bench: bad N '%s'\n", argv[2]);
        return 1;
    }
    if (stack && !BENCH_HAVE_STACK) {
        fprintf(stderr, "att_bench: the stack probe is for Arm targets only\n");
        return 1;
    }
    if (att_filter_settings_default(kind, 0.01f, &settings) != ATT_OK ||
        att_filter_init(&f, kind, &settings) != ATT_OK) {
        fprintf(stderr, "att_bench: filter '%s' is not available\n", argv[1]);
        return 1;
    }
    if (stage != NULL) {
        att_calib_settings_t cs;
        if (!bench_stages(stage, &cs) || att_filter_calibrate(&f, &cs) != ATT_OK) {
            fprintf(stderr, "att_bench: unknown or refused stage '%s'\n", stage);
            return 1;
        }
        accout = cs.accel_outputs;
    }
    for (i = 0ul; i < n; i++) {
        uint32_t flags;
        bench_att_sample(i, &s);
#if BENCH_HAVE_STACK
        if (stack) {
            uint32_t used = bench_probe(&f, &s, &out, &flags);
            deepest = used > deepest ? used : deepest;
        } else {
            flags = att_filter_step(&f, &s, &out);
        }
#else
        flags = att_filter_step(&f, &s, &out);
#endif
        sum ^= flags;
        sum = (sum << 1) ^ bench_bits(out.q.w) ^ bench_bits(out.q.z);
        if (accout) {
            att_filter_accel(&f, &acc);
            sum ^= bench_bits(acc.earth.z);
        }
    }
    if (stack) {
        printf("stack %s %lu\n", argv[1], (unsigned long)deepest);
    }
    printf("%s %lu %08lx\n", argv[1], n, (unsigned long)sum);
    return 0;
}
