/**
 * @file startup.c
 * @brief Bare-metal start-up for Cortex-M cores: vector table, reset handler.
 *
 * One start-up for every Cortex-M target of attica: ARMv7E-M with FPv4-SP (Cortex-M4F) or FPv5
 * (Cortex-M7), ARMv8-M Mainline with its FPU (Cortex-M33, secure state) and ARMv6-M without FPU
 * (Cortex-M0/M0+, soft float). Reset_Handler calls att_port_fp_init() (att_fpenv.c: on a core with an
 * FPU it enables it and sets FPSCR and FPDSCR to the IEEE mode attica needs; without one there is
 * nothing to set), copies .data from its load address, clears .bss, checks the floating-point
 * environment with att_port_fp_ok() (att_port_fatal(ATT_PORT_EXIT_FPSCR) if the FPU did not take
 * it), runs static constructors when newlib is linked, calls main(argc, argv) with the arguments of
 * att_port_args() and hands its status to att_port_exit().
 *
 * Link att_fpenv.c with it. A project with its own (vendor) start-up uses att_fpenv.c alone.
 *
 * Symbols expected from the linker script (mps2_an386.ld, mps2_an500.ld, mps2_an505.ld and
 * microbit.ld define them): __stack_top__, __data_load__, __data_start__, __data_end__,
 * __bss_start__, __bss_end__.
 *
 * The exception and interrupt handlers are weak aliases of one default handler that reports a
 * fault; define a function of the same name (e.g. SysTick_Handler, att_irq5_handler) to override.
 */
#include "att_port.h"

#include <stddef.h>
#include <stdint.h>

int main(int argc, char **argv);

extern uint32_t __stack_top__;
extern uint32_t __data_load__;
extern uint32_t __data_start__;
extern uint32_t __data_end__;
extern uint32_t __bss_start__;
extern uint32_t __bss_end__;

/* newlib's constructor runner; absent (NULL) in images linked without a C library. */
extern void __libc_init_array(void) __attribute__((weak));

typedef void (*att_handler_t)(void);

void Reset_Handler(void);
void att_default_handler(void);
void NMI_Handler(void);
void HardFault_Handler(void);
void MemManage_Handler(void);
void BusFault_Handler(void);
void UsageFault_Handler(void);
void SVC_Handler(void);
void DebugMon_Handler(void);
void PendSV_Handler(void);
void SysTick_Handler(void);
void SecureFault_Handler(void);
void _init(void);
void _fini(void);

#define ATT_WEAK_HANDLER(name) void name(void) __attribute__((weak, alias("att_default_handler")))
ATT_WEAK_HANDLER(NMI_Handler);
ATT_WEAK_HANDLER(HardFault_Handler);
ATT_WEAK_HANDLER(MemManage_Handler);
ATT_WEAK_HANDLER(BusFault_Handler);
ATT_WEAK_HANDLER(UsageFault_Handler);
ATT_WEAK_HANDLER(SVC_Handler);
ATT_WEAK_HANDLER(DebugMon_Handler);
ATT_WEAK_HANDLER(PendSV_Handler);
ATT_WEAK_HANDLER(SysTick_Handler);
ATT_WEAK_HANDLER(SecureFault_Handler);

/* The first 32 external interrupts (MPS2 AN385/AN386/AN500/AN505: UARTs, timers, ethernet...; nRF51: the
 * peripherals). Boards with more leave the rest unused: these images enable none. */
