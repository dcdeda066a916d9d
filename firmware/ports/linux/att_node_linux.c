/**
 * @file att_node_linux.c
 * @brief attica CAN node on Linux SocketCAN: `attica-node`.
 *
 *     attica-node --channel vcan0 --filter ars --rate 285.714 [--fd] [--bitrate 500000]
 *                 [--data-bitrate 2000000] [--output-divider N] [--diag-divider N] [--count N]
 *                 [--rcvbuf BYTES] [--id-offset N] [--quiet]
 *
 * The portable node core (att_node.c) does all the work; this port only moves frames between a
 * CAN_RAW socket and the core:
 *
 *     read frame -> att_node_rx -> att_node_poll -> att_node_tx -> write frame
 *
 * It stops cleanly on SIGINT/SIGTERM or after --count filter steps and prints one stats line.
 * POSIX and Linux headers are used here only (the core stays C99 without OS dependencies), so this
 * file is compiled with the firmware flags plus -std=gnu99 (the socket headers need the GNU/BSD
 * definitions such as struct ifreq); see the `node` target of the Makefile.
 *
 * A full tx queue (ENOBUFS, e.g. a bus that cannot keep up or a held qdisc) is waited out: no output
 * is dropped, the inputs wait in the socket's receive buffer. An interface that goes down or is
 * removed stops the node with a message naming it.
 *
 * Exit status: 0 on a clean stop, 1 on a socket or runtime error, 2 on a usage or settings error.
 */
#include <errno.h>
#include <fcntl.h>
#include <net/if.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <linux/can.h>
#include <linux/can/raw.h>

#include "attica/att_can.h"
#include "attica/att_filter.h"
#include "attica/att_node.h"

#define PROG "attica-node"

static volatile sig_atomic_t g_stop = 0;

static void on_signal(int sig) {
    (void)sig;
    g_stop = 1;
}

/** Command line options. */
typedef struct {
    const char *channel;
    const char *filter;
    float rate;
    int fd;
    unsigned long bitrate;
    unsigned long data_bitrate;
    unsigned long output_divider;
    unsigned long diag_divider;
    unsigned long long count; /* 0 = run until a signal */
    int rcvbuf;               /* socket receive buffer bytes, 0 = kernel default */
    int quiet;
    const char *calib_file;   /* calibration loaded at start and saved by the persistence hook; NULL = none */
    int accel_out;            /* linear / earth acceleration frames */
    long id_offset;           /* added to every attica CAN ID (att_node_settings_t.id_offset) */
} options_t;

/** Frames and errors seen by the port itself (the core keeps its own counters). */
typedef struct {
    unsigned long long rx_frames;
    unsigned long long tx_frames;
    unsigned long long rx_ignored; /* extended, remote or error frames: not attica's */
    unsigned long long rx_rejected; /* att_node_rx returned false (ring full) */
    unsigned long long tx_retries;  /* write() had to wait for buffer space */
    unsigned long long tx_full;     /* episodes of a full tx queue (ENOBUFS / EAGAIN): waited, nothing lost */
    unsigned long long steps;
} port_stats_t;

static const char *g_channel = "";

/** A clear message for an interface that went down or disappeared (errno ENODEV / ENETDOWN / ENXIO). */
static int iface_gone(int err) {
    if (err != ENODEV && err != ENETDOWN && err != ENXIO) return 0;
    fprintf(stderr, PROG ": error: CAN interface '%s' %s (%s): stopping\n", g_channel,
            err == ENETDOWN ? "went down" : "was removed", strerror(err));
    return 1;
}

