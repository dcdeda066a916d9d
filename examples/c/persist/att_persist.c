/**
 * @file att_persist.c
 * @brief Example: the CAN node's configuration in two alternating flash slots (see att_persist.h).
 */
#include "att_persist.h"

#include <string.h>

/* The record as bytes, padded to the flash programming unit. */
#define ATT_PERSIST_IMAGE_BYTES \
    (((sizeof(att_persist_record_t) + ATT_PERSIST_ALIGN - 1u) / ATT_PERSIST_ALIGN) * ATT_PERSIST_ALIGN)
#define ATT_PERSIST_CHUNK 32u /* bytes compared per read when a save is read back */

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

/* a is a later sequence number than b (serial number arithmetic: they wrap). */
static bool att_seq_newer(uint32_t a, uint32_t b)
{
    return a != b && (uint32_t)(a - b) < 0x80000000u;
}

/* The sequence number after a (0 is skipped: an erased header cannot pass for one). */
static uint32_t att_seq_next(uint32_t a)
{
    return (a == 0xffffffffu) ? 1u : a + 1u;
}

void att_persist_config_of(const att_node_t *n, att_persist_config_t *c)
{
    if (n == NULL || c == NULL) {
        return;
    }
    memset(c, 0, sizeof *c);
    c->kind = n->kind;
    memcpy(&c->filter, &n->fs, sizeof c->filter);
#if ATT_WITH_CALIB
    memcpy(&c->calib, &n->cal, sizeof c->calib);
#endif
}

/*
 * Read slot into img and say what it holds. *seq is the record's sequence number and *known whether it
 * can be trusted: a complete header (magic, this layout, sequence_check == ~sequence) even when the CRC
 * fails (a save cut after its header).
 */
static att_persist_slot_t att_slot_read(const att_flash_io_t *io, uint32_t slot, att_persist_image_t *img,
                                        uint32_t *seq, bool *known)
{
    size_t i;
    bool erased = true;
    bool header;
    *seq = 0u;
    *known = false;
    if (!att_io_ok(io) || !io->read(io->ctx, slot, 0u, img->bytes, (uint32_t)sizeof img->bytes)) {
        return ATT_PERSIST_SLOT_IO;
    }
    for (i = 0u; i < sizeof img->bytes; i++) {
        erased = erased && img->bytes[i] == 0xffu;
    }
    if (erased) {
        return ATT_PERSIST_SLOT_EMPTY;
    }
    if (img->rec.magic != ATT_PERSIST_MAGIC) {
        return ATT_PERSIST_SLOT_CORRUPT;
    }
    header = img->rec.sequence_check == ~img->rec.sequence && img->rec.sequence != 0u;
    if (header) {
        *seq = img->rec.sequence;
        *known = true;
    }
    /* the layout before the CRC: its place depends on the layout */
    if (img->rec.version != (uint16_t)ATT_PERSIST_VERSION ||
        img->rec.length != (uint16_t)sizeof(att_persist_config_t)) {
        return header ? ATT_PERSIST_SLOT_LAYOUT : ATT_PERSIST_SLOT_CORRUPT;
    }
    if (!header || img->rec.crc != att_record_crc(img)) {
        return ATT_PERSIST_SLOT_CORRUPT;
    }
    return ATT_PERSIST_SLOT_VALID;
}

/* The node's settings s with the kind, filter settings and calibration of a record. */
static void att_settings_with(att_node_settings_t *t, const att_node_settings_t *s, const att_persist_config_t *c)
{
    *t = *s;
    t->kind = c->kind;
    memcpy(&t->filter, &c->filter, sizeof t->filter);
#if ATT_WITH_CALIB
    memcpy(&t->calib, &c->calib, sizeof t->calib);
#endif
}

