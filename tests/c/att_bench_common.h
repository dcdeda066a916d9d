/**
 * @file att_bench_common.h
 * @brief The benchmark input stream and the stack probe, shared by att_bench.c and the peers' drivers.
 *
 * Test-harness header (C99 and C++): attica (tests/c/att_bench.c) and the peers' drivers
 * (tests/c/att_peer_fusion.c, tests/c/att_peer_vqf.cpp) step their filters on exactly the same samples
 * and measure their stack the same way, so their figures can be put side by side.
 *
 * Inputs (bench_sample): a 32-bit LCG drives gyro rates in +-0.5 rad/s and a specific force near +g on
 * z (level within a few degrees, |a| close to g so corrections are applied), mag near a 50 uT field
 * with a 60 degree dip; every 1000 steps, 300 steps are at rest (tiny rates) so rest detection and bias
 * estimation paths are taken too. Units: rad/s, m/s^2, uT, sensor frame (drivers convert for peers
 * that want others).
 *
 * Stack (bench_stack_paint / bench_stack_used, Arm only): paint BENCH_PAINT_WORDS words below the
 * stack pointer of the caller, call, and find the lowest word that changed: the depth of the call in
 * bytes below the caller's stack pointer.
 */
#ifndef ATT_BENCH_COMMON_H
#define ATT_BENCH_COMMON_H

#include <stdint.h>
#include <string.h>

#define BENCH_PAINT_WORDS 1024u /* 4 KiB painted below the probe */
#define BENCH_PAINT 0xA5C3A5C3u

static uint32_t bench_state = 12345u;

/* Uniform in [-1, 1) from a 32-bit LCG (Numerical Recipes constants); exact float arithmetic. */
static inline float bench_uniform(void)
{
    bench_state = bench_state * 1664525u + 1013904223u;
    return (float)(bench_state >> 8) * 0x1p-23f - 1.0f;
}

/* Sample i of the stream: gyr (rad/s), acc (m/s^2), mag (uT). */
static inline void bench_sample(unsigned long i, float gyr[3], float acc[3], float mag[3])
{
    const int rest = (i % 1000ul) >= 700ul;
    const float rate = rest ? 0.002f : 0.5f;
    gyr[0] = rate * bench_uniform();
    gyr[1] = rate * bench_uniform();
    gyr[2] = rate * bench_uniform();
    acc[0] = 0.3f * bench_uniform();
    acc[1] = 0.3f * bench_uniform();
    acc[2] = 9.75f + 0.1f * bench_uniform();
    mag[0] = 0.5f * bench_uniform();
    mag[1] = 25.0f + 0.5f * bench_uniform();
    mag[2] = -43.3f + 0.5f * bench_uniform();
}

static inline uint32_t bench_bits(float f)
{
    uint32_t w;
    memcpy(&w, &f, sizeof w);
    return w;
}

#if defined(__arm__)
#define BENCH_HAVE_STACK 1
static inline uintptr_t bench_stack_pointer(void)
{
    uintptr_t sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    return sp;
}

/* Paint below the current stack pointer; call from a noinline probe, right before the measured call. */
static inline volatile uint32_t *bench_stack_paint(void)
{
    volatile uint32_t *top = (volatile uint32_t *)bench_stack_pointer();
    volatile uint32_t *p;
    for (p = top - BENCH_PAINT_WORDS; p < top; p++) {
        *p = BENCH_PAINT;
    }
    return top;
}

/* Bytes used below top since bench_stack_paint(top). */
static inline uint32_t bench_stack_used(volatile uint32_t *top)
{
    volatile uint32_t *p = top - BENCH_PAINT_WORDS;
    while (p < top && *p == BENCH_PAINT) {
        p++;
    }
    return (uint32_t)(top - p) * 4u;
}
#else
#define BENCH_HAVE_STACK 0
#endif

#endif /* ATT_BENCH_COMMON_H */
