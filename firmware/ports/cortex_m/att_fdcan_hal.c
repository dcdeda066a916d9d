/**
 * @file att_fdcan_hal.c
 * @brief FDCAN / M_CAN HAL of the attica node (see att_fdcan_hal.h).
 */
#include "att_fdcan_hal.h"

#include <string.h>

#define ATT_G4_RAM_BYTES 0x350u /* message RAM of one G0/G4 instance */
#define ATT_ELEMENT_HEADER 8u   /* two header words before the data of an Rx / Tx element */

/* Nominal phase (NBTP): prescaler 1..512, TSEG1 2..256, TSEG2 1..128, SJW 1..128 quanta. */
#define ATT_N_BRP_MAX 512u
#define ATT_N_TQ_MIN 8u
#define ATT_N_TQ_MAX 385u
#define ATT_N_TSEG1_MIN 2u
#define ATT_N_TSEG1_MAX 256u
#define ATT_N_TSEG2_MAX 128u
/* Data phase (DBTP): prescaler 1..32, TSEG1 1..32, TSEG2 1..16, SJW 1..16 quanta. */
#define ATT_D_BRP_MAX 32u
#define ATT_D_BRP_MAX_TDC 2u  /* transmitter delay compensation works with DBRP 1 or 2 only */
#define ATT_D_TQ_MIN 5u
#define ATT_D_TQ_MAX 49u
#define ATT_D_TSEG1_MAX 32u
#define ATT_D_TSEG2_MAX 16u
#define ATT_TDC_ABOVE 1000000u /* data bitrates above this use TDC */
#define ATT_TDCO_MAX 127u

const att_fdcan_layout_t att_fdcan_layout_g4 = {
    ATT_FDCAN_G4, /* variant */
    0x000u,       /* 28 standard filter elements */
    28u,
    0x0B0u, /* Rx FIFO 0: 3 elements of 18 words */
    3u,
    0x278u, /* 3 Tx buffers of 18 words */
    3u,
    64u,
};

/* Register offsets that differ between the two maps. */
typedef struct {
    uint32_t rxf0s;
    uint32_t rxf0a;
    uint32_t txbar;
    uint32_t ir_lost; /* IR: Rx FIFO 0 and Rx FIFO 1 message lost (RF0L | RF1L) */
    uint32_t ir_rf0l; /* IR: Rx FIFO 0 message lost */
    uint32_t ir_all;  /* IR: every flag the map defines */
} att_fdcan_map_t;

static const att_fdcan_map_t att_map_g4 = {ATT_FDCAN_G4_RXF0S, ATT_FDCAN_G4_RXF0A, ATT_FDCAN_G4_TXBAR,
                                           ATT_FDCAN_G4_IR_RF0L | ATT_FDCAN_G4_IR_RF1L, ATT_FDCAN_G4_IR_RF0L,
                                           0x00ffffffu};
static const att_fdcan_map_t att_map_h7 = {ATT_FDCAN_H7_RXF0S, ATT_FDCAN_H7_RXF0A, ATT_FDCAN_H7_TXBAR,
                                           ATT_FDCAN_H7_IR_RF0L | ATT_FDCAN_H7_IR_RF1L, ATT_FDCAN_H7_IR_RF0L,
                                           0x3fffffffu};

static const uint8_t att_dlc_len[16] = {0u, 1u, 2u, 3u, 4u, 5u, 6u, 7u, 8u, 12u, 16u, 20u, 24u, 32u, 48u, 64u};

static uint32_t att_mmio_read(void *ctx, uint32_t offset)
{
    return *(volatile uint32_t *)((uintptr_t)ctx + offset);
}

static void att_mmio_write(void *ctx, uint32_t offset, uint32_t value)
{
    *(volatile uint32_t *)((uintptr_t)ctx + offset) = value;
}

att_fdcan_hal_io_t att_fdcan_hal_mmio(void *base)
{
    att_fdcan_hal_io_t io;
    io.ctx = base;
    io.read = att_mmio_read;
    io.write = att_mmio_write;
    return io;
}

static uint32_t att_rd(const att_fdcan_hal_t *h, uint32_t offset) { return h->regs.read(h->regs.ctx, offset); }

static void att_wr(const att_fdcan_hal_t *h, uint32_t offset, uint32_t value)
{
    h->regs.write(h->regs.ctx, offset, value);
}

static uint32_t att_ram_rd(const att_fdcan_hal_t *h, uint32_t offset) { return h->ram.read(h->ram.ctx, offset); }

