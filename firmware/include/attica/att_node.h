/**
 * @file att_node.h
 * @brief The attica CAN node: frames in, filter steps, frames out. Pure (no time source, no I/O).
 *
 * @code
 * static att_node_t node;                // its rings are large by default: static, never on the stack
 * att_node_settings_t s;
 * att_can_frame_t f;
 * att_node_settings_default(ATT_FILTER_ARS, 100.0f, &s);   // kind, sample RATE in Hz (not a period)
 * if (att_node_init(&node, &s) != ATT_OK) { ... }   // ATT_ERR_SETTINGS also for bus load > 100 %
 * for (;;) {
 *     while (can_receive(&f)) { (void)att_node_rx(&node, &f); }   // e.g. from the rx interrupt
 *     (void)att_node_poll(&node);                                   // assemble, step, queue outputs
 *     while (can_tx_free() && att_node_tx(&node, &f)) { can_send(&f); }
 * }
 * @endcode
 *
 * With the IMU on the node's own board, each sample goes in with att_node_push_sample(&node, &sample)
 * instead of frames (same checks, counters and outputs as an IMU_FD frame). The node's size is set at
 * build time (att_config.h: kinds, stages, ATT_NODE_RX_RING / ATT_NODE_TX_RING, ATT_NODE_WITH_FD);
 * its CAN IDs at init (id_offset: every ID + offset; att_node_rx_ids lists the ones it receives, for
 * the controller's acceptance filter; `attica dbc --id-offset N` writes the matching DBC). The E2E
 * data ID of a message stays 0x0A00 + its DBC ID whatever the offset.
 *
 * Input: IMU_GYRO + IMU_ACC + IMU_MAG with one counter (any order) or one IMU_FD form a sample. A
 * complete sample steps the filter over the sample periods since the last sample stepped, as the E2E
 * counters tell them: att_filter_step_n with n = (counter - last sample's counter) mod 16, so 1 for the
 * next sample and k + 1 after k lost samples (whole or discarded partial ones: a lost sample is
 * integrated, held from the next one, not ignored); 1 for the first sample and for a distance of 0 (a
 * re-sent sample after a stale partial). The counters are 4 bits: after 15 lost whole samples the
 * next one has the last counter and is dropped as a duplicate, and a run of 15 or more lost samples is
 * integrated short by a multiple of 16 periods. Both input formats are accepted in either output mode
 * (IMU_FD only in builds with ATT_NODE_WITH_FD: otherwise it is an unknown ID). Every frame is checked
 * in this order: known ID (else unknown_ids), length and classic/FD format (dlc_errors), E2E CRC
 * (crc_errors); then the sample assembly:
 * - a classic IMU frame whose counter differs from the sample being assembled discards that partial
 *   sample (stale_partials) and starts a new one;
 * - a frame of a part already present, or of the sample just completed, is dropped (duplicates);
 * - a new sample whose counter is not the previous sample's + 1 (mod 16) is accepted and counted once
 *   in counter_gaps (one or more whole samples were lost); it steps over the periods since the last
 *   sample stepped (above).
 * Rejected frames never touch the filter.
 *
 * Output, every output_divider-th filter step: classic QUAT_A, QUAT_B, QUAT16, EULER, BIAS, STATUS, or
 * one ATT_OUT_FD when settings.fd; then ATT_DIAG (classic) after every diag_divider-th set, followed by
 * ATT_DIAG_BUS when a port reports its CAN controller's counters (att_node_set_bus_diag) and by
 * ATT_MAG_OFFSET while the filter estimates a hard-iron offset (mars, mekf: hard_iron_tau > 0;
 * att_filter_mag_offset). A sample
 * stepped over n periods queues at most one set, after its last step, when its steps reach or pass a
 * multiple of output_divider (the filter's step count: from init, a reset or a select); the set's flags
 * are the OR over the n steps, its steps field the filter's step count. The counter of a set is the set
 * index mod 16 (= sample index mod 16 when output_divider is 1 and no sample was lost), so a receiver
 * sees consecutive counters. att_node_poll only takes a frame from the rx ring while the tx ring has
 * room for a whole set plus a command answer (ATT_NODE_SET_MAX frames): the node never drops outputs;
 * if the application does not drain tx, the rx ring fills and further frames are counted in
 * rx_overflows.
 *
 * Commands (CMD): 1 select filter (arg = kind: a fresh filter; the init settings when it is the init
 * kind, else att_filter_settings_default(kind, 1 / sample_rate)), 2 reset (att_filter_reset), 3 set
 * gain (arg = ATT_CAN_GAIN_*, value): validated like att_filter_init; the filter keeps its state
 * (attitude, bias, covariance...) and only its settings and the gains derived from them change. Every
 * command with a good CRC is answered by an ATT_STATUS with ack = ATT_CAN_ACK_ANSWER | result << 4 |
 * cmd and the command's counter; a bad CRC is counted (crc_errors) and not answered.
 *
 * Calibration commands (answered by ATT_CAL_ACK instead): 4 CAL_BEGIN opens a session with a shadow
 * copy (arg 0: of the applied calibration, 1: identity), 5 CAL_SET writes field arg of the shadow
 * (att_calib_field_set; bad argument without a session or for an unknown field / non-integer value),
 * 6 CAL_COMMIT validates the whole shadow (refused with the att_calib_error_t reason, nothing applied,
 * the session stays open to be corrected) and applies it atomically to the running filter (its state
 * is kept), closes the session and calls the persistence hook; 7 CAL_ABORT drops the shadow; 8
 * SET_CONVENTION (arg) and 9 SET_REMAP (arg 0 .. 24) change one thing of the applied calibration
 * atomically. Selecting another filter keeps the calibration. The shadow never touches the filter.
 */
