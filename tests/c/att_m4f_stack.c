/**
 * @file att_m4f_stack.c
 * @brief Measured stack depth (high-water mark) and state sizes on the target, printed as text.
 *
 * Test harness for a Cortex-M4F image (startup.c + semihost.c, newlib stdio over semihosting), run by
 * tools/attica_dev/footprint.py. For every filter kind with default settings: att_filter_init, then
 * ATT_STACK_STEPS steps of att_filter_step on synthetic samples (motion, rest periods and, every few
 * steps, an invalid or out-of-range sample so the error paths run too). For the CAN node: init, then
 * samples as IMU frames through att_node_rx / att_node_poll / att_node_tx, with a command now and then.
 *
 * Depth of a call = bytes between the caller's stack pointer and the lowest word the call wrote: the
 * stack below the probe is painted with a pattern before each call and scanned after it.
 *
 * Output lines (stdout):   stack <function> <kind> <bytes>      sizeof <type> <bytes>
 * Exit status 0, or 1 if a filter or the node refused its default settings.
 */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "attica/att_filter.h"
#include "attica/att_node.h"

#define ATT_STACK_STEPS 3000u
#define ATT_PAINT_WORDS 1024u /* 4 KiB painted below the probe */
#define ATT_PAINT 0xA5C3A5C3u

static uint32_t lcg = 2463534242u;

static float uniform(void)
{
    lcg = lcg * 1664525u + 1013904223u;
    return (float)(lcg >> 8) * 0x1p-23f - 1.0f;
}

/* Motion for 700 of every 1000 steps, then rest; every 7th sample has one invalid or odd part. */
static void sample(uint32_t i, att_sample_t *s)
{
    const int rest = (i % 1000u) >= 700u;
    const float rate = rest ? 0.002f : 0.8f;
    const float zero = 0.0f;
    s->gyr.x = rate * uniform();
    s->gyr.y = rate * uniform();
    s->gyr.z = rate * uniform();
    s->acc.x = 0.4f * uniform();
    s->acc.y = 0.4f * uniform();
    s->acc.z = 9.7f + 0.2f * uniform();
    s->mag.x = 0.5f * uniform();
    s->mag.y = 25.0f + 0.5f * uniform();
    s->mag.z = -43.3f + 0.5f * uniform();
    if (i % 7u != 0u) {
        return;
    }
    switch ((i / 7u) % 7u) {
    case 0: /* NaN gyro */
        s->gyr.y = zero / zero;
        break;
    case 1: /* no accel */
        s->acc.x = 0.0f;
        s->acc.y = 0.0f;
        s->acc.z = 0.0f;
        break;
    case 2: /* accel over range */
        s->acc.z = 200.0f;
        break;
    case 3: /* gyro over range */
        s->gyr.z = 50.0f;
        break;
    case 4: /* mag absent */
        s->mag.x = zero / zero;
        s->mag.y = s->mag.x;
        s->mag.z = s->mag.x;
        break;
    case 5: /* mag disturbed */
        s->mag.y = 300.0f;
        break;
    default: /* linear acceleration */
        s->acc.x = 6.0f;
        break;
    }
}

static uintptr_t stack_pointer(void)
{
    uintptr_t sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    return sp;
}

static volatile uint32_t *paint_below_sp(void)
{
    volatile uint32_t *top = (volatile uint32_t *)stack_pointer();
    volatile uint32_t *p;
    for (p = top - ATT_PAINT_WORDS; p < top; p++) {
        *p = ATT_PAINT;
    }
    return top;
}

static uint32_t used_below(volatile uint32_t *top)
{
    volatile uint32_t *p = top - ATT_PAINT_WORDS;
    while (p < top && *p == ATT_PAINT) {
        p++;
    }
    return (uint32_t)(top - p) * 4u;
}

/* Every probe: paint, call, scan; noinline so that top is this function's own stack pointer. */
__attribute__((noinline)) static uint32_t probe_step(att_filter_t *f, const att_sample_t *s, att_output_t *o)
{
    volatile uint32_t *top = paint_below_sp();
    (void)att_filter_step(f, s, o);
    return used_below(top);
}

__attribute__((noinline)) static uint32_t probe_init(att_filter_t *f, att_filter_kind_t k,
                                                     const att_filter_settings_t *s, att_status_t *st)
{
    volatile uint32_t *top = paint_below_sp();
    *st = att_filter_init(f, k, s);
    return used_below(top);
}

__attribute__((noinline)) static uint32_t probe_node_init(att_node_t *n, const att_node_settings_t *s,
                                                          att_status_t *st)
{
    volatile uint32_t *top = paint_below_sp();
    *st = att_node_init(n, s);
    return used_below(top);
}

__attribute__((noinline)) static uint32_t probe_node_rx(att_node_t *n, const att_can_frame_t *f)
{
    volatile uint32_t *top = paint_below_sp();
    (void)att_node_rx(n, f);
    return used_below(top);
}

__attribute__((noinline)) static uint32_t probe_node_poll(att_node_t *n)
{
    volatile uint32_t *top = paint_below_sp();
    (void)att_node_poll(n);
    return used_below(top);
}

