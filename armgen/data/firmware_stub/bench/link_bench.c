/*
 * Cortex-M4F cost of the host link (benchmarks/bench_link.py): the controller with the
 * compiled-in task's configuration and fw_link, fed frames from memory (built here with the
 * link's own packers: the same bytes a UART would deliver), timed with SysTick under
 * `qemu-system-arm -icount shift=0` (a count is calib_insns / calib_ticks instructions, as
 * arm/fw_main.c). A HELLO, then FW_BENCH_FRAMES twists, each followed by FW_BENCH_QUIET ticks
 * without a frame; per part, "# key value" lines of SysTick counts (sum, max, count):
 *
 *   rx          fw_link_receive of a TWIST frame's bytes (the interrupt's work), per frame
 *   input_frame fw_link_input on the tick a TWIST arrives: decode, checks, dispatch, servo step
 *   input_servo fw_link_input on a tick without a frame: the servo step alone
 *   ctrl        ctrl_tick with the servo's SETPOINT
 *   output_reply fw_link_output with the TELEMETRY reply (tool pose, packing, CRC, COBS)
 *   output_quiet fw_link_output without a frame to send
 * then a second session opened with HELLO.replies = ACK and as many twists again:
 *   output_ack  fw_link_output with the ACK reply (packing, CRC, COBS; no tool pose)
 * then a zero twist until the arm rests, STOP, and a pose stream (POSE_WAYPOINT every
 * FW_BENCH_QUIET + 1 ticks, the tool along x at 2 cm/s):
 *   input_pose  fw_link_input on a tick without a frame: the pose stream's step alone
 */
#include <stdint.h>
#include <string.h>

#include "controller.h"
#include "fw_link.h"
#include "fw_task.h"
#include "semihost.h"

#ifndef FW_BENCH_FRAMES
#define FW_BENCH_FRAMES 50u
#endif
#ifndef FW_BENCH_QUIET
#define FW_BENCH_QUIET 19u /* ticks between two twists: 50 Hz twists at 1 kHz */
#endif

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SYST_MASK 0xFFFFFFu
#define ELAPSED(t0, t1) (((t0) - (t1)) & SYST_MASK) /* SysTick counts down, 24 bits */

typedef struct {
  uint32_t sum, max, count;
} stat;

static ctrl controller;
static fw_link link_state;
static uint8_t frame[FW_LINK_MAX_ENCODED + 1u];

static void add(stat *s, uint32_t d) {
  s->sum += d;
  s->max = d > s->max ? d : s->max;
  ++s->count;
}

static void put_stat(const char *key, const stat *s) {
  sh_puts("# ");
  sh_puts(key);
  sh_put_kv("_sum", s->sum);
  sh_puts("# ");
  sh_puts(key);
  sh_put_kv("_max", s->max);
  sh_puts("# ");
  sh_puts(key);
  sh_put_kv("_count", s->count);
}

__attribute__((noinline)) static uint32_t timed_calib(uint32_t iterations) {
  uint32_t t0, t1;
  t0 = SYST_CVR;
  __asm__ volatile(".syntax unified\n1: subs %0, %0, #1\n\tbne 1b" : "+r"(iterations)::"cc");
  t1 = SYST_CVR;
  return ELAPSED(t0, t1);
}

static void drain(void) {
  uint8_t sink[128];
  while (fw_link_transmit(&link_state, sink, sizeof sink) > 0u) {
  }
}

typedef struct {
  stat rx, input_frame, input_servo, control, output_reply, output_quiet;
} costs;

