/**
 * @file att_calib.h
 * @brief Input and output stages around every filter: sensor models, mounting, output convention.
 *
 * @code
 * static att_filter_t f;                                 // initialised: att_filter_init
 * att_filter_settings_t s;
 * att_calib_settings_t cs;
 * att_filter_settings_default(ATT_FILTER_MARS, 0.01f, &s);
 * (void)att_filter_init(&f, ATT_FILTER_MARS, &s);
 * att_calib_settings_default(&cs);                      // identity everywhere, ENU
 * cs.gyro.offset = (att_vec3_t){0.01f, -0.02f, 0.0f};   // rad/s (a C99 compound literal)
 * cs.mag.hard_iron = (att_vec3_t){12.5f, -3.0f, 40.2f}; // uT; cs.mag.soft_iron[9] likewise
 * cs.remap = att_calib_remap_parse("+y+x-z");           // the board is mounted rotated
 * cs.convention = ATT_CONV_NED;
 * if (att_filter_calibrate(&f, &cs) != ATT_OK) {        // refused: the filter is unchanged
 *     log_refused("calib", att_calib_error_name(att_calib_settings_check(&cs)), "");   // "gyro matrix" ...
 * }
 * @endcode
 *
 * Input stage (att_calib_apply; att_filter_step applies it before the filter's own step):
 * - inertial model of the gyro (rad/s) and the accel (m/s^2): v = M (s * (raw - o)), misalignment M
 *   (3x3), sensitivity s (3), offset o (3);
 * - magnetic model (uT): m = S (raw - h), soft-iron S (3x3), hard-iron h (3); an absent mag sample
 *   stays absent: the zero vector is passed on unchanged, and a NaN component makes every component
 *   NaN (0 * NaN is NaN);
 * - mounting: v_body = R v, R the rotation body <- sensor, given as a unit quaternion or as one of the
 *   24 axis remaps by name (att_calib_remap_parse).
 * Each sensor's model and the mounting are folded, when the settings are applied, into one stage per
 * sensor: nothing (identity), a signed permutation of the axes (a remap without a model: no
 * arithmetic, exact), or v = A (raw - o) with A = R M diag(s) (A[i][j] = M[i][j] s[j] for the model,
 * then the rows permuted and negated for a remap, exact, or multiplied by the quaternion's matrix,
 * (R[i][0] X[0][j] + R[i][1] X[1][j]) + R[i][2] X[2][j]). The filter then works in the body frame:
 * gyro_bias is body frame, and so are the sensor-frame inputs the filter documents.
 *
 * Output stage: the attitude (q, euler) with the earth frame of the convention: ENU (the filters'
 * own, default), NED (x north, y east, z down) or NWU (x north, y west, z up); the body frame is the
 * one after mounting in every convention (q_conv = c * q_enu with c the rotation conv <- ENU:
 * NED q = ((-x - y) a, (w + z) a, (w - z) a, (y - x) a), NWU q = ((w + z) a, (x + y) a, (y - x) a,
 * (z - w) a), a = 0x1.6a09e6p-1 (1/sqrt 2)). Euler angles are those of q_conv. Earth-frame vectors
 * convert exactly: NED (y, x, -z), NWU (y, -x, z) of the ENU (x, y, z).
 *
 * Stages that change nothing cost nothing in att_filter_step beyond one flag test.
 */
#ifndef ATT_CALIB_H
#define ATT_CALIB_H

#include "attica/att_config.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** Earth frame of the outputs (values are part of the CAN contract: do not renumber). */
typedef enum {
    ATT_CONV_ENU = 0, /**< x east, y north, z up (the filters' own frame; default) */
    ATT_CONV_NED = 1, /**< x north, y east, z down */
    ATT_CONV_NWU = 2  /**< x north, y west, z up */
} att_convention_t;

#define ATT_CALIB_REMAPS 24 /* axis remaps, numbered 1 .. 24 (att_calib_remap_name) */

/** Inertial sensor model v = M (s * (raw - o)) of a gyro (rad/s) or an accelerometer (m/s^2). */
typedef struct {
    float misalignment[9];  /**< M, row-major, unitless; finite, |entries| <= 1e3, |det| >= 2^-60, Frobenius
                                 condition number <= 3100 */
    att_vec3_t sensitivity; /**< s, per-axis scale, unitless; each component in (0, 1e3] */
    att_vec3_t offset;      /**< o, sensor frame, the sensor's unit; gyro: each component in [-1e3, 1e3] rad/s,
                                 accel: each component in [-1e4, 1e4] m/s^2 */
} att_calib_inertial_t;

