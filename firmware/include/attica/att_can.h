/**
 * @file att_can.h
 * @brief attica CAN codec: frames, CRC-8 J1850 / E2E, int16 quantisation, frame set encoders/decoders.
 *
 * The frame layout is defined by firmware/can/attica.dbc (the single source of truth); the bit packing
 * is done by the code cantools generated from it (firmware/src/can/generated/att_can_db.c). This
 * module adds the parts a DBC cannot express: the E2E CRC, our quantisation and the grouping into
 * frame sets. See docs/can.md.
 *
 * - CRC: CRC-8 SAE J1850 (poly 0x1D, init 0xFF, final XOR 0xFF, not reflected; check 0x4B). E2E as in
 *   AUTOSAR profile 1: over the 16-bit data ID (0x0A00 + CAN ID, low byte first), then the frame's
 *   bytes 1..len-1; the result goes to byte 0. ATT_QUAT_A/B/QUAT16 have no room for a CRC: the CRC of
 *   ATT_STATUS of the same set also covers their 24 bytes (att_can_status_crc).
 * - Quantisation: q = round_half_even(x * 2^k) after clamping x * 2^k to [-32767, 32767]; NaN -> -32768
 *   (ATT_CAN_NA, "not available"). Dequantisation q * 2^-k is exact in float32; -32768 -> NaN.
 * - Counters: byte 1 low nibble of every frame with room: sample index (inputs) or output set index
 *   (outputs) mod 16; all frames of one set share it.
 */
#ifndef ATT_CAN_H
#define ATT_CAN_H