static void att_ram_wr(const att_fdcan_hal_t *h, uint32_t offset, uint32_t value)
{
    h->ram.write(h->ram.ctx, offset, value);
}

static const att_fdcan_map_t *att_map(const att_fdcan_hal_t *h)
{
    return (h->layout.variant == ATT_FDCAN_G4) ? &att_map_g4 : &att_map_h7;
}

/* Wait until (CCCR & mask) == want; false after ATT_FDCAN_HAL_SPIN reads. */
static bool att_wait_cccr(const att_fdcan_hal_t *h, uint32_t mask, uint32_t want)
{
    uint32_t i;
    for (i = 0u; i < ATT_FDCAN_HAL_SPIN; i++) {
        if ((att_rd(h, ATT_FDCAN_CCCR) & mask) == want) {
            return true;
        }
    }
    return false;
}

uint32_t att_fdcan_dlc_to_len(uint32_t dlc, bool fd)
{
    if (dlc > 15u) {
        return 0u;
    }
    if (!fd && dlc > 8u) {
        return 8u;
    }
    return att_dlc_len[dlc];
}

uint32_t att_fdcan_len_to_dlc(uint32_t len)
{
    uint32_t dlc;
    for (dlc = 0u; dlc < 15u; dlc++) {
        if (att_dlc_len[dlc] >= len) {
            return dlc;
        }
    }
    return 15u;
}

/* Element data size code of RXESC / TXESC (000 = 8 bytes ... 111 = 64 bytes); 8 for a size without one. */
static uint32_t att_size_code(uint32_t data_bytes)
{
    static const uint8_t sizes[8] = {8u, 12u, 16u, 20u, 24u, 32u, 48u, 64u};
    uint32_t c;
    for (c = 0u; c < 8u; c++) {
        if (sizes[c] == data_bytes) {
            return c;
        }
    }
    return 8u;
}

static uint32_t att_element_bytes(const att_fdcan_layout_t *l) { return ATT_ELEMENT_HEADER + l->data_bytes; }

uint32_t att_fdcan_layout_h7(uint32_t start, uint32_t rx_n, uint32_t tx_n, uint32_t data_bytes,
                             att_fdcan_layout_t *l)
{
    uint32_t end;
    if (l == NULL) {
        return 0u;
    }
    memset(l, 0, sizeof *l);
    l->variant = ATT_FDCAN_H7;
    l->filters = start;
    l->filters_max = ATT_FDCAN_HAL_FILTERS;
    l->rx_fifo0_n = rx_n;
    l->tx_fifo_n = tx_n;
    l->data_bytes = data_bytes;
    if ((start & 3u) != 0u || start >= ATT_FDCAN_H7_RAM_BYTES || rx_n == 0u || rx_n > 64u || tx_n == 0u ||
        tx_n > 32u || att_size_code(data_bytes) > 7u) {
        return 0u;
    }
    l->rx_fifo0 = start + 4u * ATT_FDCAN_HAL_FILTERS;
    l->tx_fifo = l->rx_fifo0 + rx_n * att_element_bytes(l);
    end = l->tx_fifo + tx_n * att_element_bytes(l);
    return (end <= ATT_FDCAN_H7_RAM_BYTES) ? end : 0u;
}

/* [a, a + an) and [b, b + bn) overlap. */
static bool att_overlap(uint32_t a, uint32_t an, uint32_t b, uint32_t bn) { return a < b + bn && b < a + an; }