#define ATT_IRQ(n) void att_irq##n##_handler(void); ATT_WEAK_HANDLER(att_irq##n##_handler)
ATT_IRQ(0); ATT_IRQ(1); ATT_IRQ(2); ATT_IRQ(3); ATT_IRQ(4); ATT_IRQ(5); ATT_IRQ(6); ATT_IRQ(7);
ATT_IRQ(8); ATT_IRQ(9); ATT_IRQ(10); ATT_IRQ(11); ATT_IRQ(12); ATT_IRQ(13); ATT_IRQ(14); ATT_IRQ(15);
ATT_IRQ(16); ATT_IRQ(17); ATT_IRQ(18); ATT_IRQ(19); ATT_IRQ(20); ATT_IRQ(21); ATT_IRQ(22); ATT_IRQ(23);
ATT_IRQ(24); ATT_IRQ(25); ATT_IRQ(26); ATT_IRQ(27); ATT_IRQ(28); ATT_IRQ(29); ATT_IRQ(30); ATT_IRQ(31);

/** Vector table: initial main stack pointer, then 15 system and 32 external handlers (slot 7 is
 * SecureFault on ARMv8-M Mainline and reserved on ARMv7-M and ARMv6-M). */
typedef struct {
    uint32_t *stack_top;
    att_handler_t handler[15 + 32];
} att_vectors_t;

__attribute__((section(".vectors"), used)) const att_vectors_t att_vectors = {
    &__stack_top__,
    {
        Reset_Handler, NMI_Handler, HardFault_Handler, MemManage_Handler, BusFault_Handler,
        UsageFault_Handler,
#if defined(__ARM_FEATURE_CMSE)
        SecureFault_Handler,
#else
        NULL,
#endif
        NULL, NULL, NULL, SVC_Handler, DebugMon_Handler, NULL, PendSV_Handler,
        SysTick_Handler,
        att_irq0_handler, att_irq1_handler, att_irq2_handler, att_irq3_handler, att_irq4_handler,
        att_irq5_handler, att_irq6_handler, att_irq7_handler, att_irq8_handler, att_irq9_handler,
        att_irq10_handler, att_irq11_handler, att_irq12_handler, att_irq13_handler, att_irq14_handler,
        att_irq15_handler, att_irq16_handler, att_irq17_handler, att_irq18_handler, att_irq19_handler,
        att_irq20_handler, att_irq21_handler, att_irq22_handler, att_irq23_handler, att_irq24_handler,
        att_irq25_handler, att_irq26_handler, att_irq27_handler, att_irq28_handler, att_irq29_handler,
        att_irq30_handler, att_irq31_handler,
    },
};

/* ---- default hooks (semihost.c replaces them) ------------------------------------------------------ */

__attribute__((weak)) int att_port_args(char ***argv)
{
    static char *no_args[1] = {NULL};
    *argv = no_args;
    return 0;
}

__attribute__((weak)) void att_port_fatal(int status)
{
    (void)status;
    for (;;) {
        __asm__ volatile("bkpt 0x00");
    }
}

__attribute__((weak)) void att_port_exit(int status)
{
    (void)status;
    for (;;) {
        __asm__ volatile("wfi");
    }
}

void att_default_handler(void) { att_port_fatal(ATT_PORT_EXIT_FAULT); }

/* newlib's __libc_init_array calls _init (normally from crti.o, not linked: -nostartfiles). */
__attribute__((weak)) void _init(void) {}
__attribute__((weak)) void _fini(void) {}

/* ---- reset ---------------------------------------------------------------------------------------- */

void Reset_Handler(void)
{
    volatile uint32_t *dst;
    const uint32_t *src;
    char **argv;
    int argc;
    att_port_fp_init();
    /* volatile stores: the loops must not become calls to memcpy/memset before .data exists */
    src = &__data_load__;
    for (dst = &__data_start__; dst < &__data_end__; dst++) {
        *dst = *src++;
    }
    for (dst = &__bss_start__; dst < &__bss_end__; dst++) {
        *dst = 0u;
    }
    if (!att_port_fp_ok()) {
        att_port_fatal(ATT_PORT_EXIT_FPSCR);
    }
    if (__libc_init_array != NULL) {
        __libc_init_array();
    }
    argc = att_port_args(&argv);
    att_port_exit(main(argc, argv));
    for (;;) {
        __asm__ volatile("wfi");
    }
}