#include "attica/att_config.h"
#include "attica/att_filter.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** Identifiers, scales and codes of the attica CAN interface (values fixed by attica.dbc). */
enum {
    ATT_CAN_ID_IMU_GYRO = 0x100,   /**< host -> node: gyro, int16 2^-10 rad/s */
    ATT_CAN_ID_IMU_ACC = 0x101,    /**< host -> node: accel, int16 2^-8 m/s^2 */
    ATT_CAN_ID_IMU_MAG = 0x102,    /**< host -> node: mag, int16 2^-5 uT */
    ATT_CAN_ID_IMU_FD = 0x110,     /**< host -> node: whole sample, CAN FD 64 B, float32 */
    ATT_CAN_ID_QUAT_A = 0x200,     /**< node -> host: q_w, q_x float32 (no CRC: covered by STATUS) */
    ATT_CAN_ID_QUAT_B = 0x201,     /**< node -> host: q_y, q_z float32 (covered by STATUS) */
    ATT_CAN_ID_QUAT16 = 0x202,     /**< node -> host: q int16 2^-14 (covered by STATUS) */
    ATT_CAN_ID_EULER = 0x203,      /**< node -> host: roll, pitch, yaw int16 2^-13 rad */
    ATT_CAN_ID_BIAS = 0x204,       /**< node -> host: gyro bias int16 2^-15 rad/s */
    ATT_CAN_ID_STATUS = 0x205,     /**< node -> host: kind, flags, steps, errors, command answer */
    ATT_CAN_ID_DIAG = 0x206,       /**< node -> host: rx error counters */
    ATT_CAN_ID_OUT_FD = 0x210,     /**< node -> host: whole output set, CAN FD 64 B */
    ATT_CAN_ID_LIN_ACC = 0x207,    /**< node -> host: linear acceleration, body, int16 2^-8 m/s^2 */
    ATT_CAN_ID_EARTH_ACC = 0x208,  /**< node -> host: earth-frame acceleration, int16 2^-8 m/s^2 */
    ATT_CAN_ID_CAL_ACK = 0x209,    /**< node -> host: answer to a calibration command */
    ATT_CAN_ID_DIAG_BUS = 0x20A,   /**< node -> host: CAN controller counters of the port (after ATT_DIAG) */
    ATT_CAN_ID_MAG_OFFSET = 0x20B, /**< node -> host: hard-iron offset estimated (mars, mekf), int16 2^-5 uT */
    ATT_CAN_ID_ACCEL_FD = 0x211,   /**< node -> host: gravity, linear, earth acceleration, CAN FD 64 B */
    ATT_CAN_ID_CMD = 0x300,        /**< host -> node: command */
    ATT_CAN_DATA_ID_BASE = 0x0A00, /**< E2E data ID = base + CAN ID */
    ATT_CAN_CLASSIC_LEN = 8,       /**< length of every classic attica frame */
    ATT_CAN_FD_LEN = 64,           /**< length of IMU_FD and ATT_OUT_FD */
    ATT_CAN_GYR_FRAC = 10,         /**< gyro scale 2^-10 rad/s */
    ATT_CAN_ACC_FRAC = 8,          /**< accel scale 2^-8 m/s^2 */
    ATT_CAN_MAG_FRAC = 5,          /**< mag scale 2^-5 uT */
    ATT_CAN_QUAT16_FRAC = 14,      /**< ATT_QUAT16 scale 2^-14 */
    ATT_CAN_EULER_FRAC = 13,       /**< ATT_EULER scale 2^-13 rad */
    ATT_CAN_BIAS_FRAC = 15,        /**< ATT_BIAS scale 2^-15 rad/s */
    ATT_CAN_FRAC_MIN = -30,        /**< smallest frac_bits accepted by (de)quantise */
    ATT_CAN_FRAC_MAX = 30,         /**< largest frac_bits accepted by (de)quantise */
    ATT_CAN_NA = -32768,           /**< int16 code of "not available" (NaN) */
    ATT_CAN_Q_FULL = 32767,        /**< int16 code of full scale; in an IMU field: clipped (att_can_decode_imu_part) */
    ATT_CAN_CMD_SELECT = 1,        /**< command: select filter, arg = att_filter_kind_t */
    ATT_CAN_CMD_RESET = 2,         /**< command: reset the filter */
    ATT_CAN_CMD_SET_GAIN = 3,      /**< command: set gain, arg = ATT_CAN_GAIN_*, value */
    ATT_CAN_CMD_CAL_BEGIN = 4,     /**< calibration session: shadow = applied (arg 0) or identity (arg 1) */
    ATT_CAN_CMD_CAL_SET = 5,       /**< shadow field arg (att_calib_field_set index) = value */
    ATT_CAN_CMD_CAL_COMMIT = 6,    /**< validate the shadow, apply it atomically, persist */
    ATT_CAN_CMD_CAL_ABORT = 7,     /**< drop the shadow */
    ATT_CAN_CMD_SET_CONVENTION = 8, /**< arg = att_convention_t, applied atomically */
    ATT_CAN_CMD_SET_REMAP = 9,     /**< arg = mounting remap 0 .. 24, applied atomically */
    ATT_CAN_PERSIST_NONE = 0,      /**< ATT_CAL_ACK.persisted: no hook registered */
    ATT_CAN_PERSIST_OK = 1,        /**< the port hook saved the configuration */
    ATT_CAN_PERSIST_FAILED = 2,    /**< the hook failed (the configuration is applied all the same) */
    ATT_CAN_GAIN_TAU_ACC = 1,      /**< accel correction time constant: ars.tau, mars.tau_acc (s) */
    ATT_CAN_GAIN_TAU_MAG = 2,      /**< mag correction time constant: mars.tau_mag (s) */
    ATT_CAN_GAIN_KF_R = 3,         /**< KF measurement noise r_noise */
    ATT_CAN_GAIN_EKF_R = 4,        /**< EKF measurement noise r_phi and r_theta */
    ATT_CAN_GAIN_DECLINATION = 5,  /**< magnetic declination: mars.declination, mekf.declination (rad); from
                                        the next heading alignment (RESET applies it at once) */
    ATT_CAN_ACK_ANSWER = 0x80,     /**< ATT_STATUS.ack bit 7: this STATUS answers a command */
    ATT_CAN_ACK_OK = 0,            /**< ack result (bits 4..6): done */
    ATT_CAN_ACK_UNKNOWN_CMD = 1,   /**< ack result: unknown command code */
    ATT_CAN_ACK_BAD_ARG = 2,       /**< ack result: arg not valid (kind / parameter for this filter) */
    ATT_CAN_ACK_REFUSED = 3,       /**< ack result: value refused by the settings validation; no change */
    ATT_CAN_BUS_ACTIVE = 0,        /**< ATT_DIAG_BUS.state: error-active */
    ATT_CAN_BUS_WARNING = 1,       /**< error warning: an error counter reached 96 */
    ATT_CAN_BUS_PASSIVE = 2,       /**< error-passive: an error counter above 127 */
    ATT_CAN_BUS_OFF = 3            /**< bus-off (the port's back-off or recovery under way) */
};

