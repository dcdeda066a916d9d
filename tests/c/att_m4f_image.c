/**
 * @file att_m4f_image.c
 * @brief Minimal firmware images for the footprint figures: one part of attica, used as an application would.
 *
 * Built by tools/attica_dev/footprint.py once per image with -DATT_IMAGE=<n>, linked against libattica.a with
 * startup.c, newlib-nano and --gc-sections, never run. Inputs come from volatile globals and results go
 * to volatile globals, so nothing is optimised away; the state lives in this file's .bss (so the
 * library's own .data/.bss stay what the library itself needs: nothing).
 *
 *   ATT_IMAGE  1..7  one filter through its own API (att_<kind>_settings_default, init, reset, step):
 *                    1 ars, 2 mars, 3 kf, 4 ekf, 5 gyro, 6 tilt, 7 mekf (the att_filter_kind_t values)
 *              10    the filters through the unified interface (att_filter_*): the kind is a volatile
 *                    (ATT_IMAGE_KIND, default ATT_FILTER_ARS), so every kind compiled in is linked; built
 *                    with a configuration of att_config.h (e.g. -DATT_WITH_EKF=0) it shows what that
 *                    configuration costs
 *              13    the loop of images 1..7 (settings, init, step, reset) through att_filter.h, for the
 *                    kind ATT_IMAGE_KIND: with a configuration of only that kind it compares with its
 *                    own image
 *              11    the CAN codec: every att_can_* function
 *              12    the CAN node (att_node_*): filters + codec + node
 *              0     start-up only (baseline)
 */
#include <stdint.h>
#include <string.h>

#include "attica/att_filter.h"
#if ATT_IMAGE >= 11
#include "attica/att_can.h"
#include "attica/att_node.h"
#endif

#ifndef ATT_IMAGE
#error "define ATT_IMAGE"
#endif
#ifndef ATT_IMAGE_KIND
#define ATT_IMAGE_KIND ATT_FILTER_ARS
#endif

static volatile float in[9];
static volatile uint32_t out_flags;
static volatile float out_q[4];
static volatile int run = 1;

__attribute__((unused)) static att_vec3_t v3(int i)
{
    att_vec3_t v;
    v.x = in[i];
    v.y = in[i + 1];
    v.z = in[i + 2];
    return v;
}

__attribute__((unused)) static void put_q(att_quat_t q)
{
    out_q[0] = q.w;
    out_q[1] = q.x;
    out_q[2] = q.y;
    out_q[3] = q.z;
}