att_status_t att_persist_node_init(att_node_t *n, att_node_settings_t *s, att_persist_t *p, const att_flash_io_t *io,
                                   att_persist_boot_t *boot)
{
    att_persist_image_t img;
    att_node_settings_t t;
    att_persist_boot_t b;
    uint32_t seq[ATT_PERSIST_SLOTS];
    bool known[ATT_PERSIST_SLOTS];
    bool tried[ATT_PERSIST_SLOTS] = {false, false};
    uint32_t top = 0u; /* the latest sequence number of a complete record (loaded or refused) */
    uint32_t i;
    uint32_t round;
    if (n == NULL || s == NULL || p == NULL) {
        return ATT_ERR_NULL;
    }
    memset(&b, 0, sizeof b);
    b.source = ATT_PERSIST_NONE;
    b.slot = (uint8_t)ATT_PERSIST_NO_SLOT;
    for (i = 0u; i < ATT_PERSIST_SLOTS; i++) {
        b.slots[i] = att_slot_read(io, i, &img, &seq[i], &known[i]);
        if (b.slots[i] == ATT_PERSIST_SLOT_VALID && (top == 0u || att_seq_newer(seq[i], top))) {
            top = seq[i];
        }
    }
    /* the newest complete record att_node_init accepts; the other one if it refuses */
    for (round = 0u; round < ATT_PERSIST_SLOTS && b.slot == (uint8_t)ATT_PERSIST_NO_SLOT; round++) {
        uint32_t pick = ATT_PERSIST_NO_SLOT;
        for (i = 0u; i < ATT_PERSIST_SLOTS; i++) {
            if (b.slots[i] == ATT_PERSIST_SLOT_VALID && !tried[i] &&
                (pick == ATT_PERSIST_NO_SLOT || att_seq_newer(seq[i], seq[pick]))) {
                pick = i;
            }
        }
        if (pick == ATT_PERSIST_NO_SLOT) {
            break;
        }
        tried[pick] = true;
        b.slots[pick] = att_slot_read(io, pick, &img, &seq[pick], &known[pick]); /* again: one image on the stack */
        if (b.slots[pick] != ATT_PERSIST_SLOT_VALID) {
            continue;
        }
        att_settings_with(&t, s, &img.rec.config);
        if (att_node_init(n, &t) == ATT_OK) {
            b.slot = (uint8_t)pick;
            b.sequence = seq[pick];
        } else {
            b.slots[pick] = ATT_PERSIST_SLOT_REFUSED;
        }
    }
    if (b.slot == (uint8_t)ATT_PERSIST_NO_SLOT) {
        const att_status_t r = att_node_init(n, s);
        if (r != ATT_OK) {
            return r;
        }
    } else {
        /* NEW unless the other slot shows a later save that did not complete: a damaged record whose
           header says it is later, or whose header is unreadable, or an erased slot after the first save
           (from the second save on, both slots hold a record except while one is being written) */
        const uint32_t other = 1u - (uint32_t)b.slot;
        const att_persist_slot_t o = b.slots[other];
        bool cut;
        if (o == ATT_PERSIST_SLOT_VALID) {
            cut = false;
        } else if (o == ATT_PERSIST_SLOT_EMPTY) {
            cut = b.sequence != 1u;
        } else {
            cut = !known[other] || att_seq_newer(seq[other], b.sequence);
        }
        b.source = cut ? ATT_PERSIST_OLD : ATT_PERSIST_NEW;
        *s = t;
    }
    for (i = 0u; i < ATT_PERSIST_SLOTS; i++) {
        if (b.slots[i] == ATT_PERSIST_SLOT_REFUSED && att_seq_newer(seq[i], top)) {
            top = seq[i];
        }
    }
    p->io = io;
    p->node = n;
    att_persist_config_of(n, &p->saved); /* the configuration running: nothing to save until it changes */
    p->have_saved = b.slot != (uint8_t)ATT_PERSIST_NO_SLOT;
    p->slot = b.slot;
    p->sequence = b.sequence;
    p->next_sequence = att_seq_next(top);
    p->saves = 0u;
    p->failures = 0u;
#if ATT_WITH_CALIB
    att_node_set_persist(n, att_persist_hook, p);
#endif
    if (boot != NULL) {
        *boot = b;
    }
    return ATT_OK;
}

/* The record of the node's configuration (its sequence number and CRC set by att_write). */
static void att_image_of(const att_persist_t *p, att_persist_image_t *img)
{
    memset(img->bytes, 0xff, sizeof img->bytes); /* the padding after the record stays erased */
    memset(&img->rec, 0, sizeof img->rec);       /* defined bytes in the struct's own padding */
    img->rec.magic = ATT_PERSIST_MAGIC;
    img->rec.version = (uint16_t)ATT_PERSIST_VERSION;
    img->rec.length = (uint16_t)sizeof(att_persist_config_t);
    att_persist_config_of(p->node, &img->rec.config);
}

