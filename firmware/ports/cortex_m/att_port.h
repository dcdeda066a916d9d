/**
 * @file att_port.h
 * @brief Cortex-M port of attica: floating-point environment, start-up hooks, exit hooks.
 *
 * Three files, linked as needed:
 * - att_fpenv.c: the floating-point environment alone (att_port_fp_init, att_port_fp_ok,
 *   att_port_fpscr). A project with its own (vendor) start-up links just this file and calls
 *   att_port_fp_init() in its reset handler before any floating-point instruction runs (with the
 *   FPU off the first one faults), then att_port_fp_ok() once.
 * - startup.c: a complete bare-metal start-up (vector table, .data copy and .bss clear, then main())
 *   for ARMv7E-M (M4F, M7), ARMv8-M Mainline (M33) and ARMv6-M (M0/M0+), free of board specifics;
 *   its Reset_Handler calls the two functions of att_fpenv.c (link both).
 * - semihost.c: ARM semihosting (command line, exit status, newlib stdio on host files) for test
 *   images run under QEMU.
 *
 * The numerics contract of attica (bit-identical results on every CPU) needs, on the FPU:
 * round to nearest even, no flush-to-zero, no default-NaN mode ("RunFast" off), in thread mode and
 * in every exception handler that runs a filter (FPDSCR gives the FPSCR of handlers).
 * att_port_fp_init() sets exactly that and att_port_fp_ok() checks it. On a core without an FPU
 * (soft float) both are no-ops that succeed.
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

/* att_fpenv.c */
/**
 * Enable CP10/CP11 (CPACR), set the mode bits of FPSCR and FPDSCR to ATT_FPSCR_REQUIRED (IEEE: see
 * above), clear FPSCR's cumulative exception flags, keep lazy FP context saving (FPCCR ASPEN, LSPEN).
 * Privileged code only (the reset handler). No-op without an FPU.
 */
void att_port_fp_init(void);
/** true when the FPU is enabled and FPSCR and FPDSCR have the mode bits attica needs (always without an FPU). */
bool att_port_fp_ok(void);
/** The current FPSCR (ATT_FPSCR_REQUIRED without an FPU). */
uint32_t att_port_fpscr(void);

/* startup.c (weak defaults), semihost.c (semihosting versions) */

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