/** One CAN or CAN FD frame (classic: len 0..8; FD: len up to 64). */
typedef struct {
    uint32_t id;      /**< 11-bit identifier */
    uint8_t len;      /**< data length in bytes: 0..8 classic, up to 64 for FD */
    uint8_t fd;       /**< 1 = CAN FD frame */
    uint8_t data[64]; /**< payload; bytes from len on are zero in frames built here */
} att_can_frame_t;

/** Result of att_can_check. */
typedef enum {
    ATT_CAN_OK = 0,             /**< known ID, right length, CRC right (or no CRC in this message) */
    ATT_CAN_ERR_UNKNOWN_ID = 1, /**< not an attica message */
    ATT_CAN_ERR_DLC = 2,        /**< wrong length or classic/FD format for this ID */
    ATT_CAN_ERR_CRC = 3         /**< E2E CRC mismatch */
} att_can_check_t;

/** The receive error counters carried by ATT_DIAG (each saturates at 255 on the bus). */
typedef struct {
    uint32_t crc_errors;
    uint32_t counter_gaps;
    uint32_t dlc_errors;
    uint32_t unknown_ids;
    uint32_t duplicates;
    uint32_t stale_partials;
} att_can_diag_t;

/**
 * The CAN controller counters carried by ATT_DIAG_BUS (a port's, through att_node_set_bus_diag; each
 * counter saturates at 255 on the bus).
 */
typedef struct {
    uint8_t state;          /**< ATT_CAN_BUS_ACTIVE / _WARNING / _PASSIVE / _OFF now */
    uint8_t lec;            /**< last error code the controller reported: 0 none yet, 1 stuff, 2 form, 3 ack,
                                 4 bit recessive, 5 bit dominant, 6 CRC */
    uint32_t bus_off;       /**< bus-off episodes entered */
    uint32_t recoveries;    /**< bus-off episodes ended (back on the bus after the port's recovery) */
    uint32_t error_passive; /**< entries into error-passive */
    uint32_t error_warning; /**< entries into error warning */
    uint32_t rx_overruns;   /**< receive FIFO overruns (frames lost in the controller) */
} att_can_bus_diag_t;

/** A command (CMD frame). */
typedef struct {
    uint8_t counter; /**< 0..15, echoed in the answer */
    uint8_t cmd;     /**< ATT_CAN_CMD_* */
    uint8_t arg;     /**< kind (select) or ATT_CAN_GAIN_* (set gain) */
    float value;     /**< set gain: the new value */
} att_can_cmd_t;

/** Fields of an ATT_CAL_ACK frame (the answer to CMD 4..9). */
typedef struct {
    uint8_t counter;   /**< the command's counter */
    uint8_t cmd;       /**< the command answered */
    uint8_t result;    /**< ATT_CAN_ACK_OK / _UNKNOWN_CMD / _BAD_ARG / _REFUSED */
    uint8_t reason;    /**< att_calib_error_t of a refusal (0 otherwise) */
    uint8_t index;     /**< CAL_SET: the field index; CAL_COMMIT: the fields set in the session */
    uint8_t persisted; /**< ATT_CAN_PERSIST_* */
    uint8_t session;   /**< 1 while a session is open */
} att_can_cal_ack_t;

