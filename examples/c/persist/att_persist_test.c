/**
 * @file att_persist_test.c
 * @brief The flash-page persistence example on the host, against a RAM-backed fake flash page.
 *
 * The fake page behaves like NOR flash: erase sets every byte to 0xFF, programming needs erased bytes
 * and whole 8-byte units, and a power loss can be simulated after any number of programmed bytes (a
 * torn write). A real attica node runs with the hook: calibration commands over CAN frames change
 * and persist its calibration; a "reboot" (a second node initialised from the page) must find it, and
 * every damaged page must give the defaults.
 *
 * Prints "ok ..." / "FAIL ..." per check; exit status = number of failures.
 */
#include <stdio.h>
#include <string.h>

#include "att_persist.h"
#include "attica/att_can.h"
#include "attica/att_node.h"

#define PAGE_BYTES 2048u

typedef struct {
    uint8_t mem[PAGE_BYTES];
    uint32_t erases;
    uint32_t programs;
    int fail_erase;     /* the next erases fail */
    long tear_after;    /* bytes the next program writes before the power fails; -1: no failure */
    uint32_t misuse;    /* programming bytes that are not erased, or not in 8-byte units */
} flash_t;

static int failures;

static void check(int ok, const char *what)
{
    printf("%s %s\n", ok ? "ok" : "FAIL", what);
    if (!ok) {
        failures++;
    }
}

static bool fake_erase(void *ctx)
{
    flash_t *f = (flash_t *)ctx;
    if (f->fail_erase) {
        return false;
    }
    memset(f->mem, 0xff, sizeof f->mem);
    f->erases++;
    return true;
}

static bool fake_program(void *ctx, uint32_t offset, const uint8_t *data, uint32_t n)
{
    flash_t *f = (flash_t *)ctx;
    uint32_t i;
    f->programs++;
    if ((offset % 8u) != 0u || (n % 8u) != 0u || offset + n > PAGE_BYTES) {
        f->misuse++;
        return false;
    }
    for (i = 0u; i < n; i++) {
        if (f->tear_after >= 0 && (long)i >= f->tear_after) {
            f->tear_after = -1;
            return false; /* the power failed here */
        }
        if (f->mem[offset + i] != 0xffu) {
            f->misuse++;
            return false;
        }
        f->mem[offset + i] = data[i];
    }
    return true;
}

static bool fake_read(void *ctx, uint32_t offset, uint8_t *data, uint32_t n)
{
    const flash_t *f = (const flash_t *)ctx;
    if (offset + n > PAGE_BYTES) {
        return false;
    }
    memcpy(data, f->mem + offset, n);
    return true;
}

static flash_t page;
static const att_flash_io_t flash = {&page, PAGE_BYTES, fake_erase, fake_program, fake_read};
static att_node_t node;
static att_node_t rebooted;

static uint32_t bits(float x)
{
    uint32_t w;
    memcpy(&w, &x, sizeof w);
    return w;
}

/* Every field (att_calib_field_get) bit-equal. */
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

static int is_default(const att_calib_settings_t *c)
{
    att_calib_settings_t d;
    att_calib_settings_default(&d);
    return same_calib(c, &d);
}

/* One command frame through the node; the ATT_CAL_ACK it answers with (cmd 0xff if none). */
static att_can_cal_ack_t command(att_node_t *n, uint8_t cmd, uint8_t arg, float value)
{
    static uint8_t counter;
    att_can_cmd_t c;
    att_can_frame_t f;
    att_can_cal_ack_t ack;
    memset(&ack, 0, sizeof ack);
    ack.cmd = 0xffu;
    memset(&c, 0, sizeof c);
    c.counter = (uint8_t)(counter++ & 15u);
    c.cmd = cmd;
    c.arg = arg;
    c.value = value;
    att_can_encode_cmd(&c, &f);
    (void)att_node_rx(n, &f);
    (void)att_node_poll(n);
    while (att_node_tx(n, &f)) {
        if (f.id == (uint32_t)ATT_CAN_ID_CAL_ACK) {
            (void)att_can_decode_cal_ack(&f, &ack);
        }
    }
    return ack;
}

static att_persist_status_t reboot(void)
{
    att_node_settings_t s;
    att_persist_status_t why = ATT_PERSIST_IO;
    att_node_settings_default(ATT_FILTER_ARS, 100.0f, &s);
    if (att_persist_node_init(&rebooted, &s, &flash, &why) != ATT_OK) {
        return ATT_PERSIST_IO;
    }
    return why;
}

static void test_crc(void)
{
    static const uint8_t msg[9] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
    check(att_persist_crc32(msg, sizeof msg) == 0xcbf43926u, "CRC-32 of \"123456789\" is 0xCBF43926 (IEEE 802.3)");
}