#ifndef ATT_NODE_H
#define ATT_NODE_H

#include "attica/att_config.h"
#include "attica/att_can.h"
#include "attica/att_filter.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/* The ring sizes ATT_NODE_RX_RING and ATT_NODE_TX_RING and ATT_NODE_WITH_FD are options of att_config.h. */
/* Most frames one rx frame can queue: a set with everything that follows it, or (a command) 1 answer. */
#if ATT_NODE_WITH_MAG_OFFSET
#if ATT_WITH_CALIB
#define ATT_NODE_SET_MAX 11 /* 6 (set) + 2 (accel) + 1 (DIAG) + 1 (DIAG_BUS) + 1 (MAG_OFFSET) */
#else
#define ATT_NODE_SET_MAX 9 /* 6 (set) + 1 (DIAG) + 1 (DIAG_BUS) + 1 (MAG_OFFSET) */
#endif
#else
#if ATT_WITH_CALIB
#define ATT_NODE_SET_MAX 10 /* 6 (set) + 2 (accel) + 1 (DIAG) + 1 (DIAG_BUS) */
#else
#define ATT_NODE_SET_MAX 8 /* 6 (set) + 1 (DIAG) + 1 (DIAG_BUS) */
#endif
#endif
#if ATT_NODE_WITH_FD
#define ATT_NODE_FRAME_LEN 64 /* data bytes a ring entry holds */
#else
#define ATT_NODE_FRAME_LEN 8 /* data bytes a ring entry holds (classic frames only) */
#endif
#define ATT_NODE_RX_IDS_MAX 5     /* most CAN IDs a node receives (att_node_rx_ids) */
#define ATT_NODE_ID_OFFSET_MIN -256 /* att_node_settings_t.id_offset: the lowest ID (0x100) moves to 0 */
#define ATT_NODE_ID_OFFSET_MAX 1279 /* ... the highest (0x300) to 0x7FF */

/**
 * A frame as the node's rings store it (rx: as received; tx: at the DBC's ID, id_offset is added by
 * att_node_tx): att_can_frame_t itself, or with ATT_NODE_WITH_FD 0 the same fields with 8 data bytes
 * (a longer frame keeps its len and is refused by it).
 */
#if ATT_NODE_WITH_FD
typedef att_can_frame_t att_node_frame_t;
#else
typedef struct {
    uint32_t id;                      /**< 11-bit identifier */
    uint8_t len;                      /**< data length in bytes as received */
    uint8_t fd;                       /**< 1 = CAN FD frame */
    uint8_t data[ATT_NODE_FRAME_LEN]; /**< the first 8 data bytes */
} att_node_frame_t;
#endif

