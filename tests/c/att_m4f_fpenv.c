/**
 * @file att_m4f_fpenv.c
 * @brief Cortex-M4F floating-point environment left by startup.c, checked by arithmetic.
 *
 * Test harness for a Cortex-M4F image (startup.c + semihost.c), run under QEMU by tests/test_cross.py.
 * Checks, in thread mode and in an exception handler (SVC, whose FPSCR comes from FPDSCR):
 * - att_port_fp_ok() and the FPSCR mode bits (RMode 00, FZ 0, DN 0, AHP 0);
 * - subnormal results and operands are kept (no flush-to-zero);
 * - a quiet NaN operand's payload propagates (default-NaN mode off);
 * - round to nearest, ties to even;
 * and that the check can fail: with FZ set by hand att_port_fp_ok() is false and a subnormal result
 * flushes to zero (so the emulator models FZ and the arithmetic checks above mean something).
 *
 * Prints one line per check ("ok ..." / "FAIL ..."); exit status = number of failed checks.
 */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "att_port.h"

void SVC_Handler(void);

static volatile float v_min_normal = 0x1p-126f;
static volatile float v_half = 0.5f;
static volatile float v_sub = 0x1p-140f;
static volatile float v_one = 1.0f;
static volatile float v_tie = 0x1p-24f;
static volatile float v_above_tie = 0x1.8p-24f;
static volatile float v_odd = 0x1.000002p+0f; /* 1 + 2^-23 */
static volatile uint32_t svc_fpscr;
static volatile float svc_product;
static int failures;

static uint32_t bits(float f)
{
    uint32_t w;
    memcpy(&w, &f, sizeof w);
    return w;
}

static float from_bits(uint32_t w)
{
    float f;
    memcpy(&f, &w, sizeof f);
    return f;
}

static void check(int ok, const char *what, uint32_t got)
{
    printf("%s %s (0x%08lx)\n", ok ? "ok" : "FAIL", what, (unsigned long)got);
    if (!ok) {
        failures++;
    }
}

static void set_fpscr(uint32_t v) { __asm__ volatile("vmsr fpscr, %0" ::"r"(v) : "memory"); }

/* The filter could run in an interrupt: its FPSCR is FPDSCR's. */
void SVC_Handler(void)
{
    svc_fpscr = att_port_fpscr();
    svc_product = v_min_normal * v_half;
}

static void arithmetic(const char *where)
{
    char what[96];
    const float sub = v_min_normal * v_half;
    const float nan_in = from_bits(0x7fc12345u);
    volatile float nan_v = nan_in;
    const float nan_out = nan_v + v_one;
    snprintf(what, sizeof what, "%s: 2^-126 * 0.5 = 2^-127 (no flush to zero)", where);
    check(bits(sub) == 0x00400000u, what, bits(sub));
    snprintf(what, sizeof what, "%s: subnormal operand kept: 2^-140 * 2 = 2^-139", where);
    check(bits(v_sub * 2.0f) == 0x00000400u, what, bits(v_sub * 2.0f));
    snprintf(what, sizeof what, "%s: NaN payload propagates (default NaN off)", where);
    check(bits(nan_out) == 0x7fc12345u, what, bits(nan_out));
    snprintf(what, sizeof what, "%s: 1 + 2^-24 = 1 (tie to even)", where);
    check(bits(v_one + v_tie) == 0x3f800000u, what, bits(v_one + v_tie));
    snprintf(what, sizeof what, "%s: (1 + 2^-23) + 2^-24 = 1 + 2^-22 (tie to even)", where);
    check(bits(v_odd + v_tie) == 0x3f800002u, what, bits(v_odd + v_tie));
    snprintf(what, sizeof what, "%s: 1 + 1.5 * 2^-24 = 1 + 2^-23 (nearest)", where);
    check(bits(v_one + v_above_tie) == 0x3f800001u, what, bits(v_one + v_above_tie));
}

int main(void)
{
    uint32_t fpscr = att_port_fpscr();
    check(att_port_fp_ok(), "att_port_fp_ok() after start-up", fpscr);
    check((fpscr & ATT_FPSCR_MODE_MASK) == ATT_FPSCR_REQUIRED, "FPSCR RMode=00 FZ=0 DN=0 AHP=0", fpscr);
    arithmetic("thread");

    __asm__ volatile("svc 0" ::: "memory");
    check((svc_fpscr & ATT_FPSCR_MODE_MASK) == ATT_FPSCR_REQUIRED, "handler FPSCR (from FPDSCR) in IEEE mode",
          svc_fpscr);
    check(bits(svc_product) == 0x00400000u, "handler: 2^-126 * 0.5 = 2^-127", bits(svc_product));

    /* The check must be able to fail: flush-to-zero on by hand. */
    set_fpscr(fpscr | ATT_FPSCR_FZ);
    {
        const int detected = !att_port_fp_ok();
        const float flushed = v_min_normal * v_half;
        set_fpscr(fpscr);
        check(detected, "att_port_fp_ok() is false with FZ set", fpscr | ATT_FPSCR_FZ);
        check(bits(flushed) == 0u, "with FZ set 2^-126 * 0.5 flushes to 0 (the emulator models FZ)",
              bits(flushed));
    }
    set_fpscr(fpscr | ATT_FPSCR_DN);
    {
        const int detected = !att_port_fp_ok();
        volatile float nan_v = from_bits(0x7fc12345u);
        const float dn = nan_v + v_one;
        set_fpscr(fpscr);
        check(detected, "att_port_fp_ok() is false with DN set", fpscr | ATT_FPSCR_DN);
        check(bits(dn) == 0x7fc00000u, "with DN set the NaN is the default NaN (the emulator models DN)",
              bits(dn));
    }
    check(att_port_fp_ok(), "att_port_fp_ok() again after restoring FPSCR", att_port_fpscr());
    printf("%d failure(s)\n", failures);
    return failures;
}