att_status_t att_fdcan_hal_layout_check(const att_fdcan_layout_t *l)
{
    uint32_t filt_bytes;
    uint32_t rx_bytes;
    uint32_t tx_bytes;
    if (l == NULL) {
        return ATT_ERR_NULL;
    }
    if (l->variant == ATT_FDCAN_G4) {
        const att_fdcan_layout_t *g = &att_fdcan_layout_g4;
        return (l->filters == g->filters && l->filters_max == g->filters_max && l->rx_fifo0 == g->rx_fifo0 &&
                l->rx_fifo0_n == g->rx_fifo0_n && l->tx_fifo == g->tx_fifo && l->tx_fifo_n == g->tx_fifo_n &&
                l->data_bytes == g->data_bytes)
                   ? ATT_OK
                   : ATT_ERR_SETTINGS;
    }
    if (l->variant != ATT_FDCAN_H7 || att_size_code(l->data_bytes) > 7u || l->rx_fifo0_n == 0u ||
        l->rx_fifo0_n > 64u || l->tx_fifo_n == 0u || l->tx_fifo_n > 32u || l->filters_max < ATT_FDCAN_HAL_FILTERS ||
        l->filters_max > 128u || ((l->filters | l->rx_fifo0 | l->tx_fifo) & 3u) != 0u ||
        l->filters >= ATT_FDCAN_H7_RAM_BYTES || l->rx_fifo0 >= ATT_FDCAN_H7_RAM_BYTES ||
        l->tx_fifo >= ATT_FDCAN_H7_RAM_BYTES) {
        return ATT_ERR_SETTINGS;
    }
    filt_bytes = 4u * l->filters_max;
    rx_bytes = l->rx_fifo0_n * att_element_bytes(l);
    tx_bytes = l->tx_fifo_n * att_element_bytes(l);
    if (l->filters + filt_bytes > ATT_FDCAN_H7_RAM_BYTES || l->rx_fifo0 + rx_bytes > ATT_FDCAN_H7_RAM_BYTES ||
        l->tx_fifo + tx_bytes > ATT_FDCAN_H7_RAM_BYTES || att_overlap(l->filters, filt_bytes, l->rx_fifo0, rx_bytes) ||
        att_overlap(l->filters, filt_bytes, l->tx_fifo, tx_bytes) ||
        att_overlap(l->rx_fifo0, rx_bytes, l->tx_fifo, tx_bytes)) {
        return ATT_ERR_SETTINGS;
    }
    return ATT_OK;
}

/*
 * One phase of the bit timing: with prescaler brp, the bit has tq = clk / (brp * rate) quanta (exact),
 * 1 (sync) + tseg1 + tseg2, the sample point after 1 + tseg1 = round(tq * sp_num / sp_den).
 */
typedef struct {
    uint32_t tq_min, tq_max, tseg1_min, tseg1_max, tseg2_max, sp_num, sp_den;
} att_phase_limits_t;

static const att_phase_limits_t att_nominal = {ATT_N_TQ_MIN,   ATT_N_TQ_MAX, ATT_N_TSEG1_MIN, ATT_N_TSEG1_MAX,
                                               ATT_N_TSEG2_MAX, 7u,           8u};
static const att_phase_limits_t att_data = {ATT_D_TQ_MIN, ATT_D_TQ_MAX, 1u, ATT_D_TSEG1_MAX, ATT_D_TSEG2_MAX, 3u, 4u};

static bool att_phase(uint32_t clk, uint32_t rate, uint32_t brp, const att_phase_limits_t *lim, uint32_t *tseg1,
                      uint32_t *tseg2)
{
    uint32_t per;
    uint32_t tq;
    uint32_t t1;
    uint32_t t2;
    if (rate == 0u || brp == 0u) {
        return false;
    }
    per = rate * brp;
    if (per / brp != rate || clk % per != 0u) {
        return false;
    }
    tq = clk / per;
    if (tq < lim->tq_min || tq > lim->tq_max) {
        return false;
    }
    t1 = (tq * lim->sp_num + lim->sp_den / 2u) / lim->sp_den - 1u;
    t2 = tq - 1u - t1;
    if (t1 < lim->tseg1_min || t1 > lim->tseg1_max || t2 < 1u || t2 > lim->tseg2_max) {
        return false;
    }
    *tseg1 = t1;
    *tseg2 = t2;
    return true;
}

/* Smallest nominal prescaler that works (0: none). */
static uint32_t att_nominal_brp(uint32_t clk, uint32_t rate, uint32_t *t1, uint32_t *t2)
{
    uint32_t brp;
    for (brp = 1u; brp <= ATT_N_BRP_MAX; brp++) {
        if (att_phase(clk, rate, brp, &att_nominal, t1, t2)) {
            return brp;
        }
    }
    return 0u;
}

