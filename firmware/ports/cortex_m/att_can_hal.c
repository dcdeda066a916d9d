/**
 * @file att_can_hal.c
 * @brief bxCAN HAL of the attica node (see att_can_hal.h).
 */
#include "att_can_hal.h"

#include <string.h>

#define ATT_BXCAN_MAILBOXES 3u
#define ATT_BXCAN_MAILBOX_STRIDE 0x10u
#define ATT_BXCAN_TQ_MIN 8u
#define ATT_BXCAN_TQ_MAX 25u
#define ATT_BXCAN_BRP_MAX 1024u
#define ATT_BXCAN_TS1_MAX 16u
#define ATT_BXCAN_TS2_MAX 8u

static uint32_t att_mmio_read(void *ctx, uint32_t offset)
{
    return *(volatile uint32_t *)((uintptr_t)ctx + offset);
}

static void att_mmio_write(void *ctx, uint32_t offset, uint32_t value)
{
    *(volatile uint32_t *)((uintptr_t)ctx + offset) = value;
}

att_can_hal_io_t att_can_hal_mmio(void *base)
{
    att_can_hal_io_t io;
    io.ctx = base;
    io.read = att_mmio_read;
    io.write = att_mmio_write;
    return io;
}

static uint32_t att_rd(const att_can_hal_t *h, uint32_t offset) { return h->io.read(h->io.ctx, offset); }

static void att_wr(const att_can_hal_t *h, uint32_t offset, uint32_t value) { h->io.write(h->io.ctx, offset, value); }

/* Wait until (MSR & mask) == want; false after ATT_CAN_HAL_SPIN reads. */
static bool att_wait_msr(const att_can_hal_t *h, uint32_t mask, uint32_t want)
{
    uint32_t i;
    for (i = 0u; i < ATT_CAN_HAL_SPIN; i++) {
        if ((att_rd(h, ATT_BXCAN_MSR) & mask) == want) {
            return true;
        }
    }
    return false;
}

uint32_t att_can_hal_btr(uint32_t pclk_hz, uint32_t bitrate)
{
    uint32_t tq;
    if (bitrate == 0u) {
        return 0u;
    }
    for (tq = ATT_BXCAN_TQ_MAX; tq >= ATT_BXCAN_TQ_MIN; tq--) {
        const uint32_t per_bit = bitrate * tq;
        uint32_t brp;
        uint32_t ts1;
        uint32_t ts2;
        if (per_bit / tq != bitrate || pclk_hz % per_bit != 0u) {
            continue;
        }
        brp = pclk_hz / per_bit;
        /* sample point after 1 (sync) + ts1 quanta = 87.5 % of the bit, rounded */
        ts1 = (tq * 7u + 4u) / 8u - 1u;
        ts2 = tq - 1u - ts1;
        if (brp < 1u || brp > ATT_BXCAN_BRP_MAX || ts1 < 1u || ts1 > ATT_BXCAN_TS1_MAX || ts2 < 1u ||
            ts2 > ATT_BXCAN_TS2_MAX) {
            continue;
        }
        /* SJW = 1 tq (field 0), TS2 - 1 at bit 20, TS1 - 1 at bit 16, BRP - 1 at bit 0 */
        return ((ts2 - 1u) << 20) | ((ts1 - 1u) << 16) | (brp - 1u);
    }
    return 0u;
}

/*
 * Acceptance filter (RM0090 32.7.4): banks 0 .. ATT_CAN_HAL_FILTER_BANKS - 1 in 16-bit identifier list
 * mode (FM1R bit = 1, FS1R bit = 0), assigned to FIFO 0 (FFA1R bit = 0). A 16-bit filter holds
 * STID[10:0] << 5 | RTR << 4 | IDE << 3 | EXID[17:15]; a standard data frame of identifier id matches
 * the entry id << 5 exactly (RTR 0, IDE 0, EXID 0: remote and extended frames never match). A bank
 * holds four entries: FxR1 = e0 | e1 << 16, FxR2 = e2 | e3 << 16. The node's n IDs fill
 * ceil(n / 4) banks in order; the free entries of the last bank repeat its first ID (a duplicate
 * changes nothing). Banks not needed are deactivated. Frames that match no active filter are dropped
 * by the controller: they never reach FIFO 0.
 */