static void usage(FILE *to) {
    fprintf(to,
            "usage: " PROG " --channel IFACE [--filter KIND] [--rate HZ] [--fd] [--bitrate BIT/S]\n"
            "                   [--data-bitrate BIT/S] [--output-divider N] [--diag-divider N] [--count N]\n"
            "                   [--rcvbuf BYTES] [--calib-file PATH] [--accel-out] [--id-offset N] [--quiet]\n"
            "\n"
            "Run an attica filter as a CAN node on a SocketCAN interface (vcan0, can0...).\n"
            "  --channel IFACE       SocketCAN interface (required)\n"
            "  --filter KIND         ars, mars, kf, ekf, gyro, tilt or mekf (default ars)\n"
            "  --rate HZ             IMU sample rate = 1/dt of the filter (default 285.714)\n"
            "  --fd                  CAN FD: IMU_FD in, ATT_OUT_FD out (interface MTU must be 72)\n"
            "  --bitrate BIT/S       nominal bit rate used for the bus load check (default 500000)\n"
            "  --data-bitrate BIT/S  CAN FD data phase bit rate (default 2000000 with --fd)\n"
            "  --output-divider N    send outputs every Nth filter step (default 1)\n"
            "  --diag-divider N      send ATT_DIAG every Nth output set, 0 = never (default 16)\n"
            "  --count N             stop after N filter steps (default: run until SIGINT/SIGTERM)\n"
            "  --rcvbuf BYTES        socket receive buffer (default 4194304; 0 = kernel default)\n"
            "  --calib-file PATH     calibration file: loaded at start (if it exists), rewritten after every\n"
            "                        calibration command (CMD 4..9); lines 'INDEX 0xBITS' (att_calib_field_set)\n"
            "  --accel-out           send ATT_LIN_ACC + ATT_EARTH_ACC (or ATT_ACCEL_FD) after every set\n"
            "  --id-offset N         add N to every attica CAN ID, in and out (-256 .. 1279, 0x.. allowed;\n"
            "                        default 0: the IDs of attica.dbc; 'attica dbc --id-offset N' writes the DBC)\n"
            "  --quiet               no start-up line\n");
}

static int parse_ulong(const char *opt, const char *text, unsigned long long max, unsigned long long *out) {
    char *end = NULL;
    unsigned long long v;
    if (text == NULL || *text == '\0' || *text == '-') {
        fprintf(stderr, PROG ": error: %s expects a non-negative integer, got '%s'\n", opt, text ? text : "");
        return -1;
    }
    errno = 0;
    v = strtoull(text, &end, 10);
    if (errno != 0 || end == text || *end != '\0' || v > max) {
        fprintf(stderr, PROG ": error: %s expects an integer in 0..%llu, got '%s'\n", opt, max, text);
        return -1;
    }
    *out = v;
    return 0;
}

#if ATT_WITH_CALIB
/*
 * The calibration file: one line per field, "INDEX 0xBITS" with the IEEE-754 bits of the float value
 * (exact, no decimal conversion). Written to PATH.tmp and renamed over PATH, so a crash never leaves a
 * half-written file.
 */
static bool calib_save(void *ctx, const att_calib_settings_t *c) {
    const char *path = (const char *)ctx;
    char tmp[4096];
    FILE *f;
    uint32_t i;
    int ok = 1;
    if (snprintf(tmp, sizeof tmp, "%s.tmp", path) >= (int)sizeof tmp) return false;
    f = fopen(tmp, "w");
    if (f == NULL) return false;
    ok = fprintf(f, "# attica calibration: field index and float32 bits (att_calib_field_set)\n") > 0;
    for (i = 0; i < ATT_CALIB_FIELDS && ok; ++i) {
        float v = 0.0f;
        uint32_t bits;
        (void)att_calib_field_get(c, i, &v);
        memcpy(&bits, &v, sizeof bits);
        ok = fprintf(f, "%u 0x%08x\n", (unsigned)i, (unsigned)bits) > 0;
    }
    if (fclose(f) != 0) ok = 0;
    if (!ok || rename(tmp, path) != 0) {
        (void)remove(tmp);
        return false;
    }
    return true;
}

