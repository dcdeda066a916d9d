/**
 * @file att_persist_test.c
 * @brief The two-slot flash persistence example on the host, against RAM-backed fake flash pages.
 *
 * The fake pages behave like NOR flash: erase sets every byte of a page to 0xFF, programming needs
 * erased bytes and whole 8-byte units. A power cut can be set before a save: before the erase, during
 * the erase (the first j bytes of the page erased), or during the programming after any number k of
 * bytes (k = 0: erased but nothing written; k = the whole image: written, not yet read back); from then
 * on every flash operation fails until the next "reboot". A real attica node runs with the store:
 * commands over CAN frames (SET_CONVENTION, SET_REMAP, a calibration session, SET_GAIN, SELECT) change
 * its configuration, and the hook or att_persist_poll saves it; a reboot re-initialises the node from the
 * pages. Every reboot must give the configuration before the save or the one after it, whole (never a
 * mix, never the defaults once something was saved), and report which by its sequence number and source.
 *
 * Prints "ok ..." / "FAIL ..." per check; exit status = number of failures.
 */
#include <stdio.h>
#include <string.h>

#include "att_persist.h"
#include "attica/att_can.h"
#include "attica/att_node.h"

#define PAGE_BYTES 2048u
#define IMAGE_BYTES \
    ((uint32_t)(((sizeof(att_persist_record_t) + ATT_PERSIST_ALIGN - 1u) / ATT_PERSIST_ALIGN) * ATT_PERSIST_ALIGN))
#define RECORD_BYTES ((uint32_t)sizeof(att_persist_record_t))

typedef enum { CUT_NONE, CUT_BEFORE_ERASE, CUT_IN_ERASE, CUT_IN_PROGRAM } cut_t;

typedef struct {
    uint8_t mem[ATT_PERSIST_SLOTS][PAGE_BYTES];
    uint32_t erases;
    uint32_t programs;
    uint32_t misuse;   /* programming bytes that are not erased, or not in 8-byte units */
    cut_t cut;         /* the power cut armed for the next save */
    uint32_t cut_at;   /* bytes erased (CUT_IN_ERASE) or programmed (CUT_IN_PROGRAM) before it */
    uint32_t written;  /* bytes programmed since the cut was armed */
    int dead;          /* the power is gone: every operation fails until reboot() */
    int fail_reads;    /* reads fail (a broken flash) */
} flash_t;

static int failures;

static void check(int ok, const char *what)
{
    printf("%s %s\n", ok ? "ok" : "FAIL", what);
    if (!ok) {
        failures++;
    }
}

static bool fake_erase(void *ctx, uint32_t page)
{
    flash_t *f = (flash_t *)ctx;
    if (f->dead || page >= ATT_PERSIST_SLOTS) {
        return false;
    }
    if (f->cut == CUT_BEFORE_ERASE) {
        f->dead = 1;
        return false;
    }
    if (f->cut == CUT_IN_ERASE) {
        memset(f->mem[page], 0xff, f->cut_at < PAGE_BYTES ? f->cut_at : PAGE_BYTES);
        f->dead = 1;
        return false;
    }
    memset(f->mem[page], 0xff, PAGE_BYTES);
    f->erases++;
    return true;
}

static bool fake_program(void *ctx, uint32_t page, uint32_t offset, const uint8_t *data, uint32_t n)
{
    flash_t *f = (flash_t *)ctx;
    uint32_t i;
    if (f->dead || page >= ATT_PERSIST_SLOTS) {
        return false;
    }
    f->programs++;
    if ((offset % 8u) != 0u || (n % 8u) != 0u || offset + n > PAGE_BYTES) {
        f->misuse++;
        return false;
    }
    for (i = 0u; i < n; i++) {
        if (f->cut == CUT_IN_PROGRAM && f->written == f->cut_at) {
            f->dead = 1;
            return false; /* the power failed here */
        }
        if (f->mem[page][offset + i] != 0xffu) {
            f->misuse++;
            return false;
        }
        f->mem[page][offset + i] = data[i];
        f->written++;
    }
    if (f->cut == CUT_IN_PROGRAM && f->written == f->cut_at) {
        f->dead = 1; /* every byte written, the power fails before the read-back */
        return false;
    }
    return true;
}

