/**
 * @file board.c
 * @brief A stand-in board for building this example in CI (no real IMU or clock setup): replace it with
 * your drivers. board_imu_read gives a sensor lying still, level; board_idle returns at once.
 */
#include "board.h"

static volatile uint32_t imu_ready; /* set by the IMU's data-ready interrupt on a real board */

void board_init(void)
{
    imu_ready = 1u;
}

bool board_imu_read(att_sample_t *in)
{
    if (imu_ready == 0u) {
        return false;
    }
    in->gyr.x = 0.0f;
    in->gyr.y = 0.0f;
    in->gyr.z = 0.0f;
    in->acc.x = 0.0f;
    in->acc.y = 0.0f;
    in->acc.z = 9.80665f;
    in->mag.x = 0.0f;
    in->mag.y = 0.0f;
    in->mag.z = 0.0f;
    return true;
}

void board_idle(void)
{
}
