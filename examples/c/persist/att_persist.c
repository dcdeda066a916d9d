/**
 * @file att_persist.c
 * @brief Example: the CAN node's calibration in one flash page with a CRC (see att_persist.h).
 */
#include "att_persist.h"

#include <string.h>

/* The record as bytes, padded to the flash programming unit. */
#define ATT_PERSIST_IMAGE_BYTES \
    (((sizeof(att_persist_record_t) + ATT_PERSIST_ALIGN - 1u) / ATT_PERSIST_ALIGN) * ATT_PERSIST_ALIGN)

typedef union {
    att_persist_record_t rec;
    uint8_t bytes[ATT_PERSIST_IMAGE_BYTES];
} att_persist_image_t;

uint32_t att_persist_crc32(const uint8_t *data, size_t n)
{
    uint32_t c = 0xffffffffu;
    size_t i;
    uint32_t k;
    if (data == NULL) {
        return 0u;
    }
    for (i = 0u; i < n; i++) {
        c ^= data[i];
        for (k = 0u; k < 8u; k++) {
            c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
        }
    }
    return ~c;
}

static uint32_t att_record_crc(const att_persist_image_t *img)
{
    return att_persist_crc32(img->bytes, offsetof(att_persist_record_t, crc));
}

static bool att_io_ok(const att_flash_io_t *io)
{
    return io != NULL && io->erase != NULL && io->program != NULL && io->read != NULL &&
           io->page_bytes >= ATT_PERSIST_IMAGE_BYTES;
}

att_persist_status_t att_persist_load(const att_flash_io_t *io, att_calib_settings_t *calib)
{
    att_persist_image_t img;
    size_t i;
    bool erased = true;
    if (calib == NULL) {
        return ATT_PERSIST_IO;
    }
    att_calib_settings_default(calib);
    if (!att_io_ok(io) || !io->read(io->ctx, 0u, img.bytes, (uint32_t)sizeof img.bytes)) {
        return ATT_PERSIST_IO;
    }
    for (i = 0u; i < sizeof img.bytes; i++) {
        erased = erased && img.bytes[i] == 0xffu;
    }
    if (erased) {
        return ATT_PERSIST_EMPTY;
    }
    if (img.rec.magic != ATT_PERSIST_MAGIC) {
        return ATT_PERSIST_CORRUPT;
    }
    /* the header first: the CRC's place depends on the layout */
    if (img.rec.version != ATT_PERSIST_VERSION || img.rec.length != (uint16_t)sizeof(att_calib_settings_t)) {
        return ATT_PERSIST_LAYOUT;
    }
    if (img.rec.crc != att_record_crc(&img)) {
        return ATT_PERSIST_CORRUPT;
    }
    if (att_calib_settings_check(&img.rec.calib) != ATT_CALIB_OK) {
        return ATT_PERSIST_INVALID;
    }
    *calib = img.rec.calib;
    return ATT_PERSIST_LOADED;
}

bool att_persist_save(const att_flash_io_t *io, const att_calib_settings_t *calib)
{
    att_persist_image_t img;
    att_persist_image_t back;
    if (!att_io_ok(io) || calib == NULL || att_calib_settings_check(calib) != ATT_CALIB_OK) {
        return false;
    }
    memset(img.bytes, 0xff, sizeof img.bytes); /* the padding after the record stays erased */
    memset(&img.rec, 0, sizeof img.rec);       /* defined bytes in the struct's own padding */
    img.rec.magic = ATT_PERSIST_MAGIC;
    img.rec.version = (uint16_t)ATT_PERSIST_VERSION;
    img.rec.length = (uint16_t)sizeof(att_calib_settings_t);
    memcpy(&img.rec.calib, calib, sizeof img.rec.calib);
    img.rec.crc = att_record_crc(&img);
    if (!io->erase(io->ctx) || !io->program(io->ctx, 0u, img.bytes, (uint32_t)sizeof img.bytes) ||
        !io->read(io->ctx, 0u, back.bytes, (uint32_t)sizeof back.bytes)) {
        return false;
    }
    return memcmp(img.bytes, back.bytes, sizeof img.bytes) == 0;
}

bool att_persist_hook(void *ctx, const att_calib_settings_t *calib)
{
    return att_persist_save((const att_flash_io_t *)ctx, calib);
}

att_status_t att_persist_node_init(att_node_t *n, att_node_settings_t *s, const att_flash_io_t *io,
                                   att_persist_status_t *why)
{
    att_persist_status_t st;
    att_status_t r;
    if (n == NULL || s == NULL || io == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_persist_load(io, &s->calib);
    if (why != NULL) {
        *why = st;
    }
    r = att_node_init(n, s);
    if (r == ATT_OK) {
        /* the hook's context is the caller's io (att_node_persist_fn takes a non-const context) */
        att_node_set_persist(n, att_persist_hook, (void *)(uintptr_t)io);
    }
    return r;
}
