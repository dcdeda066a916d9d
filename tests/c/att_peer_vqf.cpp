/**
 * @file att_peer_vqf.cpp
 * @brief VQF (Laidig and Seel's versatile quaternion filter, the C++ of the vqf sdist) on the benchmark
 * inputs.
 *
 * A driver for the peer comparison of `make cycles`, `make bench` and `make footprint`: it is built
 * with VQF's own vqf.cpp, which tools/attica_dev/peer_sources.py fetches with `pip download` into
 * build/ (never part of this repository), with VQF_SINGLE_PRECISION (float, as attica) and the same
 * CPU and optimisation flags as attica, plus -fno-exceptions -fno-rtti on the microcontrollers.
 *
 *   att_peer_vqf KIND N [stack]     KIND: vqf6 (update(gyr, acc), getQuat6D) or
 *                                         vqf9 (update(gyr, acc, mag), getQuat9D)
 *
 * VQF's default parameters at a sample time of 0.01 s (attica's dt); the samples of
 * att_bench_common.h in VQF's units (rad/s, m/s^2, mag in any unit: uT). The instruction counts cover
 * att_peer_step (one update and the quaternion out) and its callees; with "stack" (Arm) every call is
 * probed and the deepest printed as "stack KIND BYTES". Prints a checksum.
 *
 * With -DATT_PEER_IMAGE=6 or 9 it is instead a minimal firmware image for the footprint (inputs from
 * volatile globals, no stdio), like tests/c/att_m4f_image.c for attica. No heap: the filter object
 * lives in main's frame.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "att_bench_common.h"
#include "vqf.hpp"

#if defined(__arm__)
// -nostartfiles: no crtbegin.o, which would define it; referenced by static-destructor registration.
extern "C" {
void *__dso_handle = nullptr;
}
#endif

static VQF *vqf;
static int nine;
/* The footprint image links one update only; the benchmark program picks at run time. */
#if defined(ATT_PEER_IMAGE)
#define PEER_NINE (ATT_PEER_IMAGE == 9)
#else
#define PEER_NINE nine
#endif
static vqf_real_t q_out[4];

extern "C" void att_peer_step(const vqf_real_t *g, const vqf_real_t *a, const vqf_real_t *m);

// The counted call: one update and the attitude out (noinline: its own function in the trace).
extern "C" __attribute__((noinline)) void att_peer_step(const vqf_real_t *g, const vqf_real_t *a,
                                                        const vqf_real_t *m)
{
    if (PEER_NINE) {
        vqf->update(g, a, m);
        vqf->getQuat9D(q_out);
    } else {
        vqf->update(g, a);
        vqf->getQuat6D(q_out);
    }
}

#if defined(ATT_PEER_IMAGE)
static volatile float in[9];
static volatile float out_q[4];
static volatile int run = 1;

int main(void)
{
    VQF filter(0.01f);
    vqf_real_t g[3];
    vqf_real_t a[3];
    vqf_real_t m[3];
    vqf = &filter;
    while (run) {
        for (int j = 0; j < 3; j++) {
            g[j] = in[j];
            a[j] = in[3 + j];
            m[j] = in[6 + j];
        }
        att_peer_step(g, a, m);
        for (int j = 0; j < 4; j++) {
            out_q[j] = q_out[j];
        }
    }
    return 0;
}
#else

#if BENCH_HAVE_STACK
__attribute__((noinline)) static uint32_t peer_probe(const vqf_real_t *g, const vqf_real_t *a,
                                                     const vqf_real_t *m)
{
    volatile uint32_t *top = bench_stack_paint();
    att_peer_step(g, a, m);
    return bench_stack_used(top);
}
#endif

int main(int argc, char **argv)
{
    int stack = 0;
    char *end = nullptr;
    if (argc == 4 && strcmp(argv[3], "stack") == 0) {
        stack = 1;
    } else if (argc != 3) {
        fprintf(stderr, "usage: att_peer_vqf vqf6|vqf9 N [stack]\n");
        return 1;
    }
    if (strcmp(argv[1], "vqf9") == 0) {
        nine = 1;
    } else if (strcmp(argv[1], "vqf6") != 0) {
        fprintf(stderr, "att_peer_vqf: unknown kind '%s' (vqf6, vqf9)\n", argv[1]);
        return 1;
    }
    unsigned long n = strtoul(argv[2], &end, 10);
    if (end == nullptr || *end != '\0') {
        fprintf(stderr, "att_peer_vqf: bad N '%s'\n", argv[2]);
        return 1;
    }
    if (stack && !BENCH_HAVE_STACK) {
        fprintf(stderr, "att_peer_vqf: the stack probe is for Arm targets only\n");
        return 1;
    }
    VQF filter(0.01f);
    vqf = &filter;
    uint32_t sum = 0u;
    uint32_t deepest = 0u;
    for (unsigned long i = 0ul; i < n; i++) {
        float gs[3];
        float as[3];
        float ms[3];
        vqf_real_t g[3];
        vqf_real_t a[3];
        vqf_real_t m[3];
        bench_sample(i, gs, as, ms);
        for (int j = 0; j < 3; j++) {
            g[j] = gs[j];
            a[j] = as[j];
            m[j] = ms[j];
        }
#if BENCH_HAVE_STACK
        if (stack) {
            uint32_t used = peer_probe(g, a, m);
            deepest = used > deepest ? used : deepest;
        } else {
            att_peer_step(g, a, m);
        }
#else
        att_peer_step(g, a, m);
#endif
        sum = (sum << 1) ^ bench_bits((float)q_out[0]) ^ bench_bits((float)q_out[3]);
    }
    if (stack) {
        printf("stack %s %lu\n", argv[1], (unsigned long)deepest);
    }
    printf("%s %lu %08lx q %.6f %.6f %.6f %.6f\n", argv[1], n, (unsigned long)sum, (double)q_out[0],
           (double)q_out[1], (double)q_out[2], (double)q_out[3]);
    return 0;
}
#endif