/** Fields of an ATT_STATUS frame. */
typedef struct {
    uint8_t counter;     /**< set counter, or the command's counter in an answer */
    uint8_t kind;        /**< att_filter_kind_t (0..15) */
    uint16_t flags;      /**< ATT_FLAG_* of the last step */
    uint16_t steps;      /**< low 16 bits of the filter's step counter */
    uint8_t error_count; /**< saturating total of rx errors */
    uint8_t ack;         /**< 0, or ATT_CAN_ACK_ANSWER | result << 4 | (cmd & 15) */
} att_can_status_t;

/**
 * Raw CRC-8 J1850 update: runs the register crc (no final XOR) over len bytes and returns it.
 * The CRC of a buffer is att_can_crc8(buf, n, 0xFF) ^ 0xFF. NULL data with len > 0 returns crc.
 */
uint8_t att_can_crc8(const uint8_t *data, size_t len, uint8_t crc);
/** E2E CRC (with final XOR) over data_id (low byte first) then len payload bytes (bytes 1.. of a frame). */
uint8_t att_can_e2e_crc(uint16_t data_id, const uint8_t *payload, size_t len);
/** round_half_even(x * 2^frac_bits) clamped to [-32767, 32767]; NaN (or frac_bits out of range) -> -32768. */
int16_t att_can_quantise(float x, int32_t frac_bits);
/** v * 2^-frac_bits, exact; -32768 (or frac_bits out of range) -> NaN. */
float att_can_dequantise(int16_t v, int32_t frac_bits);

/** Length of an attica message (8 or 64), 0 for an unknown ID. */
uint8_t att_can_msg_len(uint32_t id);
/** True when the message has a CRC/counter in bytes 0/1 (all but ATT_QUAT_A/B/QUAT16). */
bool att_can_msg_has_crc(uint32_t id);
/** E2E data ID of a CAN ID (0x0A00 + id). */
uint16_t att_can_data_id(uint32_t id);
/** Check a received frame: known ID, length and format, CRC (ATT_STATUS: its own bytes only). */
att_can_check_t att_can_check(const att_can_frame_t *f);
/** Write the E2E CRC into byte 0 of a frame that has one (no-op for the others and for NULL). */
void att_can_seal(att_can_frame_t *f);
/** E2E CRC of an output set: data ID, STATUS bytes 1..7, then the 8 bytes of QUAT_A, QUAT_B, QUAT16. */
uint8_t att_can_status_crc(const att_can_frame_t *status, const att_can_frame_t *quat_a,
                           const att_can_frame_t *quat_b, const att_can_frame_t *quat16);
/** The alive counter (byte 1 low nibble) of a frame with one; 0 for NULL / frames without. */
uint8_t att_can_counter(const att_can_frame_t *f);

/** Encode a sample as IMU_GYRO, IMU_ACC, IMU_MAG (out[0..2]), sealed, counter & 15. NaN mag = absent. */
void att_can_encode_imu(const att_sample_t *in, uint8_t counter, att_can_frame_t out[3]);
/** Encode a sample as one IMU_FD frame (float32, exact), sealed. */
void att_can_encode_imu_fd(const att_sample_t *in, uint8_t counter, att_can_frame_t *out);
/** Encode ATT_LIN_ACC and ATT_EARTH_ACC (out[0], out[1]) of the acceleration outputs a, sealed. */
void att_can_encode_accel(const att_accel_t *a, uint8_t counter, att_can_frame_t out[2]);
/** Encode ATT_ACCEL_FD (float32, exact) of the acceleration outputs a, sealed. */
void att_can_encode_accel_fd(const att_accel_t *a, uint8_t counter, att_can_frame_t *out);
/** The acceleration outputs of an ATT_ACCEL_FD frame (no CRC check); valid = ATT_OUT_ACCEL or 0. */
bool att_can_decode_accel_fd(const att_can_frame_t *f, att_accel_t *out);
/** The 3 dequantised values of an ATT_LIN_ACC / ATT_EARTH_ACC frame (no CRC check). */
bool att_can_decode_accel_part(const att_can_frame_t *f, att_vec3_t *v);
/** Encode an ATT_CAL_ACK, sealed. */
void att_can_encode_cal_ack(const att_can_cal_ack_t *a, att_can_frame_t *out);
/** The fields of an ATT_CAL_ACK frame (no CRC check). */
bool att_can_decode_cal_ack(const att_can_frame_t *f, att_can_cal_ack_t *out);
/** The 3 dequantised values of an IMU_GYRO/ACC/MAG frame (no CRC check: att_can_check first); a field
 * at full scale (+-ATT_CAN_Q_FULL: clipped by the frame, at or beyond 32767 2^-k) gives +-32767 2^112
 * (about +-1.7e38), which every filter takes as beyond its range (a gyro's starts the recovery of a
 * clipping gyro). Outputs decode with the plain att_can_dequantise. */