#if ATT_IMAGE == 1
static att_ars_t state;
int main(void)
{
    att_ars_settings_t s;
    att_ars_settings_default(&s, 0.01f);
    if (att_ars_init(&state, &s) != ATT_OK) {
        return 1;
    }
    while (run) {
        out_flags = att_ars_step(&state, v3(0), v3(3));
        put_q(state.st.q);
        if (out_flags == 0xffffffffu) {
            att_ars_reset(&state);
        }
    }
    return 0;
}
#elif ATT_IMAGE == 2
static att_mars_t state;
int main(void)
{
    att_mars_settings_t s;
    att_mars_settings_default(&s, 0.01f);
    if (att_mars_init(&state, &s) != ATT_OK) {
        return 1;
    }
    while (run) {
        out_flags = att_mars_step(&state, v3(0), v3(3), v3(6));
        put_q(state.st.q);
        if (out_flags == 0xffffffffu) {
            att_mars_reset(&state);
        }
    }
    return 0;
}
#elif ATT_IMAGE == 3
static att_kf_t state;
int main(void)
{
    att_kf_settings_t s;
    att_kf_settings_default(&s, 0.01f);
    if (att_kf_init(&state, &s) != ATT_OK) {
        return 1;
    }
    while (run) {
        out_flags = att_kf_step(&state, v3(0), v3(3));
        put_q(state.st.q);
        if (out_flags == 0xffffffffu) {
            att_kf_reset(&state);
        }
    }
    return 0;
}
#elif ATT_IMAGE == 4
static att_ekf_t state;
int main(void)
{
    att_ekf_settings_t s;
    att_filter_t f;
    att_output_t o;
    att_ekf_settings_default(&s, 0.01f);
    if (att_ekf_init(&state, &s) != ATT_OK) {
        return 1;
    }
    while (run) {
        out_flags = att_ekf_step(&state, v3(0), v3(3));
        /* the EKF's state is Euler angles: its quaternion comes with the output */
        f.kind = ATT_FILTER_EKF;
        memcpy(&f.u.ekf, &state, sizeof state);
        att_filter_output(&f, &o);
        put_q(o.q);
        if (out_flags == 0xffffffffu) {
            att_ekf_reset(&state);
        }
    }
    return 0;
}
#elif ATT_IMAGE == 5
static att_gyro_t state;
int main(void)
{
    att_gyro_settings_t s;
    att_gyro_settings_default(&s, 0.01f);
    if (att_gyro_init(&state, &s) != ATT_OK) {
        return 1;
    }
    while (run) {
        out_flags = att_gyro_step(&state, v3(0));
        put_q(state.st.q);
        if (out_flags == 0xffffffffu) {
            att_gyro_reset(&state);
        }
    }
    return 0;
}
#elif ATT_IMAGE == 6
static att_tilt_t state;
int main(void)
{
    att_tilt_settings_t s;
    att_tilt_settings_default(&s);
    if (att_tilt_init(&state, &s) != ATT_OK) {
        return 1;
    }
    while (run) {
        out_flags = att_tilt_step(&state, v3(3));
        put_q(state.st.q);
        if (out_flags == 0xffffffffu) {
            att_tilt_reset(&state);
        }
    }
    return 0;
}
#elif ATT_IMAGE == 7
static att_mekf_t state;
int main(void)
{
    att_mekf_settings_t s;
    att_mekf_settings_default(&s, 0.01f);
    if (att_mekf_init(&state, &s) != ATT_OK) {
        return 1;
    }
    while (run) {
        out_flags = att_mekf_step(&state, v3(0), v3(3), v3(6));
        put_q(state.st.q);
        if (out_flags == 0xffffffffu) {
            att_mekf_reset(&state);
        }
    }
    return 0;
}
#elif ATT_IMAGE == 10 || ATT_IMAGE == 13
static att_filter_t state;
#if ATT_IMAGE == 10
static volatile int kind = ATT_IMAGE_KIND; /* a volatile: every kind compiled in is linked */
#define ATT_IMAGE_RUN_KIND ((att_filter_kind_t)kind)
#else
#define ATT_IMAGE_RUN_KIND ATT_IMAGE_KIND /* a constant: the loop of the kinds' own images */
#endif
int main(void)
{
    att_filter_settings_t s;
    att_sample_t x;
    att_output_t o;
    if (att_filter_settings_default(ATT_IMAGE_RUN_KIND, 0.01f, &s) != ATT_OK ||
        att_filter_init(&state, ATT_IMAGE_RUN_KIND, &s) != ATT_OK) {
        return 1;
    }
    while (run) {
        x.gyr = v3(0);
        x.acc = v3(3);
        x.mag = v3(6);
        out_flags = att_filter_step(&state, &x, &o);
        put_q(o.q);
        if (out_flags == 0xffffffffu) {
            att_filter_reset(&state);
#if ATT_IMAGE == 10
            att_filter_output(&state, &o);
            out_q[0] = (float)att_filter_name(state.kind)[0];
#endif
        }
    }
    return 0;
}
#elif ATT_IMAGE == 11
static volatile uint8_t sink;
int main(void)
{
    att_can_frame_t f[6];
    att_sample_t x;
    att_output_t o;
    att_vec3_t v;
    att_can_status_t st;
    att_can_diag_t d;
    att_can_cmd_t c;
    memset(&o, 0, sizeof o);
    memset(&d, 0, sizeof d);
    memset(&c, 0, sizeof c);
    while (run) {
        x.gyr = v3(0);
        x.acc = v3(3);
        x.mag = v3(6);
        att_can_encode_imu(&x, 1u, f);
        att_can_encode_imu_fd(&x, 2u, &f[3]);
        sink = (uint8_t)att_can_check(&f[0]);
        sink = (uint8_t)att_can_decode_imu_part(&f[1], &v);
        sink = (uint8_t)att_can_decode_imu_fd(&f[3], &x);
        sink = (uint8_t)att_can_encode_output_set(&o, ATT_FILTER_ARS, 3u, 0u, f);
        att_can_encode_output_fd(&o, ATT_FILTER_ARS, 4u, &f[0]);
        sink = (uint8_t)att_can_decode_output(&f[0], &o);
        sink = (uint8_t)att_can_decode_status(&f[5], &st);
        att_can_encode_status(&st, &f[5]);
        att_can_encode_diag(&d, 5u, &f[1]);
        att_can_encode_cmd(&c, &f[2]);
        sink = (uint8_t)att_can_decode_cmd(&f[2], &c);
        sink = att_can_counter(&f[2]);
        sink = att_can_msg_len(f[2].id);
        sink = (uint8_t)att_can_msg_has_crc(f[2].id);
        sink = (uint8_t)att_can_data_id(f[2].id);
        att_can_seal(&f[4]);
        sink = att_can_status_crc(&f[5], &f[0], &f[1], &f[2]);
        sink = att_can_crc8(f[0].data, 8u, 0xffu);
        sink = att_can_e2e_crc(0x0b00u, f[0].data, 7u);
        sink = (uint8_t)att_can_quantise(in[0], 10);
        out_q[0] = att_can_dequantise((int16_t)in[1], 10) + v.x + o.q.w;
    }
    return 0;
}
#elif ATT_IMAGE == 12
static att_node_t node;
int main(void)
{
    att_node_settings_t s;
    att_can_frame_t f;
    if (att_node_settings_default(ATT_FILTER_ARS, 100.0f, &s) != ATT_OK || att_node_init(&node, &s) != ATT_OK) {
        return 1;
    }
    while (run) {
        f.id = (uint32_t)in[0];
        f.len = 8u;
        f.fd = 0u;
        memset(f.data, 0, sizeof f.data);
        f.data[0] = (uint8_t)in[1];
        (void)att_node_rx(&node, &f);
        out_flags = (uint32_t)att_node_poll(&node);
        while (att_node_tx(&node, &f)) {
            out_q[0] = (float)f.data[0];
        }
    }
    return 0;
}
#elif ATT_IMAGE == 0
int main(void)
{
    while (run) {
        out_q[0] = in[0];
    }
    return 0;
}
#else
#error "unknown ATT_IMAGE"
#endif