static void att_filter_banks(const att_can_hal_t *h, const uint32_t *ids, size_t n_ids)
{
    uint32_t bank;
    uint32_t mine = 0u;
    uint32_t used = 0u;
    for (bank = 0u; bank < ATT_CAN_HAL_FILTER_BANKS; bank++) {
        mine |= (uint32_t)1u << bank;
        if ((size_t)bank * 4u < n_ids) {
            used |= (uint32_t)1u << bank;
        }
    }
    att_wr(h, ATT_BXCAN_FMR, att_rd(h, ATT_BXCAN_FMR) | ATT_BXCAN_FMR_FINIT);
    att_wr(h, ATT_BXCAN_FA1R, att_rd(h, ATT_BXCAN_FA1R) & ~mine);
    att_wr(h, ATT_BXCAN_FM1R, att_rd(h, ATT_BXCAN_FM1R) | mine);
    att_wr(h, ATT_BXCAN_FS1R, att_rd(h, ATT_BXCAN_FS1R) & ~mine);
    att_wr(h, ATT_BXCAN_FFA1R, att_rd(h, ATT_BXCAN_FFA1R) & ~mine);
    for (bank = 0u; bank < ATT_CAN_HAL_FILTER_BANKS; bank++) {
        uint32_t e[4];
        uint32_t k;
        const size_t first = (size_t)bank * 4u;
        if (first >= n_ids) {
            e[0] = e[1] = e[2] = e[3] = 0u;
        } else {
            for (k = 0u; k < 4u; k++) {
                const size_t j = (first + k < n_ids) ? first + k : first;
                e[k] = (ids[j] & 0x7ffu) << 5;
            }
        }
        att_wr(h, ATT_BXCAN_F0R1 + ATT_BXCAN_BANK_STRIDE * bank, e[0] | (e[1] << 16));
        att_wr(h, ATT_BXCAN_F0R2 + ATT_BXCAN_BANK_STRIDE * bank, e[2] | (e[3] << 16));
    }
    att_wr(h, ATT_BXCAN_FA1R, att_rd(h, ATT_BXCAN_FA1R) | used);
    att_wr(h, ATT_BXCAN_FMR, att_rd(h, ATT_BXCAN_FMR) & ~ATT_BXCAN_FMR_FINIT);
}

att_status_t att_can_hal_init(att_can_hal_t *h, att_can_hal_io_t io, att_node_t *node, uint32_t pclk_hz)
{
    uint32_t btr;
    uint32_t ids[ATT_NODE_RX_IDS_MAX];
    size_t n_ids;
    size_t i;
    if (h == NULL || node == NULL || io.read == NULL || io.write == NULL) {
        return ATT_ERR_NULL;
    }
    btr = att_can_hal_btr(pclk_hz, node->s.bitrate);
    if (node->s.fd || btr == 0u) {
        return ATT_ERR_SETTINGS;
    }
    n_ids = att_node_rx_ids(node, ids);
    if (n_ids == 0u || n_ids > (size_t)4u * ATT_CAN_HAL_FILTER_BANKS) {
        return ATT_ERR_SETTINGS;
    }
    for (i = 0u; i < n_ids; i++) {
        if (ids[i] > 0x7ffu) {
            return ATT_ERR_SETTINGS;
        }
    }
    memset(h, 0, sizeof *h);
    h->io = io;
    h->node = node;
    h->btr = btr;
    /* wake up, enter initialisation mode */
    att_wr(h, ATT_BXCAN_MCR, (att_rd(h, ATT_BXCAN_MCR) & ~ATT_BXCAN_MCR_SLEEP) | ATT_BXCAN_MCR_INRQ);
    if (!att_wait_msr(h, ATT_BXCAN_MSR_INAK | ATT_BXCAN_MSR_SLAK, ATT_BXCAN_MSR_INAK)) {
        return ATT_ERR_SETTINGS;
    }
    att_wr(h, ATT_BXCAN_MCR, ATT_BXCAN_MCR_INRQ | ATT_BXCAN_MCR_ABOM | ATT_BXCAN_MCR_TXFP);
    att_wr(h, ATT_BXCAN_BTR, btr);
    att_wr(h, ATT_BXCAN_IER, 0u); /* polled; enable FMPIE0 (bit 1) yourself to be woken by frames */
    att_filter_banks(h, ids, n_ids);
    /* leave initialisation mode: normal operation once 11 recessive bits were seen on the bus */
    att_wr(h, ATT_BXCAN_MCR, ATT_BXCAN_MCR_ABOM | ATT_BXCAN_MCR_TXFP);
    if (!att_wait_msr(h, ATT_BXCAN_MSR_INAK, 0u)) {
        return ATT_ERR_SETTINGS;
    }
    return ATT_OK;
}

