/**
 * @file main.c
 * @brief An attica CAN node on a small board (docs/firmware-quickstart.md): the IMU on the same board,
 * the ARS filter, the outputs on a classic CAN bus through the bxCAN port.
 *
 * Every sample of the IMU goes into the node with att_node_push_sample (the filter steps at once and
 * the node queues the output frames); att_can_hal_service receives commands from the bus, and sends
 * the queued frames. The node's size is set by my_attica_config.h; the port's acceptance filter lets
 * only the node's own IDs (att_node_rx_ids) reach the CPU.
 */
#include "attica/att_node.h"

#include "att_can_hal.h"
#include "board.h"

static att_node_t node;   /* sized by my_attica_config.h (make footprint): a static, no heap */
static att_can_hal_t can; /* the bxCAN port */

static void fail(void)
{
    for (;;) {
        board_idle(); /* a real board would blink an LED here */
    }
}

int main(void)
{
    att_node_settings_t s;
    att_sample_t in;
    board_init();
    if (att_node_settings_default(ATT_FILTER_ARS, BOARD_IMU_RATE_HZ, &s) != ATT_OK) {
        fail();
    }
    s.bitrate = BOARD_CAN_BITRATE;
    s.filter.ars.tau = 1.0f; /* accel correction time constant, s (the per-sample gain is then unused) */
    s.id_offset = 0;         /* the IDs of attica.dbc; another node on the bus would take e.g. 0x20 */
    if (att_node_init(&node, &s) != ATT_OK) {
        fail(); /* att_filter_settings_check(ATT_FILTER_ARS, &s.filter, &why) names a refused filter field */
    }
    if (att_can_hal_init(&can, att_can_hal_mmio(BOARD_CAN_BASE), &node, BOARD_CAN_PCLK_HZ) != ATT_OK) {
        fail();
    }
    for (;;) {
        if (board_imu_read(&in)) {
            (void)att_node_push_sample(&node, &in); /* false only when tx is full: counted by the node */
        }
        (void)att_can_hal_service(&can); /* commands in, output frames out */
        board_idle();
    }
}