att_status_t att_fdcan_hal_timing(uint32_t kernel_hz, uint32_t bitrate, uint32_t data_bitrate,
                                  att_fdcan_timing_t *t)
{
    uint32_t nbrp = 0u;
    uint32_t n1 = 0u;
    uint32_t n2 = 0u;
    if (t == NULL) {
        return ATT_ERR_NULL;
    }
    memset(t, 0, sizeof *t);
    if (bitrate == 0u || (data_bitrate != 0u && data_bitrate < bitrate)) {
        return ATT_ERR_SETTINGS;
    }
    if (data_bitrate != 0u) {
        const bool tdc = data_bitrate > ATT_TDC_ABOVE;
        const uint32_t dmax = tdc ? ATT_D_BRP_MAX_TDC : ATT_D_BRP_MAX;
        uint32_t dbrp = 0u;
        uint32_t d1 = 0u;
        uint32_t d2 = 0u;
        uint32_t b;
        for (b = 1u; b <= dmax; b++) {
            uint32_t c1;
            uint32_t c2;
            if (!att_phase(kernel_hz, data_bitrate, b, &att_data, &c1, &c2)) {
                continue;
            }
            if (dbrp == 0u) {
                dbrp = b; /* first working data prescaler: the fallback */
                d1 = c1;
                d2 = c2;
            }
            if (att_phase(kernel_hz, bitrate, b, &att_nominal, &n1, &n2)) {
                dbrp = b; /* the same prescaler in both phases */
                d1 = c1;
                d2 = c2;
                nbrp = b;
                break;
            }
        }
        if (dbrp == 0u) {
            return ATT_ERR_SETTINGS;
        }
        if (nbrp == 0u) {
            nbrp = att_nominal_brp(kernel_hz, bitrate, &n1, &n2);
            if (nbrp == 0u) {
                return ATT_ERR_SETTINGS;
            }
        }
        t->dbtp = ((dbrp - 1u) << 16) | ((d1 - 1u) << 8) | ((d2 - 1u) << 4) | (d2 - 1u);
        if (tdc) {
            const uint32_t tdco = dbrp * (1u + d1); /* the sample point in kernel clock periods */
            if (tdco > ATT_TDCO_MAX) {
                t->dbtp = 0u;
                return ATT_ERR_SETTINGS;
            }
            t->dbtp |= ATT_FDCAN_DBTP_TDC;
            t->tdcr = tdco << 8; /* TDCF 0: no filter window */
        }
    } else {
        nbrp = att_nominal_brp(kernel_hz, bitrate, &n1, &n2);
        if (nbrp == 0u) {
            return ATT_ERR_SETTINGS;
        }
    }
    t->nbtp = ((n2 - 1u) << 25) | ((nbrp - 1u) << 16) | ((n1 - 1u) << 8) | (n2 - 1u);
    return ATT_OK;
}

/* Write the standard filter elements: two of the node's IDs each (the last repeated for an odd count). */
static void att_write_filters(const att_fdcan_hal_t *h, const uint32_t *ids, size_t n_ids)
{
    uint32_t e;
    for (e = 0u; e < h->filter_elements; e++) {
        const size_t a = 2u * (size_t)e;
        const size_t b = (a + 1u < n_ids) ? a + 1u : a;
        att_ram_wr(h, h->layout.filters + 4u * e,
                   ATT_FDCAN_SFT_DUAL | ATT_FDCAN_SFEC_FIFO0 | ((ids[a] & 0x7ffu) << 16) | (ids[b] & 0x7ffu));
    }
}

static void att_ram_clear(const att_fdcan_hal_t *h, uint32_t offset, uint32_t bytes)
{
    uint32_t i;
    for (i = 0u; i < bytes; i += 4u) {
        att_ram_wr(h, offset + i, 0u);
    }
}

/* Message RAM and the registers that describe it (INIT and CCE set). */
static void att_configure_ram(const att_fdcan_hal_t *h, const uint32_t *ids, size_t n_ids)
{
    const att_fdcan_layout_t *l = &h->layout;
    if (l->variant == ATT_FDCAN_G4) {
        att_ram_clear(h, 0u, ATT_G4_RAM_BYTES);
        att_write_filters(h, ids, n_ids);
        /* LSS = our elements, LSE = 0, F0OM = 0 (blocking), reject everything else */
        att_wr(h, ATT_FDCAN_G4_RXGFC, (h->filter_elements << 16) | ATT_FDCAN_GFC_REJECT_ALL_OTHERS);
        att_wr(h, ATT_FDCAN_TXBC, 0u); /* TFQM = 0: Tx FIFO */
    } else {
        const uint32_t code = att_size_code(l->data_bytes);
        att_ram_clear(h, l->filters, 4u * l->filters_max);
        att_ram_clear(h, l->rx_fifo0, l->rx_fifo0_n * att_element_bytes(l));
        att_ram_clear(h, l->tx_fifo, l->tx_fifo_n * att_element_bytes(l));
        att_write_filters(h, ids, n_ids);
        att_wr(h, ATT_FDCAN_H7_GFC, ATT_FDCAN_GFC_REJECT_ALL_OTHERS);
        att_wr(h, ATT_FDCAN_H7_SIDFC, (h->filter_elements << 16) | (l->filters & 0xfffcu));
        att_wr(h, ATT_FDCAN_H7_XIDFC, 0u);
        att_wr(h, ATT_FDCAN_H7_RXF0C, (l->rx_fifo0_n << 16) | (l->rx_fifo0 & 0xfffcu)); /* F0OM 0, F0WM 0 */
        att_wr(h, ATT_FDCAN_H7_RXF1C, 0u);
        att_wr(h, ATT_FDCAN_H7_RXBC, 0u);
        att_wr(h, ATT_FDCAN_H7_RXESC, code | (code << 4) | (code << 8));
        att_wr(h, ATT_FDCAN_TXBC, (l->tx_fifo_n << 24) | (l->tx_fifo & 0xfffcu)); /* NDTB 0, TFQM 0 */
        att_wr(h, ATT_FDCAN_H7_TXESC, code);
        att_wr(h, ATT_FDCAN_H7_TXEFC, 0u);
    }
}

