/**
 * @file att_doc_prelude.h
 * @brief What the C snippets of the docs and headers assume around them, simulated so that each one
 * runs on the host and prints what it computed (tests/test_docs_c.py).
 *
 * - your IMU driver: read_imu(&in) gives one sample of a board lying still, tilted by ATT_DOC_ROLL
 *   about x (rad/s, m/s^2, uT; sensor frame; the field of a place at 60 deg dip, north along +y);
 * - your CAN driver: can_receive / can_tx_free / can_send exchange frames with a simulated host that
 *   sends that IMU's samples as IMU_GYRO/ACC/MAG frames and decodes the node's outputs;
 * - your application: publish(q, v, flags) keeps the last values; log_refused(field, rule, unit) prints
 *   a refused setting, print_rule(field, rule, unit, holds) a line of a settings contract;
 * - your flash driver: flash_erase / flash_program / flash_read on two RAM pages of 2 KB, erased at the
 *   start (the persistence example's att_flash_io_t).
 * After ATT_DOC_SAMPLES samples the program ends (exit 0) and prints one report line:
 *   "report samples=N published=P q=w,x,y,z v=x,y,z flags=0x.. sent=S quat_frames=Q"
 * att_doc_fail() stands for the "{ ... }" of an error branch: reaching it prints and exits 3.
 */
#ifndef ATT_DOC_PRELUDE_H
#define ATT_DOC_PRELUDE_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "attica/attica.h"

#ifndef ATT_DOC_SAMPLES
#define ATT_DOC_SAMPLES 2000L
#endif
#define ATT_DOC_ROLL 0.3f /* rad: the board's roll (sin/cos below are of this angle) */
#define ATT_DOC_SIN_ROLL 0.29552020666f
#define ATT_DOC_COS_ROLL 0.95533648912f

static long att_doc_samples;
static long att_doc_published;
static long att_doc_sent;
static long att_doc_quat_frames;
static att_quat_t att_doc_q;
static att_vec3_t att_doc_v;
static uint32_t att_doc_flags;
static bool att_doc_registered;

static void att_doc_report(void)
{
    printf("report samples=%ld published=%ld q=%.6f,%.6f,%.6f,%.6f v=%.6f,%.6f,%.6f flags=0x%lx sent=%ld "
           "quat_frames=%ld\n",
           att_doc_samples, att_doc_published, (double)att_doc_q.w, (double)att_doc_q.x, (double)att_doc_q.y,
           (double)att_doc_q.z, (double)att_doc_v.x, (double)att_doc_v.y, (double)att_doc_v.z,
           (unsigned long)att_doc_flags, att_doc_sent, att_doc_quat_frames);
}

static void att_doc_start(void)
{
    if (!att_doc_registered) {
        att_doc_registered = true;
        (void)atexit(att_doc_report);
    }
}

/** An error branch of a snippet was taken. */
static void att_doc_fail(int line)
{
    printf("doc_fail line=%d\n", line);
    exit(3);
}

/** One sample of the still, tilted board; the program ends after ATT_DOC_SAMPLES of them. */
static void att_doc_sample(att_sample_t *in)
{
    const float g = 9.80665f;
    att_doc_start();
    if (att_doc_samples >= ATT_DOC_SAMPLES) {
        exit(0);
    }
    att_doc_samples++;
    in->gyr.x = 0.001f; /* rad/s: a small constant gyro bias */
    in->gyr.y = -0.002f;
    in->gyr.z = 0.0005f;
    in->acc.x = 0.0f; /* m/s^2: gravity seen by a board rolled by ATT_DOC_ROLL */
    in->acc.y = g * ATT_DOC_SIN_ROLL;
    in->acc.z = g * ATT_DOC_COS_ROLL;
    /* uT: earth field (0, 25, -43.3) ENU (north +y, dip 60 deg) seen by the rolled board */
    in->mag.x = 0.0f;
    in->mag.y = 25.0f * ATT_DOC_COS_ROLL - 43.3f * ATT_DOC_SIN_ROLL;
    in->mag.z = 25.0f * ATT_DOC_SIN_ROLL + 43.3f * ATT_DOC_COS_ROLL;
}

/** Your IMU driver: true when a new sample is in *in (here: always). */
static bool read_imu(att_sample_t *in)
{
    att_doc_sample(in);
    return true;
}

/** Your application: use the attitude (q sensor-to-earth; v: Euler angles rad, or a vector). */
static void publish(att_quat_t q, att_vec3_t v, uint32_t flags)
{
    att_doc_start();
    att_doc_published++;
    att_doc_q = q;
    att_doc_v = v;
    att_doc_flags = flags;
}

