/*
 * Vector table and reset handler for the Arm MPS2 AN386 (Cortex-M4F), bare metal, for
 * firmware_stub/arm/mps2_an386.ld; the same for the other MPS2 images armgen runs on
 * (AN500 Cortex-M7, AN385 for Cortex-M0+ code, AN505 Cortex-M33 with mps2_an505.ld). No CMSIS needed.
 *
 * Reset_Handler: enable the FPU (CPACR CP10/CP11 full access) before any floating-point
 * instruction can run, copy .data from its load address, zero .bss, run static constructors,
 * call main() and hand its return value to _exit() (semihost.c routes it to the host).
 * Faults print their name over semihosting and exit with status 128 + exception number, so a
 * crashing program under QEMU ends instead of hanging.
 *
 * Link with -nostartfiles (this file replaces crt0). Interrupt handlers are weak aliases of
 * Default_Handler: define e.g. `void SysTick_Handler(void)` in the application to override.
 */
#include <stdint.h>

#include "semihost.h"

extern uint32_t __data_load[], __data_start[], __data_end[];
extern uint32_t __bss_start[], __bss_end[];
extern uint32_t __stack_top[];
extern void (*__preinit_array_start[])(void);
extern void (*__preinit_array_end[])(void);
extern void (*__init_array_start[])(void);
extern void (*__init_array_end[])(void);

int main(void);
void _exit(int status) __attribute__((noreturn));

/* The copy/zero loops must stay loops: GCC would otherwise turn them into memcpy/memset calls
 * into the C library before it is set up. */
void Reset_Handler(void) __attribute__((noreturn, optimize("no-tree-loop-distribute-patterns")));
void Default_Handler(void);
void NMI_Handler(void) __attribute__((weak, alias("Default_Handler")));
void HardFault_Handler(void) __attribute__((weak, alias("Default_Handler")));
void MemManage_Handler(void) __attribute__((weak, alias("Default_Handler")));
void BusFault_Handler(void) __attribute__((weak, alias("Default_Handler")));
void UsageFault_Handler(void) __attribute__((weak, alias("Default_Handler")));
void SVC_Handler(void) __attribute__((weak, alias("Default_Handler")));
void DebugMon_Handler(void) __attribute__((weak, alias("Default_Handler")));
void PendSV_Handler(void) __attribute__((weak, alias("Default_Handler")));
void SysTick_Handler(void) __attribute__((weak, alias("Default_Handler")));
void IRQ_Handler(void) __attribute__((weak, alias("Default_Handler")));

#define SCB_CPACR (*(volatile uint32_t *)0xE000ED88u)
#define SCB_ICSR (*(volatile uint32_t *)0xE000ED04u)
#define SCB_SHCSR (*(volatile uint32_t *)0xE000ED24u)
#define MPS2_IRQS 32 /* AN386 external interrupts: UARTs, timers, GPIO, ethernet ... */

typedef void (*vector_t)(void);

/* The table VTOR points at on reset (address 0, see the linker script). */
__attribute__((section(".isr_vector"), used)) const vector_t armgen_vector_table[16 + MPS2_IRQS] = {
    (vector_t)(uintptr_t)__stack_top, /* initial main stack pointer */
    Reset_Handler,
    NMI_Handler,
    HardFault_Handler,
    MemManage_Handler,
    BusFault_Handler,
    UsageFault_Handler,
    0, 0, 0, 0, /* reserved */
    SVC_Handler,
    DebugMon_Handler,
    0, /* reserved */
    PendSV_Handler,
    SysTick_Handler,
    /* external interrupts 0 .. MPS2_IRQS-1 */
    IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler,
    IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler,
    IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler,
    IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler, IRQ_Handler,
};

void Reset_Handler(void) {
  uint32_t *src, *dst;
  void (**fn)(void);
  /* CP10 and CP11 full access: the FPU is off after reset and the first VFP instruction
   * would raise UsageFault (NOCP). The barriers make the new setting visible before any
   * floating-point instruction below or in main(). A soft-float build (Cortex-M0+, whose
   * Armv6-M has no CPACR) leaves it alone. */
#if defined(__ARM_FP)
  SCB_CPACR |= (0xFu << 20);
  __asm__ volatile("dsb\n\tisb" ::: "memory");
#endif
  for (src = __data_load, dst = __data_start; dst < __data_end;) {
    *dst++ = *src++;
  }
  for (dst = __bss_start; dst < __bss_end;) {
    *dst++ = 0u;
  }
  for (fn = __preinit_array_start; fn < __preinit_array_end; ++fn) {
    (*fn)();
  }
  for (fn = __init_array_start; fn < __init_array_end; ++fn) {
    (*fn)();
  }
  _exit(main());
}

/* Any unexpected exception: report which one (IPSR) and stop. Uses semihosting, so it is
 * only meaningful under QEMU or a debugger. */
void Default_Handler(void) {
  uint32_t ipsr;
  __asm__ volatile("mrs %0, ipsr" : "=r"(ipsr));
  ipsr &= 0x1FFu;
  sh_puts("unexpected exception ");
  sh_put_u32(ipsr);
  sh_puts("\n");
  _exit((int)(128u + ipsr));
}
