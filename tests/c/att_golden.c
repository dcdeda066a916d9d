/**
 * @file att_golden.c
 * @brief Golden-vector runner: feeds files of inputs through the firmware and writes the outputs.
 *
 * Test harness, not firmware: plain C99 with stdio/stdlib only (no POSIX), so the same program runs
 * natively, under qemu-user (aarch64, riscv64) and on a Cortex-M4F with semihosting. All file data
 * is explicitly little-endian, so one set of files serves every target. Python side:
 * tools/attica_dev/golden.py (writes inputs, runs this program, compares with the numpy reference).
 *
 * Usage
 *   att_golden math FN in.bin out.bin          FN: sin cos atan2 asin acos sqrt wrap_pi quat_mul ...
 *   att_golden KIND settings.txt in.bin out.bin KIND: a filter name of att_filter_name (ars, mars, ...)
 *   att_golden list                            print the math functions and filter kinds
 * Exit status: 0 ok, 1 usage, 2 file/format error, 3 settings refused by the filter.
 *
 * Table files (inputs and outputs), little-endian, header of 48 bytes:
 *   off  0  char[4]  magic "ATGV"
 *   off  4  u32      version (1)
 *   off  8  u32      rows
 *   off 12  u32      width: 32-bit words per row
 *   off 16  u32      streams: independent filter instances interleaved row by row (1 for math)
 *   off 20  u32      reserved, 0
 *   off 24  char[24] tag: the math function or filter kind name, NUL padded ("" = unchecked on input)
 *   then rows * width words, row-major; a word is a u32 or the bits of an IEEE-754 binary32 float.
 *
 * math: input row = the function's arguments concatenated, output row = its results; the rows are
 * those of host/attica/native.py _MAPQ (e.g. quat_mul: a(4) b(4) -> 4; quat_normalize: q(4) ->
 * q(4) ok(1) with ok 1.0f/0.0f). The scalar functions have width 1 (atan2: y x -> 1).
 *
 * filters: input row = gyr(3) acc(3) [mag(3)] (width 6, mag absent, or 9), floats. Row r belongs to
 * step r / streams of instance r % streams. Output row (17 words) = att_output_t field by field, as
 * att_filter_output gives it after the step: q(4) euler(3) gyro_bias(3) cov(4) as floats, flags,
 * steps, valid as u32.
 *
 * Settings file: text, one "key=value" per line, "#" starts a comment, blank lines ignored:
 *   format=attica-settings-1     (optional; checked when present)
 *   kind=ars                     (optional; must match the command when present)
 *   dt=0x3c23d70a                float fields: the binary32 bit pattern (here 0.01), read by strtoul
 *   bias_mode=3                  integer, enum and bool fields: decimal or 0x hex
 *   bias_init.x=0x00000000       vector/quaternion members as name.x / name.w ...
 *   calib.12=0x3c23d70a          the input/output stages (att_calib.h): field 12 of att_calib_field_set
 *                                (here the gyro offset x), as binary32 bits; any calib.N key applies
 *                                att_filter_calibrate to every instance after init
 * Fields not given keep att_filter_settings_default(kind, 0.01f). Unknown keys are an error.
 */
#include <errno.h>
#include <limits.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "attica/att_filter.h"
#include "attica/att_math.h"
#include "attica/att_sensor.h"

#define GV_VERSION 1u
#define GV_HEADER_BYTES 48u
#define GV_TAG_BYTES 24u
#define GV_MAX_WIDTH 64u
#define GV_OUT_WIDTH 17u

/* The word I/O copies floats bit for bit to and from uint32_t: float must be 32 bits wide (and
 * IEEE-754 binary32, which the firmware requires anyway). */
typedef char gv_check_float_size[(sizeof(float) == 4u && sizeof(uint32_t) == 4u) ? 1 : -1];

enum { GV_OK = 0, GV_EXIT_USAGE = 1, GV_EXIT_IO = 2, GV_EXIT_SETTINGS = 3 };

typedef struct {
    uint32_t rows;
    uint32_t width;
    uint32_t streams;
    char tag[GV_TAG_BYTES + 1u];
} gv_header_t;

/* ---- little-endian words ---------------------------------------------------------------------- */