/* Load PATH into c (starting from c's values); 0 ok or no file, -1 with a message for a bad file. */
static int calib_load(const char *path, att_calib_settings_t *c) {
    char line[256];
    unsigned long lineno = 0;
    FILE *f = fopen(path, "r");
    att_calib_error_t e;
    if (f == NULL) return (errno == ENOENT) ? 0 : -1;
    while (fgets(line, sizeof line, f) != NULL) {
        unsigned idx;
        unsigned bits;
        float v;
        ++lineno;
        if (line[0] == '#' || line[0] == '\n') continue;
        if (sscanf(line, "%u 0x%x", &idx, &bits) != 2 || idx >= ATT_CALIB_FIELDS) {
            fprintf(stderr, PROG ": error: %s:%lu: expected 'INDEX 0xBITS' with INDEX < %d\n", path, lineno,
                    ATT_CALIB_FIELDS);
            fclose(f);
            return -1;
        }
        memcpy(&v, &bits, sizeof v);
        if (!att_calib_field_set(c, idx, v)) {
            fprintf(stderr, PROG ": error: %s:%lu: field %u refuses that value\n", path, lineno, idx);
            fclose(f);
            return -1;
        }
    }
    fclose(f);
    e = att_calib_settings_check(c);
    if (e != ATT_CALIB_OK) {
        fprintf(stderr, PROG ": error: %s: invalid calibration: %s\n", path, att_calib_error_name(e));
        return -1;
    }
    return 0;
}
#endif

static int parse_args(int argc, char **argv, options_t *o) {
    int i;
    unsigned long long v = 0;
    memset(o, 0, sizeof *o);
    o->filter = "ars";
    o->rate = 285.714f;
    o->bitrate = 500000UL;
    o->output_divider = 1UL;
    o->diag_divider = 16UL;
    o->rcvbuf = 4 * 1024 * 1024;
    for (i = 1; i < argc; ++i) {
        const char *a = argv[i];
        const char *val = (i + 1 < argc) ? argv[i + 1] : NULL;
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            usage(stdout);
            exit(0);
        } else if (strcmp(a, "--fd") == 0) {
            o->fd = 1;
            continue;
        } else if (strcmp(a, "--accel-out") == 0) {
            o->accel_out = 1;
            continue;
        } else if (strcmp(a, "--quiet") == 0 || strcmp(a, "-q") == 0) {
            o->quiet = 1;
            continue;
        }
        if (val == NULL) {
            fprintf(stderr, PROG ": error: %s\n", strncmp(a, "--", 2) == 0 ? "option needs a value" : "bad argument");
            fprintf(stderr, PROG ": (at '%s'; see --help)\n", a);
            return -1;
        }
        if (strcmp(a, "--calib-file") == 0) {
            o->calib_file = val;
        } else if (strcmp(a, "--channel") == 0) {
            o->channel = val;
        } else if (strcmp(a, "--filter") == 0) {
            o->filter = val;
        } else if (strcmp(a, "--rate") == 0) {
            char *end = NULL;
            float r;
            errno = 0;
            r = strtof(val, &end);
            if (errno != 0 || end == val || *end != '\0' || !(r > 0.0f) || r > 1.0e6f) {
                fprintf(stderr, PROG ": error: --rate expects a sample rate in Hz > 0, got '%s'\n", val);
                return -1;
            }
            o->rate = r;
        } else if (strcmp(a, "--bitrate") == 0) {
            if (parse_ulong(a, val, 0xFFFFFFFFULL, &v) != 0) return -1;
            o->bitrate = (unsigned long)v;
        } else if (strcmp(a, "--data-bitrate") == 0) {
            if (parse_ulong(a, val, 0xFFFFFFFFULL, &v) != 0) return -1;
            o->data_bitrate = (unsigned long)v;
        } else if (strcmp(a, "--output-divider") == 0) {
            if (parse_ulong(a, val, 0xFFFFFFFFULL, &v) != 0) return -1;
            o->output_divider = (unsigned long)v;
        } else if (strcmp(a, "--diag-divider") == 0) {
            if (parse_ulong(a, val, 0xFFFFFFFFULL, &v) != 0) return -1;
            o->diag_divider = (unsigned long)v;
        } else if (strcmp(a, "--rcvbuf") == 0) {
            if (parse_ulong(a, val, 0x7FFFFFFFULL, &v) != 0) return -1;
            o->rcvbuf = (int)v;
        } else if (strcmp(a, "--id-offset") == 0) {
            char *end = NULL;
            long off;
            errno = 0;
            off = strtol(val, &end, 0);
            if (errno != 0 || end == val || *end != '\0' || off < ATT_NODE_ID_OFFSET_MIN || off > ATT_NODE_ID_OFFSET_MAX) {
                fprintf(stderr, PROG ": error: --id-offset expects an integer from %d to %d (every ID stays 11-bit), got '%s'\n",
                        ATT_NODE_ID_OFFSET_MIN, ATT_NODE_ID_OFFSET_MAX, val);
                return -1;
            }
            o->id_offset = off;
        } else if (strcmp(a, "--count") == 0) {
            if (parse_ulong(a, val, 0xFFFFFFFFFFFFFFFFULL, &v) != 0) return -1;
            o->count = v;
        } else {
            fprintf(stderr, PROG ": error: unknown option '%s' (see --help)\n", a);
            return -1;
        }
        ++i;
    }
    if (o->channel == NULL) {
        fprintf(stderr, PROG ": error: --channel is required (e.g. --channel vcan0)\n");
        return -1;
    }
    if (strlen(o->channel) >= IFNAMSIZ) {
        fprintf(stderr, PROG ": error: interface name '%s' is too long\n", o->channel);
        return -1;
    }
    if (o->fd && o->data_bitrate == 0UL) o->data_bitrate = 2000000UL;