/**
 * Port hook that persists the node's calibration (flash on a microcontroller, a file on Linux): called
 * after every calibration change applied by a command, with the applied settings; returns true when
 * saved. Register with att_node_set_persist; load the saved settings into att_node_settings_t.calib
 * before att_node_init at start-up.
 */
typedef bool (*att_node_persist_fn)(void *ctx, const att_calib_settings_t *calib);

/**
 * Port hook that reports the CAN controller's counters (state, bus-off episodes and recoveries,
 * error-passive and error-warning entries, receive FIFO overruns, last error code) into d, which the
 * node has zeroed: called each time the node queues an ATT_DIAG, which it then follows with an
 * ATT_DIAG_BUS carrying d (same counter). The Cortex-M ports register theirs in their init
 * (att_can_hal_init, att_fdcan_hal_init): the node knows nothing of the port.
 */
typedef void (*att_node_bus_diag_fn)(void *ctx, att_can_bus_diag_t *d);

/** Node settings. */
typedef struct {
    att_filter_kind_t kind;       /**< filter to run */
    att_filter_settings_t filter; /**< its settings (the member named after kind) */
    float sample_rate;            /**< a rate, Hz, (0, 100000]; the filter's dt (s) must be 1/sample_rate within 1e-3 relative */
    uint32_t bitrate;             /**< nominal bit/s (e.g. 500000); [1000, 1000000] */
    uint32_t data_bitrate;        /**< CAN FD data phase, bit/s: 0 (classic only) or [bitrate, 16000000] */
    bool fd;                      /**< IMU_FD in / ATT_OUT_FD out instead of classic sets; true needs data_bitrate > 0 */
    uint32_t output_divider;      /**< emit outputs every Nth step (1 = every step); [1, 65535] */
    uint32_t diag_divider;        /**< ATT_DIAG after every Nth emitted set; any (0: never) */
#if ATT_WITH_CALIB
    att_calib_settings_t calib;   /**< calibration, mounting, convention (att_calib_settings_default) */
#endif
    bool accel_out;               /**< ATT_LIN_ACC + ATT_EARTH_ACC (classic) or ATT_ACCEL_FD after each set */
    int32_t id_offset;            /**< added to every attica CAN ID, in and out (0: the DBC's IDs); [-256, 1279] (every ID stays 11-bit) */
} att_node_settings_t;

/** Node counters (uint32, wrap; ATT_DIAG/ATT_STATUS carry them saturated to 8 bits). */
typedef struct {
    uint32_t rx_frames;      /**< frames accepted into the rx ring */
    uint32_t crc_errors;     /**< E2E CRC mismatch (inputs and commands) */
    uint32_t counter_gaps;   /**< new sample not following the previous one (whole samples lost; integrated) */
    uint32_t dlc_errors;     /**< wrong length or classic/FD format for the ID */
    uint32_t unknown_ids;    /**< IDs the node does not receive (incl. its own output IDs) */
    uint32_t duplicates;     /**< repeated part of a sample or of the sample just completed */
    uint32_t stale_partials; /**< partial samples discarded because a newer counter arrived */
    uint32_t rx_overflows;   /**< frames refused by att_node_rx (ring full) */
    uint32_t tx_overflows;   /**< frames dropped because the tx ring was full (should stay 0) */
    uint32_t samples;        /**< complete samples stepped (assembled from frames, or att_node_push_sample) */
    uint32_t steps;          /**< filter steps run, one per sample period: samples + the periods of lost samples
                                  integrated (>= samples; == samples when no sample was lost) */
    uint32_t sets;           /**< output sets queued */
    uint32_t tx_frames;      /**< frames handed out by att_node_tx */
    uint32_t commands;       /**< commands executed (good CRC) */
} att_node_stats_t;