static void test_first_start(void)
{
    att_node_settings_t s;
    att_persist_status_t why = ATT_PERSIST_LOADED;
    char what[120];
    memset(page.mem, 0xff, sizeof page.mem);
    page.tear_after = -1;
    att_node_settings_default(ATT_FILTER_ARS, 100.0f, &s);
    check(att_persist_node_init(&node, &s, &flash, &why) == ATT_OK && why == ATT_PERSIST_EMPTY &&
              is_default(&node.cal),
          "erased page: EMPTY, the node starts with the default calibration");
    snprintf(what, sizeof what, "the record (%lu bytes) fits the page of %u bytes",
             (unsigned long)sizeof(att_persist_record_t), PAGE_BYTES);
    check(sizeof(att_persist_record_t) + ATT_PERSIST_ALIGN <= PAGE_BYTES, what);
}

static void test_commit_persists(void)
{
    att_can_cal_ack_t a;
    const uint32_t erases = page.erases;
    a = command(&node, ATT_CAN_CMD_CAL_BEGIN, 0u, 0.0f);
    check(a.cmd == ATT_CAN_CMD_CAL_BEGIN && a.result == ATT_CAN_ACK_OK, "CAL_BEGIN answered");
    a = command(&node, ATT_CAN_CMD_CAL_SET, 12u, 0.0125f); /* gyro offset x, rad/s */
    check(a.result == ATT_CAN_ACK_OK, "CAL_SET gyro offset x = 0.0125 rad/s");
    a = command(&node, ATT_CAN_CMD_CAL_SET, 40u, -3.5f); /* hard iron y, uT */
    check(a.result == ATT_CAN_ACK_OK, "CAL_SET hard iron y = -3.5 uT");
    a = command(&node, ATT_CAN_CMD_CAL_SET, 47u, 1.0f); /* convention NED */
    check(a.result == ATT_CAN_ACK_OK, "CAL_SET convention = NED");
    a = command(&node, ATT_CAN_CMD_CAL_COMMIT, 0u, 0.0f);
    check(a.cmd == ATT_CAN_CMD_CAL_COMMIT && a.result == ATT_CAN_ACK_OK && a.persisted == ATT_CAN_PERSIST_OK &&
              page.erases == erases + 1u && page.misuse == 0u,
          "CAL_COMMIT applied and persisted (ATT_CAL_ACK persisted = 1): one erase, one program");
    check(reboot() == ATT_PERSIST_LOADED && same_calib(&rebooted.cal, &node.cal) &&
              bits(rebooted.cal.gyro.offset.x) == bits(0.0125f) && rebooted.cal.convention == ATT_CONV_NED,
          "reboot: LOADED, the node starts with exactly the committed calibration");
    a = command(&node, ATT_CAN_CMD_SET_CONVENTION, (uint8_t)ATT_CONV_NWU, 0.0f);
    check(a.persisted == ATT_CAN_PERSIST_OK && reboot() == ATT_PERSIST_LOADED &&
              rebooted.cal.convention == ATT_CONV_NWU && bits(rebooted.cal.gyro.offset.x) == bits(0.0125f),
          "SET_CONVENTION NWU persisted too; the rest kept");
}

static void test_torn_writes(void)
{
    uint32_t cut;
    uint32_t loaded = 0u;
    uint32_t not_default = 0u;
    uint32_t acks_ok = 0u;
    const uint32_t image = (uint32_t)sizeof(att_persist_record_t); /* the padding after it stays 0xFF anyway */
    char what[200];
    for (cut = 0u; cut < image; cut++) {
        att_can_cal_ack_t a;
        att_persist_status_t st;
        page.tear_after = (long)cut;
        a = command(&node, ATT_CAN_CMD_SET_CONVENTION, (uint8_t)(cut % 2u == 0u ? ATT_CONV_ENU : ATT_CONV_NED), 0.0f);
        acks_ok += (uint32_t)(a.persisted != ATT_CAN_PERSIST_FAILED);
        st = reboot();
        loaded += (uint32_t)(st == ATT_PERSIST_LOADED);
        not_default += (uint32_t)!is_default(&rebooted.cal);
    }
    snprintf(what, sizeof what,
             "a power loss after each of the %lu bytes of the record: the hook reports failure (persisted = 2), the "
             "torn page is never loaded, the node starts with the defaults",
             (unsigned long)image);
    check(acks_ok == 0u && loaded == 0u && not_default == 0u, what);
    page.tear_after = -1;
    check(command(&node, ATT_CAN_CMD_SET_CONVENTION, (uint8_t)ATT_CONV_NED, 0.0f).persisted == ATT_CAN_PERSIST_OK &&
              reboot() == ATT_PERSIST_LOADED && same_calib(&rebooted.cal, &node.cal),
          "the next save after the power came back is loaded again");
}