#if !ATT_NODE_WITH_FD
    if (o->fd) {
        fprintf(stderr, PROG ": error: --fd: this attica-node is built without CAN FD (ATT_NODE_WITH_FD 0)\n");
        return -1;
    }
#endif
#if !ATT_WITH_CALIB
    if (o->calib_file != NULL || o->accel_out) {
        fprintf(stderr, PROG ": error: %s: this attica-node is built without the calibration stages (ATT_WITH_CALIB 0)\n",
                o->calib_file != NULL ? "--calib-file" : "--accel-out");
        return -1;
    }
#endif
    return 0;
}

/** The filter kind named `name`, or ATT_FILTER_NONE. */
static att_filter_kind_t parse_kind(const char *name) {
    static const att_filter_kind_t kinds[] = {ATT_FILTER_ARS,  ATT_FILTER_MARS, ATT_FILTER_KF,  ATT_FILTER_EKF,
                                              ATT_FILTER_GYRO, ATT_FILTER_TILT, ATT_FILTER_MEKF};
    size_t i;
    for (i = 0; i < sizeof kinds / sizeof kinds[0]; ++i) {
        if (strcmp(name, att_filter_name(kinds[i])) == 0) return kinds[i];
    }
    return ATT_FILTER_NONE;
}

static int open_socket(const options_t *o) {
    struct sockaddr_can addr;
    struct ifreq ifr;
    int s = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (s < 0) {
        fprintf(stderr, PROG ": error: cannot create a CAN_RAW socket: %s%s\n", strerror(errno),
                errno == EAFNOSUPPORT ? " (this kernel has no SocketCAN: modprobe can-raw)" : "");
        return -1;
    }
    memset(&ifr, 0, sizeof ifr);
    memcpy(ifr.ifr_name, o->channel, strlen(o->channel));
    if (ioctl(s, SIOCGIFINDEX, &ifr) < 0) {
        fprintf(stderr, PROG ": error: no CAN interface '%s': %s (create one: ip link add dev %s type vcan; ip link set up %s)\n",
                o->channel, strerror(errno), o->channel, o->channel);
        close(s);
        return -1;
    }
    if (o->fd) {
        int on = 1;
        struct ifreq mtu;
        if (setsockopt(s, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) != 0) {
            fprintf(stderr, PROG ": error: cannot enable CAN FD frames on '%s': %s\n", o->channel, strerror(errno));
            close(s);
            return -1;
        }
        memset(&mtu, 0, sizeof mtu);
        memcpy(mtu.ifr_name, o->channel, strlen(o->channel));
        if (ioctl(s, SIOCGIFMTU, &mtu) == 0 && mtu.ifr_mtu != (int)CANFD_MTU) {
            fprintf(stderr, PROG ": error: '%s' is not CAN FD capable (MTU %d, need %d: ip link set %s mtu 72)\n",
                    o->channel, mtu.ifr_mtu, (int)CANFD_MTU, o->channel);
            close(s);
            return -1;
        }
    }
    if (o->rcvbuf > 0) {
        /* a bigger receive queue absorbs bursts (a host sending as fast as it can); SO_RCVBUFFORCE may
           exceed net.core.rmem_max (needs CAP_NET_ADMIN), else the kernel caps SO_RCVBUF */
        int size = o->rcvbuf;
        if (setsockopt(s, SOL_SOCKET, SO_RCVBUFFORCE, &size, sizeof size) != 0) {
            (void)setsockopt(s, SOL_SOCKET, SO_RCVBUF, &size, sizeof size);
        }
    }
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifr.ifr_ifindex;
    if (bind(s, (struct sockaddr *)&addr, sizeof addr) != 0) {
        fprintf(stderr, PROG ": error: cannot bind to '%s': %s\n", o->channel, strerror(errno));
        close(s);
        return -1;
    }
    if (fcntl(s, F_SETFL, fcntl(s, F_GETFL, 0) | O_NONBLOCK) != 0) {
        fprintf(stderr, PROG ": error: cannot make the socket non-blocking: %s\n", strerror(errno));
        close(s);
        return -1;
    }
    return s;
}

