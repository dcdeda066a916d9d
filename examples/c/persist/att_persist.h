/**
 * @file att_persist.h
 * @brief Example: the CAN node's configuration kept in two flash pages that survive a power cut.
 *
 * What is kept is what the node's commands change (att_persist_config_t): the filter kind (SELECT), the
 * running filter's settings (SET_GAIN) and, with ATT_WITH_CALIB, the calibration with the mounting and
 * the output convention (CAL_COMMIT, SET_CONVENTION, SET_REMAP). The rest of att_node_settings_t (sample
 * rate, bit rates, dividers, CAN ID offset) is the firmware's, as the caller's settings give it.
 *
 * Two slots, one flash page each, written in turn: a save erases and programs the slot that does NOT
 * hold the configuration in use, as an att_persist_record_t (magic, version, length, a sequence number
 * one above the newest, its complement, the configuration, CRC-32 last), then reads it back. A power
 * cut during a save can only damage that slot: the other one still holds the configuration before the
 * save, complete. At start-up att_persist_node_init reads both slots, takes the newest record that is
 * complete (CRC), of this layout and accepted by att_node_init (which validates every setting), and
 * says what it found (att_persist_boot_t): NEW (the newest save), OLD (the save before it: the other
 * slot holds a later save that did not complete) or NONE (no usable record: the caller's settings). A
 * record is loaded whole or not at all: the node never runs a mix of two saves, or of a save and the
 * defaults.
 *
 *     static att_node_t node;
 *     static att_persist_t store;
 *     static const att_flash_io_t flash = {NULL, 2048u, my_erase, my_program, my_read};
 *     att_node_settings_t s;
 *     att_persist_boot_t boot;
 *     att_node_settings_default(ATT_FILTER_ARS, 285.714f, &s);     // the firmware's configuration
 *     if (att_persist_node_init(&node, &s, &store, &flash, &boot) != ATT_OK) { ... }
 *     for (;;) {
 *         ...                                  // att_node_rx, att_node_poll, att_node_tx as usual
 *         (void)att_persist_poll(&store);      // a SELECT or SET_GAIN changed the configuration: saved
 *     }
 *
 * Calibration commands are saved at once, through the node's persistence hook (their answer,
 * ATT_CAL_ACK.persisted, says whether the save succeeded); SELECT and SET_GAIN do not call the hook, so
 * att_persist_poll compares the running kind and settings with the saved ones and saves a change.
 *
 * The flash is reached through att_flash_io_t (function pointers and a context), so the same code runs
 * on a microcontroller and, against RAM-backed fake pages, on the host (att_persist_test.c). For an
 * STM32G4 (2 KB pages, programmed in 64-bit double words): erase = unlock (FLASH_KEYR), FLASH_CR PER +
 * PNB = the page + STRT, wait BSY; program = PG set, two 32-bit writes per double word, wait BSY; read =
 * memcpy from the page's address. Both pages must be ones the linker keeps out of the image.
 *
 * No heap. Stack (Cortex-M4F, -Os): att_persist_node_init 856 bytes (one record image and one
 * att_node_settings_t) plus att_node_init's, att_persist_save and att_persist_poll about 460 (one image of
 * 384 bytes; the read-back is compared 32 bytes at a time). The layout of
 * the configuration is part of the record: bump ATT_PERSIST_VERSION when it changes (length catches most
 * changes by itself, e.g. another set of kinds compiled in). Records of an earlier version (1: the
 * calibration alone, one page; 2: the filter settings before mars/mekf declination and ekf recovery_time;
 * 3: before ars's and mars's covariance settings)
 * are not read (ATT_PERSIST_SLOT_LAYOUT): after the update the node starts from the caller's settings, so
 * a calibration saved by older firmware is to be sent again.
 */
#ifndef ATT_PERSIST_H
#define ATT_PERSIST_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "attica/att_calib.h"
#include "attica/att_config.h"
#include "attica/att_filter.h"
#include "attica/att_node.h"

