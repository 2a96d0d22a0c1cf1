/*
 * The firmware project's link runner for the MPS2 boards' CMSDK APB UART0 (0x40004000; QEMU's
 * first -serial): the controller with the compiled-in task's configuration, commanded over the
 * link (docs/link.md), one tick per period of SysTick, forever. Unlike bench/link_uart.c (a test
 * harness that polls the UART and prints a summary over semihosting), this is how a product
 * wires the link:
 *
 *   - the UART's receive interrupt hands each byte to fw_link_receive (the ring's producer);
 *     when the ring is full it masks itself and leaves the byte in the UART, and the main loop
 *     takes that byte and unmasks it once the tick has made room: no byte is dropped while the
 *     sender waits (QEMU and a UART with RTS flow control hold the rest; without flow control
 *     the UART's overrun would lose bytes, and fw_link would count the frame as malformed);
 *   - the SysTick interrupt counts the periods; the main loop runs one tick per period, tells
 *     the controller how many it missed (ctrl_input.missed_ticks), and sleeps (WFI) between;
 *   - queued reply bytes go out whenever the transmitter has room, between the ticks.
 *
 * No semihosting: it runs on a board without a debugger. The boards: AN386 (Cortex-M4F), AN500
 * (Cortex-M7) and AN385 (Cortex-M0+) share this UART; the AN505's (Cortex-M33) sits elsewhere.
 * On a real board of another vendor, replace the four register macros and the IRQ number.
 */
#include <stdint.h>
#include <string.h>

#include "controller.h"
#include "fw_link.h"
#include "fw_task.h"

#ifndef FW_CPU_HZ
#define FW_CPU_HZ 25000000u /* MPS2 processor clock, the SysTick source */
#endif
#ifndef FW_LINK_BAUD
#define FW_LINK_BAUD 115200u
#endif
/* The watchdog: a moving arm stops this many ticks after the last valid frame (500 ms at 1 kHz:
 * a host on a loaded PC pauses longer than 100 ms now and then). -DFW_LINK_WATCHDOG_TICKS=n */
#ifndef FW_LINK_WATCHDOG_TICKS
#define FW_LINK_WATCHDOG_TICKS 500u
#endif

#define UART0_DATA (*(volatile uint32_t *)0x40004000u)
#define UART0_STATE (*(volatile uint32_t *)0x40004004u)   /* bit 0 TX full, bit 1 RX full */
#define UART0_CTRL (*(volatile uint32_t *)0x40004008u)    /* bits 0/1 TX/RX enable, 3 RX interrupt */
#define UART0_INTCLEAR (*(volatile uint32_t *)0x4000400Cu) /* bit 1: the RX interrupt, write 1 to clear */
#define UART0_BAUDDIV (*(volatile uint32_t *)0x40004010u)
#define UART_TX_FULL 1u
#define UART_RX_FULL 2u
#define UART_CTRL_TX_RX 3u
#define UART_CTRL_RX_IRQ 8u
#define UART0_RX_IRQ 0u /* the MPS2 boards' UART0 receive interrupt */
#define NVIC_ISER0 (*(volatile uint32_t *)0xE000E100u)
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SYST_ENABLE_TICKINT_CORE 7u /* ENABLE | TICKINT | CLKSOURCE = processor clock */

/* Shared with the interrupt handlers: the link (its ring's head is the receive handler's, its
 * tail the main loop's) and the count of periods. The startup's vector table has one handler
 * for every external interrupt; only UART0's receive interrupt is enabled. */
static fw_link link_state;
static volatile uint32_t periods;

void SysTick_Handler(void);
void IRQ_Handler(void);

void SysTick_Handler(void) { periods = periods + 1u; }

void IRQ_Handler(void) {
  while ((UART0_STATE & UART_RX_FULL) != 0u) {
    if (fw_link_receive_space(&link_state) == 0u) {
      UART0_CTRL = UART_CTRL_TX_RX; /* full: wait for the tick (the byte stays in the UART) */
      break;
    }
    (void)fw_link_receive(&link_state, (uint8_t)UART0_DATA);
  }
  UART0_INTCLEAR = UART_RX_FULL;
}

/* After a tick made room: the receive interrupt on again, and the byte it left in the UART
 * taken here (the UART raises its interrupt only for a byte that arrives while it is enabled),
 * with interrupts masked so that the ring keeps one producer at a time. */
static void take_waiting_bytes(void) {
  if (fw_link_receive_space(&link_state) == 0u) {
    return;
  }
  __asm__ volatile("cpsid i" ::: "memory");
  UART0_CTRL = UART_CTRL_TX_RX | UART_CTRL_RX_IRQ;
  while ((UART0_STATE & UART_RX_FULL) != 0u && fw_link_receive_space(&link_state) > 0u) {
    (void)fw_link_receive(&link_state, (uint8_t)UART0_DATA);
  }
  __asm__ volatile("cpsie i" ::: "memory");
}

int main(void) {
  static ctrl controller;
  uint8_t tx[64];
  size_t n = 0u, i = 0u;
  uint32_t done = 0u;
  ctrl_input in;
  ctrl_output out;

  (void)ctrl_init(&controller, &fw_task);
  fw_link_init(&link_state, &fw_task, FW_LINK_WATCHDOG_TICKS);
  UART0_BAUDDIV = FW_CPU_HZ / FW_LINK_BAUD;
  UART0_CTRL = UART_CTRL_TX_RX | UART_CTRL_RX_IRQ;
  NVIC_ISER0 = 1u << UART0_RX_IRQ;
  SYST_RVR = (uint32_t)(fw_task.dt * (ctrl_real)FW_CPU_HZ) - 1u;
  SYST_CVR = 0u;
  SYST_CSR = SYST_ENABLE_TICKINT_CORE;
  for (;;) {
    uint32_t now = periods;
    if (now != done) { /* a period began: this tick (and the count of those the loop missed) */
      (void)memset(&in, 0, sizeof in);
      in.missed_ticks = now - done - 1u;
      done = now;
      fw_link_input(&link_state, &in);
      (void)ctrl_tick(&controller, &in, &out);
      fw_link_output(&link_state, &out);
      take_waiting_bytes();
    }
    if (i == n) { /* the next bytes the link queued */
      n = fw_link_transmit(&link_state, tx, sizeof tx);
      i = 0u;
    }
    while (i < n && (UART0_STATE & UART_TX_FULL) == 0u) {
      UART0_DATA = tx[i++];
    }
    if (n == 0u) {
      __asm__ volatile("wfi"); /* nothing to send: until the next period or received byte */
    }
  }
}
