/**
 * @file att_can.c
 * @brief CAN codec (see att_can.h): CRC/E2E, quantisation, frame sets on top of the cantools code.
 * Mirrored bit for bit by host/attica/can/codec.py.
 */
#include "../math/att_fp.h"

#include <string.h>

#include "attica/att_can.h"

#include "generated/att_can_db.h"

/** 1.5 * 2^23: adding and subtracting it rounds a float of magnitude < 2^22 to an integer, ties even. */
#define ATT_CAN_ROUND_MAGIC 0x1.8p23f
#define ATT_CAN_Q_MAX 32767.0f

/* --- CRC ------------------------------------------------------------------------------------ */

uint8_t att_can_crc8(const uint8_t *data, size_t len, uint8_t crc)
{
    size_t i;
    uint32_t bit;
    uint32_t c = crc;
    if (data == NULL) {
        return crc;
    }
    for (i = 0u; i < len; ++i) {
        c ^= data[i];
        for (bit = 0u; bit < 8u; ++bit) {
            c = ((c & 0x80u) != 0u) ? (((c << 1) ^ 0x1Du) & 0xFFu) : ((c << 1) & 0xFFu);
        }
    }
    return (uint8_t)c;
}

static uint8_t att_can_e2e_start(uint16_t data_id)
{
    uint8_t id[2];
    id[0] = (uint8_t)(data_id & 0xFFu);
    id[1] = (uint8_t)((data_id >> 8) & 0xFFu);
    return att_can_crc8(id, 2u, 0xFFu);
}

uint8_t att_can_e2e_crc(uint16_t data_id, const uint8_t *payload, size_t len)
{
    uint8_t c = att_can_e2e_start(data_id);
    c = att_can_crc8(payload, len, c);
    return (uint8_t)(c ^ 0xFFu);
}

/* --- quantisation ---------------------------------------------------------------------------- */