/* Read the slot back and compare it with img, ATT_PERSIST_CHUNK bytes at a time. */
static bool att_verify(const att_flash_io_t *io, uint32_t slot, const att_persist_image_t *img)
{
    uint8_t back[ATT_PERSIST_CHUNK];
    uint32_t off;
    for (off = 0u; off < (uint32_t)sizeof img->bytes; off += ATT_PERSIST_CHUNK) {
        uint32_t n = (uint32_t)sizeof img->bytes - off;
        if (n > ATT_PERSIST_CHUNK) {
            n = ATT_PERSIST_CHUNK;
        }
        if (!io->read(io->ctx, slot, off, back, n) || memcmp(back, img->bytes + off, n) != 0) {
            return false;
        }
    }
    return true;
}

/* Write img into the slot not holding the configuration in use; on success it is the one in use. */
static bool att_write(att_persist_t *p, att_persist_image_t *img)
{
    const att_flash_io_t *io = p->io;
    const uint32_t slot = (p->slot == 0u) ? 1u : 0u;
    img->rec.sequence = p->next_sequence;
    img->rec.sequence_check = ~p->next_sequence;
    img->rec.crc = att_record_crc(img);
    if (!io->erase(io->ctx, slot) || !io->program(io->ctx, slot, 0u, img->bytes, (uint32_t)sizeof img->bytes) ||
        !att_verify(io, slot, img)) {
        p->failures++;
        return false; /* the other slot still holds the configuration in use */
    }
    memcpy(&p->saved, &img->rec.config, sizeof p->saved);
    p->have_saved = true;
    p->slot = (uint8_t)slot;
    p->sequence = p->next_sequence;
    p->next_sequence = att_seq_next(p->next_sequence);
    p->saves++;
    return true;
}

/*
 * The configuration c is the one saved, byte for byte. Bytes, not fields: the padding of the settings
 * structs is compared too (it holds whatever the node's copies left there), so a change in padding alone
 * costs one save more, never a missed one.
 */
static bool att_same_as_saved(const att_persist_t *p, const att_persist_config_t *c)
{
    return memcmp((const uint8_t *)c, (const uint8_t *)&p->saved, sizeof p->saved) == 0;
}

static bool att_store_ok(const att_persist_t *p)
{
    return p != NULL && p->node != NULL && att_io_ok(p->io);
}

bool att_persist_save(att_persist_t *p)
{
    att_persist_image_t img;
    if (!att_store_ok(p)) {
        return false;
    }
    att_image_of(p, &img);
    return att_write(p, &img);
}

att_persist_result_t att_persist_poll(att_persist_t *p)
{
    att_persist_image_t img;
    if (!att_store_ok(p)) {
        return ATT_PERSIST_FAILED;
    }
    att_image_of(p, &img);
    if (att_same_as_saved(p, &img.rec.config)) {
        return ATT_PERSIST_UNCHANGED;
    }
    return att_write(p, &img) ? ATT_PERSIST_SAVED : ATT_PERSIST_FAILED;
}

#if ATT_WITH_CALIB
bool att_persist_hook(void *ctx, const att_calib_settings_t *calib)
{
    att_persist_t *p = (att_persist_t *)ctx;
    att_persist_image_t img;
    if (!att_store_ok(p) || calib == NULL) {
        return false;
    }
    att_image_of(p, &img);
    memcpy(&img.rec.config.calib, calib, sizeof img.rec.config.calib);
    if (att_same_as_saved(p, &img.rec.config)) {
        return true; /* already what the flash holds (or what the node started with) */
    }
    return att_write(p, &img);
}
#endif

const char *att_persist_source_name(att_persist_source_t s)
{
    switch (s) {
    case ATT_PERSIST_NONE: return "none";
    case ATT_PERSIST_NEW: return "new";
    case ATT_PERSIST_OLD: return "old";
    default: return "?";
    }
}

const char *att_persist_slot_name(att_persist_slot_t s)
{
    switch (s) {
    case ATT_PERSIST_SLOT_EMPTY: return "empty";
    case ATT_PERSIST_SLOT_VALID: return "valid";
    case ATT_PERSIST_SLOT_CORRUPT: return "corrupt";
    case ATT_PERSIST_SLOT_LAYOUT: return "layout";
    case ATT_PERSIST_SLOT_REFUSED: return "refused";
    case ATT_PERSIST_SLOT_IO: return "io";
    default: return "?";
    }
}