static bool fake_read(void *ctx, uint32_t page, uint32_t offset, uint8_t *data, uint32_t n)
{
    const flash_t *f = (const flash_t *)ctx;
    if (f->dead || f->fail_reads || page >= ATT_PERSIST_SLOTS || offset + n > PAGE_BYTES) {
        return false;
    }
    memcpy(data, f->mem[page] + offset, n);
    return true;
}

static flash_t flash;
static const att_flash_io_t io = {&flash, PAGE_BYTES, fake_erase, fake_program, fake_read};
static att_node_t node;
static att_persist_t store;
static att_persist_boot_t boot;

static uint32_t bits(float x)
{
    uint32_t w;
    memcpy(&w, &x, sizeof w);
    return w;
}

/* Every calibration field (att_calib_field_get) bit-equal. */
static int same_calib(const att_calib_settings_t *a, const att_calib_settings_t *b)
{
    uint32_t i;
    for (i = 0u; i < ATT_CALIB_FIELDS; i++) {
        float x = 0.0f;
        float y = 1.0f;
        if (!att_calib_field_get(a, i, &x) || !att_calib_field_get(b, i, &y) || bits(x) != bits(y)) {
            return 0;
        }
    }
    return 1;
}

/* The whole configuration: kind, every byte of the filter settings, every calibration field. */
static int same_config(const att_persist_config_t *a, const att_persist_config_t *b)
{
    return a->kind == b->kind && memcmp(&a->filter, &b->filter, sizeof a->filter) == 0 &&
           same_calib(&a->calib, &b->calib);
}

static void running(att_persist_config_t *c)
{
    att_persist_config_of(&node, c);
}

static void firmware_settings(att_node_settings_t *s)
{
    memset(s, 0, sizeof *s);
    (void)att_node_settings_default(ATT_FILTER_ARS, 100.0f, s);
}

/* The configuration the firmware starts with when nothing is saved. */
static void defaults(att_persist_config_t *c)
{
    att_node_settings_t s;
    firmware_settings(&s);
    memset(c, 0, sizeof *c);
    c->kind = s.kind;
    memcpy(&c->filter, &s.filter, sizeof c->filter);
    c->calib = s.calib;
}

/* A power-on: the power is back, the node is initialised from the pages. */
static att_status_t reboot(void)
{
    att_node_settings_t s;
    flash.dead = 0;
    flash.cut = CUT_NONE;
    firmware_settings(&s);
    memset(&boot, 0xA5, sizeof boot);
    return att_persist_node_init(&node, &s, &store, &io, &boot);
}

static void arm(cut_t cut, uint32_t at)
{
    flash.cut = cut;
    flash.cut_at = at;
    flash.written = 0u;
    flash.dead = 0;
}

/* One command frame through the node; the answer's persisted field (ATT_CAL_ACK) or result (ATT_STATUS). */
static uint8_t command(uint8_t cmd, uint8_t arg, float value)
{
    static uint8_t counter;
    att_can_cmd_t c;
    att_can_frame_t f;
    uint8_t answer = 0xffu;
    memset(&c, 0, sizeof c);
    c.counter = (uint8_t)(counter++ & 15u);
    c.cmd = cmd;
    c.arg = arg;
    c.value = value;
    att_can_encode_cmd(&c, &f);
    (void)att_node_rx(&node, &f);
    (void)att_node_poll(&node);
    while (att_node_tx(&node, &f)) {
        if (f.id == (uint32_t)ATT_CAN_ID_CAL_ACK) {
            att_can_cal_ack_t ack;
            if (att_can_decode_cal_ack(&f, &ack)) {
                answer = ack.result == ATT_CAN_ACK_OK ? ack.persisted : 0xfeu;
            }
        } else if (f.id == (uint32_t)ATT_CAN_ID_STATUS) {
            answer = 0u; /* an ATT_STATUS answer (its effect is checked through the configuration) */
        }
    }
    return answer;
}

