/**
 * @file att_hal_test_common.h
 * @brief What the register-level tests of the two CAN ports share (tests/c/att_can_hal_test.c,
 * tests/c/att_fdcan_hal_test.c): the check line, random samples, float bits, the node's receive IDs
 * written out from the DBC, and the acceptance-filter check run over a model of the controller.
 *
 * Include once, in one test program; ATT_HAL_TEST_SEED sets the random stream (default 1).
 */
#ifndef ATT_HAL_TEST_COMMON_H
#define ATT_HAL_TEST_COMMON_H

#include <stdio.h>
#include <string.h>

#include "attica/att_can.h"
#include "attica/att_filter.h"
#include "attica/att_node.h"

#ifndef ATT_HAL_TEST_SEED
#define ATT_HAL_TEST_SEED 1u
#endif

static int failures;

static void check(int ok, const char *what)
{
    printf("%s %s\n", ok ? "ok" : "FAIL", what);
    if (!ok) {
        failures++;
    }
}

static uint32_t lcg = ATT_HAL_TEST_SEED;

/** Uniform in [-1, 1). */
static float uniform(void)
{
    lcg = lcg * 1664525u + 1013904223u;
    return (float)(lcg >> 8) * 0x1p-23f - 1.0f;
}

static uint32_t bits(float x)
{
    uint32_t w;
    memcpy(&w, &x, sizeof w);
    return w;
}

/** A moving, noisy 9-axis sample (rad/s, m/s^2, uT). */
static void make_sample(att_sample_t *s)
{
    s->gyr.x = 0.5f * uniform();
    s->gyr.y = 0.5f * uniform();
    s->gyr.z = 0.5f * uniform();
    s->acc.x = 0.3f * uniform();
    s->acc.y = 0.3f * uniform();
    s->acc.z = 9.8f + 0.1f * uniform();
    s->mag.x = 20.0f;
    s->mag.y = 5.0f;
    s->mag.z = -40.0f;
}

/** The node's receive IDs, written out from the DBC's IDs (not from att_node_rx_ids). */
static uint32_t expected_ids(int32_t offset, uint32_t ids[8])
{
    uint32_t n = 0u;
    ids[n++] = (uint32_t)((int32_t)ATT_CAN_ID_IMU_GYRO + offset);
    ids[n++] = (uint32_t)((int32_t)ATT_CAN_ID_IMU_ACC + offset);
    ids[n++] = (uint32_t)((int32_t)ATT_CAN_ID_IMU_MAG + offset);
#if ATT_NODE_WITH_FD
    ids[n++] = (uint32_t)((int32_t)ATT_CAN_ID_IMU_FD + offset);
#endif
    ids[n++] = (uint32_t)((int32_t)ATT_CAN_ID_CMD + offset);
    return n;
}

/** A model of the controller's acceptance decision from its registers: frame id (11 or 29 bit), ext, rtr. */
typedef int (*accepts_fn)(uint32_t id, int ext, int rtr);

/**
 * The acceptance filter of a node at offset (label names the case): every 11-bit data frame ID is
 * accepted iff it is one of the node's receive IDs; none of those as a remote frame or as an extended
 * frame (the same value, the same top 11 bits, with the low 18 bits set, remote).
 */
static void check_acceptance(const char *label, int32_t offset, accepts_fn accepts)
{
    uint32_t want[8];
    const uint32_t n_want = expected_ids(offset, want);
    uint32_t id;
    uint32_t k;
    uint32_t accepted = 0u;
    uint32_t wrong = 0u;
    uint32_t first_wrong = 0xffffffffu;
    uint32_t bad_other = 0u;
    char what[200];
    for (id = 0u; id < 0x800u; id++) {
        int in = 0;
        const int acc = accepts(id, 0, 0);
        for (k = 0u; k < n_want; k++) {
            in |= (want[k] == id);
        }
        accepted += (uint32_t)acc;
        if (acc != in) {
            wrong++;
            first_wrong = (first_wrong == 0xffffffffu) ? id : first_wrong;
        }
    }
    snprintf(what, sizeof what,
             "%s id_offset %ld: of the 2048 standard IDs exactly the node's %lu reach the receive FIFO (%lu accepted, %lu "
             "wrong, first 0x%lx)",
             label, (long)offset, (unsigned long)n_want, (unsigned long)accepted, (unsigned long)wrong,
             (unsigned long)first_wrong);
    check(wrong == 0u && accepted == n_want, what);
    for (k = 0u; k < n_want; k++) {
        bad_other += (uint32_t)accepts(want[k], 0, 1);                     /* remote frame */
        bad_other += (uint32_t)accepts(want[k], 1, 0);                     /* extended, same value */
        bad_other += (uint32_t)accepts(want[k] << 18, 1, 0);               /* extended, same top 11 bits */
        bad_other += (uint32_t)accepts((want[k] << 18) | 0x3ffffu, 1, 0);
        bad_other += (uint32_t)accepts(want[k], 1, 1);                     /* extended remote */
    }
    snprintf(what, sizeof what, "%s id_offset %ld: remote and extended frames of those IDs are kept out", label,
             (long)offset);
    check(bad_other == 0u, what);
}

/**
 * One ATT_DIAG_BUS frame f sent right after prev: the E2E check, prev is its ATT_DIAG with the same
 * counter, and the fields equal want. Prints "diag_bus <hal> <label> data=<hex> <field>=<value> ..."
 * (want's fields) for tests/test_cross.py, which decodes data with the host's codec. Returns the
 * problems found (0: good).
 */
static uint32_t diag_bus_frame_check(const char *hal, const char *label, const att_can_frame_t *prev,
                                     const att_can_frame_t *f, const att_can_bus_diag_t *want)
{
    att_can_bus_diag_t d;
    uint32_t bad = 0u;
    uint32_t b;
    memset(&d, 0, sizeof d);
    bad += (uint32_t)(prev == NULL || prev->id != (uint32_t)ATT_CAN_ID_DIAG ||
                      att_can_counter(prev) != att_can_counter(f));
    bad += (uint32_t)(att_can_check(f) != ATT_CAN_OK || !att_can_decode_diag_bus(f, &d));
    bad += (uint32_t)(d.state != want->state || d.lec != want->lec || d.bus_off != want->bus_off ||
                      d.recoveries != want->recoveries || d.error_passive != want->error_passive ||
                      d.error_warning != want->error_warning || d.rx_overruns != want->rx_overruns);
    printf("diag_bus %s %s data=", hal, label);
    for (b = 0u; b < f->len; b++) {
        printf("%02x", f->data[b]);
    }
    printf(" state=%u lec=%u bus_off=%lu recoveries=%lu error_passive=%lu error_warning=%lu rx_overruns=%lu\n",
           (unsigned)want->state, (unsigned)want->lec, (unsigned long)want->bus_off, (unsigned long)want->recoveries,
           (unsigned long)want->error_passive, (unsigned long)want->error_warning, (unsigned long)want->rx_overruns);
    return bad;
}

#endif /* ATT_HAL_TEST_COMMON_H */