/* The controller for the node, from settings att_fdcan_hal_init validated. */
static att_status_t att_fdcan_setup(att_fdcan_hal_t *h, att_fdcan_hal_io_t regs, att_fdcan_hal_io_t ram,
                                    const att_fdcan_layout_t *l, att_node_t *node, const att_fdcan_timing_t *tp,
                                    const uint32_t *ids, size_t n_ids)
{
    const att_fdcan_timing_t t = *tp;
    uint32_t cccr;
    memset(h, 0, sizeof *h);
    h->regs = regs;
    h->ram = ram;
    h->layout = *l;
    h->node = node;
    h->timing = t;
    h->filter_elements = (uint32_t)((n_ids + 1u) / 2u);
    h->fd = node->s.data_bitrate != 0u;
    h->brs = h->fd && node->s.data_bitrate > node->s.bitrate;
    h->phase = ATT_FDCAN_HAL_ON;
    h->backoff = ATT_FDCAN_HAL_BACKOFF_FIRST;
    /* out of clock stop, into initialisation mode, configuration change enabled */
    cccr = att_rd(h, ATT_FDCAN_CCCR);
    if ((cccr & ATT_FDCAN_CCCR_CSR) != 0u) {
        att_wr(h, ATT_FDCAN_CCCR, cccr & ~ATT_FDCAN_CCCR_CSR);
        if (!att_wait_cccr(h, ATT_FDCAN_CCCR_CSA, 0u)) {
            return ATT_ERR_SETTINGS;
        }
    }
    att_wr(h, ATT_FDCAN_CCCR, ATT_FDCAN_CCCR_INIT);
    if (!att_wait_cccr(h, ATT_FDCAN_CCCR_INIT, ATT_FDCAN_CCCR_INIT)) {
        return ATT_ERR_SETTINGS;
    }
    att_wr(h, ATT_FDCAN_CCCR, ATT_FDCAN_CCCR_INIT | ATT_FDCAN_CCCR_CCE);
    /* ISO CAN FD, automatic retransmission, protocol exception handling on, no test or monitoring mode */
    cccr = ATT_FDCAN_CCCR_INIT | ATT_FDCAN_CCCR_CCE | (h->fd ? (ATT_FDCAN_CCCR_FDOE | ATT_FDCAN_CCCR_BRSE) : 0u);
    att_wr(h, ATT_FDCAN_CCCR, cccr);
    att_wr(h, ATT_FDCAN_NBTP, t.nbtp);
    if (h->fd) {
        att_wr(h, ATT_FDCAN_DBTP, t.dbtp);
        att_wr(h, ATT_FDCAN_TDCR, t.tdcr);
    }
    att_configure_ram(h, ids, n_ids);
    att_wr(h, ATT_FDCAN_IE, 0u); /* polled */
    att_wr(h, ATT_FDCAN_ILE, 0u);
    att_wr(h, ATT_FDCAN_IR, att_map(h)->ir_all); /* clear every flag (write 1 to clear) */
    /* normal operation once 11 recessive bits were seen on the bus; CCE goes with INIT */
    att_wr(h, ATT_FDCAN_CCCR, cccr & ~(ATT_FDCAN_CCCR_INIT | ATT_FDCAN_CCCR_CCE));
    if (!att_wait_cccr(h, ATT_FDCAN_CCCR_INIT, 0u)) {
        return ATT_ERR_SETTINGS;
    }
    return ATT_OK;
}

