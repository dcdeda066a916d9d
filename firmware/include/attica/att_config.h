/**
 * @file att_config.h
 * @brief Build-time configuration: which filter kinds and stages are compiled in.
 *
 * Every public header includes this one first. To change an option, either define it on the command
 * line (-DATT_WITH_EKF=0) or write a header of your own and name it, as libcanard's
 * CANARD_CONFIG_HEADER:
 *
 *     -DATT_CONFIG_HEADER='"my_attica_config.h"'      (included before the defaults below)
 *
 * The same options must be given to every file that includes an attica header, the library's own
 * sources included (CMake: target_compile_definitions on attica; attica.mk: ATTICA_CONFIG), since
 * they change the layout of att_filter_t and att_filter_settings_t. Each option is 0 or 1, written
 * as the bare digit (the kind table pastes it into a macro name); anything else stops the build.
 *
 * A kind that is compiled out is not in the unions of att_filter.h: att_filter_init,
 * att_filter_settings_default and the node's filter command refuse it (ATT_ERR_DISABLED; on CAN the
 * command's answer is REFUSED), and att_filter_name still names it. Its own header (att_<kind>.h)
 * and functions stay available for direct use. The DBC documents every kind whatever the build.
 */
#ifndef ATT_CONFIG_H
#define ATT_CONFIG_H

#ifdef ATT_CONFIG_HEADER
#include ATT_CONFIG_HEADER
#endif

/** The quaternion complementary ARS (att_ars.h), 6-axis. */
#ifndef ATT_WITH_ARS
#define ATT_WITH_ARS 1
#endif
/** The 9-axis complementary filter with magnetometer (att_mars.h). */
#ifndef ATT_WITH_MARS
#define ATT_WITH_MARS 1
#endif
/** The linear quaternion Kalman filter (att_kf.h), 6-axis. */
#ifndef ATT_WITH_KF
#define ATT_WITH_KF 1
#endif
/** The Euler-angle extended Kalman filter (att_ekf.h), 6-axis. */
#ifndef ATT_WITH_EKF
#define ATT_WITH_EKF 1
#endif
/** The gyro-only Euler-rate integration baseline (att_gyro.h). */
#ifndef ATT_WITH_GYRO
#define ATT_WITH_GYRO 1
#endif
/** The accel-only tilt baseline (att_tilt.h). */
#ifndef ATT_WITH_TILT
#define ATT_WITH_TILT 1
#endif
/** The multiplicative EKF with gyro bias, 6- or 9-axis (att_mekf.h). */
#ifndef ATT_WITH_MEKF
#define ATT_WITH_MEKF 1
#endif
/**
 * The input/output stages of att_filter_t (att_calib.h: calibration, mounting, output convention,
 * acceleration outputs). With 0, att_filter_t has no stages (the filter runs in the sensor frame,
 * ENU), att_filter_calibrate returns ATT_ERR_DISABLED and att_filter_accel gives nothing; the
 * node refuses a calibration other than the identity and answers its calibration commands REFUSED.
 */
#ifndef ATT_WITH_CALIB
#define ATT_WITH_CALIB 1
#endif

#if (ATT_WITH_ARS != 0) && (ATT_WITH_ARS != 1)
#error "ATT_WITH_ARS must be 0 or 1"
#endif
#if (ATT_WITH_MARS != 0) && (ATT_WITH_MARS != 1)
#error "ATT_WITH_MARS must be 0 or 1"
#endif
#if (ATT_WITH_KF != 0) && (ATT_WITH_KF != 1)
#error "ATT_WITH_KF must be 0 or 1"
#endif
#if (ATT_WITH_EKF != 0) && (ATT_WITH_EKF != 1)
#error "ATT_WITH_EKF must be 0 or 1"
#endif
#if (ATT_WITH_GYRO != 0) && (ATT_WITH_GYRO != 1)
#error "ATT_WITH_GYRO must be 0 or 1"
#endif
#if (ATT_WITH_TILT != 0) && (ATT_WITH_TILT != 1)
#error "ATT_WITH_TILT must be 0 or 1"
#endif
#if (ATT_WITH_MEKF != 0) && (ATT_WITH_MEKF != 1)
#error "ATT_WITH_MEKF must be 0 or 1"
#endif
#if (ATT_WITH_CALIB != 0) && (ATT_WITH_CALIB != 1)
#error "ATT_WITH_CALIB must be 0 or 1"
#endif
#if (ATT_WITH_ARS + ATT_WITH_MARS + ATT_WITH_KF + ATT_WITH_EKF + ATT_WITH_GYRO + ATT_WITH_TILT + ATT_WITH_MEKF) == 0
#error "attica needs at least one filter kind: set one of ATT_WITH_ARS ... ATT_WITH_MEKF to 1"
#endif

#endif /* ATT_CONFIG_H */