/** Your log: a refused setting, its rule and unit (prints "field: rule unit"). */
static void log_refused(const char *field, const char *rule, const char *unit)
{
    printf("%s: %s %s\n", field, rule, unit);
}

/** Your print: one line of a settings contract ("field: rule unit", "(fails)" when it does not hold). */
static void print_rule(const char *field, const char *rule, const char *unit, bool holds)
{
    printf("%s: %s %s%s\n", field, rule, unit, holds ? "" : " (fails)");
}

/* --- your flash driver: two pages of 2 KB (here in RAM, erased at the start) ----------------------- */

#define ATT_DOC_PAGE_BYTES 2048u
static uint8_t att_doc_flash[2][ATT_DOC_PAGE_BYTES];
static bool att_doc_flash_ready;

static bool att_doc_page_ok(uint32_t page, uint32_t offset, uint32_t n)
{
    if (!att_doc_flash_ready) {
        memset(att_doc_flash, 0xff, sizeof att_doc_flash);
        att_doc_flash_ready = true;
    }
    return page < 2u && offset <= ATT_DOC_PAGE_BYTES && n <= ATT_DOC_PAGE_BYTES - offset;
}

/** Your flash driver: erase a page (its bytes read 0xFF). */
static bool flash_erase(void *ctx, uint32_t page)
{
    (void)ctx;
    if (!att_doc_page_ok(page, 0u, 0u)) {
        return false;
    }
    memset(att_doc_flash[page], 0xff, ATT_DOC_PAGE_BYTES);
    return true;
}

/** Your flash driver: program n bytes (whole 8-byte units of erased bytes) at offset of a page. */
static bool flash_program(void *ctx, uint32_t page, uint32_t offset, const uint8_t *data, uint32_t n)
{
    uint32_t i;
    (void)ctx;
    if (!att_doc_page_ok(page, offset, n) || offset % 8u != 0u || n % 8u != 0u) {
        return false;
    }
    for (i = 0u; i < n; i++) {
        if (att_doc_flash[page][offset + i] != 0xffu) {
            return false;
        }
        att_doc_flash[page][offset + i] = data[i];
    }
    return true;
}

/** Your flash driver: read n bytes at offset of a page. */
static bool flash_read(void *ctx, uint32_t page, uint32_t offset, uint8_t *data, uint32_t n)
{
    (void)ctx;
    if (!att_doc_page_ok(page, offset, n)) {
        return false;
    }
    memcpy(data, att_doc_flash[page] + offset, n);
    return true;
}

/* --- a simulated CAN bus with a host that sends IMU frames and reads the outputs ------------------- */

static att_can_frame_t att_doc_rx[3];
static int att_doc_rx_left;

/** Your CAN driver: the next received frame (false: none waiting). */
static bool can_receive(att_can_frame_t *f)
{
    if (att_doc_rx_left == 0) {
        att_sample_t in;
        att_doc_sample(&in);
        att_can_encode_imu(&in, (uint8_t)(att_doc_samples & 15), att_doc_rx);
        att_doc_rx_left = 3;
        return false; /* one sample's frames per pass of the main loop */
    }
    *f = att_doc_rx[3 - att_doc_rx_left];
    att_doc_rx_left--;
    return true;
}

/** Your CAN driver: a transmit mailbox is free. */
static bool can_tx_free(void)
{
    return true;
}

/** Your CAN driver: send a frame (here: the host decodes the node's attitude outputs). */
static void can_send(const att_can_frame_t *f)
{
    att_output_t o;
    att_doc_start();
    att_doc_sent++;
    memset(&o, 0, sizeof o);
    o.q = att_doc_q;
    if (f->id == (uint32_t)ATT_CAN_ID_QUAT_A || f->id == (uint32_t)ATT_CAN_ID_QUAT_B) {
        att_doc_quat_frames++;
        (void)att_can_decode_output(f, &o);
        att_doc_q = o.q;
    } else if (f->id == (uint32_t)ATT_CAN_ID_EULER) {
        (void)att_can_decode_output(f, &o);
        att_doc_v = o.euler;
        att_doc_published++;
    } else if (f->id == (uint32_t)ATT_CAN_ID_STATUS) {
        (void)att_can_decode_output(f, &o);
        att_doc_flags = o.flags;
    }
}

#endif /* ATT_DOC_PRELUDE_H */