/**
 * Write one frame. While the interface's tx queue or the socket's send buffer is full (ENOBUFS,
 * EAGAIN) wait and retry for as long as it takes: the frame is kept, and the inputs wait in the
 * socket's receive buffer meanwhile (the core never drops an output). A warning is printed once per
 * episode. Stops on SIGINT/SIGTERM, or with a clear message when the interface goes away.
 */
static int send_frame(int s, const att_can_frame_t *f, int fd_mode, port_stats_t *st) {
    struct canfd_frame out;
    size_t size;
    int waiting = 0;
    memset(&out, 0, sizeof out);
    out.can_id = f->id & CAN_SFF_MASK;
    out.len = f->len;
    memcpy(out.data, f->data, f->len);
    if (f->fd) {
        if (!fd_mode) return 0; /* cannot happen: the core sends FD frames only in FD mode */
        out.flags = CANFD_BRS;
        size = CANFD_MTU;
    } else {
        size = CAN_MTU;
    }
    for (;;) {
        ssize_t n = write(s, &out, size);
        if (n == (ssize_t)size) {
            st->tx_frames++;
            if (waiting) {
                fprintf(stderr, PROG ": tx queue of '%s' has room again: sending\n", g_channel);
            }
            return 0;
        }
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS)) {
            struct pollfd p;
            if (!waiting) {
                waiting = 1;
                st->tx_full++;
                fprintf(stderr, PROG ": warning: tx queue of '%s' is full (%s): waiting, no output is dropped\n",
                        g_channel, strerror(errno));
            }
            if (g_stop) return -1;
            p.fd = s;
            p.events = POLLOUT;
            p.revents = 0;
            st->tx_retries++;
            (void)poll(&p, 1, 1);
            continue;
        }
        if (n < 0 && errno == EINTR) {
            if (g_stop) return -1;
            continue;
        }
        if (n < 0 && iface_gone(errno)) return -1;
        fprintf(stderr, PROG ": error: write to CAN socket failed: %s\n", n < 0 ? strerror(errno) : "short write");
        return -1;
    }
}

