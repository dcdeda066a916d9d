/**
 * @file att_fpenv.c
 * @brief Floating-point environment of attica on Cortex-M: FPU on, FPSCR and FPDSCR in IEEE mode, checked.
 *
 * Separate from startup.c and its vector table, so that a project with its own (vendor) start-up links
 * this file alone and calls att_port_fp_init() early in its reset handler (or before the first filter
 * runs) and att_port_fp_ok() once after it (see att_port.h and docs/integration.md).
 *
 * Compiled for a core with an FPU (__ARM_FP defined: Cortex-M4F, M7, M33 with FPU, ...): CPACR CP10/CP11
 * full access, FPDSCR (the FPSCR every exception handler starts with) and FPSCR set to round to
 * nearest even, no flush-to-zero, no default NaN, no alternative half precision, lazy FP context
 * saving kept on (FPCCR ASPEN + LSPEN). Without an FPU (Cortex-M0/M0+, soft float) the compiler's
 * routines are IEEE round-to-nearest with subnormals: nothing to set, and the check always passes.
 *
 * Registers (ARMv7-M Architecture Reference Manual B3.2.20 CPACR, B3.2.21 FPCCR, B3.2.24 FPDSCR; the same
 * addresses on ARMv8-M Mainline): CPACR 0xE000ED88, FPCCR 0xE000EF34, FPDSCR 0xE000EF3C.
 */
#include "att_port.h"

#include <stdbool.h>
#include <stdint.h>

#if defined(__ARM_FP)

#define ATT_CPACR (*(volatile uint32_t *)0xE000ED88u)
#define ATT_FPCCR (*(volatile uint32_t *)0xE000EF34u)
#define ATT_FPDSCR (*(volatile uint32_t *)0xE000EF3Cu)
#define ATT_CPACR_CP10_CP11 ((uint32_t)0xFu << 20)     /* full access to CP10 and CP11 (the FPU) */
#define ATT_FPCCR_ASPEN_LSPEN ((uint32_t)3u << 30)     /* automatic + lazy FP context save on exceptions */
#define ATT_FPSCR_CUMULATIVE ((uint32_t)0x9Fu)         /* IDC IXC UFC OFC DZC IOC: sticky exception flags */

uint32_t att_port_fpscr(void)
{
    uint32_t v;
    __asm__ volatile("vmrs %0, fpscr" : "=r"(v));
    return v;
}

void att_port_fp_init(void)
{
    uint32_t fpscr;
    ATT_CPACR |= ATT_CPACR_CP10_CP11;
    __asm__ volatile("dsb\n\tisb" ::: "memory");
    /* Handlers start with FPDSCR's modes: the same IEEE mode as thread code. */
    ATT_FPDSCR = (ATT_FPDSCR & ~ATT_FPSCR_MODE_MASK) | ATT_FPSCR_REQUIRED;
    ATT_FPCCR |= ATT_FPCCR_ASPEN_LSPEN;
    fpscr = (att_port_fpscr() & ~ATT_FPSCR_MODE_MASK) | ATT_FPSCR_REQUIRED;
    fpscr &= ~ATT_FPSCR_CUMULATIVE;
    __asm__ volatile("vmsr fpscr, %0" ::"r"(fpscr) : "memory");
}

bool att_port_fp_ok(void)
{
    return (ATT_CPACR & ATT_CPACR_CP10_CP11) == ATT_CPACR_CP10_CP11 &&
           (att_port_fpscr() & ATT_FPSCR_MODE_MASK) == ATT_FPSCR_REQUIRED &&
           (ATT_FPDSCR & ATT_FPSCR_MODE_MASK) == ATT_FPSCR_REQUIRED;
}

#else

/* No FPU (soft float): no floating-point environment to set; the library routines are IEEE. */
uint32_t att_port_fpscr(void) { return ATT_FPSCR_REQUIRED; }

void att_port_fp_init(void) {}

bool att_port_fp_ok(void) { return true; }

#endif