/* A HELLO (replies: FW_LINK_REPLY_*), then FW_BENCH_FRAMES twists each followed by quiet ticks. */
static void run_twists(uint8_t replies, costs *c, uint16_t *seq, ctrl_output *out) {
  fw_link_hello hello;
  fw_link_twist twist;
  uint8_t body[FW_LINK_MAX_BODY];
  ctrl_input in;
  uint32_t k, j, i, t0, t1, frame_bytes;
  hello.telemetry_period = 0u;
  hello.replies = replies;
  *seq = (uint16_t)(*seq + 1u);
  frame_bytes = (uint32_t)fw_link_frame(FW_LINK_VERSION, FW_LINK_HELLO, *seq, body, fw_link_pack_hello(&hello, body),
                                        frame);
  for (i = 0; i < frame_bytes; ++i) {
    (void)fw_link_receive(&link_state, frame[i]);
  }
  for (k = 0; k < FW_BENCH_FRAMES; ++k) {
    for (j = 0; j <= FW_BENCH_QUIET; ++j) {
      if (j == 0u) { /* a twist arrives */
        for (i = 0; i < 6u; ++i) {
          twist.xdot[i] = (i == 0u || i == 5u) ? 0.01f + 0.0002f * (float)k : 0.0f;
        }
        *seq = (uint16_t)(*seq + 1u);
        frame_bytes = (uint32_t)fw_link_frame(FW_LINK_VERSION, FW_LINK_TWIST, *seq, body,
                                              fw_link_pack_twist(&twist, body), frame);
        t0 = SYST_CVR;
        for (i = 0; i < frame_bytes; ++i) {
          (void)fw_link_receive(&link_state, frame[i]);
        }
        t1 = SYST_CVR;
        if (k > 0u) add(&c->rx, ELAPSED(t0, t1));
      }
      (void)memset(&in, 0, sizeof in);
      t0 = SYST_CVR;
      fw_link_input(&link_state, &in);
      t1 = SYST_CVR;
      if (k > 0u) add(j == 0u ? &c->input_frame : &c->input_servo, ELAPSED(t0, t1));
      t0 = SYST_CVR;
      (void)ctrl_tick(&controller, &in, out);
      t1 = SYST_CVR;
      if (k > 0u) add(&c->control, ELAPSED(t0, t1));
      t0 = SYST_CVR;
      fw_link_output(&link_state, out);
      t1 = SYST_CVR;
      if (k > 0u) add(j == 0u ? &c->output_reply : &c->output_quiet, ELAPSED(t0, t1));
      drain();
    }
  }
}

/* One host frame of `type` with `len` body bytes into the ring, then one tick. */
static void frame_and_tick(uint8_t type, const uint8_t *body, size_t len, uint16_t *seq, ctrl_output *out) {
  ctrl_input in;
  size_t i, n;
  *seq = (uint16_t)(*seq + 1u);
  n = fw_link_frame(FW_LINK_VERSION, type, *seq, body, len, frame);
  for (i = 0; i < n; ++i) {
    (void)fw_link_receive(&link_state, frame[i]);
  }
  (void)memset(&in, 0, sizeof in);
  fw_link_input(&link_state, &in);
  (void)ctrl_tick(&controller, &in, out);
  fw_link_output(&link_state, out);
  drain();
}

/* A tick without a frame; returns the SysTick count of fw_link_input. */
static uint32_t quiet_tick(ctrl_output *out) {
  ctrl_input in;
  uint32_t t0, t1;
  (void)memset(&in, 0, sizeof in);
  t0 = SYST_CVR;
  fw_link_input(&link_state, &in);
  t1 = SYST_CVR;
  (void)ctrl_tick(&controller, &in, out);
  fw_link_output(&link_state, out);
  drain();
  return ELAPSED(t0, t1);
}