/** The node: settings, filter, sample assembly, rings, counters (no heap; size: see att_config.h). */
typedef struct {
    att_node_settings_t s;                     /**< validated copy of the init settings */
    att_filter_kind_t kind;                    /**< filter kind now running */
    att_filter_settings_t fs;                  /**< settings of the running filter */
    att_filter_t f;                            /**< the filter */
    att_output_t out;                          /**< output of the last sample (flags ORed over its periods) */
    att_sample_t part;                         /**< sample being assembled */
    uint8_t part_mask;                         /**< parts present: 1 gyro, 2 acc, 4 mag; 0 = none */
    uint8_t part_counter;                      /**< counter of the sample being assembled (part_mask != 0) */
    uint8_t last_counter;                      /**< counter of the last sample stepped from frames */
    bool have_last;                            /**< last_counter is valid (a sample was stepped from frames) */
    uint32_t div_count;                        /**< filter steps since the last output_divider multiple (0 at init, reset, select) */
    uint32_t div_flags;                        /**< ATT_FLAG_* ORed over the steps since the last set (0 at init, reset, select) */
    uint32_t rx_head;                          /**< rx ring write count */
    uint32_t rx_tail;                          /**< rx ring read count */
    uint32_t tx_head;                          /**< tx ring write count */
    uint32_t tx_tail;                          /**< tx ring read count */
    att_node_frame_t rx[ATT_NODE_RX_RING];     /**< receive ring */
    att_node_frame_t tx[ATT_NODE_TX_RING];     /**< transmit ring */
    att_node_stats_t stats;                    /**< counters */
#if ATT_WITH_CALIB
    att_calib_settings_t cal;                  /**< the applied calibration (as given, before accel_out) */
    att_calib_settings_t shadow;               /**< the calibration session's copy (CAL_BEGIN .. COMMIT) */
    bool shadow_open;                          /**< a session is open */
    uint8_t shadow_count;                      /**< CAL_SET commands in the session (saturates at 255) */
#endif
    att_node_persist_fn persist;               /**< port hook (NULL: none) */
    void *persist_ctx;                         /**< its context */
    att_node_bus_diag_fn bus_diag;             /**< port hook of ATT_DIAG_BUS (NULL: none, no ATT_DIAG_BUS) */
    void *bus_diag_ctx;                        /**< its context */
} att_node_t;

/**
 * Defaults for a node of this kind receiving sample_rate samples per second. sample_rate is a RATE in
 * Hz (100.0f for 100 Hz), not a period, unlike att_filter_settings_default(kind, dt, ...), which takes
 * the period dt in s (0.01f) and which this calls with dt = 1 / sample_rate. Then 500 kbit/s classic,
 * a set every step, DIAG every 16th set, the identity calibration, no acceleration frames, offset 0.
 * ATT_ERR_SETTINGS for a rate that is not finite and > 0; ATT_ERR_NULL, ATT_ERR_KIND, ATT_ERR_DISABLED
 * as att_filter_settings_default. A period passed here by mistake (0.01f) is a rate of 0.01 Hz, a
 * filter dt of 100 s: att_node_init refuses it for every kind with a period (their dt is at most 1 s;
 * att_node_settings_check names "<kind>.dt").
 */
att_status_t att_node_settings_default(att_filter_kind_t kind, float sample_rate, att_node_settings_t *s);
/**
 * Which setting makes att_node_init refuse: the status att_node_init would return for s, and for
 * ATT_ERR_SETTINGS in why (may be NULL) the first refused field: a node field ("bitrate",
 * "id_offset", "fd" ...), the filter's ("ars.tau_acc_lp": att_filter_settings_check), the stages'
 * ("calib.gyro.sensitivity": att_calib_settings_rule), "filter.dt" (not 1 / sample_rate) or "bus load"
 * (outputs over 100 %), with its bounds, rule and unit; why->field is NULL otherwise. Not called by
 * att_node_init: an image that does not call it carries none of its text.
 */
att_status_t att_node_settings_check(const att_node_settings_t *s, att_settings_error_t *why);
/**
 * The node's own settings contract, line by line (as att_filter_settings_rule): line index of the table
 * att_node_init and att_node_settings_check are written from ("sample_rate", "bitrate" ...; the filter's
 * and the stages' are listed by att_filter_settings_rule and att_calib_settings_rule, the two rules
 * between them, filter.dt and bus load, are stated above); ATT_OK when it holds for s, ATT_ERR_SETTINGS
 * when not; past the last line out->field is NULL. ATT_ERR_NULL (field NULL) for a NULL argument.
 */
