/*
 * LD_PRELOAD adapter for linux.uml on hosts whose XSAVE area is larger than the guest kernel knows.
 *
 * Debian's user-mode-linux 6.1 restores a guest process's FPU state with PTRACE_SETREGSET
 * (NT_X86_XSTATE) from a buffer sized for AVX-512 (2,696 bytes). A host kernel with AMX in its user
 * XSAVE features (11,008 bytes) accepts only a buffer of exactly its full size and answers EFAULT:
 * the guest dies at boot ("userspace - ptrace set fp regs failed, errno = 14", tests/test_vcan_uml.py).
 * This wrapper reads the traced process's full state, overlays the bytes UML gave (the whole x87, SSE,
 * AVX and AVX-512 state and the XSAVE header) and sets the full buffer: what lies beyond UML's size is
 * the AMX tile state, which a guest process cannot use (it needs arch_prctl permission that UML's
 * kernel does not grant), so it is carried unchanged. Every other ptrace request, and a buffer that is
 * already full size, passes through. Built by the test (build/uml/xstate_pad.so); not part of attica.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdarg.h>
#include <stddef.h>
#include <string.h>
#include <sys/ptrace.h>
#include <sys/types.h>
#include <sys/uio.h>

#define XP_NT_X86_XSTATE 0x202 /* elf.h's NT_X86_XSTATE */
#define XP_MAX 65536u          /* larger than any XSAVE area (the kernel reports the size it wrote) */

typedef long (*xp_ptrace_fn)(int, pid_t, void *, void *);

long ptrace(enum __ptrace_request req, ...)
{
    static xp_ptrace_fn real;
    static unsigned char full[XP_MAX] __attribute__((aligned(64)));
    va_list ap;
    pid_t pid;
    void *addr;
    void *data;
    va_start(ap, req);
    pid = va_arg(ap, pid_t);
    addr = va_arg(ap, void *);
    data = va_arg(ap, void *);
    va_end(ap);
    if (real == NULL) {
        real = (xp_ptrace_fn)dlsym(RTLD_NEXT, "ptrace");
    }
    if ((int)req == PTRACE_SETREGSET && (long)addr == XP_NT_X86_XSTATE && data != NULL) {
        const struct iovec *iov = (const struct iovec *)data;
        struct iovec big = {full, sizeof full};
        if (iov->iov_len < sizeof full && real(PTRACE_GETREGSET, pid, addr, &big) == 0 &&
            big.iov_len > iov->iov_len) {
            memcpy(full, iov->iov_base, iov->iov_len);
            return real(PTRACE_SETREGSET, pid, addr, &big);
        }
    }
    return real((int)req, pid, addr, data);
}