/** Magnetometer model m = S (raw - h), uT. */
typedef struct {
    float soft_iron[9];   /**< S, row-major, unitless; finite, |entries| <= 1e3, |det| >= 2^-60, Frobenius
                               condition number <= 3100 */
    att_vec3_t hard_iron; /**< h, uT, sensor frame; each component in [-1e5, 1e5] */
} att_calib_mag_t;

/** Everything the input and output stages need (att_calib_settings_default: identity, ENU). */
typedef struct {
    att_calib_inertial_t gyro;   /**< gyro model, rad/s */
    att_calib_inertial_t accel;  /**< accel model, m/s^2 */
    att_calib_mag_t mag;         /**< magnetometer model, uT */
    uint32_t remap;              /**< mounting as an axis remap 1 .. 24 (att_calib_remap_parse); [0, 24] (0: the
                                      mounting quaternion) */
    att_quat_t mounting;         /**< body <- sensor (w, x, y, z); when remap is 0: finite, |mounting|^2 in
                                      [0.997, 1.003] */
    att_convention_t convention; /**< earth frame of the outputs: ENU (0), NED (1) or NWU (2) */
    float gravity;               /**< g for the acceleration outputs, m/s^2; [1, 100] */
    bool accel_outputs;          /**< keep each step's body-frame accel for att_filter_accel (3 stores/step) */
} att_calib_settings_t;

/** Why att_calib_settings_check refused settings (the first problem found, in this order). */
typedef enum {
    ATT_CALIB_OK = 0,
    ATT_CALIB_ERR_NULL = 1,              /**< settings pointer NULL */
    ATT_CALIB_ERR_GYRO_MATRIX = 2,       /**< gyro misalignment not finite, too large, singular or ill-conditioned */
    ATT_CALIB_ERR_GYRO_SENSITIVITY = 3,  /**< gyro sensitivity outside (0, 1e3] */
    ATT_CALIB_ERR_GYRO_OFFSET = 4,       /**< gyro offset not finite or |o_i| > 1e3 rad/s */
    ATT_CALIB_ERR_ACCEL_MATRIX = 5,      /**< accel misalignment (as for the gyro) */
    ATT_CALIB_ERR_ACCEL_SENSITIVITY = 6, /**< accel sensitivity outside (0, 1e3] */
    ATT_CALIB_ERR_ACCEL_OFFSET = 7,      /**< accel offset not finite or |o_i| > 1e4 m/s^2 */
    ATT_CALIB_ERR_MAG_MATRIX = 8,        /**< soft-iron matrix (as for the gyro) */
    ATT_CALIB_ERR_MAG_OFFSET = 9,        /**< hard-iron offset not finite or |h_i| > 1e5 uT */
    ATT_CALIB_ERR_REMAP = 10,            /**< remap not in 0 .. 24 */
    ATT_CALIB_ERR_MOUNTING = 11,         /**< mounting quaternion not finite or |q|^2 outside [0.997, 1.003] */
    ATT_CALIB_ERR_CONVENTION = 12,       /**< convention not ENU, NED or NWU */
    ATT_CALIB_ERR_GRAVITY = 13,          /**< gravity outside [1, 100] m/s^2 */
    ATT_CALIB_ERR_FLAG = 14              /**< accel_outputs holds neither 0 nor 1 */
} att_calib_error_t;

/** One sensor's folded input stage. */
typedef struct {
    uint32_t mode;      /**< 0 identity, 1 signed permutation (axis, neg), 2 affine v = a (raw - o) */
    float a[9];         /**< A = R M diag(s), row-major (affine) */
    att_vec3_t o;       /**< offset, sensor frame, the sensor's unit (affine) */
    uint32_t perm;      /**< the axis order as one of 6: xyz, xzy, yxz, yzx, zxy, zyx (from axis) */
    uint32_t axis[3];   /**< permutation: body axis i = raw axis axis[i] ... */
    uint32_t sign[3];   /**< ... with its sign bit flipped (exact negation) when sign[i] is 0x80000000 */
} att_calib_stage_t;

/** The applied stages (att_calib_init); part of att_filter_t. */
typedef struct {
    att_convention_t convention; /**< earth frame of the outputs */
    float gravity;               /**< g of the acceleration outputs, m/s^2 */
    att_calib_stage_t gyr;  /**< gyro stage */
    att_calib_stage_t acc;  /**< accel stage */
    att_calib_stage_t mag;  /**< mag stage */
    uint32_t active;        /**< ATT_CALIB_ACTIVE_* bits; 0 = att_filter_step skips every stage */
    att_vec3_t acc_body;    /**< the last step's accel after the input stage, m/s^2, body (accel_outputs) */
    bool have_acc;          /**< acc_body holds a sample */
} att_calib_t;