static void test_crc(void)
{
    static const uint8_t msg[9] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
    check(att_persist_crc32(msg, sizeof msg) == 0xcbf43926u, "CRC-32 of \"123456789\" is 0xCBF43926 (IEEE 802.3)");
}

static void test_first_start(void)
{
    att_persist_config_t c;
    att_persist_config_t d;
    char what[200];
    memset(&flash, 0xff, sizeof flash.mem);
    flash.misuse = 0u;
    check(reboot() == ATT_OK && boot.source == ATT_PERSIST_NONE && boot.slot == ATT_PERSIST_NO_SLOT &&
              boot.sequence == 0u && boot.slots[0] == ATT_PERSIST_SLOT_EMPTY && boot.slots[1] == ATT_PERSIST_SLOT_EMPTY,
          "erased pages: source none, both slots empty");
    running(&c);
    defaults(&d);
    check(same_config(&c, &d) && node.persist == att_persist_hook,
          "the node starts with the firmware's configuration; the persistence hook is registered");
    check(att_persist_poll(&store) == ATT_PERSIST_UNCHANGED && flash.erases == 0u,
          "nothing changed: att_persist_poll writes nothing (the defaults are not saved)");
    snprintf(what, sizeof what, "a record of %u bytes (image %u) fits a page of %u bytes", RECORD_BYTES, IMAGE_BYTES,
             PAGE_BYTES);
    check(IMAGE_BYTES <= PAGE_BYTES && offsetof(att_persist_record_t, crc) + 4u == RECORD_BYTES, what);
}

/* --- the changes of the configuration a command makes, and how each is saved --------------------- */

typedef struct {
    const char *what;
    int by_hook; /* saved by the node's hook (calibration commands), else by att_persist_poll */
} change_t;

static const change_t changes[] = {
    {"SET_CONVENTION NED (hook)", 1},
    {"SET_GAIN tau_acc 2.5 s (poll)", 0},
    {"a calibration session: gyro offset, hard iron, CAL_COMMIT (hook)", 1},
    {"SELECT mars (poll)", 0},
    {"SET_REMAP 7 (hook)", 1},
    {"SET_GAIN tau_mag 12 s on mars (poll)", 0},
};
#define N_CHANGES (sizeof changes / sizeof changes[0])

/* Make change i on the running node and let it be saved; true when the save succeeded. */
static bool apply(size_t i)
{
    switch (i) {
    case 0: return command(ATT_CAN_CMD_SET_CONVENTION, (uint8_t)ATT_CONV_NED, 0.0f) == ATT_CAN_PERSIST_OK;
    case 1:
        (void)command(ATT_CAN_CMD_SET_GAIN, ATT_CAN_GAIN_TAU_ACC, 2.5f);
        return att_persist_poll(&store) == ATT_PERSIST_SAVED;
    case 2:
        (void)command(ATT_CAN_CMD_CAL_BEGIN, 0u, 0.0f);
        (void)command(ATT_CAN_CMD_CAL_SET, 12u, 0.0125f); /* gyro offset x, rad/s */
        (void)command(ATT_CAN_CMD_CAL_SET, 40u, -3.5f);   /* hard iron y, uT */
        return command(ATT_CAN_CMD_CAL_COMMIT, 0u, 0.0f) == ATT_CAN_PERSIST_OK;
    case 3:
        (void)command(ATT_CAN_CMD_SELECT, (uint8_t)ATT_FILTER_MARS, 0.0f);
        return att_persist_poll(&store) == ATT_PERSIST_SAVED;
    case 4: return command(ATT_CAN_CMD_SET_REMAP, 7u, 0.0f) == ATT_CAN_PERSIST_OK;
    default:
        (void)command(ATT_CAN_CMD_SET_GAIN, ATT_CAN_GAIN_TAU_MAG, 12.0f);
        return att_persist_poll(&store) == ATT_PERSIST_SAVED;
    }
}

