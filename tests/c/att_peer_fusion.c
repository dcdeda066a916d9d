/**
 * @file att_peer_fusion.c
 * @brief Fusion (x-io Technologies' AHRS, the C of the imufusion sdist) on the benchmark inputs.
 *
 * A driver for the peer comparison of `make cycles`, `make bench` and `make footprint`: it is built
 * with Fusion's own sources, which tools/attica_dev/peer_sources.py fetches with `pip download` into
 * build/ (never part of this repository), with the same CPU and optimisation flags as attica.
 *
 *   att_peer_fusion KIND N [stack]     KIND: fusion6 (FusionAhrsUpdateNoMagnetometer) or
 *                                            fusion9 (FusionAhrsUpdate)
 *
 * Fusion's default settings (gain 0.5, no rejection, 3 s start-up) with the ENU convention at 100 Hz
 * (attica's dt = 0.01 s). Every step converts the sample of att_bench_common.h to Fusion's units
 * (deg/s, g; mag as is, uT) outside the counted call, then calls att_peer_step: Fusion's update and
 * FusionAhrsGetQuaternion. The instruction counts cover att_peer_step and its callees; with "stack"
 * (Arm) every call is probed and the deepest printed as "stack KIND BYTES". Prints a checksum.
 *
 * With -DATT_PEER_IMAGE=6 or 9 it is instead a minimal firmware image for the footprint (inputs from
 * volatile globals, no stdio), like tests/c/att_m4f_image.c for attica.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "Fusion.h"
#include "att_bench_common.h"

#define PEER_DEG_PER_RAD 57.29577951308232f
#define PEER_G 9.80665f

static FusionAhrs ahrs;
static int nine;
/* The footprint image links one update only; the benchmark program picks at run time. */
#if defined(ATT_PEER_IMAGE)
#define PEER_NINE (ATT_PEER_IMAGE == 9)
#else
#define PEER_NINE nine
#endif
static float q_out[4];

static void peer_init(void)
{
    FusionAhrsSettings s = fusionAhrsDefaultSettings;
    s.convention = FusionConventionEnu;
    s.sampleRate = 100.0f;
    FusionAhrsInitialise(&ahrs);
    FusionAhrsSetSettings(&ahrs, &s);
}

void att_peer_step(const FusionVector *g, const FusionVector *a, const FusionVector *m);

/* The counted call: one update and the attitude out (noinline: its own function in the trace). */
__attribute__((noinline)) void att_peer_step(const FusionVector *g, const FusionVector *a, const FusionVector *m)
{
    FusionQuaternion q;
    if (PEER_NINE) {
        FusionAhrsUpdate(&ahrs, *g, *a, *m);
    } else {
        FusionAhrsUpdateNoMagnetometer(&ahrs, *g, *a);
    }
    q = FusionAhrsGetQuaternion(&ahrs);
    q_out[0] = q.element.w;
    q_out[1] = q.element.x;
    q_out[2] = q.element.y;
    q_out[3] = q.element.z;
}

#if defined(ATT_PEER_IMAGE)
static volatile float in[9];
static volatile float out_q[4];
static volatile int run = 1;

int main(void)
{
    FusionVector g;
    FusionVector a;
    FusionVector m;
    peer_init();
    while (run) {
        g.axis.x = in[0];
        g.axis.y = in[1];
        g.axis.z = in[2];
        a.axis.x = in[3];
        a.axis.y = in[4];
        a.axis.z = in[5];
        m.axis.x = in[6];
        m.axis.y = in[7];
        m.axis.z = in[8];
        att_peer_step(&g, &a, &m);
        out_q[0] = q_out[0];
        out_q[1] = q_out[1];
        out_q[2] = q_out[2];
        out_q[3] = q_out[3];
    }
    return 0;
}
#else

#if BENCH_HAVE_STACK
__attribute__((noinline)) static uint32_t peer_probe(const FusionVector *g, const FusionVector *a,
                                                     const FusionVector *m)
{
    volatile uint32_t *top = bench_stack_paint();
    att_peer_step(g, a, m);
    return bench_stack_used(top);
}
#endif

int main(int argc, char **argv)
{
    unsigned long n;
    unsigned long i;
    uint32_t sum = 0u;
    uint32_t deepest = 0u;
    int stack = 0;
    char *end = NULL;
    if (argc == 4 && strcmp(argv[3], "stack") == 0) {
        stack = 1;
    } else if (argc != 3) {
        fprintf(stderr, "usage: att_peer_fusion fusion6|fusion9 N [stack]\n");
        return 1;
    }
    if (strcmp(argv[1], "fusion9") == 0) {
        nine = 1;
    } else if (strcmp(argv[1], "fusion6") != 0) {
        fprintf(stderr, "att_peer_fusion: unknown kind '%s' (fusion6, fusion9)\n", argv[1]);
        return 1;
    }
    n = strtoul(argv[2], &end, 10);
    if (end == NULL || *end != '\0') {
        fprintf(stderr, "att_peer_fusion: bad N '%s'\n", argv[2]);
        return 1;
    }
    if (stack && !BENCH_HAVE_STACK) {
        fprintf(stderr, "att_peer_fusion: the stack probe is for Arm targets only\n");
        return 1;
    }
    peer_init();
    for (i = 0ul; i < n; i++) {
        float gs[3];
        float as[3];
        float ms[3];
        FusionVector g;
        FusionVector a;
        FusionVector m;
        int j;
        bench_sample(i, gs, as, ms);
        for (j = 0; j < 3; j++) {
            g.array[j] = gs[j] * PEER_DEG_PER_RAD;
            a.array[j] = as[j] / PEER_G;
            m.array[j] = ms[j];
        }
#if BENCH_HAVE_STACK
        if (stack) {
            uint32_t used = peer_probe(&g, &a, &m);
            deepest = used > deepest ? used : deepest;
        } else {
            att_peer_step(&g, &a, &m);
        }
#else
        att_peer_step(&g, &a, &m);
#endif
        sum = (sum << 1) ^ bench_bits(q_out[0]) ^ bench_bits(q_out[3]);
    }
    if (stack) {
        printf("stack %s %lu\n", argv[1], (unsigned long)deepest);
    }
    printf("%s %lu %08lx q %.6f %.6f %.6f %.6f\n", argv[1], n, (unsigned long)sum, (double)q_out[0],
           (double)q_out[1], (double)q_out[2], (double)q_out[3]);
    return 0;
}
#endif
