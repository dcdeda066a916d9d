/**
 * @file fuzz_can.c
 * @brief libFuzzer target: every decoder and unpacker of the CAN codec (att_can.c and the cantools code
 * firmware/src/can/generated/att_can_db.c) on arbitrary frames, with invariants (docs/robustness.md):
 *
 * - C1 att_can_check agrees with an independent model: ID table, length/format table, and a table-driven
 *   CRC-8 J1850 written here (not the codec's bitwise one).
 * - C2 every generated unpack reads only `size` bytes (the input is copied to a heap block of exactly
 *   that size, so ASan sees any over-read) and refuses sizes below the message length.
 * - C3 pack(unpack(x)) == x & mask, where mask = pack(unpack(all ones)): unpack/pack lose nothing but
 *   unused bits; and a second round trip is the identity.
 * - C4 the codec's decoders invert its encoders on the signal bits: IMU parts (dequantise/quantise),
 *   IMU_FD (float bits), CMD, STATUS, DIAG_BUS, every output frame (att_can_decode_output).
 * - C5 quantise(dequantise(v)) == v for every int16 v and frac in range; quantise of a float is the
 *   round-half-even of x 2^k clamped to +-32767 (checked in double), NaN -> -32768.
 * - C6 a sealed frame checks OK; any single flipped bit in bytes 0..len-1 of a frame with a CRC is a
 *   CRC error (CRC-8 detects every single-bit error).
 */
#include <stdbool.h>

#include "attica/att_can.h"
#include "fuzz_common.h"
#include "fuzz_model.h"

#include "../../firmware/src/can/generated/att_can_db.h"

/* --- generated pack/unpack -------------------------------------------------------------------- */

#define FZ_MESSAGES(X)                                                                                 \
    X(imu_gyro, 0x100, 8)                                                                              \
    X(imu_acc, 0x101, 8)                                                                               \
    X(imu_mag, 0x102, 8)                                                                               \
    X(imu_fd, 0x110, 64)                                                                               \
    X(att_quat_a, 0x200, 8)                                                                            \
    X(att_quat_b, 0x201, 8)                                                                            \
    X(att_quat16, 0x202, 8)                                                                            \
    X(att_euler, 0x203, 8)                                                                             \
    X(att_bias, 0x204, 8)                                                                              \
    X(att_status, 0x205, 8)                                                                            \
    X(att_diag, 0x206, 8)                                                                              \
    X(att_lin_acc, 0x207, 8)                                                                           \
    X(att_earth_acc, 0x208, 8)                                                                         \
    X(att_cal_ack, 0x209, 8)                                                                           \
    X(att_diag_bus, 0x20a, 8)                                                                          \
    X(att_mag_offset, 0x20b, 8)                                                                        \
    X(att_accel_fd, 0x211, 64)                                                                         \
    X(att_out_fd, 0x210, 64)                                                                           \
    X(cmd, 0x300, 8)