bool att_can_decode_imu_part(const att_can_frame_t *f, att_vec3_t *v);
/** The sample in an IMU_FD frame (no CRC check). */
bool att_can_decode_imu_fd(const att_can_frame_t *f, att_sample_t *out);

/**
 * Encode an output set: QUAT_A, QUAT_B, QUAT16, EULER, BIAS, STATUS (ack 0) into out[0..5], each sealed
 * (STATUS with att_can_status_crc). Returns 6 (0 for NULL).
 */
size_t att_can_encode_output_set(const att_output_t *o, att_filter_kind_t kind, uint8_t counter,
                                 uint8_t error_count, att_can_frame_t out[6]);
/** Encode an output set as one ATT_OUT_FD frame, sealed. */
void att_can_encode_output_fd(const att_output_t *o, att_filter_kind_t kind, uint8_t counter,
                              att_can_frame_t *out);
/** Encode a stand-alone ATT_STATUS (a command answer: CRC over its own bytes), sealed. */
void att_can_encode_status(const att_can_status_t *st, att_can_frame_t *out);
/** Decode the fields of an ATT_STATUS frame. */
bool att_can_decode_status(const att_can_frame_t *f, att_can_status_t *st);
/** Encode ATT_DIAG (counters saturated at 255), sealed. */
void att_can_encode_diag(const att_can_diag_t *d, uint8_t counter, att_can_frame_t *out);
/** Encode ATT_DIAG_BUS (counters saturated at 255, state & 3, lec & 7), sealed. */
void att_can_encode_diag_bus(const att_can_bus_diag_t *d, uint8_t counter, att_can_frame_t *out);
/** The fields of an ATT_DIAG_BUS frame (no CRC check; counters as on the bus, 0 .. 255). */
bool att_can_decode_diag_bus(const att_can_frame_t *f, att_can_bus_diag_t *d);
/**
 * Encode ATT_MAG_OFFSET from att_filter_mag_offset's record: the hard-iron offset (uT; int16 2^-5 uT,
 * saturated, NaN as NA) and whether it was observable, sealed.
 */
void att_can_encode_mag_offset(const att_mag_offset_t *h, uint8_t counter, att_can_frame_t *out);
/** The fields of an ATT_MAG_OFFSET frame (no CRC check; NA as NaN; on is true: the node sends it only then). */
bool att_can_decode_mag_offset(const att_can_frame_t *f, att_mag_offset_t *h);
/** Encode a CMD frame, sealed. */
void att_can_encode_cmd(const att_can_cmd_t *c, att_can_frame_t *out);
/** Decode a CMD frame (no CRC check). */
bool att_can_decode_cmd(const att_can_frame_t *f, att_can_cmd_t *c);
/**
 * Decode the output fields one output frame carries into o (others untouched): QUAT_A q.w/q.x,
 * QUAT_B q.y/q.z, EULER euler, BIAS gyro_bias, STATUS flags/steps, OUT_FD all. QUAT16 is not decoded
 * (lossy duplicate of QUAT_A/B). Returns false for other IDs / NULL.
 */
bool att_can_decode_output(const att_can_frame_t *f, att_output_t *o);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_CAN_H */