/** 2^k as a float for k in [ATT_CAN_FRAC_MIN, ATT_CAN_FRAC_MAX] (normal range; built from the bits). */
static float att_can_pow2(int32_t k)
{
    uint32_t bits = ((uint32_t)(k + 127)) << 23;
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

int16_t att_can_quantise(float x, int32_t frac_bits)
{
    float s;
    float r;
    if (frac_bits < ATT_CAN_FRAC_MIN || frac_bits > ATT_CAN_FRAC_MAX || x != x) {
        return (int16_t)ATT_CAN_NA;
    }
    s = x * att_can_pow2(frac_bits); /* exact unless it overflows to +-Inf (clamped below) */
    if (s > ATT_CAN_Q_MAX) {
        s = ATT_CAN_Q_MAX;
    } else if (s < -ATT_CAN_Q_MAX) {
        s = -ATT_CAN_Q_MAX;
    }
    r = (s + ATT_CAN_ROUND_MAGIC) - ATT_CAN_ROUND_MAGIC; /* integral, in [-32767, 32767] */
    return (int16_t)(int32_t)r;
}

float att_can_dequantise(int16_t v, int32_t frac_bits)
{
    const bool ok = v != (int16_t)ATT_CAN_NA && frac_bits >= ATT_CAN_FRAC_MIN && frac_bits <= ATT_CAN_FRAC_MAX;
    uint32_t bits = 0x7FC00000u; /* NaN: -32768, or frac_bits out of range */
    float f;
    if (ok) {
        bits = ((uint32_t)(127 - frac_bits)) << 23; /* 2^-frac_bits */
    }
    memcpy(&f, &bits, sizeof f);
    return ok ? (float)v * f : f;
}

/* --- message table --------------------------------------------------------------------------- */

uint8_t att_can_msg_len(uint32_t id)
{
    switch (id) {
    case ATT_CAN_ID_IMU_GYRO:
    case ATT_CAN_ID_IMU_ACC:
    case ATT_CAN_ID_IMU_MAG:
    case ATT_CAN_ID_QUAT_A:
    case ATT_CAN_ID_QUAT_B:
    case ATT_CAN_ID_QUAT16:
    case ATT_CAN_ID_EULER:
    case ATT_CAN_ID_BIAS:
    case ATT_CAN_ID_STATUS:
    case ATT_CAN_ID_DIAG:
    case ATT_CAN_ID_LIN_ACC:
    case ATT_CAN_ID_EARTH_ACC:
    case ATT_CAN_ID_CAL_ACK:
    case ATT_CAN_ID_DIAG_BUS:
    case ATT_CAN_ID_MAG_OFFSET:
    case ATT_CAN_ID_CMD:
        return (uint8_t)ATT_CAN_CLASSIC_LEN;
    case ATT_CAN_ID_IMU_FD:
    case ATT_CAN_ID_OUT_FD:
    case ATT_CAN_ID_ACCEL_FD:
        return (uint8_t)ATT_CAN_FD_LEN;
    default:
        return 0u;
    }
}

bool att_can_msg_has_crc(uint32_t id)
{
    return att_can_msg_len(id) != 0u && id != ATT_CAN_ID_QUAT_A && id != ATT_CAN_ID_QUAT_B &&
           id != ATT_CAN_ID_QUAT16;
}

uint16_t att_can_data_id(uint32_t id)
{
    return (uint16_t)((ATT_CAN_DATA_ID_BASE + (id & 0x7FFu)) & 0xFFFFu);
}

static uint8_t att_can_frame_crc(const att_can_frame_t *f)
{
    return att_can_e2e_crc(att_can_data_id(f->id), &f->data[1], (size_t)f->len - 1u);
}

att_can_check_t att_can_check(const att_can_frame_t *f)
{
    uint8_t want;
    if (f == NULL) {
        return ATT_CAN_ERR_UNKNOWN_ID;
    }
    want = att_can_msg_len(f->id);
    if (want == 0u) {
        return ATT_CAN_ERR_UNKNOWN_ID;
    }
    if (f->len != want || f->fd != (uint8_t)((want == (uint8_t)ATT_CAN_FD_LEN) ? 1u : 0u)) {
        return ATT_CAN_ERR_DLC;
    }
    if (!att_can_msg_has_crc(f->id)) {
        return ATT_CAN_OK;
    }
    if (f->id == ATT_CAN_ID_STATUS && (f->data[7] & ATT_CAN_ACK_ANSWER) == 0u) {
        return ATT_CAN_OK; /* a set's STATUS: its CRC covers the set (att_can_status_crc) */
    }
    return (att_can_frame_crc(f) == f->data[0]) ? ATT_CAN_OK : ATT_CAN_ERR_CRC;
}

void att_can_seal(att_can_frame_t *f)
{
    if (f == NULL || !att_can_msg_has_crc(f->id) || f->len < 2u || f->len > 64u) {
        return;
    }
    f->data[0] = att_can_frame_crc(f);
}

uint8_t att_can_status_crc(const att_can_frame_t *status, const att_can_frame_t *quat_a,
                           const att_can_frame_t *quat_b, const att_can_frame_t *quat16)
{
    uint8_t c;
    if (status == NULL || quat_a == NULL || quat_b == NULL || quat16 == NULL) {
        return 0u;
    }
    c = att_can_e2e_start(att_can_data_id(ATT_CAN_ID_STATUS));
    c = att_can_crc8(&status->data[1], 7u, c);
    c = att_can_crc8(quat_a->data, 8u, c);
    c = att_can_crc8(quat_b->data, 8u, c);
    c = att_can_crc8(quat16->data, 8u, c);
    return (uint8_t)(c ^ 0xFFu);
}

uint8_t att_can_counter(const att_can_frame_t *f)
{
    if (f == NULL || !att_can_msg_has_crc(f->id) || f->len < 2u) {
        return 0u;
    }
    return (uint8_t)(f->data[1] & 0x0Fu);
}

static void att_can_frame_start(att_can_frame_t *f, uint32_t id)
{
    memset(f, 0, sizeof *f);
    f->id = id;
    f->len = att_can_msg_len(id);
    f->fd = (uint8_t)((f->len == (uint8_t)ATT_CAN_FD_LEN) ? 1u : 0u);
}

static uint8_t att_can_c4(uint8_t counter)
{
    return (uint8_t)(counter & 0x0Fu);
}

/* --- IMU ------------------------------------------------------------------------------------- */

void att_can_encode_imu(const att_sample_t *in, uint8_t counter, att_can_frame_t out[3])
{
    struct att_can_db_imu_gyro_t g;
    struct att_can_db_imu_acc_t a;
    struct att_can_db_imu_mag_t m;
    if (in == NULL || out == NULL) {
        return;
    }
    g.crc = 0u;
    g.counter = att_can_c4(counter);
    g.gyr_x = att_can_quantise(in->gyr.x, ATT_CAN_GYR_FRAC);
    g.gyr_y = att_can_quantise(in->gyr.y, ATT_CAN_GYR_FRAC);
    g.gyr_z = att_can_quantise(in->gyr.z, ATT_CAN_GYR_FRAC);
    att_can_frame_start(&out[0], ATT_CAN_ID_IMU_GYRO);
    (void)att_can_db_imu_gyro_pack(out[0].data, &g, sizeof out[0].data);
    att_can_seal(&out[0]);

    a.crc = 0u;
    a.counter = att_can_c4(counter);
    a.acc_x = att_can_quantise(in->acc.x, ATT_CAN_ACC_FRAC);
    a.acc_y = att_can_quantise(in->acc.y, ATT_CAN_ACC_FRAC);
    a.acc_z = att_can_quantise(in->acc.z, ATT_CAN_ACC_FRAC);
    att_can_frame_start(&out[1], ATT_CAN_ID_IMU_ACC);
    (void)att_can_db_imu_acc_pack(out[1].data, &a, sizeof out[1].data);
    att_can_seal(&out[1]);

    m.crc = 0u;
    m.counter = att_can_c4(counter);
    m.mag_x = att_can_quantise(in->mag.x, ATT_CAN_MAG_FRAC);
    m.mag_y = att_can_quantise(in->mag.y, ATT_CAN_MAG_FRAC);
    m.mag_z = att_can_quantise(in->mag.z, ATT_CAN_MAG_FRAC);
    att_can_frame_start(&out[2], ATT_CAN_ID_IMU_MAG);
    (void)att_can_db_imu_mag_pack(out[2].data, &m, sizeof out[2].data);
    att_can_seal(&out[2]);
}

void att_can_encode_imu_fd(const att_sample_t *in, uint8_t counter, att_can_frame_t *out)
{
    struct att_can_db_imu_fd_t m;
    if (in == NULL || out == NULL) {
        return;
    }
    m.crc = 0u;
    m.counter = att_can_c4(counter);
    m.gyr_x = in->gyr.x;
    m.gyr_y = in->gyr.y;
    m.gyr_z = in->gyr.z;
    m.acc_x = in->acc.x;
    m.acc_y = in->acc.y;
    m.acc_z = in->acc.z;
    m.mag_x = in->mag.x;
    m.mag_y = in->mag.y;
    m.mag_z = in->mag.z;
    att_can_frame_start(out, ATT_CAN_ID_IMU_FD);
    (void)att_can_db_imu_fd_pack(out->data, &m, sizeof out->data);
    att_can_seal(out);
}

static att_vec3_t att_can_vec3_dq(int16_t x, int16_t y, int16_t z, int32_t frac)
{
    att_vec3_t v;
    v.x = att_can_dequantise(x, frac);
    v.y = att_can_dequantise(y, frac);
    v.z = att_can_dequantise(z, frac);
    return v;
}

/* A sensor's field at the frame's full scale (+-ATT_CAN_Q_FULL) was clipped there: at or beyond 32767
 * 2^-k, its value unknown. It is given as +-32767 2^112 (about +-1.7e38), beyond every filter's range
 * (GYRO_RANGE, ACCEL_RANGE, the field rejected), so that a gyro clipped by the frame starts the recovery
 * of a clipping gyro, which it would not at 32 rad/s under a gyro_range of 34.9 (docs/can.md,
 * Scaling). Outputs keep att_can_dequantise's plain scale. */
static float att_can_dq_sensor(int16_t v, int32_t frac)
{
    if ((int32_t)v * v == (int32_t)ATT_CAN_Q_FULL * ATT_CAN_Q_FULL) {
        return (float)v * 0x1p+112f;
    }
    return att_can_dequantise(v, frac);
}

bool att_can_decode_imu_part(const att_can_frame_t *f, att_vec3_t *v)
{
    struct att_can_db_imu_gyro_t p;
    int32_t frac;
    if (f == NULL || v == NULL || f->len < (uint8_t)ATT_CAN_CLASSIC_LEN) {
        return false;
    }
    switch (f->id) {
    case ATT_CAN_ID_IMU_GYRO:
        frac = ATT_CAN_GYR_FRAC;
        break;
    case ATT_CAN_ID_IMU_ACC:
        frac = ATT_CAN_ACC_FRAC;
        break;
    case ATT_CAN_ID_IMU_MAG:
        frac = ATT_CAN_MAG_FRAC;
        break;
    default:
        return false;
    }
    /* the three parts have one layout (crc, counter, then x, y, z as int16 in bytes 2..7; the DBC's
     * signals checked alike by tests/test_can_dbc.py): one unpack serves them all */
    (void)att_can_db_imu_gyro_unpack(&p, f->data, ATT_CAN_CLASSIC_LEN);
    v->x = att_can_dq_sensor(p.gyr_x, frac);
    v->y = att_can_dq_sensor(p.gyr_y, frac);
    v->z = att_can_dq_sensor(p.gyr_z, frac);
    return true;
}

bool att_can_decode_imu_fd(const att_can_frame_t *f, att_sample_t *out)
{
    struct att_can_db_imu_fd_t m;
    if (f == NULL || out == NULL || f->id != ATT_CAN_ID_IMU_FD || f->len < (uint8_t)ATT_CAN_FD_LEN) {
        return false;
    }
    (void)att_can_db_imu_fd_unpack(&m, f->data, ATT_CAN_FD_LEN);
    out->gyr.x = m.gyr_x;
    out->gyr.y = m.gyr_y;
    out->gyr.z = m.gyr_z;
    out->acc.x = m.acc_x;
    out->acc.y = m.acc_y;
    out->acc.z = m.acc_z;
    out->mag.x = m.mag_x;
    out->mag.y = m.mag_y;
    out->mag.z = m.mag_z;
    return true;
}

/* --- outputs --------------------------------------------------------------------------------- */

static uint8_t att_can_kind4(att_filter_kind_t kind)
{
    return (uint8_t)((uint32_t)kind & 0x0Fu);
}

size_t att_can_encode_output_set(const att_output_t *o, att_filter_kind_t kind, uint8_t counter,
                                 uint8_t error_count, att_can_frame_t out[6])
{
    struct att_can_db_att_quat_a_t qa;
    struct att_can_db_att_quat_b_t qb;
    struct att_can_db_att_quat16_t q16;
    struct att_can_db_att_euler_t eu;
    struct att_can_db_att_bias_t bi;
    struct att_can_db_att_status_t st;
    if (o == NULL || out == NULL) {
        return 0u;
    }
    qa.q_w = o->q.w;
    qa.q_x = o->q.x;
    att_can_frame_start(&out[0], ATT_CAN_ID_QUAT_A);
    (void)att_can_db_att_quat_a_pack(out[0].data, &qa, sizeof out[0].data);

    qb.q_y = o->q.y;
    qb.q_z = o->q.z;
    att_can_frame_start(&out[1], ATT_CAN_ID_QUAT_B);
    (void)att_can_db_att_quat_b_pack(out[1].data, &qb, sizeof out[1].data);

    q16.q_w = att_can_quantise(o->q.w, ATT_CAN_QUAT16_FRAC);
    q16.q_x = att_can_quantise(o->q.x, ATT_CAN_QUAT16_FRAC);
    q16.q_y = att_can_quantise(o->q.y, ATT_CAN_QUAT16_FRAC);
    q16.q_z = att_can_quantise(o->q.z, ATT_CAN_QUAT16_FRAC);
    att_can_frame_start(&out[2], ATT_CAN_ID_QUAT16);
    (void)att_can_db_att_quat16_pack(out[2].data, &q16, sizeof out[2].data);

    eu.crc = 0u;
    eu.counter = att_can_c4(counter);
    eu.roll = att_can_quantise(o->euler.x, ATT_CAN_EULER_FRAC);
    eu.pitch = att_can_quantise(o->euler.y, ATT_CAN_EULER_FRAC);
    eu.yaw = att_can_quantise(o->euler.z, ATT_CAN_EULER_FRAC);
    att_can_frame_start(&out[3], ATT_CAN_ID_EULER);
    (void)att_can_db_att_euler_pack(out[3].data, &eu, sizeof out[3].data);
    att_can_seal(&out[3]);

    bi.crc = 0u;
    bi.counter = att_can_c4(counter);
    bi.bias_x = att_can_quantise(o->gyro_bias.x, ATT_CAN_BIAS_FRAC);
    bi.bias_y = att_can_quantise(o->gyro_bias.y, ATT_CAN_BIAS_FRAC);
    bi.bias_z = att_can_quantise(o->gyro_bias.z, ATT_CAN_BIAS_FRAC);
    att_can_frame_start(&out[4], ATT_CAN_ID_BIAS);
    (void)att_can_db_att_bias_pack(out[4].data, &bi, sizeof out[4].data);
    att_can_seal(&out[4]);

    st.crc = 0u;
    st.counter = att_can_c4(counter);
    st.kind = att_can_kind4(kind);
    st.flags = (uint16_t)(o->flags & 0xFFFFu);
    st.steps = (uint16_t)(o->steps & 0xFFFFu);
    st.error_count = error_count;
    st.ack = 0u;
    att_can_frame_start(&out[5], ATT_CAN_ID_STATUS);
    (void)att_can_db_att_status_pack(out[5].data, &st, sizeof out[5].data);
    out[5].data[0] = att_can_status_crc(&out[5], &out[0], &out[1], &out[2]);
    return 6u;
}

void att_can_encode_output_fd(const att_output_t *o, att_filter_kind_t kind, uint8_t counter,
                              att_can_frame_t *out)
{
    struct att_can_db_att_out_fd_t m;
    if (o == NULL || out == NULL) {
        return;
    }
    m.crc = 0u;
    m.counter = att_can_c4(counter);
    m.kind = (uint8_t)((uint32_t)kind & 0xFFu);
    m.flags = (uint16_t)(o->flags & 0xFFFFu);
    m.steps = (uint16_t)(o->steps & 0xFFFFu);
    m.q_w = o->q.w;
    m.q_x = o->q.x;
    m.q_y = o->q.y;
    m.q_z = o->q.z;
    m.roll = o->euler.x;
    m.pitch = o->euler.y;
    m.yaw = o->euler.z;
    m.bias_x = o->gyro_bias.x;
    m.bias_y = o->gyro_bias.y;
    m.bias_z = o->gyro_bias.z;
    m.cov_0 = o->cov[0];
    m.cov_1 = o->cov[1];
    m.cov_2 = o->cov[2];
    m.cov_3 = o->cov[3];
    att_can_frame_start(out, ATT_CAN_ID_OUT_FD);
    (void)att_can_db_att_out_fd_pack(out->data, &m, sizeof out->data);
    att_can_seal(out);
}

void att_can_encode_status(const att_can_status_t *st, att_can_frame_t *out)
{
    struct att_can_db_att_status_t m;
    if (st == NULL || out == NULL) {
        return;
    }
    m.crc = 0u;
    m.counter = att_can_c4(st->counter);
    m.kind = (uint8_t)(st->kind & 0x0Fu);
    m.flags = st->flags;
    m.steps = st->steps;
    m.error_count = st->error_count;
    m.ack = st->ack;
    att_can_frame_start(out, ATT_CAN_ID_STATUS);
    (void)att_can_db_att_status_pack(out->data, &m, sizeof out->data);
    att_can_seal(out);
}

bool att_can_decode_status(const att_can_frame_t *f, att_can_status_t *st)
{
    struct att_can_db_att_status_t m;
    if (f == NULL || st == NULL || f->id != ATT_CAN_ID_STATUS || f->len < (uint8_t)ATT_CAN_CLASSIC_LEN) {
        return false;
    }
    (void)att_can_db_att_status_unpack(&m, f->data, ATT_CAN_CLASSIC_LEN);
    st->counter = m.counter;
    st->kind = m.kind;
    st->flags = m.flags;
    st->steps = m.steps;
    st->error_count = m.error_count;
    st->ack = m.ack;
    return true;
}

static uint8_t att_can_sat8(uint32_t v)
{
    return (uint8_t)((v > 255u) ? 255u : v);
}

void att_can_encode_diag(const att_can_diag_t *d, uint8_t counter, att_can_frame_t *out)
{
    struct att_can_db_att_diag_t m;
    if (d == NULL || out == NULL) {
        return;
    }
    m.crc = 0u;
    m.counter = att_can_c4(counter);
    m.crc_errors = att_can_sat8(d->crc_errors);
    m.counter_gaps = att_can_sat8(d->counter_gaps);
    m.dlc_errors = att_can_sat8(d->dlc_errors);
    m.unknown_ids = att_can_sat8(d->unknown_ids);
    m.duplicates = att_can_sat8(d->duplicates);
    m.stale_partials = att_can_sat8(d->stale_partials);
    att_can_frame_start(out, ATT_CAN_ID_DIAG);
    (void)att_can_db_att_diag_pack(out->data, &m, sizeof out->data);
    att_can_seal(out);
}

void att_can_encode_diag_bus(const att_can_bus_diag_t *d, uint8_t counter, att_can_frame_t *out)
{
    struct att_can_db_att_diag_bus_t m;
    if (d == NULL || out == NULL) {
        return;
    }
    m.crc = 0u;
    m.counter = att_can_c4(counter);
    m.state = (uint8_t)(d->state & 0x03u);
    m.bus_off = att_can_sat8(d->bus_off);
    m.recoveries = att_can_sat8(d->recoveries);
    m.error_passive = att_can_sat8(d->error_passive);
    m.error_warning = att_can_sat8(d->error_warning);
    m.rx_overruns = att_can_sat8(d->rx_overruns);
    m.lec = (uint8_t)(d->lec & 0x07u);
    att_can_frame_start(out, ATT_CAN_ID_DIAG_BUS);
    (void)att_can_db_att_diag_bus_pack(out->data, &m, sizeof out->data);
    att_can_seal(out);
}

bool att_can_decode_diag_bus(const att_can_frame_t *f, att_can_bus_diag_t *d)
{
    struct att_can_db_att_diag_bus_t m;
    if (f == NULL || d == NULL || f->id != ATT_CAN_ID_DIAG_BUS || f->len < (uint8_t)ATT_CAN_CLASSIC_LEN) {
        return false;
    }
    (void)att_can_db_att_diag_bus_unpack(&m, f->data, ATT_CAN_CLASSIC_LEN);
    d->state = m.state;
    d->lec = m.lec;
    d->bus_off = m.bus_off;
    d->recoveries = m.recoveries;
    d->error_passive = m.error_passive;
    d->error_warning = m.error_warning;
    d->rx_overruns = m.rx_overruns;
    return true;
}

void att_can_encode_mag_offset(const att_mag_offset_t *h, uint8_t counter, att_can_frame_t *out)
{
    struct att_can_db_att_mag_offset_t m;
    if (h == NULL || out == NULL) {
        return;
    }
    m.crc = 0u;
    m.counter = att_can_c4(counter);
    m.estimated = h->estimated ? 1u : 0u;
    m.off_x = att_can_quantise(h->offset.x, ATT_CAN_MAG_FRAC);
    m.off_y = att_can_quantise(h->offset.y, ATT_CAN_MAG_FRAC);
    m.off_z = att_can_quantise(h->offset.z, ATT_CAN_MAG_FRAC);
    att_can_frame_start(out, ATT_CAN_ID_MAG_OFFSET);
    (void)att_can_db_att_mag_offset_pack(out->data, &m, sizeof out->data);
    att_can_seal(out);
}

bool att_can_decode_mag_offset(const att_can_frame_t *f, att_mag_offset_t *h)
{
    struct att_can_db_att_mag_offset_t m;
    if (f == NULL || h == NULL || f->id != ATT_CAN_ID_MAG_OFFSET || f->len < (uint8_t)ATT_CAN_CLASSIC_LEN) {
        return false;
    }
    (void)att_can_db_att_mag_offset_unpack(&m, f->data, ATT_CAN_CLASSIC_LEN);
    h->offset = att_can_vec3_dq(m.off_x, m.off_y, m.off_z, ATT_CAN_MAG_FRAC);
    h->on = true;
    h->estimated = m.estimated != 0u;
    return true;
}

void att_can_encode_cmd(const att_can_cmd_t *c, att_can_frame_t *out)
{
    struct att_can_db_cmd_t m;
    if (c == NULL || out == NULL) {
        return;
    }
    m.crc = 0u;
    m.counter = att_can_c4(c->counter);
    m.cmd = c->cmd;
    m.arg = c->arg;
    m.value = c->value;
    att_can_frame_start(out, ATT_CAN_ID_CMD);
    (void)att_can_db_cmd_pack(out->data, &m, sizeof out->data);
    att_can_seal(out);
}

bool att_can_decode_cmd(const att_can_frame_t *f, att_can_cmd_t *c)
{
    struct att_can_db_cmd_t m;
    if (f == NULL || c == NULL || f->id != ATT_CAN_ID_CMD || f->len < (uint8_t)ATT_CAN_CLASSIC_LEN) {
        return false;
    }
    (void)att_can_db_cmd_unpack(&m, f->data, ATT_CAN_CLASSIC_LEN);
    c->counter = m.counter;
    c->cmd = m.cmd;
    c->arg = m.arg;
    c->value = m.value;
    return true;
}

bool att_can_decode_output(const att_can_frame_t *f, att_output_t *o)
{
    if (f == NULL || o == NULL || f->len != att_can_msg_len(f->id)) {
        return false;
    }
    switch (f->id) {
    case ATT_CAN_ID_QUAT_A: {
        struct att_can_db_att_quat_a_t m;
        (void)att_can_db_att_quat_a_unpack(&m, f->data, ATT_CAN_CLASSIC_LEN);
        o->q.w = m.q_w;
        o->q.x = m.q_x;
        return true;
    }
    case ATT_CAN_ID_QUAT_B: {
        struct att_can_db_att_quat_b_t m;
        (void)att_can_db_att_quat_b_unpack(&m, f->data, ATT_CAN_CLASSIC_LEN);
        o->q.y = m.q_y;
        o->q.z = m.q_z;
        return true;
    }
    case ATT_CAN_ID_EULER: {
        struct att_can_db_att_euler_t m;
        (void)att_can_db_att_euler_unpack(&m, f->data, ATT_CAN_CLASSIC_LEN);
        o->euler = att_can_vec3_dq(m.roll, m.pitch, m.yaw, ATT_CAN_EULER_FRAC);
        return true;
    }
    case ATT_CAN_ID_BIAS: {
        struct att_can_db_att_bias_t m;
        (void)att_can_db_att_bias_unpack(&m, f->data, ATT_CAN_CLASSIC_LEN);
        o->gyro_bias = att_can_vec3_dq(m.bias_x, m.bias_y, m.bias_z, ATT_CAN_BIAS_FRAC);
        return true;
    }
    case ATT_CAN_ID_STATUS: {
        struct att_can_db_att_status_t m;
        (void)att_can_db_att_status_unpack(&m, f->data, ATT_CAN_CLASSIC_LEN);
        o->flags = m.flags;
        o->steps = m.steps;
        return true;
    }
    case ATT_CAN_ID_OUT_FD: {
        struct att_can_db_att_out_fd_t m;
        (void)att_can_db_att_out_fd_unpack(&m, f->data, ATT_CAN_FD_LEN);
        o->q.w = m.q_w;
        o->q.x = m.q_x;
        o->q.y = m.q_y;
        o->q.z = m.q_z;
        o->euler.x = m.roll;
        o->euler.y = m.pitch;
        o->euler.z = m.yaw;
        o->gyro_bias.x = m.bias_x;
        o->gyro_bias.y = m.bias_y;
        o->gyro_bias.z = m.bias_z;
        o->cov[0] = m.cov_0;
        o->cov[1] = m.cov_1;
        o->cov[2] = m.cov_2;
        o->cov[3] = m.cov_3;
        o->flags = m.flags;
        o->steps = m.steps;
        return true;
    }
    default:
        return false;
    }
}

void att_can_encode_accel(const att_accel_t *a, uint8_t counter, att_can_frame_t out[2])
{
    struct att_can_db_att_lin_acc_t l;
    struct att_can_db_att_earth_acc_t e;
    if (a == NULL || out == NULL) {
        return;
    }
    l.crc = 0u;
    l.counter = att_can_c4(counter);
    l.lin_x = att_can_quantise(a->linear.x, ATT_CAN_ACC_FRAC);
    l.lin_y = att_can_quantise(a->linear.y, ATT_CAN_ACC_FRAC);
    l.lin_z = att_can_quantise(a->linear.z, ATT_CAN_ACC_FRAC);
    att_can_frame_start(&out[0], ATT_CAN_ID_LIN_ACC);
    (void)att_can_db_att_lin_acc_pack(out[0].data, &l, sizeof out[0].data);
    att_can_seal(&out[0]);
    e.crc = 0u;
    e.counter = att_can_c4(counter);
    e.earth_x = att_can_quantise(a->earth.x, ATT_CAN_ACC_FRAC);
    e.earth_y = att_can_quantise(a->earth.y, ATT_CAN_ACC_FRAC);
    e.earth_z = att_can_quantise(a->earth.z, ATT_CAN_ACC_FRAC);
    att_can_frame_start(&out[1], ATT_CAN_ID_EARTH_ACC);
    (void)att_can_db_att_earth_acc_pack(out[1].data, &e, sizeof out[1].data);
    att_can_seal(&out[1]);
}

void att_can_encode_accel_fd(const att_accel_t *a, uint8_t counter, att_can_frame_t *out)
{
    struct att_can_db_att_accel_fd_t m;
    if (a == NULL || out == NULL) {
        return;
    }
    m.crc = 0u;
    m.counter = att_can_c4(counter);
    m.valid = (a->valid == (uint32_t)ATT_OUT_ACCEL) ? 1u : 0u;
    m.grav_x = a->gravity.x;
    m.grav_y = a->gravity.y;
    m.grav_z = a->gravity.z;
    m.lin_x = a->linear.x;
    m.lin_y = a->linear.y;
    m.lin_z = a->linear.z;
    m.earth_x = a->earth.x;
    m.earth_y = a->earth.y;
    m.earth_z = a->earth.z;
    att_can_frame_start(out, ATT_CAN_ID_ACCEL_FD);
    (void)att_can_db_att_accel_fd_pack(out->data, &m, sizeof out->data);
    att_can_seal(out);
}

bool att_can_decode_accel_fd(const att_can_frame_t *f, att_accel_t *out)
{
    struct att_can_db_att_accel_fd_t m;
    if (f == NULL || out == NULL || f->id != ATT_CAN_ID_ACCEL_FD || f->len != (uint8_t)ATT_CAN_FD_LEN) {
        return false;
    }
    if (att_can_db_att_accel_fd_unpack(&m, f->data, ATT_CAN_FD_LEN) != 0) {
        return false;
    }
    out->gravity.x = m.grav_x;
    out->gravity.y = m.grav_y;
    out->gravity.z = m.grav_z;
    out->linear.x = m.lin_x;
    out->linear.y = m.lin_y;
    out->linear.z = m.lin_z;
    out->earth.x = m.earth_x;
    out->earth.y = m.earth_y;
    out->earth.z = m.earth_z;
    out->valid = (m.valid == 1u) ? (uint32_t)ATT_OUT_ACCEL : 0u;
    return true;
}

bool att_can_decode_accel_part(const att_can_frame_t *f, att_vec3_t *v)
{
    if (f == NULL || v == NULL || f->len != (uint8_t)ATT_CAN_CLASSIC_LEN) {
        return false;
    }
    if (f->id == ATT_CAN_ID_LIN_ACC) {
        struct att_can_db_att_lin_acc_t l;
        (void)att_can_db_att_lin_acc_unpack(&l, f->data, ATT_CAN_CLASSIC_LEN);
        v->x = att_can_dequantise(l.lin_x, ATT_CAN_ACC_FRAC);
        v->y = att_can_dequantise(l.lin_y, ATT_CAN_ACC_FRAC);
        v->z = att_can_dequantise(l.lin_z, ATT_CAN_ACC_FRAC);
        return true;
    }
    if (f->id == ATT_CAN_ID_EARTH_ACC) {
        struct att_can_db_att_earth_acc_t e;
        (void)att_can_db_att_earth_acc_unpack(&e, f->data, ATT_CAN_CLASSIC_LEN);
        v->x = att_can_dequantise(e.earth_x, ATT_CAN_ACC_FRAC);
        v->y = att_can_dequantise(e.earth_y, ATT_CAN_ACC_FRAC);
        v->z = att_can_dequantise(e.earth_z, ATT_CAN_ACC_FRAC);
        return true;
    }
    return false;
}

void att_can_encode_cal_ack(const att_can_cal_ack_t *a, att_can_frame_t *out)
{
    struct att_can_db_att_cal_ack_t m;
    if (a == NULL || out == NULL) {
        return;
    }
    m.crc = 0u;
    m.counter = att_can_c4(a->counter);
    m.cmd = a->cmd;
    m.result = a->result;
    m.reason = a->reason;
    m.index = a->index;
    m.persisted = a->persisted;
    m.session = a->session;
    att_can_frame_start(out, ATT_CAN_ID_CAL_ACK);
    (void)att_can_db_att_cal_ack_pack(out->data, &m, sizeof out->data);
    att_can_seal(out);
}

bool att_can_decode_cal_ack(const att_can_frame_t *f, att_can_cal_ack_t *out)
{
    struct att_can_db_att_cal_ack_t m;
    if (f == NULL || out == NULL || f->id != ATT_CAN_ID_CAL_ACK || f->len != (uint8_t)ATT_CAN_CLASSIC_LEN) {
        return false;
    }
    (void)att_can_db_att_cal_ack_unpack(&m, f->data, ATT_CAN_CLASSIC_LEN);
    out->counter = m.counter;
    out->cmd = m.cmd;
    out->result = m.result;
    out->reason = m.reason;
    out->index = m.index;
    out->persisted = m.persisted;
    out->session = m.session;
    return true;
}