#ifdef __cplusplus
extern "C" {
#endif

#define ATT_PERSIST_MAGIC 0x43545441u /* "ATTC" in memory order on a little-endian MCU */
#define ATT_PERSIST_VERSION 6u        /* layout of the record and of att_persist_config_t (3: the filter
                                         settings grew, mars/mekf declination and ekf recovery_time; 4: ars's
                                         and mars's covariance model; 5: mekf's learnt reference field; 6:
                                         mars's and mekf's hard-iron estimate) */
#define ATT_PERSIST_ALIGN 8u          /* flash programming unit the image is padded to (STM32G4: 64 bits) */
#define ATT_PERSIST_SLOTS 2u          /* flash pages, written in turn */
#define ATT_PERSIST_NO_SLOT 0xFFu     /* att_persist_boot_t.slot when nothing was loaded */

/** Access to two erasable flash pages (page 0 and 1: the slots). Every function returns true on success. */
typedef struct {
    void *ctx;                               /**< the pages (addresses or fakes) */
    uint32_t page_bytes;                     /**< size of one page */
    bool (*erase)(void *ctx, uint32_t page); /**< erase a page (its bytes read 0xFF) */
    /** Program n bytes at offset of a page (offset and n multiples of ATT_PERSIST_ALIGN, bytes erased). */
    bool (*program)(void *ctx, uint32_t page, uint32_t offset, const uint8_t *data, uint32_t n);
    /** Read n bytes at offset of a page. */
    bool (*read)(void *ctx, uint32_t page, uint32_t offset, uint8_t *data, uint32_t n);
} att_flash_io_t;

/** The node configuration a slot holds: what the node's commands change. */
typedef struct {
    att_filter_kind_t kind;       /**< the filter running (SELECT) */
    att_filter_settings_t filter; /**< its settings, the member named after kind (SET_GAIN) */
#if ATT_WITH_CALIB
    att_calib_settings_t calib;   /**< calibration, mounting, convention (CAL_*, SET_CONVENTION, SET_REMAP) */
#endif
} att_persist_config_t;

/** What a slot holds, at offset 0 of its page (CRC over every byte before crc). */
typedef struct {
    uint32_t magic;              /**< ATT_PERSIST_MAGIC */
    uint16_t version;            /**< ATT_PERSIST_VERSION */
    uint16_t length;             /**< sizeof(att_persist_config_t) */
    uint32_t sequence;           /**< saves so far, this one included: 1, 2, ... (0 is skipped when it wraps) */
    uint32_t sequence_check;     /**< ~sequence: a torn or damaged header is seen without the CRC */
    att_persist_config_t config; /**< the configuration */
    uint32_t crc;                /**< att_persist_crc32 of the bytes from magic up to crc */
} att_persist_record_t;

/** What a slot held at start-up. */
typedef enum {
    ATT_PERSIST_SLOT_EMPTY = 0,   /**< erased: nothing written (or a save cut right after its erase) */
    ATT_PERSIST_SLOT_VALID = 1,   /**< a complete record of this layout (loaded, or older than the one loaded) */
    ATT_PERSIST_SLOT_CORRUPT = 2, /**< magic or CRC wrong: a save cut short, a bit flip, other data */
    ATT_PERSIST_SLOT_LAYOUT = 3,  /**< a complete header of another version or configuration size */
    ATT_PERSIST_SLOT_REFUSED = 4, /**< complete, but att_node_init refuses the configuration */
    ATT_PERSIST_SLOT_IO = 5       /**< the page could not be read */
} att_persist_slot_t;

/** Which configuration the node started with. */
typedef enum {
    ATT_PERSIST_NONE = 0, /**< no usable record: the caller's settings */
    ATT_PERSIST_NEW = 1,  /**< the newest save (the other slot holds an older one, or nothing yet) */
    ATT_PERSIST_OLD = 2   /**< the save before the newest: the other slot holds a later save that did not
                               complete (a power cut during it; also a record damaged in its header) */
} att_persist_source_t;