/** Drain the core's tx queue to the socket. */
static int flush_tx(int s, att_node_t *node, int fd_mode, port_stats_t *st) {
    att_can_frame_t f;
    while (att_node_tx(node, &f)) {
        if (send_frame(s, &f, fd_mode, st) != 0) return -1;
    }
    return 0;
}

static void print_stats(const att_node_t *node, const port_stats_t *st) {
    printf(PROG ": stats: steps=%llu rx_frames=%llu tx_frames=%llu ignored=%llu rx_rejected=%llu "
           "tx_retries=%llu tx_full=%llu | node: rx_frames=%lu crc_errors=%lu counter_gaps=%lu dlc_errors=%lu "
           "unknown_ids=%lu duplicates=%lu stale_partials=%lu rx_overflows=%lu tx_overflows=%lu steps=%lu\n",
           st->steps, st->rx_frames, st->tx_frames, st->rx_ignored, st->rx_rejected, st->tx_retries, st->tx_full,
           (unsigned long)node->stats.rx_frames, (unsigned long)node->stats.crc_errors,
           (unsigned long)node->stats.counter_gaps, (unsigned long)node->stats.dlc_errors,
           (unsigned long)node->stats.unknown_ids, (unsigned long)node->stats.duplicates,
           (unsigned long)node->stats.stale_partials, (unsigned long)node->stats.rx_overflows,
           (unsigned long)node->stats.tx_overflows, (unsigned long)node->stats.steps);
    fflush(stdout);
}

static att_node_t g_node; /* large static rings: keep it off the stack */

