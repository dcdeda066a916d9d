/**
 * @file semihost.c
 * @brief ARM semihosting glue for test images: command line, exit status, fault reports.
 *
 * Replaces the weak hooks of startup.c:
 * - att_port_args(): the command line from the debugger (SYS_GET_CMDLINE), split at spaces. Under
 *   QEMU it is the -kernel file name followed by the words of -append (or the arg= words of
 *   -semihosting-config).
 * - att_port_exit(): with ATT_SEMIHOST_NEWLIB defined, newlib's exit() (flushes and closes stdio,
 *   then _exit below); otherwise straight to _exit.
 * - _exit() and att_port_fatal(): SYS_EXIT_EXTENDED with the status as the debugger's exit code
 *   (QEMU exits with it), falling back to SYS_EXIT (0 = success, anything else = failure).
 *
 * Newlib's stdio (fopen/fread/fwrite/fprintf to host files, stdout and stderr) comes from librdimon
 * (--specs=rdimon.specs); define ATT_SEMIHOST_NEWLIB so that its handles are opened before main.
 */
#include "att_port.h"

#include <stddef.h>
#include <stdint.h>
#if defined(ATT_SEMIHOST_NEWLIB)
#include <stdlib.h>
void initialise_monitor_handles(void); /* librdimon: opens stdin/stdout/stderr (":tt") */
#endif

#define ATT_SH_SYS_GET_CMDLINE 0x15u
#define ATT_SH_SYS_EXIT 0x18u
#define ATT_SH_SYS_EXIT_EXTENDED 0x20u
#define ATT_SH_ADP_STOPPED_APPLICATION_EXIT 0x20026u
#define ATT_SH_ADP_STOPPED_RUNTIME_ERROR 0x20023u

/* Command-line buffer; small-RAM boards (microbit.ld: 16 KiB) build with a smaller one. */
#ifndef ATT_SH_CMDLINE_BYTES
#define ATT_SH_CMDLINE_BYTES 4096u
#endif
#define ATT_SH_MAX_ARGS 32u

void _exit(int status) __attribute__((noreturn));

/* One semihosting call: operation in r0, parameter in r1, result in r0 (BKPT 0xAB on M-profile). */
static uint32_t att_sh_call(uint32_t op, void *arg)
{
    register uint32_t r0 __asm__("r0") = op;
    register void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void _exit(int status)
{
    uint32_t block[2];
    block[0] = ATT_SH_ADP_STOPPED_APPLICATION_EXIT;
    block[1] = (uint32_t)status;
    (void)att_sh_call(ATT_SH_SYS_EXIT_EXTENDED, block);
    /* A debugger without SYS_EXIT_EXTENDED: only success or failure can be told apart. */
    block[0] = (status == 0) ? ATT_SH_ADP_STOPPED_APPLICATION_EXIT : ATT_SH_ADP_STOPPED_RUNTIME_ERROR;
    (void)att_sh_call(ATT_SH_SYS_EXIT, (void *)(uintptr_t)block[0]);
    for (;;) {
        __asm__ volatile("bkpt 0x00");
    }
}

void att_port_fatal(int status) { _exit(status); }

void att_port_exit(int status)
{
#if defined(ATT_SEMIHOST_NEWLIB)
    exit(status);
#else
    _exit(status);
#endif
}

int att_port_args(char ***argv)
{
    static char cmdline[ATT_SH_CMDLINE_BYTES];
    static char *args[ATT_SH_MAX_ARGS + 1u];
    struct {
        char *buf;
        uint32_t len;
    } block;
    int argc = 0;
    char *p = cmdline;
#if defined(ATT_SEMIHOST_NEWLIB)
    initialise_monitor_handles();
#endif
    block.buf = cmdline;
    block.len = ATT_SH_CMDLINE_BYTES - 1u;
    if (att_sh_call(ATT_SH_SYS_GET_CMDLINE, &block) != 0u || block.len >= ATT_SH_CMDLINE_BYTES) {
        block.len = 0u; /* no command line (or it does not fit): no arguments */
    }
    cmdline[block.len] = '\0';
    while (*p != '\0' && (uint32_t)argc < ATT_SH_MAX_ARGS) {
        while (*p == ' ') {
            *p++ = '\0';
        }
        if (*p == '\0') {
            break;
        }
        args[argc++] = p;
        while (*p != '\0' && *p != ' ') {
            p++;
        }
    }
    args[argc] = NULL;
    *argv = args;
    return argc;
}