/** What att_persist_node_init found. */
typedef struct {
    att_persist_source_t source;   /**< NONE, NEW or OLD */
    uint8_t slot;                  /**< the slot loaded, 0 or 1 (ATT_PERSIST_NO_SLOT: none) */
    uint32_t sequence;             /**< the sequence number of the record loaded (0: none) */
    att_persist_slot_t slots[ATT_PERSIST_SLOTS]; /**< what each slot held */
} att_persist_boot_t;

/** The store: the flash, the node, and the configuration in the newest complete slot. */
typedef struct {
    const att_flash_io_t *io;   /**< the two pages */
    att_node_t *node;           /**< the node whose configuration is kept */
    att_persist_config_t saved; /**< the configuration saved last (valid when have_saved) */
    bool have_saved;            /**< a slot holds the configuration in use (saved, or loaded at start-up) */
    uint8_t slot;               /**< the slot holding it (ATT_PERSIST_NO_SLOT: none) */
    uint32_t sequence;          /**< its sequence number (0: none) */
    uint32_t next_sequence;     /**< the sequence number of the next save */
    uint32_t saves;             /**< saves completed since start-up */
    uint32_t failures;          /**< saves that failed since start-up */
} att_persist_t;

/** Result of att_persist_poll. */
typedef enum {
    ATT_PERSIST_UNCHANGED = 0, /**< the configuration is the one saved: nothing written */
    ATT_PERSIST_SAVED = 1,     /**< it changed and was saved */
    ATT_PERSIST_FAILED = 2     /**< it changed and the save failed (tried again at the next call) */
} att_persist_result_t;

/** CRC-32 (IEEE 802.3: reflected polynomial 0xEDB88320, initial and final XOR 0xFFFFFFFF) of n bytes. */
uint32_t att_persist_crc32(const uint8_t *data, size_t n);

/** The configuration the node runs now (kind, settings, calibration; bytes not set are zero). */
void att_persist_config_of(const att_node_t *n, att_persist_config_t *c);

/**
 * Start-up: read both slots; initialise n (att_node_init) with the caller's settings s, the kind, filter
 * settings and calibration replaced by those of the newest complete record that att_node_init accepts
 * (if none, with s as given); register att_persist_hook. On ATT_OK, s holds the settings the node runs
 * with and boot (may be NULL) says what was loaded. Otherwise the status of att_node_init(n, s)
 * (ATT_ERR_NULL for a NULL argument); n is then untouched.
 */
att_status_t att_persist_node_init(att_node_t *n, att_node_settings_t *s, att_persist_t *p, const att_flash_io_t *io,
                                   att_persist_boot_t *boot);

/**
 * Save the node's configuration now, into the slot not holding the one in use: erase, program the
 * record (padded to ATT_PERSIST_ALIGN with 0xFF), read it back and compare. false on any failure (the
 * other slot still holds the configuration saved before).
 */
bool att_persist_save(att_persist_t *p);

/** Save the node's configuration if it differs from the one saved (call it after att_node_poll). */
att_persist_result_t att_persist_poll(att_persist_t *p);

#if ATT_WITH_CALIB
/**
 * The node's persistence hook (att_node_persist_fn; att_persist_node_init registers it): ctx is the
 * att_persist_t *. Saves the node's configuration with calib; true when it is saved (or already was).
 */
bool att_persist_hook(void *ctx, const att_calib_settings_t *calib);
#endif

/** Short names: "none", "new", "old"; "empty", "valid", "corrupt", "layout", "refused", "io" ("?" else). */
const char *att_persist_source_name(att_persist_source_t s);
const char *att_persist_slot_name(att_persist_slot_t s);

#ifdef __cplusplus
}
#endif

#endif /* ATT_PERSIST_H */