att_status_t att_fdcan_hal_init(att_fdcan_hal_t *h, att_fdcan_hal_io_t regs, att_fdcan_hal_io_t ram,
                                const att_fdcan_layout_t *layout, att_node_t *node, uint32_t kernel_hz)
{
    att_fdcan_timing_t t;
    uint32_t ids[ATT_NODE_RX_IDS_MAX];
    size_t n_ids;
    size_t i;
    const att_fdcan_layout_t *l = (layout != NULL) ? layout : &att_fdcan_layout_g4;
    if (h == NULL || node == NULL || regs.read == NULL || regs.write == NULL || ram.read == NULL ||
        ram.write == NULL) {
        return ATT_ERR_NULL;
    }
    if (att_fdcan_hal_layout_check(l) != ATT_OK ||
        att_fdcan_hal_timing(kernel_hz, node->s.bitrate, node->s.data_bitrate, &t) != ATT_OK ||
        (node->s.data_bitrate != 0u && l->data_bytes < (uint32_t)ATT_CAN_FD_LEN) ||
        (node->s.fd && node->s.data_bitrate == 0u)) {
        return ATT_ERR_SETTINGS;
    }
    n_ids = att_node_rx_ids(node, ids);
    if (n_ids == 0u || (n_ids + 1u) / 2u > l->filters_max) {
        return ATT_ERR_SETTINGS;
    }
    for (i = 0u; i < n_ids; i++) {
        if (ids[i] > 0x7ffu) {
            return ATT_ERR_SETTINGS;
        }
    }
    if (regs.read(regs.ctx, ATT_FDCAN_ENDN) != ATT_FDCAN_ENDN_VALUE) {
        return ATT_ERR_SETTINGS;
    }
    /* the node's outputs with ATT_DIAG_BUS must fit the bus (nothing written to the controller yet) */
    if (att_node_set_bus_diag(node, att_fdcan_hal_bus_diag, h) != ATT_OK) {
        return ATT_ERR_SETTINGS;
    }
    if (att_fdcan_setup(h, regs, ram, l, node, &t, ids, n_ids) != ATT_OK) {
        (void)att_node_set_bus_diag(node, NULL, NULL);
        return ATT_ERR_SETTINGS;
    }
    return ATT_OK;
}

size_t att_fdcan_hal_receive(att_fdcan_hal_t *h)
{
    const att_fdcan_map_t *m;
    size_t moved = 0u;
    uint32_t k;
    uint32_t st;
    if (h == NULL || h->node == NULL) {
        return 0u;
    }
    m = att_map(h);
    /* IR.RF0L / IR.RF1L (G0/G4 bits 2 / 5, H7 / M_CAN bits 3 / 7; write 1 to clear; RXF0S.RF0L is a copy):
       a frame arrived at a full FIFO (blocking mode) and was lost */
    st = att_rd(h, ATT_FDCAN_IR) & m->ir_lost;
    if (st != 0u) {
        h->stats.rx_overruns += ((st & m->ir_rf0l) != 0u ? 1u : 0u) + ((st & ~m->ir_rf0l) != 0u ? 1u : 0u);
        att_wr(h, ATT_FDCAN_IR, st);
    }
    for (k = 0u; k < h->layout.rx_fifo0_n; k++) {
        uint32_t gi;
        uint32_t base;
        uint32_t r0;
        uint32_t r1;
        st = att_rd(h, m->rxf0s);
        if ((st & 0x7fu) == 0u) {
            break; /* F0FL: FIFO empty */
        }
        gi = (st >> 8) & 0x3fu;
        if (gi >= h->layout.rx_fifo0_n) {
            break; /* not a state the controller can be in */
        }
        base = h->layout.rx_fifo0 + gi * att_element_bytes(&h->layout);
        r0 = att_ram_rd(h, base);
        r1 = att_ram_rd(h, base + 4u);
        {
            const bool fd = (r1 & ATT_FDCAN_E1_FDF) != 0u;
            const uint32_t len = att_fdcan_dlc_to_len((r1 >> ATT_FDCAN_E1_DLC_SHIFT) & 0xfu, fd);
            if ((r0 & (ATT_FDCAN_E0_XTD | ATT_FDCAN_E0_RTR)) != 0u || len > h->layout.data_bytes) {
                h->stats.rx_ignored++;
            } else {
                att_can_frame_t f;
                uint32_t w;
                memset(&f, 0, sizeof f);
                f.id = (r0 >> ATT_FDCAN_E0_STD_SHIFT) & 0x7ffu;
                f.len = (uint8_t)len;
                f.fd = fd ? 1u : 0u;
                for (w = 0u; 4u * w < len; w++) {
                    const uint32_t v = att_ram_rd(h, base + ATT_ELEMENT_HEADER + 4u * w);
                    uint32_t b;
                    for (b = 0u; b < 4u && 4u * w + b < len; b++) {
                        f.data[4u * w + b] = (uint8_t)((v >> (8u * b)) & 0xffu);
                    }
                }
                if (att_node_rx(h->node, &f)) {
                    h->stats.rx_frames++;
                    h->stats.rx_fd_frames += fd ? 1u : 0u;
                    moved++;
                } else {
                    h->stats.rx_node_full++;
                }
            }
        }
        att_wr(h, m->rxf0a, gi); /* release the element */
    }
    return moved;
}

