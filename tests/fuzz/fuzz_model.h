/**
 * @file fuzz_model.h
 * @brief An independent model of the attica frame table and E2E CRC (table-driven CRC-8 J1850, not the
 * codec's bitwise loop), used by the fuzz targets to predict att_can_check and the node's counters.
 */
#ifndef ATT_FUZZ_MODEL_H
#define ATT_FUZZ_MODEL_H

#include <stdbool.h>
#include <stdint.h>

#include "attica/att_can.h"

/* --- independent model ------------------------------------------------------------------------ */

static uint8_t crc_table[256];

static inline void crc_table_init(void)
{
    unsigned i;
    unsigned b;
    for (i = 0; i < 256u; ++i) {
        unsigned c = i;
        for (b = 0; b < 8u; ++b) {
            c = (c & 0x80u) ? ((c << 1) ^ 0x1Du) & 0xFFu : (c << 1) & 0xFFu;
        }
        crc_table[i] = (uint8_t)c;
    }
}

static inline uint8_t model_crc(uint32_t id, const uint8_t *data, size_t len)
{
    uint8_t c = 0xFFu;
    uint16_t did = (uint16_t)(0x0A00u + (id & 0x7FFu));
    size_t i;
    c = crc_table[c ^ (uint8_t)(did & 0xFFu)];
    c = crc_table[c ^ (uint8_t)(did >> 8)];
    for (i = 1; i < len; ++i) {
        c = crc_table[c ^ data[i]];
    }
    return (uint8_t)(c ^ 0xFFu);
}

static inline unsigned model_len(uint32_t id)
{
    switch (id) {
    case 0x100: case 0x101: case 0x102: case 0x200: case 0x201: case 0x202: case 0x203: case 0x204:
    case 0x205: case 0x206: case 0x207: case 0x208: case 0x209: case 0x20A: case 0x20B: case 0x300:
        return 8u;
    case 0x110: case 0x210: case 0x211:
        return 64u;
    default:
        return 0u;
    }
}

static inline bool model_has_crc(uint32_t id)
{
    return model_len(id) != 0u && id != 0x200u && id != 0x201u && id != 0x202u;
}

static inline att_can_check_t model_check(const att_can_frame_t *f)
{
    unsigned want = model_len(f->id);
    if (want == 0u) {
        return ATT_CAN_ERR_UNKNOWN_ID;
    }
    if (f->len != want || f->fd != (want == 64u ? 1u : 0u)) {
        return ATT_CAN_ERR_DLC;
    }
    if (!model_has_crc(f->id) || (f->id == 0x205u && (f->data[7] & 0x80u) == 0u)) {
        return ATT_CAN_OK;
    }
    return model_crc(f->id, f->data, f->len) == f->data[0] ? ATT_CAN_OK : ATT_CAN_ERR_CRC;
}

#endif /* ATT_FUZZ_MODEL_H */