static void att_unpack(uint32_t lo, uint32_t hi, uint8_t *data)
{
    uint32_t i;
    for (i = 0u; i < 4u; i++) {
        data[i] = (uint8_t)((lo >> (8u * i)) & 0xffu);
        data[4u + i] = (uint8_t)((hi >> (8u * i)) & 0xffu);
    }
}

static uint32_t att_pack(const uint8_t *data)
{
    return (uint32_t)data[0] | ((uint32_t)data[1] << 8) | ((uint32_t)data[2] << 16) | ((uint32_t)data[3] << 24);
}

size_t att_can_hal_receive(att_can_hal_t *h)
{
    size_t moved = 0u;
    uint32_t rf;
    if (h == NULL || h->node == NULL) {
        return 0u;
    }
    rf = att_rd(h, ATT_BXCAN_RF0R);
    if ((rf & ATT_BXCAN_RF0R_FOVR0) != 0u) {
        h->stats.rx_overruns++;
        att_wr(h, ATT_BXCAN_RF0R, ATT_BXCAN_RF0R_FOVR0); /* write 1 to clear */
    }
    while ((att_rd(h, ATT_BXCAN_RF0R) & ATT_BXCAN_RF0R_FMP0) != 0u) {
        const uint32_t rir = att_rd(h, ATT_BXCAN_RI0R);
        const uint32_t rdt = att_rd(h, ATT_BXCAN_RDT0R);
        att_can_frame_t f;
        if ((rir & (ATT_BXCAN_RIR_IDE | ATT_BXCAN_RIR_RTR)) != 0u) {
            h->stats.rx_ignored++;
        } else {
            memset(&f, 0, sizeof f);
            f.id = (rir >> 21) & 0x7ffu;
            f.len = (uint8_t)(((rdt & 0xfu) > 8u) ? 8u : (rdt & 0xfu));
            f.fd = 0u;
            att_unpack(att_rd(h, ATT_BXCAN_RDL0R), att_rd(h, ATT_BXCAN_RDH0R), f.data);
            memset(f.data + f.len, 0, sizeof f.data - f.len);
            if (att_node_rx(h->node, &f)) {
                h->stats.rx_frames++;
                moved++;
            } else {
                h->stats.rx_node_full++;
            }
        }
        att_wr(h, ATT_BXCAN_RF0R, ATT_BXCAN_RF0R_RFOM0); /* release the output mailbox */
    }
    return moved;
}

size_t att_can_hal_transmit(att_can_hal_t *h)
{
    size_t sent = 0u;
    uint32_t box;
    if (h == NULL || h->node == NULL) {
        return 0u;
    }
    for (box = 0u; box < ATT_BXCAN_MAILBOXES; box++) {
        att_can_frame_t f;
        const uint32_t base = box * ATT_BXCAN_MAILBOX_STRIDE;
        if ((att_rd(h, ATT_BXCAN_TSR) & (ATT_BXCAN_TSR_TME0 << box)) == 0u) {
            continue; /* mailbox busy */
        }
        for (;;) {
            if (!att_node_tx(h->node, &f)) {
                return sent;
            }
            if (f.fd == 0u && f.len <= 8u && f.id <= 0x7ffu) {
                break;
            }
            h->stats.tx_unsupported++;
        }
        att_wr(h, ATT_BXCAN_TI0R + base, f.id << 21); /* standard ID, data frame, TXRQ clear */
        att_wr(h, ATT_BXCAN_TDT0R + base, f.len);
        att_wr(h, ATT_BXCAN_TDL0R + base, att_pack(f.data));
        att_wr(h, ATT_BXCAN_TDH0R + base, att_pack(f.data + 4));
        att_wr(h, ATT_BXCAN_TI0R + base, (f.id << 21) | ATT_BXCAN_TIR_TXRQ);
        h->stats.tx_frames++;
        sent++;
    }
    return sent;
}

size_t att_can_hal_service(att_can_hal_t *h)
{
    size_t steps;
    bool off;
    if (h == NULL || h->node == NULL) {
        return 0u;
    }
    off = (att_rd(h, ATT_BXCAN_ESR) & ATT_BXCAN_ESR_BOFF) != 0u;
    if (off && !h->was_bus_off) {
        h->stats.bus_off++;
    }
    h->was_bus_off = off;
    (void)att_can_hal_receive(h);
    steps = att_node_poll(h->node);
    (void)att_can_hal_transmit(h);
    return steps;
}