/* The servo to rest and STOP, then a pose stream from the tool's pose: input_pose. */
static void run_poses(stat *input_pose, uint16_t *seq, ctrl_output *out) {
  fw_link_twist still;
  fw_link_pose_waypoint w;
  uint8_t body[FW_LINK_MAX_BODY];
  ctrl_real T[16], J[6 * CTRL_NDOF];
  uint32_t k, j, i;
  (void)memset(&still, 0, sizeof still);
  frame_and_tick(FW_LINK_TWIST, body, fw_link_pack_twist(&still, body), seq, out);
  for (k = 0; k < 2000u; ++k) { /* the closed loop settles */
    (void)quiet_tick(out);
  }
  frame_and_tick(FW_LINK_STOP, body, 0u, seq, out);
  for (k = 0; k < 10u; ++k) { /* the controlled stop, then DONE */
    (void)quiet_tick(out);
  }
  ctrl_gen_fk_jacobian(out->q, T, J);
  for (k = 0; k < FW_BENCH_FRAMES; ++k) {
    w.t_us = k * (FW_BENCH_QUIET + 1u) * 1000u;
    w.last = (uint8_t)(k + 1u == FW_BENCH_FRAMES);
    for (i = 0; i < 3u; ++i) {
      w.tool[i] = (float)T[12u + i] + (i == 0u ? 0.02f * (float)w.t_us * 1e-6f : 0.0f);
      w.tool[3u + i] = (float)T[i];
      w.tool[6u + i] = (float)T[4u + i];
      w.tool[9u + i] = (float)T[8u + i];
    }
    for (i = 0; i < 6u; ++i) {
      w.twist[i] = (i == 0u && k > 0u && k + 1u < FW_BENCH_FRAMES) ? 0.02f : 0.0f;
    }
    frame_and_tick(FW_LINK_POSE_WAYPOINT, body, fw_link_pack_pose_waypoint(&w, body), seq, out);
    for (j = 0; j < FW_BENCH_QUIET; ++j) {
      uint32_t d = quiet_tick(out);
      if (k > 1u) add(input_pose, d); /* the stream runs from its second waypoint on */
    }
  }
  for (k = 0; k < 2000u && out->state == CTRL_STATE_RUNNING; ++k) { /* to the last pose, at rest: DONE */
    (void)quiet_tick(out);
  }
}

int main(void) {
  stat input_pose = {0u, 0u, 0u};
  costs telemetry, ack;
  ctrl_output out;
  uint32_t calib_ticks, frame_bytes;
  uint16_t seq = 0u;
  fw_link_twist twist;
  uint8_t body[FW_LINK_MAX_BODY];

  (void)memset(&telemetry, 0, sizeof telemetry);
  (void)memset(&ack, 0, sizeof ack);
  (void)memset(&twist, 0, sizeof twist);
  SYST_RVR = SYST_MASK;
  SYST_CVR = 0u;
  SYST_CSR = 5u; /* ENABLE | CLKSOURCE = processor clock, no interrupt */
  calib_ticks = timed_calib(101000u) - timed_calib(1000u);

  (void)ctrl_init(&controller, &fw_task);
  fw_link_init(&link_state, &fw_task, 0xFFFFFFFFu); /* no watchdog: the bench sends on its own time */
  run_twists(FW_LINK_REPLY_TELEMETRY, &telemetry, &seq, &out);
  run_twists(FW_LINK_REPLY_ACK, &ack, &seq, &out);
  run_poses(&input_pose, &seq, &out);
  frame_bytes = (uint32_t)fw_link_frame(FW_LINK_VERSION, FW_LINK_TWIST, seq, body, fw_link_pack_twist(&twist, body),
                                        frame);
  sh_puts("# state ");
  sh_puts(ctrl_state_name(out.state));
  sh_puts("\n# fault ");
  sh_puts(ctrl_fault_name(out.fault));
  sh_puts("\n");
  sh_put_kv("# calib_insns", 200000u);
  sh_put_kv("# calib_ticks", calib_ticks);
  sh_put_kv("# frame_bytes", frame_bytes);
  sh_put_kv("# rx_frames", link_state.counts.rx_frames);
  sh_put_kv("# sizeof_link", (uint32_t)sizeof(fw_link));
  put_stat("rx", &telemetry.rx);
  put_stat("input_frame", &telemetry.input_frame);
  put_stat("input_servo", &telemetry.input_servo);
  put_stat("ctrl", &telemetry.control);
  put_stat("output_reply", &telemetry.output_reply);
  put_stat("output_quiet", &telemetry.output_quiet);
  put_stat("output_ack", &ack.output_reply);
  put_stat("input_pose", &input_pose);
  sh_put_kv("# pose_underruns", link_state.counts.underruns);
  sh_put_kv("# pose_rejected", link_state.counts.rejected);
  sh_puts("# end\n");
  return 0;
}
