/**
 * @file att_port.h
 * @brief Cortex-M4F port of attica: start-up, floating-point environment, exit hooks.
 *
 * startup.c is a complete bare-metal start-up for an ARMv7E-M core with the FPv4-SP FPU (Cortex-M4F),
 * written for the QEMU machine mps2-an386 (linker script mps2_an386.ld) but free of board specifics:
 * vector table, .data copy and .bss clear, FPU enable, a fixed and checked floating-point
 * environment, then main(). semihost.c adds ARM semihosting (command line, exit status, newlib
 * stdio on host files) for test images run under QEMU.
 *
 * The numerics contract of attica (bit-identical results on every CPU) needs, on the FPU:
 * round to nearest even, no flush-to-zero, no default-NaN mode ("RunFast" off), in thread mode and
 * in every exception handler that runs a filter (FPDSCR gives the FPSCR of handlers).
 * att_port_fp_init() sets exactly that and att_port_fp_ok() checks it; call the check in your own
 * start-up if you do not use this one.
 */
#ifndef ATT_PORT_H
#define ATT_PORT_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/** FPSCR / FPDSCR bits of the numerics contract. */
#define ATT_FPSCR_AHP ((uint32_t)1u << 26)          /**< alternative half precision: off */
#define ATT_FPSCR_DN ((uint32_t)1u << 25)           /**< default NaN: off */
#define ATT_FPSCR_FZ ((uint32_t)1u << 24)           /**< flush to zero: off */
#define ATT_FPSCR_RMODE ((uint32_t)3u << 22)        /**< rounding mode: 00 = to nearest, ties to even */
#define ATT_FPSCR_MODE_MASK (ATT_FPSCR_AHP | ATT_FPSCR_DN | ATT_FPSCR_FZ | ATT_FPSCR_RMODE)
#define ATT_FPSCR_REQUIRED 0ul             /**< value of the mode bits attica needs */

/** Exit status of a test image whose floating-point environment is wrong (see att_port_fp_ok). */
#define ATT_PORT_EXIT_FPSCR 90
/** Exit status of a test image that took a fault (HardFault, BusFault, ...). */
#define ATT_PORT_EXIT_FAULT 91

/** Enable CP10/CP11, set FPSCR and FPDSCR to IEEE mode (see above), keep lazy FP context saving. */
void att_port_fp_init(void);
/** true when FPSCR and FPDSCR have the mode bits attica needs and the FPU is enabled. */
bool att_port_fp_ok(void);
/** The current FPSCR. */
uint32_t att_port_fpscr(void);

/** The command line as argc/argv; the default (weak) gives argc 0. semihost.c asks the debugger. */
int att_port_args(char ***argv);
#if defined(__GNUC__)
#define ATT_PORT_NORETURN __attribute__((noreturn))
#else
#define ATT_PORT_NORETURN
#endif

/** Called with main()'s return value; the default (weak) sleeps forever. semihost.c ends the run. */
ATT_PORT_NORETURN void att_port_exit(int status);
/** Called instead of main() when att_port_fp_ok() fails after att_port_fp_init(), and on faults. */
ATT_PORT_NORETURN void att_port_fatal(int status);

#ifdef __cplusplus
}
#endif

#endif /* ATT_PORT_H */
