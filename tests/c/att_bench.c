/**
 * @file att_bench.c
 * @brief Step a filter N times on synthetic deterministic inputs (for instruction counts).
 *
 * Usage: att_bench KIND N     KIND: a filter name of att_filter_name (ars, gyro, tilt, ...)
 *
 * Runs att_filter_step N times with default settings (dt = 0.01 s) through the unified interface and
 * prints a checksum of the outputs. tools/attica_dev/bench.py runs it under valgrind --tool=callgrind
 * with --toggle-collect=att_filter_step for two values of N and divides the difference in
 * instructions by the difference in N, which removes start-up and initialisation costs.
 *
 * Inputs: a 32-bit LCG drives gyro rates in +-0.5 rad/s and a specific force near +g on z (level
 * within a few degrees, |a| close to g so corrections are applied), mag near a 50 uT field with a
 * 60 degree dip; every 1000 steps, 300 steps are at rest (tiny rates) so rest detection and bias
 * estimation paths are taken too. Test harness: plain C99 + stdio.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "attica/att_filter.h"

static uint32_t bench_state = 12345u;

/* Uniform in [-1, 1) from a 32-bit LCG (Numerical Recipes constants); exact float arithmetic. */
static float bench_uniform(void)
{
    bench_state = bench_state * 1664525u + 1013904223u;
    return (float)(bench_state >> 8) * 0x1p-23f - 1.0f;
}

static void bench_sample(unsigned long i, att_sample_t *s)
{
    const int rest = (i % 1000ul) >= 700ul;
    const float rate = rest ? 0.002f : 0.5f;
    s->gyr.x = rate * bench_uniform();
    s->gyr.y = rate * bench_uniform();
    s->gyr.z = rate * bench_uniform();
    s->acc.x = 0.3f * bench_uniform();
    s->acc.y = 0.3f * bench_uniform();
    s->acc.z = 9.75f + 0.1f * bench_uniform();
    s->mag.x = 0.5f * bench_uniform();
    s->mag.y = 25.0f + 0.5f * bench_uniform();
    s->mag.z = -43.3f + 0.5f * bench_uniform();
}

static uint32_t bench_bits(float f)
{
    uint32_t w;
    memcpy(&w, &f, sizeof w);
    return w;
}

int main(int argc, char **argv)
{
    att_filter_settings_t settings;
    att_filter_t f;
    att_output_t out;
    att_sample_t s;
    unsigned long n;
    unsigned long i;
    uint32_t sum = 0u;
    int k;
    att_filter_kind_t kind = ATT_FILTER_NONE;
    char *end = NULL;
    if (argc != 3) {
        fprintf(stderr, "usage: att_bench KIND N\n");
        return 1;
    }
    for (k = 1; k < 64; k++) {
        if (strcmp(att_filter_name((att_filter_kind_t)k), argv[1]) == 0) {
            kind = (att_filter_kind_t)k;
        }
    }
    n = strtoul(argv[2], &end, 10);
    if (end == NULL || *end != '\0') {
        fprintf(stderr, "att_bench: bad N '%s'\n", argv[2]);
        return 1;
    }
    if (att_filter_settings_default(kind, 0.01f, &settings) != ATT_OK ||
        att_filter_init(&f, kind, &settings) != ATT_OK) {
        fprintf(stderr, "att_bench: filter '%s' is not available\n", argv[1]);
        return 1;
    }
    for (i = 0ul; i < n; i++) {
        bench_sample(i, &s);
        sum ^= att_filter_step(&f, &s, &out);
        sum = (sum << 1) ^ bench_bits(out.q.w) ^ bench_bits(out.q.z);
    }
    printf("%s %lu %08lx\n", argv[1], n, (unsigned long)sum);
    return 0;
}