att_status_t att_node_settings_rule(const att_node_settings_t *s, uint32_t index, att_settings_error_t *out);
/**
 * Validate the settings (incl. the filter's, and bus load <= 100 %) and initialise the node (empty
 * rings, zero counters). ATT_ERR_NULL / ATT_ERR_SETTINGS / ATT_ERR_KIND / ATT_ERR_DISABLED leave n
 * untouched; att_node_settings_check says which setting was refused.
 */
att_status_t att_node_init(att_node_t *n, const att_node_settings_t *s);
/**
 * Fraction of the bus time taken by the node's periodic outputs (1.0 = 100 %), worst-case stuffing;
 * see docs/can.md (ATT_MAG_OFFSET counted when the init filter estimates a hard-iron offset). -1 for
 * NULL or settings that cannot be evaluated (rates, bitrates, dividers).
 */
float att_node_bus_load(const att_node_settings_t *s);
/** Worst-case bits of a classic frame with len data bytes and an 11-bit ID (incl. 3 bits intermission). */
uint32_t att_node_classic_bits(uint32_t len);
/** Worst-case bit time of a CAN FD frame (11-bit ID, bit rate switch) in s; -1 for a bad bitrate. */
float att_node_fd_frame_time(uint32_t len, uint32_t bitrate, uint32_t data_bitrate);
/** Push a received frame (false: NULL, or the rx ring is full: counted in rx_overflows). */
bool att_node_rx(att_node_t *n, const att_can_frame_t *f);
/**
 * Give the node a sample from an IMU on its own board (no CAN frame): it is stepped at once, with the
 * same filter checks, counters (samples, steps, sets) and output frames as a sample that arrived as an
 * IMU_FD frame with the next counter, bit for bit (gyro rad/s, accel m/s^2, mag uT, sensor frame; NaN or
 * zero mag = absent). It has no counter: always one sample period (the counters of frames are not touched).
 * Frames still waiting in the rx ring are processed first (att_node_poll), so the order of arrival
 * holds. False: NULL, or the tx ring has no room for a whole output set (the application has not
 * drained att_node_tx): the sample is not used and is counted in rx_overflows.
 */
bool att_node_push_sample(att_node_t *n, const att_sample_t *in);
/**
 * The standard CAN IDs the node receives (IMU_GYRO, IMU_ACC, IMU_MAG, IMU_FD when the build has CAN
 * FD, CMD; each + id_offset), for a port's acceptance filter. Returns how many (0 for NULL).
 */
size_t att_node_rx_ids(const att_node_t *n, uint32_t ids[ATT_NODE_RX_IDS_MAX]);
/** Process queued rx frames: check, assemble, step, answer, queue tx. Returns the filter steps run
 * (sample periods: more than the samples when lost samples were integrated). */
size_t att_node_poll(att_node_t *n);
/** Register (or with NULL remove) the persistence hook of the calibration. */
void att_node_set_persist(att_node_t *n, att_node_persist_fn fn, void *ctx);
/**
 * Register (or with fn NULL remove) the hook of the CAN controller's counters: with one, every ATT_DIAG
 * is followed by an ATT_DIAG_BUS (one more classic frame every diag_divider-th set; none with
 * diag_divider 0). att_node_init removes it. ATT_OK; ATT_ERR_NULL (n NULL); ATT_ERR_SETTINGS, and
 * nothing registered, when the periodic outputs with that frame would need more than the whole bus
 * (att_node_bus_load counts without it).
 */
att_status_t att_node_set_bus_diag(att_node_t *n, att_node_bus_diag_fn fn, void *ctx);
/** Pop the next frame to send (false: none). */
bool att_node_tx(att_node_t *n, att_can_frame_t *f);
/** Frames waiting in the tx ring. */
size_t att_node_tx_pending(const att_node_t *n);
/** The receive error counters as carried by ATT_DIAG. */
void att_node_diag(const att_node_t *n, att_can_diag_t *d);
/** Saturating (255) total of receive errors, as in ATT_STATUS.error_count. */
uint8_t att_node_error_count(const att_node_t *n);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_NODE_H */
