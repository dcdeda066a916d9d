/**
 * @file attica.h
 * @brief Umbrella header: the whole public C API of attica in one include.
 *
 * @code
 * #include "attica/attica.h"
 * @endcode
 *
 * - att_version.h: ATT_VERSION_MAJOR/MINOR/PATCH/STRING (the Python package has the same version);
 * - att_types.h: vectors (sensor frame), quaternions (w, x, y, z, sensor-to-earth, earth frame ENU),
 *   samples (gyr rad/s, acc m/s^2, mag uT), output records, status flags (ATT_FLAG_*) and their names;
 * - att_filter.h: the unified interface (att_filter_settings_default, att_filter_init,
 *   att_filter_step, att_filter_output, att_filter_retune) over every filter kind:
 *   att_ars.h, att_mars.h, att_kf.h, att_ekf.h, att_gyro.h, att_tilt.h (their settings structs);
 * - att_math.h, att_sensor.h, att_bias.h, att_magref.h, att_hardiron.h: quaternion/Euler helpers, sample
 *   checks, the shared rest detector and gyro bias, the learnt reference field and the hard-iron
 *   estimate of mars and mekf;
 * - att_can.h, att_node.h: the CAN codec (firmware/can/attica.dbc) and the CAN node.
 *
 * Every header is self-contained: including only the one you need works as well. None exposes inline
 * arithmetic, so your own compiler flags cannot change attica's results (firmware/cflags.txt applies
 * to attica's sources only).
 */
#ifndef ATTICA_H
#define ATTICA_H

#include "attica/att_config.h"
#include "attica/att_version.h"
#include "attica/att_types.h"
#include "attica/att_math.h"
#include "attica/att_sensor.h"
#include "attica/att_bias.h"
#include "attica/att_magref.h"
#include "attica/att_hardiron.h"
#include "attica/att_ars.h"
#include "attica/att_mars.h"
#include "attica/att_kf.h"
#include "attica/att_ekf.h"
#include "attica/att_gyro.h"
#include "attica/att_tilt.h"
#include "attica/att_mekf.h"
#include "attica/att_calib.h"
#include "attica/att_filter.h"
#include "attica/att_can.h"
#include "attica/att_node.h"

#endif /* ATTICA_H */