__attribute__((noinline)) static uint32_t probe_node_tx(att_node_t *n, att_can_frame_t *f, int *got)
{
    volatile uint32_t *top = paint_below_sp();
    *got = att_node_tx(n, f) ? 1 : 0;
    return used_below(top);
}

static uint32_t max_u32(uint32_t a, uint32_t b) { return a > b ? a : b; }

static att_filter_t filter;
static att_node_t node;

static int filters(void)
{
    int k;
    for (k = 1; k < 16; k++) {
        att_filter_settings_t s;
        att_output_t out;
        att_sample_t in;
        att_status_t st = ATT_ERR_KIND;
        uint32_t i;
        uint32_t depth_step = 0u;
        uint32_t depth_init;
        const att_filter_kind_t kind = (att_filter_kind_t)k;
        if (att_filter_settings_default(kind, 0.01f, &s) != ATT_OK) {
            continue;
        }
        depth_init = probe_init(&filter, kind, &s, &st);
        if (st != ATT_OK) {
            fprintf(stderr, "att_m4f_stack: %s refused its default settings\n", att_filter_name(kind));
            return 1;
        }
        for (i = 0u; i < ATT_STACK_STEPS; i++) {
            sample(i, &in);
            depth_step = max_u32(depth_step, probe_step(&filter, &in, &out));
        }
        printf("stack att_filter_init %s %lu\n", att_filter_name(kind), (unsigned long)depth_init);
        printf("stack att_filter_step %s %lu\n", att_filter_name(kind), (unsigned long)depth_step);
    }
    return 0;
}

static int node_run(void)
{
    att_node_settings_t s;
    att_can_frame_t frames[3];
    att_can_frame_t f;
    att_sample_t in;
    att_status_t st = ATT_ERR_KIND;
    uint32_t i;
    uint32_t j;
    uint32_t d_init;
    uint32_t d_rx = 0u;
    uint32_t d_poll = 0u;
    uint32_t d_tx = 0u;
    int got = 1;
    if (att_node_settings_default(ATT_FILTER_ARS, 100.0f, &s) != ATT_OK) {
        fprintf(stderr, "att_m4f_stack: no node defaults\n");
        return 1;
    }
    d_init = probe_node_init(&node, &s, &st);
    if (st != ATT_OK) {
        fprintf(stderr, "att_m4f_stack: att_node_init refused the defaults (%d)\n", (int)st);
        return 1;
    }
    for (i = 0u; i < ATT_STACK_STEPS; i++) {
        sample(i, &in);
        att_can_encode_imu(&in, (uint8_t)(i & 15u), frames);
        for (j = 0u; j < 3u; j++) {
            d_rx = max_u32(d_rx, probe_node_rx(&node, &frames[j]));
        }
        if (i % 500u == 250u) { /* select the next filter kind: a fresh init inside poll */
            att_can_cmd_t c;
            memset(&c, 0, sizeof c);
            c.counter = (uint8_t)(i & 15u);
            c.cmd = ATT_CAN_CMD_SELECT;
            c.arg = (uint8_t)(1u + (i / 500u) % 6u);
            att_can_encode_cmd(&c, &f);
            d_rx = max_u32(d_rx, probe_node_rx(&node, &f));
        }
        d_poll = max_u32(d_poll, probe_node_poll(&node));
        got = 1;
        while (got) {
            d_tx = max_u32(d_tx, probe_node_tx(&node, &f, &got));
        }
    }
    printf("stack att_node_init node %lu\n", (unsigned long)d_init);
    printf("stack att_node_rx node %lu\n", (unsigned long)d_rx);
    printf("stack att_node_poll node %lu\n", (unsigned long)d_poll);
    printf("stack att_node_tx node %lu\n", (unsigned long)d_tx);
    printf("steps att_node_poll node %lu\n", (unsigned long)node.stats.steps);
    return 0;
}

int main(void)
{
    int st;
    printf("sizeof att_filter_t %lu\n", (unsigned long)sizeof(att_filter_t));
    printf("sizeof att_ars_t %lu\n", (unsigned long)sizeof(att_ars_t));
    printf("sizeof att_mars_t %lu\n", (unsigned long)sizeof(att_mars_t));
    printf("sizeof att_kf_t %lu\n", (unsigned long)sizeof(att_kf_t));
    printf("sizeof att_ekf_t %lu\n", (unsigned long)sizeof(att_ekf_t));
    printf("sizeof att_gyro_t %lu\n", (unsigned long)sizeof(att_gyro_t));
    printf("sizeof att_tilt_t %lu\n", (unsigned long)sizeof(att_tilt_t));
    printf("sizeof att_filter_settings_t %lu\n", (unsigned long)sizeof(att_filter_settings_t));
    printf("sizeof att_output_t %lu\n", (unsigned long)sizeof(att_output_t));
    printf("sizeof att_node_t %lu\n", (unsigned long)sizeof(att_node_t));
    printf("sizeof att_can_frame_t %lu\n", (unsigned long)sizeof(att_can_frame_t));
    st = filters();
    if (st == 0) {
        st = node_run();
    }
    return st;
}