static uint32_t gv_get_u32(const unsigned char *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static void gv_put_u32(unsigned char *p, uint32_t w)
{
    p[0] = (unsigned char)(w & 0xffu);
    p[1] = (unsigned char)((w >> 8) & 0xffu);
    p[2] = (unsigned char)((w >> 16) & 0xffu);
    p[3] = (unsigned char)((w >> 24) & 0xffu);
}

static float gv_w2f(uint32_t w)
{
    float f;
    memcpy(&f, &w, sizeof f);
    return f;
}

static uint32_t gv_f2w(float f)
{
    uint32_t w;
    memcpy(&w, &f, sizeof w);
    return w;
}

/* ---- table files ------------------------------------------------------------------------------ */

static int gv_read_header(FILE *fp, const char *path, gv_header_t *h)
{
    unsigned char b[GV_HEADER_BYTES];
    uint32_t version;
    if (fread(b, 1u, sizeof b, fp) != sizeof b) {
        fprintf(stderr, "att_golden: %s: short header\n", path);
        return GV_EXIT_IO;
    }
    if (memcmp(b, "ATGV", 4u) != 0) {
        fprintf(stderr, "att_golden: %s: bad magic (not an attica golden table)\n", path);
        return GV_EXIT_IO;
    }
    version = gv_get_u32(b + 4);
    if (version != GV_VERSION) {
        fprintf(stderr, "att_golden: %s: version %lu, expected %lu\n", path, (unsigned long)version,
                (unsigned long)GV_VERSION);
        return GV_EXIT_IO;
    }
    h->rows = gv_get_u32(b + 8);
    h->width = gv_get_u32(b + 12);
    h->streams = gv_get_u32(b + 16);
    memcpy(h->tag, b + 24, GV_TAG_BYTES);
    h->tag[GV_TAG_BYTES] = '\0';
    if (h->width == 0u || h->width > GV_MAX_WIDTH || h->streams == 0u || h->rows % h->streams != 0u) {
        fprintf(stderr, "att_golden: %s: bad shape rows=%lu width=%lu streams=%lu\n", path,
                (unsigned long)h->rows, (unsigned long)h->width, (unsigned long)h->streams);
        return GV_EXIT_IO;
    }
    return GV_OK;
}

static int gv_write_header(FILE *fp, const char *path, uint32_t rows, uint32_t width, uint32_t streams,
                           const char *tag)
{
    unsigned char b[GV_HEADER_BYTES];
    size_t n = strlen(tag);
    memset(b, 0, sizeof b);
    memcpy(b, "ATGV", 4u);
    gv_put_u32(b + 4, GV_VERSION);
    gv_put_u32(b + 8, rows);
    gv_put_u32(b + 12, width);
    gv_put_u32(b + 16, streams);
    memcpy(b + 24, tag, (n < GV_TAG_BYTES) ? n : GV_TAG_BYTES);
    if (fwrite(b, 1u, sizeof b, fp) != sizeof b) {
        fprintf(stderr, "att_golden: %s: write failed\n", path);
        return GV_EXIT_IO;
    }
    return GV_OK;
}

static int gv_read_row(FILE *fp, const char *path, uint32_t width, uint32_t *words)
{
    unsigned char b[4u * GV_MAX_WIDTH];
    uint32_t i;
    if (fread(b, 4u, width, fp) != width) {
        fprintf(stderr, "att_golden: %s: file shorter than its header says\n", path);
        return GV_EXIT_IO;
    }
    for (i = 0u; i < width; i++) {
        words[i] = gv_get_u32(b + 4u * i);
    }
    return GV_OK;
}

static int gv_write_row(FILE *fp, const char *path, uint32_t width, const uint32_t *words)
{
    unsigned char b[4u * GV_MAX_WIDTH];
    uint32_t i;
    for (i = 0u; i < width; i++) {
        gv_put_u32(b + 4u * i, words[i]);
    }
    if (fwrite(b, 4u, width, fp) != width) {
        fprintf(stderr, "att_golden: %s: write failed\n", path);
        return GV_EXIT_IO;
    }
    return GV_OK;
}

static int gv_check_tag(const gv_header_t *h, const char *path, const char *name)
{
    if (h->tag[0] != '\0' && strcmp(h->tag, name) != 0) {
        fprintf(stderr, "att_golden: %s: made for '%s', not '%s'\n", path, h->tag, name);
        return GV_EXIT_IO;
    }
    return GV_OK;
}

static int gv_close(FILE *fp, const char *path, int status)
{
    if (fclose(fp) != 0 && status == GV_OK) {
        fprintf(stderr, "att_golden: %s: close failed\n", path);
        return GV_EXIT_IO;
    }
    return status;
}

/* ---- math functions --------------------------------------------------------------------------- */

static att_vec3_t gv_v3(const float *p)
{
    att_vec3_t v;
    v.x = p[0];
    v.y = p[1];
    v.z = p[2];
    return v;
}

static att_quat_t gv_q(const float *p)
{
    att_quat_t q;
    q.w = p[0];
    q.x = p[1];
    q.y = p[2];
    q.z = p[3];
    return q;
}

static void gv_put_v3(float *p, att_vec3_t v)
{
    p[0] = v.x;
    p[1] = v.y;
    p[2] = v.z;
}

static void gv_put_q(float *p, att_quat_t q)
{
    p[0] = q.w;
    p[1] = q.x;
    p[2] = q.y;
    p[3] = q.z;
}

static void gv_sin(const float *in, float *out) { out[0] = att_sinf(in[0]); }
static void gv_cos(const float *in, float *out) { out[0] = att_cosf(in[0]); }
static void gv_atan2(const float *in, float *out) { out[0] = att_atan2f(in[0], in[1]); }
static void gv_asin(const float *in, float *out) { out[0] = att_asinf(in[0]); }
static void gv_acos(const float *in, float *out) { out[0] = att_acosf(in[0]); }
static void gv_sqrt(const float *in, float *out) { out[0] = att_sqrtf(in[0]); }
static void gv_wrap_pi(const float *in, float *out) { out[0] = att_wrap_pi(in[0]); }

static void gv_quat_mul(const float *in, float *out) { gv_put_q(out, att_quat_mul(gv_q(in), gv_q(in + 4))); }

static void gv_quat_normalize(const float *in, float *out)
{
    att_quat_t q;
    const bool ok = att_quat_normalize(gv_q(in), &q);
    gv_put_q(out, q);
    out[4] = ok ? 1.0f : 0.0f;
}

static void gv_quat_rotate(const float *in, float *out)
{
    gv_put_v3(out, att_quat_rotate(gv_q(in), gv_v3(in + 4)));
}

static void gv_quat_rotate_inv(const float *in, float *out)
{
    gv_put_v3(out, att_quat_rotate_inv(gv_q(in), gv_v3(in + 4)));
}

static void gv_quat_from_euler(const float *in, float *out)
{
    gv_put_q(out, att_quat_from_euler(in[0], in[1], in[2]));
}

static void gv_quat_to_euler(const float *in, float *out) { gv_put_v3(out, att_quat_to_euler(gv_q(in))); }
static void gv_quat_to_matrix(const float *in, float *out) { att_quat_to_matrix(gv_q(in), out); }
static void gv_quat_from_rotvec(const float *in, float *out) { gv_put_q(out, att_quat_from_rotvec(gv_v3(in))); }

static void gv_quat_from_axis_angle(const float *in, float *out)
{
    gv_put_q(out, att_quat_from_axis_angle(gv_v3(in), in[3]));
}

static void gv_vec3_normalize(const float *in, float *out)
{
    att_vec3_t v;
    const bool ok = att_vec3_normalize(gv_v3(in), &v);
    gv_put_v3(out, v);
    out[3] = ok ? 1.0f : 0.0f;
}

static void gv_vec3_cross(const float *in, float *out)
{
    gv_put_v3(out, att_vec3_cross(gv_v3(in), gv_v3(in + 3)));
}

static void gv_sensor_tilt(const float *in, float *out) { gv_put_v3(out, att_sensor_tilt(gv_v3(in))); }

typedef struct {
    const char *name;
    uint32_t in_width;
    uint32_t out_width;
    void (*fn)(const float *in, float *out);
} gv_math_t;

static const gv_math_t gv_math[] = {
    {"sin", 1u, 1u, gv_sin},
    {"cos", 1u, 1u, gv_cos},
    {"atan2", 2u, 1u, gv_atan2},
    {"asin", 1u, 1u, gv_asin},
    {"acos", 1u, 1u, gv_acos},
    {"sqrt", 1u, 1u, gv_sqrt},
    {"wrap_pi", 1u, 1u, gv_wrap_pi},
    {"quat_mul", 8u, 4u, gv_quat_mul},
    {"quat_normalize", 4u, 5u, gv_quat_normalize},
    {"quat_rotate", 7u, 3u, gv_quat_rotate},
    {"quat_rotate_inv", 7u, 3u, gv_quat_rotate_inv},
    {"quat_from_euler", 3u, 4u, gv_quat_from_euler},
    {"quat_to_euler", 4u, 3u, gv_quat_to_euler},
    {"quat_to_matrix", 4u, 9u, gv_quat_to_matrix},
    {"quat_from_rotvec", 3u, 4u, gv_quat_from_rotvec},
    {"quat_from_axis_angle", 4u, 4u, gv_quat_from_axis_angle},
    {"vec3_normalize", 3u, 4u, gv_vec3_normalize},
    {"vec3_cross", 6u, 3u, gv_vec3_cross},
    {"sensor_tilt", 3u, 3u, gv_sensor_tilt},
};

#define GV_N_MATH (sizeof gv_math / sizeof gv_math[0])

static const gv_math_t *gv_find_math(const char *name)
{
    size_t i;
    for (i = 0u; i < GV_N_MATH; i++) {
        if (strcmp(gv_math[i].name, name) == 0) {
            return &gv_math[i];
        }
    }
    return NULL;
}

static int gv_run_math(const char *name, const char *in_path, const char *out_path)
{
    const gv_math_t *m = gv_find_math(name);
    gv_header_t h;
    FILE *fin;
    FILE *fout;
    uint32_t words[GV_MAX_WIDTH];
    float in[GV_MAX_WIDTH];
    float out[GV_MAX_WIDTH];
    uint32_t r;
    uint32_t i;
    int st;
    if (m == NULL) {
        fprintf(stderr, "att_golden: unknown math function '%s' (try: att_golden list)\n", name);
        return GV_EXIT_USAGE;
    }
    fin = fopen(in_path, "rb");
    if (fin == NULL) {
        fprintf(stderr, "att_golden: cannot open %s\n", in_path);
        return GV_EXIT_IO;
    }
    st = gv_read_header(fin, in_path, &h);
    if (st == GV_OK) {
        st = gv_check_tag(&h, in_path, name);
    }
    if (st == GV_OK && h.width != m->in_width) {
        fprintf(stderr, "att_golden: %s: width %lu, %s takes %lu\n", in_path, (unsigned long)h.width, name,
                (unsigned long)m->in_width);
        st = GV_EXIT_IO;
    }
    if (st != GV_OK) {
        return gv_close(fin, in_path, st);
    }
    fout = fopen(out_path, "wb");
    if (fout == NULL) {
        fprintf(stderr, "att_golden: cannot create %s\n", out_path);
        return gv_close(fin, in_path, GV_EXIT_IO);
    }
    st = gv_write_header(fout, out_path, h.rows, m->out_width, 1u, name);
    for (r = 0u; r < h.rows && st == GV_OK; r++) {
        st = gv_read_row(fin, in_path, m->in_width, words);
        if (st != GV_OK) {
            break;
        }
        for (i = 0u; i < m->in_width; i++) {
            in[i] = gv_w2f(words[i]);
        }
        m->fn(in, out);
        for (i = 0u; i < m->out_width; i++) {
            words[i] = gv_f2w(out[i]);
        }
        st = gv_write_row(fout, out_path, m->out_width, words);
    }
    st = gv_close(fin, in_path, st);
    return gv_close(fout, out_path, st);
}

/* ---- filter settings -------------------------------------------------------------------------- */

typedef enum { GV_F32 = 0, GV_INT = 1 } gv_field_type_t;

typedef struct {
    att_filter_kind_t kind;
    const char *name;
    size_t offset;
    size_t size;
    gv_field_type_t type;
} gv_field_t;

/* One line per settings field; member is the path inside att_filter_settings_t. */
#define GV_FIELD(kind, name, member, type)                                                                   \
    {kind, name, offsetof(att_filter_settings_t, member), sizeof(((att_filter_settings_t *)NULL)->member), type}

static const gv_field_t gv_fields[] = {
/* Generated from the settings dataclasses (host/attica/settings.py, whose field names are the C
 * member names) by tools/attica_dev/golden.py write_fields_header(): one GV_FIELD line per field. */
#include "att_golden_fields.h"
};

#define GV_N_FIELDS (sizeof gv_fields / sizeof gv_fields[0])

/* A kind is available when the firmware has defaults for it (att_filter_settings_default). */
static int gv_kind_available(att_filter_kind_t kind)
{
    att_filter_settings_t s;
    return strcmp(att_filter_name(kind), "?") != 0 && att_filter_settings_default(kind, 0.01f, &s) == ATT_OK;
}

static int gv_kind_from_name(const char *name, att_filter_kind_t *kind)
{
    int k;
    for (k = 1; k < 64; k++) {
        if (gv_kind_available((att_filter_kind_t)k) && strcmp(att_filter_name((att_filter_kind_t)k), name) == 0) {
            *kind = (att_filter_kind_t)k;
            return 1;
        }
    }
    return 0;
}

/* Store an integer into a field of 1, 2 or 4 bytes (enum, bool, uint32_t) in native byte order. */
static int gv_store_int(unsigned char *dst, size_t size, uint32_t value)
{
    if (size == sizeof(uint8_t) && value <= 0xffu) {
        const uint8_t v = (uint8_t)value;
        memcpy(dst, &v, sizeof v);
        return 1;
    }
    if (size == sizeof(uint16_t) && value <= 0xffffu) {
        const uint16_t v = (uint16_t)value;
        memcpy(dst, &v, sizeof v);
        return 1;
    }
    if (size == sizeof(uint32_t)) {
        memcpy(dst, &value, sizeof value);
        return 1;
    }
    return 0;
}

static char *gv_trim(char *s)
{
    char *end;
    while (*s == ' ' || *s == '\t') {
        s++;
    }
    end = s + strlen(s);
    while (end > s && (end[-1] == ' ' || end[-1] == '\t' || end[-1] == '\r' || end[-1] == '\n')) {
        end--;
    }
    *end = '\0';
    return s;
}

static int gv_parse_u32(const char *text, uint32_t *value)
{
    char *end = NULL;
    unsigned long v;
    if (*text == '\0' || *text == '-' || *text == '+') {
        return 0;
    }
    errno = 0;
    v = strtoul(text, &end, 0);
    if (end == NULL || *end != '\0' || errno == ERANGE) {
        return 0;
    }
#if ULONG_MAX > 0xffffffffUL
    if (v > 0xffffffffUL) {
        return 0;
    }
#endif
    *value = (uint32_t)v;
    return 1;
}

static int gv_apply(att_filter_kind_t kind, att_filter_settings_t *s, const char *key, const char *val,
                    const char *path, unsigned long line)
{
    size_t i;
    uint32_t w;
    if (!gv_parse_u32(val, &w)) {
        fprintf(stderr, "att_golden: %s:%lu: '%s' is not a 32-bit unsigned number\n", path, line, val);
        return GV_EXIT_IO;
    }
    for (i = 0u; i < GV_N_FIELDS; i++) {
        const gv_field_t *f = &gv_fields[i];
        unsigned char *dst = (unsigned char *)s + f->offset;
        if (f->kind != kind || strcmp(f->name, key) != 0) {
            continue;
        }
        if (f->type == GV_F32) {
            const float x = gv_w2f(w);
            memcpy(dst, &x, sizeof x);
            return GV_OK;
        }
        if (!gv_store_int(dst, f->size, w)) {
            fprintf(stderr, "att_golden: %s:%lu: %s=%s does not fit the field\n", path, line, key, val);
            return GV_EXIT_IO;
        }
        return GV_OK;
    }
    fprintf(stderr, "att_golden: %s:%lu: %s has no setting '%s'\n", path, line, att_filter_name(kind), key);
    return GV_EXIT_IO;
}

static att_calib_settings_t gv_calib; /* the calib.N keys of the settings file */
static int gv_have_calib;

static int gv_apply_calib(const char *key, const char *val, const char *path, unsigned long line)
{
    char *end = NULL;
    unsigned long idx = strtoul(key + 6, &end, 10);
    uint32_t w;
    if (!gv_have_calib) {
        att_calib_settings_default(&gv_calib);
        gv_have_calib = 1;
    }
    if (end == key + 6 || *end != '\0' || idx >= (unsigned long)ATT_CALIB_FIELDS || !gv_parse_u32(val, &w) ||
        !att_calib_field_set(&gv_calib, (uint32_t)idx, gv_w2f(w))) {
        fprintf(stderr, "att_golden: %s:%lu: bad calibration field %s=%s\n", path, line, key, val);
        return GV_EXIT_IO;
    }
    return GV_OK;
}

static int gv_read_settings(const char *path, att_filter_kind_t kind, att_filter_settings_t *s)
{
    char buf[512];
    unsigned long line = 0ul;
    int st = GV_OK;
    FILE *fp = fopen(path, "r");
    if (fp == NULL) {
        fprintf(stderr, "att_golden: cannot open %s\n", path);
        return GV_EXIT_IO;
    }
    if (att_filter_settings_default(kind, 0.01f, s) != ATT_OK) {
        fprintf(stderr, "att_golden: no settings for filter '%s'\n", att_filter_name(kind));
        return gv_close(fp, path, GV_EXIT_SETTINGS);
    }
    while (st == GV_OK && fgets(buf, (int)sizeof buf, fp) != NULL) {
        char *hash;
        char *eq;
        char *key;
        char *val;
        line++;
        if (strchr(buf, '\n') == NULL && !feof(fp)) {
            fprintf(stderr, "att_golden: %s:%lu: line too long\n", path, line);
            st = GV_EXIT_IO;
            break;
        }
        hash = strchr(buf, '#');
        if (hash != NULL) {
            *hash = '\0';
        }
        key = gv_trim(buf);
        if (*key == '\0') {
            continue;
        }
        eq = strchr(key, '=');
        if (eq == NULL) {
            fprintf(stderr, "att_golden: %s:%lu: expected key=value\n", path, line);
            st = GV_EXIT_IO;
            break;
        }
        *eq = '\0';
        val = gv_trim(eq + 1);
        key = gv_trim(key);
        if (strcmp(key, "format") == 0) {
            if (strcmp(val, "attica-settings-1") != 0) {
                fprintf(stderr, "att_golden: %s:%lu: unknown format '%s'\n", path, line, val);
                st = GV_EXIT_IO;
            }
        } else if (strcmp(key, "kind") == 0) {
            if (strcmp(val, att_filter_name(kind)) != 0) {
                fprintf(stderr, "att_golden: %s: settings for '%s', not '%s'\n", path, val, att_filter_name(kind));
                st = GV_EXIT_IO;
            }
        } else if (strncmp(key, "calib.", 6) == 0) {
            st = gv_apply_calib(key, val, path, line);
        } else {
            st = gv_apply(kind, s, key, val, path, line);
        }
    }
    if (st == GV_OK && ferror(fp)) {
        fprintf(stderr, "att_golden: %s: read error\n", path);
        st = GV_EXIT_IO;
    }
    return gv_close(fp, path, st);
}

/* ---- filters ---------------------------------------------------------------------------------- */

static void gv_output_words(const att_output_t *o, uint32_t *w)
{
    w[0] = gv_f2w(o->q.w);
    w[1] = gv_f2w(o->q.x);
    w[2] = gv_f2w(o->q.y);
    w[3] = gv_f2w(o->q.z);
    w[4] = gv_f2w(o->euler.x);
    w[5] = gv_f2w(o->euler.y);
    w[6] = gv_f2w(o->euler.z);
    w[7] = gv_f2w(o->gyro_bias.x);
    w[8] = gv_f2w(o->gyro_bias.y);
    w[9] = gv_f2w(o->gyro_bias.z);
    w[10] = gv_f2w(o->cov[0]);
    w[11] = gv_f2w(o->cov[1]);
    w[12] = gv_f2w(o->cov[2]);
    w[13] = gv_f2w(o->cov[3]);
    w[14] = o->flags;
    w[15] = o->steps;
    w[16] = o->valid;
}

static att_vec3_t gv_words_v3(const uint32_t *w)
{
    att_vec3_t v;
    v.x = gv_w2f(w[0]);
    v.y = gv_w2f(w[1]);
    v.z = gv_w2f(w[2]);
    return v;
}

static int gv_run_filter(att_filter_kind_t kind, const char *set_path, const char *in_path, const char *out_path)
{
    att_filter_settings_t settings;
    att_filter_t *filters;
    att_output_t out;
    att_sample_t sample;
    gv_header_t h;
    FILE *fin;
    FILE *fout;
    uint32_t words[GV_MAX_WIDTH];
    uint32_t r;
    uint32_t j;
    att_status_t init;
    int st;
    const char *name = att_filter_name(kind);

    st = gv_read_settings(set_path, kind, &settings);
    if (st != GV_OK) {
        return st;
    }
    fin = fopen(in_path, "rb");
    if (fin == NULL) {
        fprintf(stderr, "att_golden: cannot open %s\n", in_path);
        return GV_EXIT_IO;
    }
    st = gv_read_header(fin, in_path, &h);
    if (st == GV_OK) {
        st = gv_check_tag(&h, in_path, name);
    }
    if (st == GV_OK && h.width != 6u && h.width != 9u) {
        fprintf(stderr, "att_golden: %s: width %lu; filters take 6 (gyr acc) or 9 (gyr acc mag)\n", in_path,
                (unsigned long)h.width);
        st = GV_EXIT_IO;
    }
    if (st != GV_OK) {
        return gv_close(fin, in_path, st);
    }
    filters = (att_filter_t *)calloc(h.streams, sizeof *filters);
    if (filters == NULL) {
        fprintf(stderr, "att_golden: out of memory for %lu filters\n", (unsigned long)h.streams);
        return gv_close(fin, in_path, GV_EXIT_IO);
    }
    for (j = 0u; j < h.streams; j++) {
        init = att_filter_init(&filters[j], kind, &settings);
        if (init != ATT_OK) {
            fprintf(stderr, "att_golden: %s: att_filter_init(%s) refused the settings (status %d)\n", set_path,
                    name, (int)init);
            free(filters);
            return gv_close(fin, in_path, GV_EXIT_SETTINGS);
        }
        if (gv_have_calib && att_filter_calibrate(&filters[j], &gv_calib) != ATT_OK) {
            fprintf(stderr, "att_golden: %s: att_filter_calibrate refused the calibration (%s)\n", set_path,
                    att_calib_error_name(att_calib_settings_check(&gv_calib)));
            free(filters);
            return gv_close(fin, in_path, GV_EXIT_SETTINGS);
        }
    }
    fout = fopen(out_path, "wb");
    if (fout == NULL) {
        fprintf(stderr, "att_golden: cannot create %s\n", out_path);
        free(filters);
        return gv_close(fin, in_path, GV_EXIT_IO);
    }
    st = gv_write_header(fout, out_path, h.rows, GV_OUT_WIDTH, h.streams, name);
    sample.mag.x = 0.0f;
    sample.mag.y = 0.0f;
    sample.mag.z = 0.0f;
    for (r = 0u; r < h.rows && st == GV_OK; r++) {
        st = gv_read_row(fin, in_path, h.width, words);
        if (st != GV_OK) {
            break;
        }
        sample.gyr = gv_words_v3(words);
        sample.acc = gv_words_v3(words + 3);
        if (h.width == 9u) {
            sample.mag = gv_words_v3(words + 6);
        }
        (void)att_filter_step(&filters[r % h.streams], &sample, &out);
        /* the full record (derived outputs too: Euler angles, covariance) after every step */
        att_filter_output(&filters[r % h.streams], &out);
        gv_output_words(&out, words);
        st = gv_write_row(fout, out_path, GV_OUT_WIDTH, words);
    }
    free(filters);
    st = gv_close(fin, in_path, st);
    return gv_close(fout, out_path, st);
}

/* ---- main ------------------------------------------------------------------------------------- */

static void gv_list(void)
{
    size_t i;
    int k;
    printf("math");
    for (i = 0u; i < GV_N_MATH; i++) {
        printf(" %s:%lu:%lu", gv_math[i].name, (unsigned long)gv_math[i].in_width,
               (unsigned long)gv_math[i].out_width);
    }
    printf("\nfilters");
    for (k = 1; k < 64; k++) {
        if (gv_kind_available((att_filter_kind_t)k)) {
            printf(" %s", att_filter_name((att_filter_kind_t)k));
        }
    }
    printf("\n");
}

static int gv_usage(void)
{
    fprintf(stderr, "usage: att_golden math FN in.bin out.bin\n"
                    "       att_golden KIND settings.txt in.bin out.bin   (KIND: see att_golden list)\n"
                    "       att_golden list\n");
    return GV_EXIT_USAGE;
}

int main(int argc, char **argv)
{
    att_filter_kind_t kind;
    if (argc == 2 && strcmp(argv[1], "list") == 0) {
        gv_list();
        return GV_OK;
    }
    if (argc != 5) {
        return gv_usage();
    }
    if (strcmp(argv[1], "math") == 0) {
        return gv_run_math(argv[2], argv[3], argv[4]);
    }
    if (gv_kind_from_name(argv[1], &kind)) {
        return gv_run_filter(kind, argv[2], argv[3], argv[4]);
    }
    fprintf(stderr, "att_golden: unknown command '%s'\n", argv[1]);
    return gv_usage();
}