/** att_calib_t.active bits. */
enum {
    ATT_CALIB_ACTIVE_INPUT = 0x1u, /**< some input stage is not the identity */
    ATT_CALIB_ACTIVE_CONV = 0x2u,  /**< convention is not ENU */
    ATT_CALIB_ACTIVE_ACC = 0x4u    /**< accel_outputs */
};

/** Acceleration outputs (att_filter_accel), m/s^2. */
typedef struct {
    att_vec3_t gravity; /**< the specific force of gravity, body frame (what the accel reads at rest, +g up) */
    att_vec3_t linear;  /**< accel minus gravity, body frame */
    att_vec3_t earth;   /**< accel rotated into the earth frame of the convention, gravity removed */
    uint32_t valid;     /**< ATT_OUT_ACCEL when the fields hold values, else 0 (fields 0) */
} att_accel_t;

/** Identity models, identity mounting (quaternion (1, 0, 0, 0)), ENU, g = 9.80665, no accel outputs. */
void att_calib_settings_default(att_calib_settings_t *s);
/** The first problem of the settings (ATT_CALIB_OK when they are valid). */
att_calib_error_t att_calib_settings_check(const att_calib_settings_t *s);
/**
 * The stages' settings contract, line by line (as att_filter_settings_rule): line index of the table
 * att_calib_settings_check is written from, in its order ("calib.gyro.sensitivity", the bounds, the
 * rule in words, the unit); ATT_OK when it holds for s, ATT_ERR_SETTINGS when not; past the last line
 * out->field is NULL. ATT_ERR_NULL (field NULL) for a NULL argument.
 */
att_status_t att_calib_settings_rule(const att_calib_settings_t *s, uint32_t index, att_settings_error_t *out);
/** ATT_OK, or ATT_ERR_SETTINGS / ATT_ERR_NULL (att_calib_settings_check says why). */
att_status_t att_calib_settings_validate(const att_calib_settings_t *s);
/** Validate and fold the settings into c; on error c is unchanged. */
att_status_t att_calib_init(att_calib_t *c, const att_calib_settings_t *s);
/**
 * The input stage in place: gyr (rad/s), acc (m/s^2), mag (uT), sensor frame in, calibrated body
 * frame out. A zero mag vector (absent) is left unchanged; a NaN component stays NaN.
 */
void att_calib_apply(const att_calib_t *c, att_vec3_t *gyr, att_vec3_t *acc, att_vec3_t *mag);
/** q (sensor-to-ENU) expressed in the earth frame of convention conv (unknown conv: q). */
att_quat_t att_calib_quat_to(att_quat_t q, att_convention_t conv);
/** An earth-frame vector of ENU in the frame of convention conv (exact: a signed permutation). */
att_vec3_t att_calib_vec_to(att_vec3_t v, att_convention_t conv);
/** The axis remap number (1 .. 24) of a name like "+x-z+y" (body x = +sensor x, y = -z, z = +y); 0 if none. */
uint32_t att_calib_remap_parse(const char *name);
/** The name of remap 1 .. 24 ("+x+y+z" is 1, the identity); NULL for another number. */
const char *att_calib_remap_name(uint32_t remap);
/**
 * Field i of the settings as one float (the CAN command CAL_SET and the persisted form): 0..8 gyro
 * misalignment (row-major), 9..11 gyro sensitivity, 12..14 gyro offset, 15..29 the same for the accel,
 * 30..38 soft iron, 39..41 hard iron, 42..45 mounting quaternion w, x, y, z, 46 remap, 47 convention,
 * 48 gravity, 49 accel_outputs. Integer fields (46, 47, 49) take exact integers 0 .. 2^24. Writes
 * nothing and returns false for an unknown index or an integer field given a non-integer; the settings
 * as a whole are validated later (att_calib_settings_check).
 */
bool att_calib_field_set(att_calib_settings_t *s, uint32_t index, float value);
/** Field i of the settings (see att_calib_field_set); false for an unknown index or NULL. */
bool att_calib_field_get(const att_calib_settings_t *s, uint32_t index, float *value);
#define ATT_CALIB_FIELDS 50 /* number of att_calib_field_set indices */
/** Short text of an att_calib_error_t ("gyro matrix", ...; "?" if unknown). */
const char *att_calib_error_name(att_calib_error_t e);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_CALIB_H */