static void test_changes_persist(void)
{
    size_t i;
    int all = 1;
    int alternate = 1;
    for (i = 0u; i < N_CHANGES; i++) {
        att_persist_config_t before;
        att_persist_config_t after;
        att_persist_config_t loaded;
        uint32_t seq;
        running(&before);
        all = all && reboot() == ATT_OK; /* from the pages, as after a power-on */
        seq = boot.sequence;
        all = all && apply(i);
        running(&after);
        all = all && !same_config(&before, &after) && store.sequence == seq + 1u;
        alternate = alternate && store.slot == (uint8_t)(i % 2u);
        all = all && reboot() == ATT_OK && boot.source == ATT_PERSIST_NEW && boot.sequence == seq + 1u;
        running(&loaded);
        all = all && same_config(&loaded, &after);
        if (!all) {
            printf("  change %u (%s) failed\n", (unsigned)i, changes[i].what);
            break;
        }
    }
    check(all, "each change (SET_CONVENTION, SET_GAIN, a calibration session, SELECT, SET_REMAP) is saved, by the "
               "hook or att_persist_poll; a reboot gives exactly that configuration, source new, the next sequence");
    check(alternate && flash.misuse == 0u, "the saves alternate between slot 0 and slot 1; flash used by the rules");
    check(node.kind == ATT_FILTER_MARS && node.cal.remap == 7u && node.cal.convention == ATT_CONV_NED &&
              bits(node.cal.gyro.offset.x) == bits(0.0125f) && bits(node.fs.mars.tau_mag) == bits(12.0f),
          "the last reboot runs mars with tau_mag 12 s, remap 7, NED and the gyro offset of the session");
    check(att_persist_poll(&store) == ATT_PERSIST_UNCHANGED &&
              command(ATT_CAN_CMD_SET_CONVENTION, (uint8_t)ATT_CONV_NED, 0.0f) == ATT_CAN_PERSIST_OK &&
              store.saves == 0u,
          "a command that changes nothing writes nothing (and its answer says persisted)");
}

/* --- power cuts at every byte -------------------------------------------------------------------- */

typedef struct {
    uint32_t cases;
    uint32_t old_loaded;
    uint32_t new_loaded;
    uint32_t mixed;       /* neither the old nor the new configuration (or the defaults after a save) */
    uint32_t wrong_seq;   /* the reported sequence does not name the configuration loaded */
    uint32_t wrong_source;
    uint32_t wrong_side;  /* old after a complete write, new after an incomplete one */
    uint32_t ack_lies;    /* the save reported success though the power was cut */
    uint32_t complete;    /* cuts after the record was whole on the page (only its read-back was cut) */
    uint32_t not_again;   /* the same change saved again after the reboot is not loaded */
} tally_t;

/* The page holds a whole record of sequence number seq: its header and CRC check (written to the end). */
static bool whole_record(const uint8_t *page, uint32_t seq)
{
    att_persist_record_t r;
    memcpy(&r, page, sizeof r);
    return r.magic == ATT_PERSIST_MAGIC && r.version == (uint16_t)ATT_PERSIST_VERSION &&
           r.length == (uint16_t)sizeof(att_persist_config_t) && r.sequence == seq && r.sequence_check == ~seq &&
           r.crc == att_persist_crc32(page, offsetof(att_persist_record_t, crc));
}

/*
 * From the pages in `pages` (the state before the save, the node's configuration `old` with sequence
 * old_seq, 0 = none saved), change i is made and saved with the power cut as armed; then a reboot.
 */