/* The controller as configured can send f (standard ID, length for its format and the elements). */
static bool att_sendable(const att_fdcan_hal_t *h, const att_can_frame_t *f)
{
    if (f->id > 0x7ffu) {
        return false;
    }
    if (f->fd != 0u) {
        return h->fd && f->len <= 64u && att_dlc_len[att_fdcan_len_to_dlc(f->len)] <= h->layout.data_bytes;
    }
    return f->len <= 8u;
}

/* Put index of a free Tx FIFO element, or -1 (full, bus-off, or not in normal operation). */
static int32_t att_tx_slot(const att_fdcan_hal_t *h)
{
    uint32_t q;
    uint32_t pi;
    if (h->phase != ATT_FDCAN_HAL_ON || (att_rd(h, ATT_FDCAN_CCCR) & ATT_FDCAN_CCCR_INIT) != 0u) {
        return -1;
    }
    q = att_rd(h, ATT_FDCAN_TXFQS);
    pi = (q >> 16) & 0x1fu;
    if ((q & ATT_FDCAN_TXFQS_TFQF) != 0u || (q & 0x3fu) == 0u || pi >= h->layout.tx_fifo_n) {
        return -1;
    }
    return (int32_t)pi;
}

/* Write f into Tx buffer pi and request its transmission. */
static void att_put(att_fdcan_hal_t *h, const att_can_frame_t *f, uint32_t pi)
{
    const uint32_t base = h->layout.tx_fifo + pi * att_element_bytes(&h->layout);
    const uint32_t dlc = (f->fd != 0u) ? att_fdcan_len_to_dlc(f->len) : f->len;
    const uint32_t padded = att_fdcan_dlc_to_len(dlc, f->fd != 0u);
    uint32_t e1 = dlc << ATT_FDCAN_E1_DLC_SHIFT; /* EFC 0: no Tx event, MM 0 */
    uint32_t w;
    if (f->fd != 0u) {
        e1 |= ATT_FDCAN_E1_FDF | (h->brs ? ATT_FDCAN_E1_BRS : 0u);
    }
    att_ram_wr(h, base, (f->id & 0x7ffu) << ATT_FDCAN_E0_STD_SHIFT); /* ESI 0, XTD 0, RTR 0 */
    att_ram_wr(h, base + 4u, e1);
    for (w = 0u; 4u * w < padded; w++) {
        uint32_t v = 0u;
        uint32_t b;
        for (b = 0u; b < 4u; b++) {
            const uint32_t i = 4u * w + b;
            v |= (uint32_t)((i < f->len) ? f->data[i] : 0u) << (8u * b);
        }
        att_ram_wr(h, base + ATT_ELEMENT_HEADER + 4u * w, v);
    }
    att_wr(h, att_map(h)->txbar, (uint32_t)1u << pi);
    h->stats.tx_frames++;
    h->stats.tx_fd_frames += (f->fd != 0u) ? 1u : 0u;
}

att_status_t att_fdcan_hal_send(att_fdcan_hal_t *h, const att_can_frame_t *f)
{
    int32_t slot;
    if (h == NULL || f == NULL || h->node == NULL) {
        return ATT_ERR_NULL;
    }
    if (!att_sendable(h, f)) {
        h->stats.tx_unsupported++;
        return ATT_ERR_SETTINGS;
    }
    slot = att_tx_slot(h);
    if (slot < 0) {
        return ATT_ERR_STATE;
    }
    att_put(h, f, (uint32_t)slot);
    return ATT_OK;
}

size_t att_fdcan_hal_transmit(att_fdcan_hal_t *h)
{
    size_t sent = 0u;
    uint32_t k;
    if (h == NULL || h->node == NULL) {
        return 0u;
    }
    for (k = 0u; k < h->layout.tx_fifo_n; k++) {
        att_can_frame_t f;
        const int32_t slot = att_tx_slot(h);
        if (slot < 0) {
            break;
        }
        for (;;) {
            if (!att_node_tx(h->node, &f)) {
                return sent;
            }
            if (att_sendable(h, &f)) {
                break;
            }
            h->stats.tx_unsupported++;
        }
        att_put(h, &f, (uint32_t)slot);
        sent++;
    }
    return sent;
}

