/**
 * @file board.h
 * @brief What this example needs from a board (yours replaces board.c): the IMU driver, a clock, and
 * where the CAN controller is. The node itself is in main.c.
 */
#ifndef BOARD_H
#define BOARD_H

#include <stdbool.h>
#include <stdint.h>

#include "attica/att_filter.h"

#define BOARD_IMU_RATE_HZ 285.714f  /**< IMU output data rate (its data-ready interrupt rate), Hz */
#define BOARD_CAN_BITRATE 500000u   /**< CAN bit/s */
#define BOARD_CAN_PCLK_HZ 42000000u /**< the CAN controller's kernel clock (APB1 of an STM32F4 at 168 MHz), Hz */
#define BOARD_CAN_BASE ((void *)0x40006400u) /**< bxCAN1 of an STM32F4 */

/** Clocks, pins, the IMU on SPI with its data-ready interrupt, the CAN pins and clock. */
void board_init(void);
/**
 * The IMU's newest sample when one is ready since the last call (set by the data-ready interrupt):
 * gyro rad/s, accel m/s^2, mag uT (all zero when the IMU has none), in the IMU's own axes.
 */
bool board_imu_read(att_sample_t *in);
/** Sleep until the next interrupt (WFI), or return at once. */
void board_idle(void);

#endif /* BOARD_H */