static void one_cut(const uint8_t pages[ATT_PERSIST_SLOTS][PAGE_BYTES], size_t i, uint32_t old_seq, cut_t cut,
                    uint32_t at, tally_t *t)
{
    att_persist_config_t old;
    att_persist_config_t new_cfg;
    att_persist_config_t got;
    uint8_t target_before[PAGE_BYTES];
    uint32_t target;
    bool saved;
    bool complete;
    bool new_side;
    att_persist_source_t want;
    memcpy(flash.mem, pages, sizeof flash.mem);
    (void)reboot();
    target = (store.slot == 0u) ? 1u : 0u;
    memcpy(target_before, flash.mem[target], PAGE_BYTES);
    running(&old);
    arm(cut, at);
    saved = apply(i);
    running(&new_cfg);
    complete = whole_record(flash.mem[target], old_seq == 0u ? 1u : old_seq + 1u);
    t->cases++;
    t->complete += (uint32_t)complete;
    t->ack_lies += (uint32_t)saved;
    if (reboot() != ATT_OK) {
        t->mixed++;
        return;
    }
    running(&got);
    new_side = same_config(&got, &new_cfg);
    if (new_side) {
        t->new_loaded++;
        t->wrong_seq += (uint32_t)(boot.sequence != old_seq + 1u || boot.slot != target);
    } else if (same_config(&got, &old)) {
        t->old_loaded++;
        t->wrong_seq += (uint32_t)(boot.sequence != old_seq);
    } else {
        t->mixed++;
        return;
    }
    t->wrong_side += (uint32_t)(new_side != complete);
    /* what the boot can tell: new when the save completed, or when the flash holds no trace of it (the
       target page as it was, or erased while the old record is the first save); old otherwise */
    if (old_seq == 0u) {
        want = new_side ? ATT_PERSIST_NEW : ATT_PERSIST_NONE;
    } else if (new_side || memcmp(target_before, flash.mem[target], PAGE_BYTES) == 0) {
        want = ATT_PERSIST_NEW;
    } else {
        uint32_t k;
        bool blank = true;
        for (k = 0u; k < PAGE_BYTES; k++) {
            blank = blank && flash.mem[target][k] == 0xffu;
        }
        want = (blank && old_seq == 1u) ? ATT_PERSIST_NEW : ATT_PERSIST_OLD;
    }
    t->wrong_source += (uint32_t)(boot.source != want);
    if (!new_side) { /* the power is back: the same change again is saved and loaded */
        att_persist_config_t again;
        bool ok = apply(i) && reboot() == ATT_OK && boot.source == ATT_PERSIST_NEW && boot.sequence == old_seq + 1u;
        running(&again);
        t->not_again += (uint32_t)!(ok && same_config(&again, &new_cfg));
    }
}