/* Wait h->backoff service calls before the next recovery, and double it for the one after (to MAX). */
static void att_backoff(att_fdcan_hal_t *h)
{
    h->phase = ATT_FDCAN_HAL_BACKOFF;
    h->wait = h->backoff;
    h->backoff = (h->backoff > ATT_FDCAN_HAL_BACKOFF_MAX / 2u) ? ATT_FDCAN_HAL_BACKOFF_MAX : 2u * h->backoff;
    h->good = 0u;
}

/*
 * Bus-off recovery (RM0440 FDCAN operating modes; Bosch M_CAN user's manual, PSR note): at bus-off the
 * controller sets CCCR.INIT of its own accord and stops; once the CPU clears INIT it waits for 129
 * occurrences of 11 recessive bits, then resets its error counters and clears PSR.BO. Clearing INIT
 * clears CCE with it; the configuration (bit timing, filters, RAM) is kept.
 */
static void att_recover(const att_fdcan_hal_t *h)
{
    const uint32_t cccr = att_rd(h, ATT_FDCAN_CCCR);
    if ((cccr & ATT_FDCAN_CCCR_INIT) != 0u) {
        att_wr(h, ATT_FDCAN_CCCR, cccr & ~(ATT_FDCAN_CCCR_INIT | ATT_FDCAN_CCCR_CCE));
    }
}

/*
 * The fault confinement state from PSR (0x44 in both maps): LEC bits 2:0 (0 none, 1 stuff, 2 form, 3
 * acknowledgment, 4 bit1, 5 bit0, 6 CRC; 7 "no change": set to 7 by every read), EP bit 5, EW bit 6,
 * BO bit 7.
 */
static void att_faults(att_fdcan_hal_t *h)
{
    const uint32_t psr = att_rd(h, ATT_FDCAN_PSR);
    const bool off = (psr & ATT_FDCAN_PSR_BO) != 0u;
    const bool passive = (psr & ATT_FDCAN_PSR_EP) != 0u;
    const bool warning = (psr & ATT_FDCAN_PSR_EW) != 0u;
    const uint32_t lec = psr & ATT_FDCAN_PSR_LEC;
    if (lec != 0u && lec != 7u) {
        h->stats.lec = lec;
    }
    h->stats.error_passive += (passive && !h->passive) ? 1u : 0u;
    h->stats.error_warning += (warning && !h->warning) ? 1u : 0u;
    h->passive = passive;
    h->warning = warning;
    switch (h->phase) {
    case ATT_FDCAN_HAL_ON:
        if (off) {
            h->stats.bus_off++;
            att_backoff(h);
        } else if (passive) {
            h->good = 0u;
        } else if (h->good < ATT_FDCAN_HAL_BACKOFF_RESET) {
            h->good++;
            if (h->good == ATT_FDCAN_HAL_BACKOFF_RESET) {
                h->backoff = ATT_FDCAN_HAL_BACKOFF_FIRST; /* a good while on the bus: start over */
            }
        }
        break;
    case ATT_FDCAN_HAL_BACKOFF:
        if (!off) { /* left bus-off without the driver (someone else cleared INIT) */
            h->stats.recoveries++;
            h->phase = ATT_FDCAN_HAL_ON;
        } else if (h->wait > 1u) {
            h->wait--;
        } else {
            att_recover(h);
            h->phase = ATT_FDCAN_HAL_RECOVERING;
        }
        break;
    default: /* ATT_FDCAN_HAL_RECOVERING */
        if (!off) {
            h->stats.recoveries++;
            h->phase = ATT_FDCAN_HAL_ON;
        } else if ((att_rd(h, ATT_FDCAN_CCCR) & ATT_FDCAN_CCCR_INIT) != 0u) {
            /* INIT set again: back on the bus and bus-off again between two calls (frames pending in
               the Tx buffers since before were retried): an episode ended, a new one begins */
            h->stats.recoveries++;
            h->stats.bus_off++;
            att_backoff(h);
        }
        break;
    }
}

void att_fdcan_hal_bus_diag(void *ctx, att_can_bus_diag_t *d)
{
    const att_fdcan_hal_t *h = (const att_fdcan_hal_t *)ctx;
    if (h == NULL || d == NULL) {
        return;
    }
    if (h->phase != ATT_FDCAN_HAL_ON) {
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

size_t att_fdcan_hal_service(att_fdcan_hal_t *h)
{
    size_t steps;
    if (h == NULL || h->node == NULL) {
        return 0u;
    }
    att_faults(h);
    (void)att_fdcan_hal_receive(h);
    steps = att_node_poll(h->node);
    (void)att_fdcan_hal_transmit(h);
    return steps;
}
