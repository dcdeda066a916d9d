/**
 * @file att_config_test.c
 * @brief What a build configuration (att_config.h) does to the public interface, printed for
 * tests/test_configs.py: built once per configuration with the firmware's own flags.
 *
 * Output lines:
 *   kind NUM NAME default=STATUS init=STATUS   every att_filter_kind_t value 1..7 (and 0, 8)
 *   sizeof att_filter_t=N largest_kind=N       the union against the largest kind compiled in
 *   calibrate=STATUS                           att_filter_calibrate on an initialised filter
 *   select NUM result=R                        the node's SELECT command for each kind (R: ack result)
 *   hard_iron KIND init=STATUS offset=STATUS   mars and mekf (when compiled in) with hard_iron_tau 60 s:
 *                                              att_filter_init, then att_filter_mag_offset on the
 *                                              default settings
 */
#include <stdio.h>
#include <string.h>

#include "attica/att_can.h"
#include "attica/att_filter.h"
#include "attica/att_node.h"

/* The hard-iron estimate (att_config.h ATT_WITH_HARD_IRON) of mars and mekf, where compiled in. */
static void hard_iron(void)
{
    static const att_filter_kind_t kinds[2] = {ATT_FILTER_MARS, ATT_FILTER_MEKF};
    unsigned i;
    for (i = 0u; i < 2u; i++) {
        static att_filter_t f;
        att_filter_settings_t s;
        att_mag_offset_t h;
        int init;
        if (att_filter_settings_default(kinds[i], 0.01f, &s) != ATT_OK) {
            continue;
        }
#if ATT_WITH_MARS
        if (kinds[i] == ATT_FILTER_MARS) {
            s.mars.hard_iron_tau = 60.0f;
        }
#endif
#if ATT_WITH_MEKF
        if (kinds[i] == ATT_FILTER_MEKF) {
            s.mekf.hard_iron_tau = 60.0f;
        }
#endif
        init = (int)att_filter_init(&f, kinds[i], &s);
        (void)att_filter_settings_default(kinds[i], 0.01f, &s);
        (void)att_filter_init(&f, kinds[i], &s);
        printf("hard_iron %s init=%d offset=%d\n", att_filter_name(kinds[i]), init,
               (int)att_filter_mag_offset(&f, &h));
    }
}

static size_t largest_kind(void)
{
    size_t m = 0u;
#if ATT_WITH_ARS
    m = (sizeof(att_ars_t) > m) ? sizeof(att_ars_t) : m;
#endif
#if ATT_WITH_MARS
    m = (sizeof(att_mars_t) > m) ? sizeof(att_mars_t) : m;
#endif
#if ATT_WITH_KF
    m = (sizeof(att_kf_t) > m) ? sizeof(att_kf_t) : m;
#endif
#if ATT_WITH_EKF
    m = (sizeof(att_ekf_t) > m) ? sizeof(att_ekf_t) : m;
#endif
#if ATT_WITH_GYRO
    m = (sizeof(att_gyro_t) > m) ? sizeof(att_gyro_t) : m;
#endif
#if ATT_WITH_TILT
    m = (sizeof(att_tilt_t) > m) ? sizeof(att_tilt_t) : m;
#endif
#if ATT_WITH_MEKF
    m = (sizeof(att_mekf_t) > m) ? sizeof(att_mekf_t) : m;
#endif
    return m;
}

/* The answer (ack result) of the node to SELECT kind, or -1 when there is none. */
static int node_select(att_filter_kind_t running, int kind)
{
    static att_node_t node;
    att_node_settings_t s;
    att_can_cmd_t c;
    att_can_frame_t f;
    att_can_status_t st;
    int result = -1;
    if (att_node_settings_default(running, 100.0f, &s) != ATT_OK || att_node_init(&node, &s) != ATT_OK) {
        return -2;
    }
    memset(&c, 0, sizeof c);
    c.cmd = (uint8_t)ATT_CAN_CMD_SELECT;
    c.arg = (uint8_t)kind;
    c.counter = 1u;
    att_can_encode_cmd(&c, &f);
    (void)att_node_rx(&node, &f);
    (void)att_node_poll(&node);
    while (att_node_tx(&node, &f)) {
        if (att_can_decode_status(&f, &st) && (st.ack & (uint8_t)ATT_CAN_ACK_ANSWER) != 0u) {
            result = (int)((st.ack >> 4) & 7u);
        }
    }
    return result;
}

int main(void)
{
    att_filter_settings_t s;
    att_filter_t f;
    att_calib_settings_t cs;
    att_filter_kind_t running = ATT_FILTER_NONE;
    int k;
    for (k = 0; k <= 8; k++) {
        const att_filter_kind_t kind = (att_filter_kind_t)k;
        const int d = (int)att_filter_settings_default(kind, 0.01f, &s);
        const int i = (d == 0) ? (int)att_filter_init(&f, kind, &s) : d;
        if (i == 0 && running == ATT_FILTER_NONE) {
            running = kind;
        }
        printf("kind %d %s default=%d init=%d\n", k, att_filter_name(kind), d, i);
    }
    printf("sizeof att_filter_t=%u largest_kind=%u\n", (unsigned)sizeof(att_filter_t), (unsigned)largest_kind());
    (void)att_filter_settings_default(running, 0.01f, &s);
    (void)att_filter_init(&f, running, &s);
    att_calib_settings_default(&cs);
    printf("calibrate=%d\n", (int)att_filter_calibrate(&f, &cs));
    hard_iron();
    for (k = 1; k <= 8; k++) {
        printf("select %d result=%d\n", k, node_select(running, k));
    }
    return 0;
}