int main(int argc, char **argv) {
    options_t o;
    att_node_settings_t ns;
    att_filter_kind_t kind;
    att_status_t st;
    port_stats_t ps;
    struct sigaction sa;
    int s;
    int rc = 0;

    setvbuf(stdout, NULL, _IOLBF, 0);
    if (parse_args(argc, argv, &o) != 0) return 2;
    kind = parse_kind(o.filter);
    if (kind == ATT_FILTER_NONE) {
        fprintf(stderr, PROG ": error: unknown filter '%s' (known: ars, mars, kf, ekf, gyro, tilt, mekf)\n", o.filter);
        return 2;
    }

    if (att_node_settings_default(kind, o.rate, &ns) != ATT_OK) {
        fprintf(stderr, PROG ": error: filter '%s' is not available in this build, or --rate %g is out of range\n",
                o.filter, (double)o.rate);
        return 2;
    }
    ns.bitrate = (uint32_t)o.bitrate;
    ns.data_bitrate = (uint32_t)o.data_bitrate;
    ns.fd = o.fd != 0;
    ns.output_divider = (uint32_t)o.output_divider;
    ns.diag_divider = (uint32_t)o.diag_divider;
    ns.accel_out = o.accel_out != 0;
    ns.id_offset = (int32_t)o.id_offset;
#if ATT_WITH_CALIB
    if (o.calib_file != NULL && calib_load(o.calib_file, &ns.calib) != 0) {
        fprintf(stderr, PROG ": error: cannot use calibration file '%s'\n", o.calib_file);
        return 2;
    }
#endif
    st = att_node_init(&g_node, &ns);
    if (st != ATT_OK) {
        float load = att_node_bus_load(&ns);
        if (load > 1.0f) {
            fprintf(stderr,
                    PROG ": error: the outputs need %.1f %% of the %lu bit/s bus at %g Hz: more than 100 %%, refused "
                    "(raise --output-divider or --bitrate%s)\n",
                    (double)(load * 100.0f), o.bitrate, (double)o.rate, o.fd ? "/--data-bitrate" : ", or use --fd");
        } else {
            fprintf(stderr, PROG ": error: invalid node settings (status %d): check --rate, --bitrate, "
                    "--data-bitrate and --output-divider (>= 1)\n", (int)st);
        }
        return 2;
    }

#if ATT_WITH_CALIB
    if (o.calib_file != NULL) att_node_set_persist(&g_node, calib_save, (void *)o.calib_file);
#endif
    g_channel = o.channel;
    s = open_socket(&o);
    if (s < 0) return 1;

    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0; /* no SA_RESTART: poll() returns EINTR */
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);

    memset(&ps, 0, sizeof ps);
    if (!o.quiet) {
        printf(PROG ": %s on %s (%s, %lu bit/s%s), %g Hz, output bus load %.1f %%: ready\n", att_filter_name(kind),
               o.channel, o.fd ? "CAN FD" : "classic CAN", o.bitrate, o.fd ? " nominal" : "", (double)o.rate,
               (double)(att_node_bus_load(&ns) * 100.0f));
        fflush(stdout);
    }

    while (!g_stop && (o.count == 0 || ps.steps < o.count)) {
        struct pollfd p;
        int r;
        p.fd = s;
        p.events = POLLIN;
        p.revents = 0;
        r = poll(&p, 1, 200);
        if (r < 0) {
            if (errno == EINTR) continue;
            fprintf(stderr, PROG ": error: poll failed: %s\n", strerror(errno));
            rc = 1;
            break;
        }
        if (r == 0) continue;
        if (p.revents & (POLLERR | POLLHUP | POLLNVAL)) {
            int err = 0;
            socklen_t len = sizeof err;
            (void)getsockopt(s, SOL_SOCKET, SO_ERROR, &err, &len);
            if (!iface_gone(err)) {
                fprintf(stderr, PROG ": error: CAN socket error on '%s': %s\n", o.channel,
                        err ? strerror(err) : "poll reported an error");
            }
            rc = 1;
            break;
        }
        /* read everything that is queued, feeding the core as we go */
        for (;;) {
            struct canfd_frame in;
            att_can_frame_t f;
            ssize_t n = read(s, &in, sizeof in);
            if (n < 0) {
                if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) break;
                if (!iface_gone(errno)) fprintf(stderr, PROG ": error: read from CAN socket failed: %s\n", strerror(errno));
                rc = 1;
                break;
            }
            if (n != (ssize_t)CAN_MTU && n != (ssize_t)CANFD_MTU) {
                fprintf(stderr, PROG ": error: unexpected read size %ld from the CAN socket\n", (long)n);
                rc = 1;
                break;
            }
            ps.rx_frames++;
            if (in.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) {
                ps.rx_ignored++;
                continue;
            }
            memset(&f, 0, sizeof f);
            f.id = in.can_id & CAN_SFF_MASK;
            f.fd = (uint8_t)(n == (ssize_t)CANFD_MTU);
            {
                uint8_t max_len = (uint8_t)(f.fd ? CANFD_MAX_DLEN : CAN_MAX_DLEN);
                f.len = in.len > max_len ? max_len : in.len;
            }
            memcpy(f.data, in.data, f.len);
            if (!att_node_rx(&g_node, &f)) ps.rx_rejected++;
            ps.steps += (unsigned long long)att_node_poll(&g_node);
            if (flush_tx(s, &g_node, o.fd, &ps) != 0) {
                rc = 1;
                break;
            }
            if (o.count != 0 && ps.steps >= o.count) break;
        }
        if (rc != 0) break;
    }
    if (rc == 0) {
        ps.steps += (unsigned long long)att_node_poll(&g_node);
        if (flush_tx(s, &g_node, o.fd, &ps) != 0) rc = 1;
    }
    print_stats(&g_node, &ps);
    close(s);
    return rc;
}