static void test_power_cuts(void)
{
    static uint8_t pages[ATT_PERSIST_SLOTS][PAGE_BYTES];
    static uint8_t after[ATT_PERSIST_SLOTS][PAGE_BYTES];
    static const uint32_t erase_cuts[] = {1u, 4u, 12u, 16u, 17u, 100u, 200u, 371u, 376u, 1000u, 2047u};
    tally_t t;
    size_t i;
    uint32_t k;
    uint32_t e;
    uint32_t complete_pages = 0u;
    uint32_t expect_complete = 0u;
    char what[480];
    memset(&t, 0, sizeof t);
    memset(flash.mem, 0xff, sizeof flash.mem);
    flash.misuse = 0u;
    (void)reboot();
    for (i = 0u; i < N_CHANGES; i++) {
        const uint8_t(*before)[PAGE_BYTES] = (const uint8_t(*)[PAGE_BYTES])pages;
        uint32_t old_seq;
        uint32_t target;
        memcpy(pages, flash.mem, sizeof pages);
        /* the same save without a cut: the pages it leaves are the next generation's */
        (void)reboot();
        old_seq = boot.sequence;
        target = (store.slot == 0u) ? 1u : 0u;
        (void)apply(i);
        memcpy(after, flash.mem, sizeof after);
        complete_pages += (uint32_t)whole_record(after[target], old_seq + 1u);
        /* a cut after k bytes leaves a whole record when the bytes from k on already read as erased flash
           (0xFF): every k after the last byte of the record that is not 0xFF (a CRC ending in 0xFF, say) */
        k = RECORD_BYTES;
        while (k > 0u && after[target][k - 1u] == 0xffu) {
            k--;
        }
        expect_complete += IMAGE_BYTES - k + 1u;
        one_cut(before, i, old_seq, CUT_BEFORE_ERASE, 0u, &t);
        for (e = 0u; e < sizeof erase_cuts / sizeof erase_cuts[0]; e++) {
            one_cut(before, i, old_seq, CUT_IN_ERASE, erase_cuts[e], &t);
        }
        for (k = 0u; k <= IMAGE_BYTES; k++) {
            one_cut(before, i, old_seq, CUT_IN_PROGRAM, k, &t);
        }
        memcpy(flash.mem, after, sizeof flash.mem);
    }
    snprintf(what, sizeof what,
             "a power cut at every byte of %u saves (before the erase, %u points within the erase, after each of "
             "k = 0 .. %u programmed bytes; k = 0 is erased but not written): %u reboots, %u with the old "
             "configuration, %u with the new one (exactly those cut after the last byte of the record that is not "
             "erased flash: %u; k >= %u for a record not ending in 0xFF), none with a mix",
             (unsigned)N_CHANGES, (unsigned)(sizeof erase_cuts / sizeof erase_cuts[0]), IMAGE_BYTES, t.cases,
             t.old_loaded, t.new_loaded, (unsigned)expect_complete, RECORD_BYTES);
    check(t.mixed == 0u && t.wrong_side == 0u && t.old_loaded + t.new_loaded == t.cases &&
              t.new_loaded == t.complete && t.complete == expect_complete &&
              expect_complete >= (uint32_t)N_CHANGES * (IMAGE_BYTES - RECORD_BYTES + 1u) &&
              complete_pages == (uint32_t)N_CHANGES,
          what);
    if (t.mixed != 0u || t.wrong_side != 0u || t.new_loaded != t.complete) {
        printf("  mixed %u, loaded on the wrong side %u, new %u, whole records %u\n", t.mixed, t.wrong_side,
               t.new_loaded, t.complete);
    }
    check(t.wrong_seq == 0u && t.wrong_source == 0u,
          "each reboot reports which: the sequence number and slot of the record loaded, source new (complete, "
          "or no trace of the cut save on the flash), old (a cut save in the other slot) or none");
    check(t.ack_lies == 0u, "a save cut by the power is never reported as saved (ATT_CAL_ACK.persisted, poll)");
    check(t.not_again == 0u, "after each cut the power comes back: the same change is saved and loaded");
    check(flash.misuse == 0u, "never programs a byte that is not erased, always whole 8-byte units");
}

/* --- bit flips in a stored slot ------------------------------------------------------------------ */

static void test_bit_flips(void)
{
    static uint8_t good[ATT_PERSIST_SLOTS][PAGE_BYTES];
    att_persist_config_t newest;
    att_persist_config_t older;
    att_persist_config_t got;
    uint32_t newest_slot;
    uint32_t seq;
    uint32_t s;
    uint32_t bit;
    uint32_t counts[2][3];
    uint32_t bad = 0u;
    char what[300];
    memset(counts, 0, sizeof counts);
    (void)reboot(); /* the pages of test_power_cuts: both slots hold a record */
    memcpy(good, flash.mem, sizeof good);
    running(&newest);
    newest_slot = store.slot;
    seq = boot.sequence;
    {
        /* the older record: the other slot's configuration, loaded alone */
        memset(flash.mem[newest_slot], 0xff, PAGE_BYTES);
        (void)reboot();
        running(&older);
        bad += (uint32_t)(boot.sequence != seq - 1u || same_config(&older, &newest));
    }
    for (s = 0u; s < ATT_PERSIST_SLOTS; s++) {
        const bool in_newest = s == newest_slot;
        for (bit = 0u; bit < IMAGE_BYTES * 8u; bit++) {
            const uint32_t byte = bit / 8u;
            const bool covered = byte < RECORD_BYTES; /* the image's padding after the record is not read */
            const bool header = byte < 4u || (byte >= 8u && byte < 16u); /* magic, sequence, its check */
            bool want_new;
            att_persist_source_t want;
            memcpy(flash.mem, good, sizeof good);
            flash.mem[s][byte] ^= (uint8_t)(1u << (bit % 8u));
            if (reboot() != ATT_OK) {
                bad++;
                continue;
            }
            running(&got);
            want_new = !(in_newest && covered);
            /* the boot cannot tell a damaged header of the older record from a cut save: it says old */
            want = (want_new && !(covered && header && !in_newest)) ? ATT_PERSIST_NEW : ATT_PERSIST_OLD;
            if (want_new) {
                bad += (uint32_t)(!same_config(&got, &newest) || boot.sequence != seq || boot.source != want);
            } else {
                bad += (uint32_t)(!same_config(&got, &older) || boot.sequence != seq - 1u || boot.source != want);
            }
            counts[in_newest ? 0 : 1][want_new ? (want == ATT_PERSIST_NEW ? 0 : 1) : 2]++;
        }
    }
    memcpy(flash.mem, good, sizeof good);
    snprintf(what, sizeof what,
             "every bit of both slots flipped (%u bits each): in the newest record the older configuration is "
             "loaded (%u, source old), in its padding the newest (%u); in the older record the newest is loaded "
             "(%u source new, %u source old: its magic or sequence damaged); never a mix",
             IMAGE_BYTES * 8u, counts[0][2], counts[0][0], counts[1][0], counts[1][1]);
    check(bad == 0u, what);
}