/** One message: unpack the input (exactly `size` bytes on the heap), C2 and C3. */
#define FZ_ROUNDTRIP(name, id, msglen)                                                                 \
    static void rt_##name(const uint8_t *bytes, size_t size, uint8_t mask_out[64])                     \
    {                                                                                                  \
        struct att_can_db_##name##_t m;                                                                \
        uint8_t ones[64];                                                                              \
        uint8_t a[64];                                                                                 \
        uint8_t b[64];                                                                                 \
        uint8_t mask[64];                                                                              \
        uint8_t *heap = (uint8_t *)malloc(size ? size : 1u);                                           \
        int r;                                                                                         \
        size_t i;                                                                                      \
        if (size) memcpy(heap, bytes, size);                                                           \
        memset(&m, 0, sizeof m);                                                                       \
        r = att_can_db_##name##_unpack(&m, heap, size);                                                \
        free(heap);                                                                                    \
        memset(ones, 0xFF, sizeof ones);                                                               \
        {                                                                                              \
            struct att_can_db_##name##_t mo;                                                           \
            memset(&mo, 0, sizeof mo);                                                                 \
            FZ_CHECK(att_can_db_##name##_unpack(&mo, ones, msglen) == 0, #name ": unpack of ones");    \
            memset(mask, 0, sizeof mask);                                                              \
            FZ_CHECK(att_can_db_##name##_pack(mask, &mo, 64u) == (msglen), #name ": pack length");    \
        }                                                                                              \
        memcpy(mask_out, mask, 64u);                                                                   \
        if (size < (msglen)) {                                                                         \
            FZ_CHECK(r != 0, #name ": unpack accepted %zu bytes < %d", size, msglen);                  \
            return;                                                                                    \
        }                                                                                              \
        FZ_CHECK(r == 0, #name ": unpack refused %zu bytes", size);                                    \
        memset(a, 0xA5, sizeof a);                                                                     \
        FZ_CHECK(att_can_db_##name##_pack(a, &m, (msglen) - 1u) < 0, #name ": pack into a short buffer"); \
        FZ_CHECK(att_can_db_##name##_pack(a, &m, 64u) == (msglen), #name ": pack length");            \
        for (i = 0; i < (msglen); ++i) {                                                               \
            FZ_CHECK(a[i] == (uint8_t)(bytes[i] & mask[i]), #name ": byte %zu: pack(unpack) %02x, input %02x mask %02x", \
                     i, a[i], bytes[i], mask[i]);                                                      \
        }                                                                                              \
        memset(&m, 0, sizeof m);                                                                       \
        FZ_CHECK(att_can_db_##name##_unpack(&m, a, msglen) == 0, #name ": second unpack");             \
        FZ_CHECK(att_can_db_##name##_pack(b, &m, 64u) == (msglen), #name ": second pack");            \
        FZ_CHECK(memcmp(a, b, msglen) == 0, #name ": second round trip differs");                      \
    }

FZ_MESSAGES(FZ_ROUNDTRIP)

static uint8_t g_mask[0x400][64]; /* signal-bit masks by ID (filled on the fly) */

static void all_roundtrips(const uint8_t *bytes, size_t size)
{
#define FZ_CALL(name, id, msglen) rt_##name(bytes, size, g_mask[id]);
    FZ_MESSAGES(FZ_CALL)
#undef FZ_CALL
}

/* --- codec decoders --------------------------------------------------------------------------- */

static void expect_masked(const att_can_frame_t *in, const att_can_frame_t *re, size_t from, size_t to,
                          const char *what)
{
    size_t i;
    const uint8_t *mask = g_mask[in->id & 0x3FFu];
    for (i = from; i < to; ++i) {
        FZ_CHECK(re->data[i] == (uint8_t)(in->data[i] & mask[i]), "%s: id %03x byte %zu: re-encoded %02x, input %02x",
                 what, (unsigned)in->id, i, re->data[i], in->data[i]);
    }
}

static void check_decoders(const att_can_frame_t *f)
{
    att_vec3_t v;
    att_sample_t s;
    att_can_cmd_t c;
    att_can_status_t st;
    att_output_t o;
    att_can_frame_t re[6];
    bool is_part = f->id == 0x100u || f->id == 0x101u || f->id == 0x102u;
    uint8_t counter = (uint8_t)(f->data[1] & 0x0Fu);

    FZ_CHECK(att_can_decode_imu_part(f, &v) == (is_part && f->len >= 8u), "decode_imu_part acceptance");
    if (is_part && f->len >= 8u) {
        memset(&s, 0, sizeof s);
        if (f->id == 0x100u) s.gyr = v;
        if (f->id == 0x101u) s.acc = v;
        if (f->id == 0x102u) s.mag = v;
        att_can_encode_imu(&s, counter, re);
        expect_masked(f, &re[f->id - 0x100u], 1u, 8u, "imu part");
        FZ_CHECK(att_can_check(&re[f->id - 0x100u]) == ATT_CAN_OK, "encoded imu part does not check");
    }
    FZ_CHECK(att_can_decode_imu_fd(f, &s) == (f->id == 0x110u && f->len >= 64u), "decode_imu_fd acceptance");
    if (f->id == 0x110u && f->len >= 64u) {
        att_can_encode_imu_fd(&s, counter, &re[0]);
        expect_masked(f, &re[0], 1u, 64u, "imu fd");
        FZ_CHECK(att_can_check(&re[0]) == ATT_CAN_OK, "encoded imu fd does not check");
    }
    FZ_CHECK(att_can_decode_cmd(f, &c) == (f->id == 0x300u && f->len >= 8u), "decode_cmd acceptance");
    if (f->id == 0x300u && f->len >= 8u) {
        att_can_encode_cmd(&c, &re[0]);
        expect_masked(f, &re[0], 1u, 8u, "cmd");
        FZ_CHECK(att_can_check(&re[0]) == ATT_CAN_OK, "encoded cmd does not check");
    }
    FZ_CHECK(att_can_decode_status(f, &st) == (f->id == 0x205u && f->len >= 8u), "decode_status acceptance");
    if (f->id == 0x205u && f->len >= 8u) {
        att_can_encode_status(&st, &re[0]);
        expect_masked(f, &re[0], 1u, 8u, "status");
        FZ_CHECK(st.counter < 16u && st.kind < 16u, "status nibbles out of range");
    }
    {
        /* the calibration answer and the acceleration frames invert their encoders on the signal bits */
        att_can_cal_ack_t ack;
        att_accel_t acc;
        bool is_acc = f->id == 0x207u || f->id == 0x208u;
        FZ_CHECK(att_can_decode_cal_ack(f, &ack) == (f->id == 0x209u && f->len == 8u), "decode_cal_ack acceptance");
        if (f->id == 0x209u && f->len == 8u) {
            att_can_encode_cal_ack(&ack, &re[0]);
            expect_masked(f, &re[0], 1u, 8u, "cal ack");
            FZ_CHECK(att_can_check(&re[0]) == ATT_CAN_OK, "encoded cal ack does not check");
        }
        att_can_bus_diag_t bus;
        FZ_CHECK(att_can_decode_diag_bus(f, &bus) == (f->id == 0x20Au && f->len >= 8u), "decode_diag_bus acceptance");
        if (f->id == 0x20Au && f->len >= 8u) {
            FZ_CHECK(bus.state < 4u && bus.lec < 8u && bus.bus_off < 256u && bus.rx_overruns < 256u, "diag bus ranges");
            att_can_encode_diag_bus(&bus, counter, &re[0]);
            expect_masked(f, &re[0], 1u, 8u, "diag bus");
            FZ_CHECK(att_can_check(&re[0]) == ATT_CAN_OK, "encoded diag bus does not check");
        }
        {
            /* the hard-iron offset: NA decodes to NaN and encodes back to NA, so the frame inverts */
            att_mag_offset_t h;
            FZ_CHECK(att_can_decode_mag_offset(f, &h) == (f->id == 0x20Bu && f->len >= 8u),
                     "decode_mag_offset acceptance");
            if (f->id == 0x20Bu && f->len >= 8u) {
                att_can_encode_mag_offset(&h, counter, &re[0]);
                expect_masked(f, &re[0], 1u, 8u, "mag offset");
                FZ_CHECK(att_can_check(&re[0]) == ATT_CAN_OK, "encoded mag offset does not check");
            }
        }
        FZ_CHECK(att_can_decode_accel_part(f, &v) == (is_acc && f->len == 8u), "decode_accel_part acceptance");
        if (is_acc && f->len == 8u) {
            memset(&acc, 0, sizeof acc);
            if (f->id == 0x207u) acc.linear = v;
            else acc.earth = v;
            att_can_encode_accel(&acc, counter, re);
            expect_masked(f, &re[f->id - 0x207u], 1u, 8u, "accel part");
            FZ_CHECK(att_can_check(&re[f->id - 0x207u]) == ATT_CAN_OK, "encoded accel part does not check");
        }
        FZ_CHECK(att_can_decode_accel_fd(f, &acc) == (f->id == 0x211u && f->len == 64u), "decode_accel_fd acceptance");
        if (f->id == 0x211u && f->len == 64u) {
            FZ_CHECK(acc.valid == 0u || acc.valid == ATT_OUT_ACCEL, "accel fd valid");
            if (acc.valid != 0u || (f->data[2] == 0u)) {
                att_can_encode_accel_fd(&acc, counter, &re[0]);
                FZ_CHECK(att_can_check(&re[0]) == ATT_CAN_OK, "encoded accel fd does not check");
                if (f->data[2] <= 1u) expect_masked(f, &re[0], 1u, 64u, "accel fd");
            }
        }
    }
    memset(&o, 0, sizeof o);
    {
        bool want = f->len == model_len(f->id) &&
                    (f->id == 0x200u || f->id == 0x201u || f->id == 0x203u || f->id == 0x204u || f->id == 0x205u ||
                     f->id == 0x210u);
        bool got = att_can_decode_output(f, &o);
        FZ_CHECK(got == want, "decode_output acceptance id %03x len %u: %d", (unsigned)f->id, f->len, (int)got);
        if (got && f->id == 0x210u) {
            att_can_encode_output_fd(&o, (att_filter_kind_t)f->data[2], counter, &re[0]);
            expect_masked(f, &re[0], 1u, 64u, "out fd");
        } else if (got) {
            size_t k = (f->id == 0x200u) ? 0u : (f->id == 0x201u) ? 1u : (f->id == 0x203u) ? 3u : (f->id == 0x204u) ? 4u : 5u;
            FZ_CHECK(att_can_encode_output_set(&o, ATT_FILTER_ARS, counter, 0u, re) == 6u, "output set size");
            if (k == 5u) {
                expect_masked(f, &re[5], 2u, 6u, "status flags/steps");
            } else {
                expect_masked(f, &re[k], k < 2u ? 0u : 2u, 8u, "output frame");
            }
        }
    }
}

/* --- quantisation ----------------------------------------------------------------------------- */

static void check_quantise(float x, int32_t k, int16_t v)
{
    int16_t q;
    float d;
    if (k < ATT_CAN_FRAC_MIN || k > ATT_CAN_FRAC_MAX) {
        FZ_CHECK(att_can_quantise(x, k) == ATT_CAN_NA, "quantise with frac %d out of range", (int)k);
        d = att_can_dequantise(v, k);
        FZ_CHECK(d != d, "dequantise with frac %d out of range is not NaN", (int)k);
        return;
    }
    d = att_can_dequantise(v, k);
    if (v == ATT_CAN_NA) {
        FZ_CHECK(d != d, "dequantise(-32768) is not NaN");
    } else {
        FZ_CHECK((double)d == ldexp((double)v, -k), "dequantise(%d, %d) inexact", v, (int)k);
    }
    FZ_CHECK(att_can_quantise(d, k) == v, "quantise(dequantise(%d, %d)) = %d", v, (int)k, att_can_quantise(d, k));
    q = att_can_quantise(x, k);
    if (x != x) {
        FZ_CHECK(q == ATT_CAN_NA, "quantise(NaN) = %d", q);
    } else {
        double s = ldexp((double)x, k);
        double want;
        if (s > 32767.0) {
            want = 32767.0;
        } else if (s < -32767.0) {
            want = -32767.0;
        } else {
            want = nearbyint(s); /* default rounding mode: half to even */
        }
        FZ_CHECK((double)q == want, "quantise(%a, %d) = %d, want %.0f", (double)x, (int)k, q, want);
    }
}

/* --- CRC -------------------------------------------------------------------------------------- */

static void check_crc(const att_can_frame_t *in, uint32_t flip)
{
    att_can_frame_t f = *in;
    unsigned want = model_len(f.id);
    size_t bit;
    if (!model_has_crc(f.id)) {
        return;
    }
    f.len = (uint8_t)want;
    f.fd = (uint8_t)(want == 64u);
    if (f.id == 0x205u) {
        f.data[7] |= 0x80u; /* an answer STATUS: CRC over its own bytes */
    }
    att_can_seal(&f);
    FZ_CHECK(f.data[0] == model_crc(f.id, f.data, f.len), "seal wrote %02x, model %02x", f.data[0],
             model_crc(f.id, f.data, f.len));
    FZ_CHECK(att_can_check(&f) == ATT_CAN_OK, "sealed frame does not check");
    FZ_CHECK(att_can_e2e_crc(att_can_data_id(f.id), &f.data[1], (size_t)f.len - 1u) == f.data[0], "e2e_crc");
    bit = (size_t)(flip % (8u * want));
    if (f.id == 0x205u && bit == 63u) {
        return; /* that bit turns the answer into a set STATUS (checked over the set) */
    }
    f.data[bit / 8u] ^= (uint8_t)(1u << (bit % 8u));
    FZ_CHECK(att_can_check(&f) == ATT_CAN_ERR_CRC, "single bit flip %zu not detected (id %03x)", bit, (unsigned)f.id);
}

/* --- entry ------------------------------------------------------------------------------------ */

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    crc_table_init();
    return 0;
}

/* (0x20B last: the indices below it pick the IDs they picked before it was added) */
static const uint32_t known_ids[] = {0x100, 0x101, 0x102, 0x110, 0x200, 0x201, 0x202, 0x203, 0x204, 0x205,
                                     0x206, 0x207, 0x208, 0x209, 0x20A, 0x210, 0x211, 0x300, 0x20B};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_reader_t r;
    att_can_frame_t f;
    uint16_t idsel;
    uint8_t lensel;
    size_t i;
    if (size > 256u) {
        return -1; /* longer inputs add nothing: the frame is at most 64 bytes */
    }
    crc_table_init();
    fz_init(&r, data, size);
    idsel = fz_u16(&r);
    lensel = fz_u8(&r);
    memset(&f, 0, sizeof f);
    /* mostly attica IDs (else the decoders are rarely reached), sometimes any 11-bit ID */
    f.id = (idsel & 0x8000u) ? (uint32_t)(idsel & 0x7FFu)
                             : known_ids[(idsel & 0xFFu) % (sizeof known_ids / sizeof known_ids[0])];
    if (lensel & 0x80u) {
        f.len = (uint8_t)(lensel & 0x7Fu); /* up to 127: the decoders must not trust it */
        f.fd = (uint8_t)((lensel >> 6) & 1u);
        if (f.len > 64u) f.len = 64u;
    } else {
        f.len = (uint8_t)model_len(f.id);
        f.fd = (uint8_t)(f.len == 64u);
    }
    for (i = 0; i < 64u; ++i) {
        f.data[i] = fz_u8(&r);
    }
    FZ_CHECK(att_can_check(&f) == model_check(&f), "att_can_check %d, model %d (id %03x len %u fd %u)",
             (int)att_can_check(&f), (int)model_check(&f), (unsigned)f.id, f.len, f.fd);
    FZ_CHECK(att_can_msg_len(f.id) == model_len(f.id), "msg_len");
    FZ_CHECK(att_can_msg_has_crc(f.id) == model_has_crc(f.id), "msg_has_crc");
    FZ_CHECK(att_can_counter(&f) == ((model_has_crc(f.id) && f.len >= 2u) ? (f.data[1] & 0x0Fu) : 0u), "counter");
    all_roundtrips(f.data, f.len);
    all_roundtrips(data, size < 64u ? size : 64u); /* unpack on the raw input length too */
    check_decoders(&f);
    check_crc(&f, fz_u32(&r));
    {
        int16_t v = (int16_t)fz_u16(&r);
        int32_t k = (int32_t)(int8_t)fz_u8(&r);
        float x = fz_float(&r);
        check_quantise(x, k, v);
        check_quantise(x, (int32_t)(((uint32_t)(uint8_t)k) % 61u) - 30, v);
    }
    (void)att_can_crc8(NULL, 5u, 0x12u);
    return 0;
}
