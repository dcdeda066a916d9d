/**
 * @file att_persist.h
 * @brief Example: the CAN node's calibration kept in one flash page, with a CRC, through the node's hook.
 *
 * The node calls its persistence hook (att_node_set_persist) with the applied calibration after every
 * change a command makes (CAL_COMMIT, SET_CONVENTION, SET_REMAP). att_persist_hook writes it into one
 * flash page as an att_persist_record_t (magic, version, length, the att_calib_settings_t, CRC-32),
 * erase then program, and reads it back to verify; its result goes to the host in ATT_CAL_ACK.persisted.
 * At start-up att_persist_load reads the page: a record with the right magic, version and length, a
 * matching CRC and settings that att_calib_settings_check accepts is loaded into
 * att_node_settings_t.calib before att_node_init; anything else (an erased page, a write torn by a
 * power loss, another firmware's record, a bit flip) is ignored and the defaults
 * (att_calib_settings_default) are used. att_persist_node_init does the three steps.
 *
 *     static att_node_t node;
 *     static const att_flash_io_t flash = {&my_page, 2048u, my_erase, my_program, my_read};
 *     att_node_settings_t s;
 *     att_persist_status_t why;
 *     att_node_settings_default(ATT_FILTER_ARS, 285.714f, &s);
 *     if (att_persist_node_init(&node, &s, &flash, &why) != ATT_OK) { ... }   // why: LOADED, EMPTY, ...
 *
 * The flash is reached through att_flash_io_t (function pointers and a context), so the same code runs
 * on a microcontroller and, against a RAM-backed fake page, on the host (att_persist_test.c). For an
 * STM32G4 (2 KB pages, programmed in 64-bit double words): erase = unlock (FLASH_KEYR), FLASH_CR PER +
 * PNB = the page + STRT, wait BSY; program = PG set, two 32-bit writes per double word, wait BSY; read =
 * memcpy from the page's address. The page must be one the linker keeps out of the image.
 *
 * One page means a power loss during a save loses the previous calibration too (the defaults are used
 * at the next start, and the host sees persisted = failed or no answer): use two pages written in turn
 * with a sequence number if that matters. No heap: att_persist_save builds the record and reads it back
 * on the stack (2 x 216 bytes with the default att_calib_settings_t; the record itself is 212 bytes).
 * The layout of att_calib_settings_t is part of the record: bump ATT_PERSIST_VERSION when it changes
 * (length catches most changes by itself).
 */
#ifndef ATT_PERSIST_H
#define ATT_PERSIST_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "attica/att_calib.h"
#include "attica/att_config.h"
#include "attica/att_node.h"

#if !ATT_WITH_CALIB
#error "att_persist stores the node's calibration: it needs ATT_WITH_CALIB 1"
#endif

#ifdef __cplusplus
extern "C" {
#endif

#define ATT_PERSIST_MAGIC 0x43545441u /* "ATTC" in memory order on a little-endian MCU */
#define ATT_PERSIST_VERSION 1u        /* layout of the record and of att_calib_settings_t */
#define ATT_PERSIST_ALIGN 8u          /* flash programming unit the image is padded to (STM32G4: 64 bits) */

/** Access to one erasable flash page. Every function returns true on success. */
typedef struct {
    void *ctx;                /**< the page (address or fake) */
    uint32_t page_bytes;      /**< size of the page */
    bool (*erase)(void *ctx); /**< erase the page (bytes read 0xFF) */
    /** Program n bytes at offset (offset and n multiples of ATT_PERSIST_ALIGN, bytes erased before). */
    bool (*program)(void *ctx, uint32_t offset, const uint8_t *data, uint32_t n);
    /** Read n bytes at offset. */
    bool (*read)(void *ctx, uint32_t offset, uint8_t *data, uint32_t n);
} att_flash_io_t;

/** What the page holds, at offset 0 (CRC over every byte before crc). */
typedef struct {
    uint32_t magic;             /**< ATT_PERSIST_MAGIC */
    uint16_t version;           /**< ATT_PERSIST_VERSION */
    uint16_t length;            /**< sizeof(att_calib_settings_t) */
    att_calib_settings_t calib; /**< the applied calibration */
    uint32_t crc;               /**< att_persist_crc32 of the bytes from magic up to crc */
} att_persist_record_t;

/** Why att_persist_load used the defaults (or not). */
typedef enum {
    ATT_PERSIST_LOADED = 0,  /**< a good record: its calibration is loaded */
    ATT_PERSIST_EMPTY = 1,   /**< the page is erased (nothing saved yet) */
    ATT_PERSIST_CORRUPT = 2, /**< magic wrong or CRC mismatch: a torn write, a bit flip, other data */
    ATT_PERSIST_LAYOUT = 3,  /**< a record of another version or calibration size */
    ATT_PERSIST_INVALID = 4, /**< CRC good but att_calib_settings_check refuses the settings */
    ATT_PERSIST_IO = 5       /**< the page could not be read (or io is NULL / too small) */
} att_persist_status_t;

/** CRC-32 (IEEE 802.3: reflected polynomial 0xEDB88320, initial and final XOR 0xFFFFFFFF) of n bytes. */
uint32_t att_persist_crc32(const uint8_t *data, size_t n);

/**
 * Load the saved calibration into calib, or the defaults (att_calib_settings_default) when the page
 * holds no good record (see att_persist_status_t). calib is always valid afterwards.
 */
att_persist_status_t att_persist_load(const att_flash_io_t *io, att_calib_settings_t *calib);

/**
 * Save calib: refuse settings att_calib_settings_check refuses, erase the page, program the record
 * (padded to ATT_PERSIST_ALIGN with 0xFF), read it back and compare. false on any failure.
 */
bool att_persist_save(const att_flash_io_t *io, const att_calib_settings_t *calib);

/** The node's persistence hook (att_node_persist_fn): ctx is the const att_flash_io_t *. */
bool att_persist_hook(void *ctx, const att_calib_settings_t *calib);

/**
 * Start-up: att_persist_load into s->calib (why says what was found; may be NULL), att_node_init(n, s),
 * then att_node_set_persist(n, att_persist_hook, io). The result of att_node_init (ATT_ERR_NULL for a
 * NULL argument).
 */
att_status_t att_persist_node_init(att_node_t *n, att_node_settings_t *s, const att_flash_io_t *io,
                                   att_persist_status_t *why);

#ifdef __cplusplus
}
#endif

#endif /* ATT_PERSIST_H */
