/**
 * @file att_node_run.c
 * @brief The CAN node of one build configuration over a file of frames, for tests/test_node_configs.py.
 *
 *     att_node_run KIND RATE FD BITRATE DATA_BITRATE ID_OFFSET IN OUT
 *
 * IN holds att_can_frame_t records (72 bytes, attica.can.layout.FRAME_DTYPE); each is pushed with
 * att_node_rx, then att_node_poll runs and the tx ring is drained into OUT (same records), as a port
 * does. Prints "steps=N" and the counters ("name=value", att_node_stats_t order), or "init=STATUS"
 * when att_node_init refuses the settings (exit 3).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "attica/att_can.h"
#include "attica/att_node.h"

static att_node_t node; /* large with the default rings: static */

int main(int argc, char **argv)
{
    att_node_settings_t s;
    att_can_frame_t f;
    att_status_t st;
    FILE *in;
    FILE *out;
    size_t steps = 0u;
    if (argc != 9) {
        fprintf(stderr, "usage: %s KIND RATE FD BITRATE DATA_BITRATE ID_OFFSET IN OUT\n", argv[0]);
        return 2;
    }
    st = att_node_settings_default((att_filter_kind_t)atoi(argv[1]), (float)atof(argv[2]), &s);
    if (st != ATT_OK) {
        printf("default=%d\n", (int)st);
        return 3;
    }
    s.fd = atoi(argv[3]) != 0;
    s.bitrate = (uint32_t)strtoul(argv[4], NULL, 10);
    s.data_bitrate = (uint32_t)strtoul(argv[5], NULL, 10);
    s.id_offset = (int32_t)strtol(argv[6], NULL, 0);
    st = att_node_init(&node, &s);
    if (st != ATT_OK) {
        printf("init=%d\n", (int)st);
        return 3;
    }
    in = fopen(argv[7], "rb");
    out = fopen(argv[8], "wb");
    if (in == NULL || out == NULL) {
        fprintf(stderr, "cannot open %s or %s\n", argv[7], argv[8]);
        return 2;
    }
    while (fread(&f, sizeof f, 1u, in) == 1u) {
        (void)att_node_rx(&node, &f);
        steps += att_node_poll(&node);
        while (att_node_tx(&node, &f)) {
            if (fwrite(&f, sizeof f, 1u, out) != 1u) {
                return 2;
            }
        }
    }
    (void)fclose(in);
    if (fclose(out) != 0) {
        return 2;
    }
    printf("sizeof_frame=%u\nsizeof_node=%u\nsteps=%u\n", (unsigned)sizeof f, (unsigned)sizeof node, (unsigned)steps);
    printf("rx_frames=%u\ncrc_errors=%u\ncounter_gaps=%u\ndlc_errors=%u\nunknown_ids=%u\nduplicates=%u\n",
           (unsigned)node.stats.rx_frames, (unsigned)node.stats.crc_errors, (unsigned)node.stats.counter_gaps,
           (unsigned)node.stats.dlc_errors, (unsigned)node.stats.unknown_ids, (unsigned)node.stats.duplicates);
    printf("stale_partials=%u\nrx_overflows=%u\ntx_overflows=%u\nsamples=%u\nsteps_stat=%u\nsets=%u\n",
           (unsigned)node.stats.stale_partials, (unsigned)node.stats.rx_overflows,
           (unsigned)node.stats.tx_overflows, (unsigned)node.stats.samples, (unsigned)node.stats.steps,
           (unsigned)node.stats.sets);
    printf("tx_frames=%u\ncommands=%u\n", (unsigned)node.stats.tx_frames, (unsigned)node.stats.commands);
    return 0;
}
