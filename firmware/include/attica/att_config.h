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
 *
 * The CAN node (att_node.h) has three options of its own: the sizes of its receive and transmit rings
 * (ATT_NODE_RX_RING, ATT_NODE_TX_RING) and whether it handles CAN FD frames at all
 * (ATT_NODE_WITH_FD). Together with the kinds and the stages they set the node's RAM: att_node_t is
 * about 11 KB with the defaults and under 1 KB with ARS alone, no stages, classic frames and rings of
 * 8 (docs/firmware-quickstart.md has the measured table).
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

/**
 * The hard-iron offset estimated on the device by mars and mekf (att_hardiron.h; opt-in at run time with
 * their setting hard_iron_tau > 0). With 0 its code is left out (about 2 KB of flash per kind on a
 * Cortex-M4F at -Os), their settings validation refuses hard_iron_tau > 0 and att_filter_mag_offset
 * returns ATT_ERR_DISABLED; the state keeps its fields.
 */
#ifndef ATT_WITH_HARD_IRON
#define ATT_WITH_HARD_IRON 1
#endif

/**
 * CAN FD in the node: IMU_FD in, ATT_OUT_FD / ATT_ACCEL_FD out (att_node_settings_t.fd). With 0 the
 * node handles classic frames only: its rings store 8 data bytes a frame instead of 64, settings with
 * fd true are refused, and an IMU_FD frame is not for it (counted in unknown_ids).
 */
#ifndef ATT_NODE_WITH_FD
#define ATT_NODE_WITH_FD 1
#endif
/** Frames in the node's receive ring: a power of two, at least 4 (a classic sample and a command). */
#ifndef ATT_NODE_RX_RING
#define ATT_NODE_RX_RING 64
#endif
/**
 * Frames in the node's transmit ring: a power of two, at least ATT_NODE_SET_MAX (the most frames one
 * received frame can queue: 8 without the stages, 10 with them; see att_node.h).
 */
#ifndef ATT_NODE_TX_RING
#define ATT_NODE_TX_RING 64
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
#if (ATT_WITH_HARD_IRON != 0) && (ATT_WITH_HARD_IRON != 1)
#error "ATT_WITH_HARD_IRON must be 0 or 1"
#endif
#if (ATT_WITH_ARS + ATT_WITH_MARS + ATT_WITH_KF + ATT_WITH_EKF + ATT_WITH_GYRO + ATT_WITH_TILT + ATT_WITH_MEKF) == 0
#error "attica needs at least one filter kind: set one of ATT_WITH_ARS ... ATT_WITH_MEKF to 1"
#endif
#if (ATT_NODE_WITH_FD != 0) && (ATT_NODE_WITH_FD != 1)
#error "ATT_NODE_WITH_FD must be 0 or 1"
#endif
#if (ATT_NODE_RX_RING < 4) || (ATT_NODE_RX_RING > 65536) || ((ATT_NODE_RX_RING & (ATT_NODE_RX_RING - 1)) != 0)
#error "ATT_NODE_RX_RING must be a power of two from 4 to 65536"
#endif
/* Derived, not an option: the node sends ATT_MAG_OFFSET (a kind with the hard-iron estimate is built). */
#if ATT_WITH_HARD_IRON && (ATT_WITH_MARS || ATT_WITH_MEKF)
#define ATT_NODE_WITH_MAG_OFFSET 1 /* (att_node.h: ATT_NODE_SET_MAX) */
#else
#define ATT_NODE_WITH_MAG_OFFSET 0 /* (att_node.h: ATT_NODE_SET_MAX) */
#endif
#if (ATT_NODE_TX_RING < 8 + 2 * ATT_WITH_CALIB + ATT_NODE_WITH_MAG_OFFSET) || (ATT_NODE_TX_RING > 65536) || \
    ((ATT_NODE_TX_RING & (ATT_NODE_TX_RING - 1)) != 0)
#error "ATT_NODE_TX_RING must be a power of two from ATT_NODE_SET_MAX (8, 10 with ATT_WITH_CALIB; 1 more with mars or mekf and ATT_WITH_HARD_IRON) to 65536"
#endif

#endif /* ATT_CONFIG_H */
