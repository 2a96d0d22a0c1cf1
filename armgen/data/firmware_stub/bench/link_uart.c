/*
 * The host link on the Cortex-M4F over a UART (tests/test_link_qemu.py): the controller with the
 * compiled-in task's configuration and fw_link on the MPS2 AN386's CMSDK UART0 (0x40004000,
 * QEMU's first -serial), one tick per period of SysTick (processor clock FW_CPU_HZ), polled:
 * the received bytes into fw_link_receive, the tick, the queued bytes out. Runs FW_LINK_TICKS
 * ticks (default 60 s at the task's period), then prints "# key value" lines over semihosting.
 * The UART is served between the ticks, a byte whenever it can take or give one, so a tick
 * never waits for the wire (at 115 200 baud a TELEMETRY reply is 17 ms of it).
 * Run without -icount, so that the board's time is the host's (the client paces its frames by
 * the wall clock).
 */
#include <stdint.h>
#include <string.h>

#include "controller.h"
#include "fw_link.h"
#include "fw_task.h"
#include "semihost.h"

#ifndef FW_CPU_HZ
#define FW_CPU_HZ 25000000u /* MPS2 AN386 processor clock, the SysTick source */
#endif
#ifndef FW_LINK_SECONDS
#define FW_LINK_SECONDS 60u
#endif
#ifndef FW_LINK_WATCHDOG_TICKS
#define FW_LINK_WATCHDOG_TICKS 500u
#endif

#define UART0_DATA (*(volatile uint32_t *)0x40004000u)
#define UART0_STATE (*(volatile uint32_t *)0x40004004u) /* bit 0 TX full, bit 1 RX full */
#define UART0_CTRL (*(volatile uint32_t *)0x40004008u)  /* bit 0 TX enable, bit 1 RX enable */
#define UART0_BAUDDIV (*(volatile uint32_t *)0x40004010u)
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SYST_COUNTFLAG 0x10000u

static ctrl controller;
static fw_link link_state;

int main(void) {
  uint8_t tx[64];
  uint32_t tick, ticks, period, sent = 0u;
  size_t n = 0u, i = 0u;
  ctrl_input in;
  ctrl_output out;

  period = (uint32_t)(fw_task.dt * (ctrl_real)FW_CPU_HZ);
  ticks = (uint32_t)((ctrl_real)FW_LINK_SECONDS / fw_task.dt);
  UART0_BAUDDIV = FW_CPU_HZ / 115200u;
  UART0_CTRL = 3u;
  SYST_RVR = period - 1u;
  SYST_CVR = 0u;
  SYST_CSR = 5u; /* ENABLE | CLKSOURCE = processor clock; COUNTFLAG marks each period */
  (void)ctrl_init(&controller, &fw_task);
  fw_link_init(&link_state, &fw_task, FW_LINK_WATCHDOG_TICKS);
  for (tick = 0u; tick < ticks; ++tick) {
    while ((SYST_CSR & SYST_COUNTFLAG) == 0u) {
      if ((UART0_STATE & 2u) != 0u && fw_link_receive_space(&link_state) > 0u) {
        (void)fw_link_receive(&link_state, (uint8_t)UART0_DATA);
      }
      if (i == n) { /* the next bytes the link queued */
        n = fw_link_transmit(&link_state, tx, sizeof tx);
        i = 0u;
      }
      if (i < n && (UART0_STATE & 1u) == 0u) {
        UART0_DATA = tx[i++];
        ++sent;
      }
    }
    (void)memset(&in, 0, sizeof in);
    fw_link_input(&link_state, &in);
    (void)ctrl_tick(&controller, &in, &out);
    fw_link_output(&link_state, &out);
  }
  sh_puts("# state ");
  sh_puts(ctrl_state_name(out.state));
  sh_puts("\n# fault ");
  sh_puts(ctrl_fault_name(out.fault));
  sh_puts("\n");
  sh_put_kv("# ticks", ticks);
  sh_put_kv("# rx_frames", link_state.counts.rx_frames);
  sh_put_kv("# bytes_sent", sent);
  sh_puts("# end\n");
  return 0;
}