static void test_bit_flips(void)
{
    flash_t good = page;
    uint32_t i;
    uint32_t loaded = 0u;
    uint32_t not_default = 0u;
    char what[160];
    for (i = 0u; i < (uint32_t)sizeof(att_persist_record_t); i++) {
        page = good;
        page.mem[i] ^= (uint8_t)(1u << (i % 8u));
        loaded += (uint32_t)(reboot() == ATT_PERSIST_LOADED);
        not_default += (uint32_t)!is_default(&rebooted.cal);
    }
    snprintf(what, sizeof what, "one bit flipped in any of the %lu record bytes: never loaded, defaults",
             (unsigned long)sizeof(att_persist_record_t));
    check(loaded == 0u && not_default == 0u, what);
    page = good;
}

/* A record written by hand (another firmware, or settings this one refuses), with a correct CRC. */
static void put_record(const att_persist_record_t *rec)
{
    att_persist_record_t r = *rec;
    r.crc = att_persist_crc32((const uint8_t *)&r, offsetof(att_persist_record_t, crc));
    memset(page.mem, 0xff, sizeof page.mem);
    memcpy(page.mem, &r, sizeof r);
}

static void test_other_records(void)
{
    att_persist_record_t rec;
    att_calib_settings_t c;
    const flash_t good = page;
    memset(&rec, 0, sizeof rec);
    rec.magic = ATT_PERSIST_MAGIC;
    rec.version = (uint16_t)(ATT_PERSIST_VERSION + 1u);
    rec.length = (uint16_t)sizeof(att_calib_settings_t);
    att_calib_settings_default(&rec.calib);
    rec.calib.convention = ATT_CONV_NED;
    put_record(&rec);
    check(reboot() == ATT_PERSIST_LAYOUT && is_default(&rebooted.cal), "a record of another version: LAYOUT, defaults");
    rec.version = (uint16_t)ATT_PERSIST_VERSION;
    rec.length = (uint16_t)(sizeof(att_calib_settings_t) - 4u);
    put_record(&rec);
    check(reboot() == ATT_PERSIST_LAYOUT && is_default(&rebooted.cal), "a record of another length: LAYOUT, defaults");
    rec.length = (uint16_t)sizeof(att_calib_settings_t);
    rec.calib.gravity = 0.0f;
    put_record(&rec);
    check(reboot() == ATT_PERSIST_INVALID && is_default(&rebooted.cal),
          "good CRC, settings att_calib_settings_check refuses (gravity 0): INVALID, defaults");
    rec.calib.gravity = 9.80665f;
    put_record(&rec);
    check(reboot() == ATT_PERSIST_LOADED && rebooted.cal.convention == ATT_CONV_NED,
          "the same record with good settings: LOADED");
    rec.magic = 0x12345678u;
    put_record(&rec);
    check(reboot() == ATT_PERSIST_CORRUPT && is_default(&rebooted.cal), "wrong magic: CORRUPT, defaults");
    /* save refuses bad settings without touching the page */
    page = good;
    att_calib_settings_default(&c);
    c.gyro.sensitivity.y = -1.0f;
    {
        const uint32_t erases = page.erases;
        check(!att_persist_save(&flash, &c) && page.erases == erases && reboot() == ATT_PERSIST_LOADED,
              "att_persist_save refuses settings att_calib_settings_check refuses; the page keeps the good record");
    }
    page.fail_erase = 1;
    check(command(&node, ATT_CAN_CMD_SET_CONVENTION, (uint8_t)ATT_CONV_ENU, 0.0f).persisted == ATT_CAN_PERSIST_FAILED,
          "an erase that fails: the hook reports failure");
    page.fail_erase = 0;
    {
        att_flash_io_t small = flash;
        small.page_bytes = 64u;
        att_calib_settings_default(&c);
        c.convention = ATT_CONV_NED;
        check(att_persist_load(NULL, &c) == ATT_PERSIST_IO && is_default(&c) &&
                  att_persist_load(&small, &c) == ATT_PERSIST_IO && !att_persist_save(&small, &c) &&
                  !att_persist_save(NULL, &c) && !att_persist_save(&flash, NULL),
              "NULL io, a page too small for the record, NULL settings: refused, defaults");
        check(att_persist_node_init(NULL, NULL, &flash, NULL) == ATT_ERR_NULL, "att_persist_node_init NULL");
    }
}

int main(void)
{
    test_crc();
    test_first_start();
    test_commit_persists();
    test_torn_writes();
    test_bit_flips();
    test_other_records();
    printf("%d failure(s)\n", failures);
    return failures;
}
