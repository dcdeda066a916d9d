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
    /* the node's outputs with ATT_DIAG_BUS must fit the bus (nothing written to the controller yet) */
    if (att_node_set_bus_diag(node, att_can_hal_bus_diag, h) != ATT_OK) {
        return ATT_ERR_SETTINGS;
    }
    memset(h, 0, sizeof *h);
    h->io = io;
    h->node = node;
    h->btr = btr;
    h->phase = ATT_CAN_HAL_ON;
    h->backoff = ATT_CAN_HAL_BACKOFF_FIRST;
    /* wake up, enter initialisation mode */
    att_wr(h, ATT_BXCAN_MCR, (att_rd(h, ATT_BXCAN_MCR) & ~ATT_BXCAN_MCR_SLEEP) | ATT_BXCAN_MCR_INRQ);
    if (!att_wait_msr(h, ATT_BXCAN_MSR_INAK | ATT_BXCAN_MSR_SLAK, ATT_BXCAN_MSR_INAK)) {
        (void)att_node_set_bus_diag(node, NULL, NULL);
        return ATT_ERR_SETTINGS;
    }
    /* ABOM clear: a bus-off lasts until the driver recovers (att_can_hal_service, after a back-off) */
    att_wr(h, ATT_BXCAN_MCR, ATT_BXCAN_MCR_INRQ | ATT_BXCAN_MCR_TXFP);
    att_wr(h, ATT_BXCAN_BTR, btr);
    att_wr(h, ATT_BXCAN_IER, 0u); /* polled; enable FMPIE0 (bit 1) yourself to be woken by frames */
    att_filter_banks(h, ids, n_ids);
    /* leave initialisation mode: normal operation once 11 recessive bits were seen on the bus */
    att_wr(h, ATT_BXCAN_MCR, ATT_BXCAN_MCR_TXFP);
    if (!att_wait_msr(h, ATT_BXCAN_MSR_INAK, 0u)) {
        (void)att_node_set_bus_diag(node, NULL, NULL);
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
    /* RFxR.FOVRx (bit 4, rc_w1): a frame arrived at a full FIFO and was lost (RM0090 32.7.5, 32.9.2) */
    rf = att_rd(h, ATT_BXCAN_RF0R);
    if ((rf & ATT_BXCAN_RF0R_FOVR0) != 0u) {
        h->stats.rx_overruns++;
        att_wr(h, ATT_BXCAN_RF0R, ATT_BXCAN_RF0R_FOVR0); /* write 1 to clear */
    }
    if ((att_rd(h, ATT_BXCAN_RF1R) & ATT_BXCAN_RF0R_FOVR0) != 0u) {
        h->stats.rx_overruns++;
        att_wr(h, ATT_BXCAN_RF1R, ATT_BXCAN_RF0R_FOVR0); /* FOVR1: same bit, write 1 to clear */
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
    if (h == NULL || h->node == NULL || h->phase != ATT_CAN_HAL_ON) {
        return 0u; /* bus-off: the frames wait in the node until the controller is back on the bus */
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

/*
 * Bus-off recovery with ABOM clear (RM0090 32.7.6, error management): software starts it by taking the
 * controller into initialisation mode and out again; the controller then still waits for 128
 * occurrences of 11 recessive bits before it leaves bus-off (ESR.BOFF clear, error-active). Enter:
 * MCR.INRQ (bit 0) set, MSR.INAK (bit 0) acknowledges; leave: INRQ clear. The bit timing and the
 * filters are kept (initialisation mode does not reset them). False when INAK did not come within
 * ATT_CAN_HAL_SPIN reads (INRQ is then left set: the next attempt sets it again).
 */
static bool att_recover(const att_can_hal_t *h)
{
    att_wr(h, ATT_BXCAN_MCR, ATT_BXCAN_MCR_INRQ | ATT_BXCAN_MCR_TXFP);
    if (!att_wait_msr(h, ATT_BXCAN_MSR_INAK, ATT_BXCAN_MSR_INAK)) {
        return false;
    }
    att_wr(h, ATT_BXCAN_MCR, ATT_BXCAN_MCR_TXFP);
    return true;
}

/*
 * Abort what the mailboxes still hold (RM0090 32.9.2, CAN_TSR: ABRQ0/1/2 at bits 7, 15, 23, set by
 * software, cleared by hardware once the mailbox is empty, no effect on an empty mailbox; TME0/1/2 at
 * bits 26..28). With nothing pending the controller cannot transmit, so cannot go bus-off again, until
 * the driver sees it back on the bus and fills the mailboxes.
 */
static void att_abort_mailboxes(att_can_hal_t *h)
{
    const uint32_t tsr = att_rd(h, ATT_BXCAN_TSR);
    uint32_t abrq = 0u;
    uint32_t box;
    for (box = 0u; box < ATT_BXCAN_MAILBOXES; box++) {
        if ((tsr & (ATT_BXCAN_TSR_TME0 << box)) == 0u) {
            abrq |= ATT_BXCAN_TSR_ABRQ0 << (8u * box);
            h->stats.tx_aborted++;
        }
    }
    if (abrq != 0u) {
        att_wr(h, ATT_BXCAN_TSR, abrq); /* the rc_w1 status bits written 0: unchanged */
    }
}

/* Wait h->backoff service calls before the next recovery, and double it for the one after (to MAX). */
static void att_backoff(att_can_hal_t *h)
{
    h->phase = ATT_CAN_HAL_BACKOFF;
    h->wait = h->backoff;
    h->backoff = (h->backoff > ATT_CAN_HAL_BACKOFF_MAX / 2u) ? ATT_CAN_HAL_BACKOFF_MAX : 2u * h->backoff;
    h->good = 0u;
}

/*
 * The controller's fault confinement state from ESR (RM0090 32.9.2, CAN_ESR at 0x18): EWGF bit 0 (TEC
 * or REC >= 96), EPVF bit 1 (> 127), BOFF bit 2 (TEC > 255), LEC bits 6:4 (0 no error, 1 stuff, 2 form,
 * 3 acknowledgment, 4 bit recessive, 5 bit dominant, 6 CRC, 7 set by software); all read only but LEC.
 */
static void att_faults(att_can_hal_t *h)
{
    const uint32_t esr = att_rd(h, ATT_BXCAN_ESR);
    const bool off = (esr & ATT_BXCAN_ESR_BOFF) != 0u;
    const bool passive = (esr & ATT_BXCAN_ESR_EPVF) != 0u;
    const bool warning = (esr & ATT_BXCAN_ESR_EWGF) != 0u;
    const uint32_t lec = (esr >> ATT_BXCAN_ESR_LEC_SHIFT) & 7u;
    if (lec != 0u && lec != 7u) {
        h->stats.lec = lec;
    }
    h->stats.error_passive += (passive && !h->passive) ? 1u : 0u;
    h->stats.error_warning += (warning && !h->warning) ? 1u : 0u;
    h->passive = passive;
    h->warning = warning;
    switch (h->phase) {
    case ATT_CAN_HAL_ON:
        if (off) {
            h->stats.bus_off++;
            att_abort_mailboxes(h);
            att_backoff(h);
        } else if (passive) {
            h->good = 0u;
        } else if (h->good < ATT_CAN_HAL_BACKOFF_RESET) {
            h->good++;
            if (h->good == ATT_CAN_HAL_BACKOFF_RESET) {
                h->backoff = ATT_CAN_HAL_BACKOFF_FIRST; /* a good while on the bus: start over */
            }
        }
        break;
    case ATT_CAN_HAL_BACKOFF:
        if (!off) { /* left bus-off without the driver (someone else re-initialised it) */
            h->stats.recoveries++;
            h->phase = ATT_CAN_HAL_ON;
        } else if (h->wait > 1u) {
            h->wait--;
        } else if (att_recover(h)) {
            h->phase = ATT_CAN_HAL_RECOVERING;
        } else {
            h->stats.recovery_timeouts++;
            att_backoff(h);
        }
        break;
    default: /* ATT_CAN_HAL_RECOVERING */
        if (!off) {
            h->stats.recoveries++;
            h->phase = ATT_CAN_HAL_ON;
        }
        break;
    }
}

void att_can_hal_bus_diag(void *ctx, att_can_bus_diag_t *d)
{
    const att_can_hal_t *h = (const att_can_hal_t *)ctx;
    if (h == NULL || d == NULL) {
        return;
    }
    if (h->phase != ATT_CAN_HAL_ON) {
        d->state = (uint8_t)ATT_CAN_BUS_OFF;
    } else if (h->passive) {
        d->state = (uint8_t)ATT_CAN_BUS_PASSIVE;
    } else {
        d->state = (uint8_t)(h->warning ? ATT_CAN_BUS_WARNING : ATT_CAN_BUS_ACTIVE);
    }
    d->lec = (uint8_t)h->stats.lec;
    d->bus_off = h->stats.bus_off;
    d->recoveries = h->stats.recoveries;
    d->error_passive = h->stats.error_passive;
    d->error_warning = h->stats.error_warning;
    d->rx_overruns = h->stats.rx_overruns;
}

size_t att_can_hal_service(att_can_hal_t *h)
{
    size_t steps;
    if (h == NULL || h->node == NULL) {
        return 0u;
    }
    att_faults(h);
    (void)att_can_hal_receive(h);
    steps = att_node_poll(h->node);
    (void)att_can_hal_transmit(h);
    return steps;
}