/* --- records written by hand --------------------------------------------------------------------- */

/* A record with a correct CRC (another firmware's, or settings this node refuses) into slot. */
static void put_record(uint32_t slot, const att_persist_record_t *rec)
{
    att_persist_record_t r = *rec;
    r.crc = att_persist_crc32((const uint8_t *)&r, offsetof(att_persist_record_t, crc));
    memset(flash.mem[slot], 0xff, PAGE_BYTES);
    memcpy(flash.mem[slot], &r, sizeof r);
}

static void record_of_defaults(att_persist_record_t *rec, uint32_t seq)
{
    memset(rec, 0, sizeof *rec);
    rec->magic = ATT_PERSIST_MAGIC;
    rec->version = (uint16_t)ATT_PERSIST_VERSION;
    rec->length = (uint16_t)sizeof(att_persist_config_t);
    rec->sequence = seq;
    rec->sequence_check = ~seq;
    defaults(&rec->config);
}

static void test_other_records(void)
{
    att_persist_record_t rec;
    att_persist_record_t older;
    att_persist_config_t c;
    memset(flash.mem, 0xff, sizeof flash.mem);
    record_of_defaults(&older, 4u);
    older.config.calib.convention = ATT_CONV_NWU;
    put_record(0u, &older);
    record_of_defaults(&rec, 5u);
    rec.config.calib.convention = ATT_CONV_NED;
    rec.version = (uint16_t)(ATT_PERSIST_VERSION + 1u);
    put_record(1u, &rec);
    check(reboot() == ATT_OK && boot.slots[1] == ATT_PERSIST_SLOT_LAYOUT && boot.slot == 0u && boot.sequence == 4u &&
              boot.source == ATT_PERSIST_OLD && node.cal.convention == ATT_CONV_NWU,
          "a later record of another version: layout, not loaded; the older record is (source old)");
    rec.version = (uint16_t)ATT_PERSIST_VERSION;
    rec.config.filter.ars.dt = 0.02f; /* the firmware samples at 100 Hz: att_node_init refuses dt 0.02 s */
    put_record(1u, &rec);
    check(reboot() == ATT_OK && boot.slots[1] == ATT_PERSIST_SLOT_REFUSED && boot.slot == 0u &&
              boot.source == ATT_PERSIST_OLD && node.cal.convention == ATT_CONV_NWU && store.next_sequence == 6u,
          "a later complete record att_node_init refuses (its dt is not 1 / sample_rate): refused; the older one "
          "is loaded, and the next save is numbered after the refused one");
    check(att_persist_save(&store) && store.slot == 1u && store.sequence == 6u && reboot() == ATT_OK &&
              boot.sequence == 6u && boot.source == ATT_PERSIST_NEW && boot.slots[0] == ATT_PERSIST_SLOT_VALID,
          "the next save replaces the refused record, not the one in use");
    older.config.calib.gravity = 0.0f; /* att_calib_settings_check refuses it */
    put_record(0u, &older);
    put_record(1u, &rec);
    {
        att_persist_config_t d;
        defaults(&d);
        check(reboot() == ATT_OK && boot.source == ATT_PERSIST_NONE && boot.slots[0] == ATT_PERSIST_SLOT_REFUSED &&
                  boot.slots[1] == ATT_PERSIST_SLOT_REFUSED && (running(&c), same_config(&c, &d)),
              "both records refused by att_node_init: source none, the firmware's configuration");
    }
    record_of_defaults(&rec, 0xffffffffu);
    rec.config.calib.convention = ATT_CONV_NED;
    put_record(0u, &rec);
    record_of_defaults(&older, 0xfffffffeu);
    put_record(1u, &older);
    check(reboot() == ATT_OK && boot.sequence == 0xffffffffu && boot.slot == 0u && boot.source == ATT_PERSIST_NEW &&
              store.next_sequence == 1u,
          "sequence 0xFFFFFFFF is newer than 0xFFFFFFFE; the next is 1 (0 is skipped)");
    check(command(ATT_CAN_CMD_SET_CONVENTION, (uint8_t)ATT_CONV_ENU, 0.0f) == ATT_CAN_PERSIST_OK && reboot() == ATT_OK &&
              boot.sequence == 1u && boot.slot == 1u && boot.source == ATT_PERSIST_NEW &&
              node.cal.convention == ATT_CONV_ENU,
          "across the wrap: sequence 1 is newer than 0xFFFFFFFF");
    rec.magic = 0x12345678u;
    put_record(0u, &rec);
    check(reboot() == ATT_OK && boot.slots[0] == ATT_PERSIST_SLOT_CORRUPT && boot.slot == 1u, "wrong magic: corrupt");
    flash.fail_reads = 1;
    check(reboot() == ATT_OK && boot.source == ATT_PERSIST_NONE && boot.slots[0] == ATT_PERSIST_SLOT_IO &&
              boot.slots[1] == ATT_PERSIST_SLOT_IO && !att_persist_save(&store) &&
              att_persist_poll(&store) == ATT_PERSIST_UNCHANGED,
          "pages that cannot be read: io, source none; a save cannot be verified and fails");
    flash.fail_reads = 0;
    {
        att_flash_io_t small = io;
        att_node_settings_t s;
        small.page_bytes = 64u;
        firmware_settings(&s);
        check(att_persist_node_init(&node, &s, &store, &small, &boot) == ATT_OK && boot.slots[0] == ATT_PERSIST_SLOT_IO &&
                  !att_persist_save(&store) && att_persist_poll(&store) == ATT_PERSIST_FAILED,
              "pages too small for the record: io, nothing saved");
        check(att_persist_node_init(&node, &s, &store, NULL, &boot) == ATT_OK && boot.source == ATT_PERSIST_NONE &&
                  !att_persist_save(&store),
              "no flash (io NULL): the node runs the firmware's configuration");
        check(att_persist_node_init(NULL, &s, &store, &io, NULL) == ATT_ERR_NULL &&
                  att_persist_node_init(&node, NULL, &store, &io, NULL) == ATT_ERR_NULL &&
                  att_persist_node_init(&node, &s, NULL, &io, NULL) == ATT_ERR_NULL && !att_persist_save(NULL) &&
                  att_persist_poll(NULL) == ATT_PERSIST_FAILED && !att_persist_hook(NULL, &node.cal),
              "NULL arguments refused");
        s.sample_rate = -1.0f;
        memset(flash.mem, 0xff, sizeof flash.mem);
        check(att_persist_node_init(&node, &s, &store, &io, NULL) == ATT_ERR_SETTINGS,
              "settings att_node_init refuses, nothing saved: its status");
    }
    check(strcmp(att_persist_source_name(ATT_PERSIST_OLD), "old") == 0 &&
              strcmp(att_persist_slot_name(ATT_PERSIST_SLOT_REFUSED), "refused") == 0,
          "names of sources and slot states");
}

int main(void)
{
    test_crc();
    test_first_start();
    test_changes_persist();
    test_power_cuts();
    test_bit_flips();
    test_other_records();
    printf("%d failure(s)\n", failures);
    return failures;
}
