/*
 * The host link of the joint controller (docs/link.md): a byte stream (UART, USB CDC, TCP, a
 * pseudo-terminal) carrying the messages of fw_link_msgs.h in COBS frames with a CRC-32.
 *
 *   fw_link l;                                    one per link; no heap, no globals
 *   fw_link_init(&l, &config, watchdog_ticks);    after ctrl_init, with the same configuration
 *   in the UART interrupt (or a poll):   fw_link_receive(&l, byte);
 *   every period dt:
 *     ctrl_input in = {0};
 *     fw_link_input(&l, &in);                     frames -> this tick's command or setpoint
 *     ctrl_tick(&c, &in, &out);
 *     fw_link_output(&l, &out);                   replies and telemetry
 *     n = fw_link_transmit(&l, buf, sizeof buf);  bytes for the UART
 *
 * The link sits on top of the controller: it reads the controller's outputs and writes its
 * inputs, and every command it makes goes through the controller's checks (limits, speed).
 *
 * Receive: a ring buffer filled a byte at a time (single producer, single consumer: the
 * interrupt writes head, the tick reads tail); the tick decodes whole frames. A frame that is
 * no COBS, too short or too long, of another protocol version, with a bad CRC-32, of an unknown
 * type or length, before the session's HELLO, or with a sequence number not newer than the
 * last one is counted and dropped: never acted on. One valid frame is taken per tick (acted
 * on and answered); frames after it wait in the ring for the next tick.
 *
 * Watchdog: while a session is open and the arm moves (RUNNING or DEGRADED), a tick more than
 * watchdog_ticks after the last valid frame decides a controlled stop: the joint velocities
 * ramp down together (one common duration, each joint within its qddot_max), then the
 * controller latches STALE (CTRL_CMD_STALE). Nothing is acted on after that decision.
 *
 * Stream: timed joint waypoints (t, q, qd) buffered, interpolated at every tick by the cubic
 * Hermite between the two around t, and followed within each joint's qdot_max and qddot_max
 * (the step to the interpolated point, limited); the controller receives it as a setpoint.
 *
 * Servo: a tool twist (TWIST) followed at every tick by the resolved-rate step (the generated
 * step_fault: gradient projection with the damping from sigma_min), closed on the pose the
 * executed twist integrates to, with the chosen null-space criterion's self-motion; the joint
 * velocities are scaled down together (the tool's direction kept) so that every joint keeps its
 * qdot_max, its qddot_max and a braking distance to its limits.
 *
 * Pose stream: timed tool poses (POSE_WAYPOINT: pose and twist) interpolated in task space at
 * every tick (position: cubic Hermite; orientation: a cubic Hermite of the rotation vector from
 * the pose before) and followed by the same resolved-rate step; where the limits scale the step
 * down the stream's clock slows alike, so the tool stays on the path.
 */
#ifndef ARMGEN_FW_LINK_H
#define ARMGEN_FW_LINK_H

#include <stddef.h>
#include <stdint.h>

#include "controller.h"
#include "fw_link_msgs.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Receive ring, bytes (a power of two): at 115 200 baud 11.5 bytes arrive per millisecond, so
 * 1 024 bytes hold ~90 ms of traffic between two ticks. -DFW_LINK_RX_RING=n */
#ifndef FW_LINK_RX_RING
#define FW_LINK_RX_RING 1024u
#endif
/* Transmit buffer, bytes: several telemetry frames between two drains. */
#ifndef FW_LINK_TX_BUFFER
#define FW_LINK_TX_BUFFER 2048u
#endif
/* Buffered stream waypoints: at 50 Hz, 32 waypoints are 0.64 s of lead. */
#ifndef FW_LINK_WAYPOINTS
#define FW_LINK_WAYPOINTS 32u
#endif
/* A stream's first waypoint must lie this close to the held command, rad (m): the stream starts
 * where the arm is, never with a jump. */
#define FW_LINK_STREAM_START_TOL CTRL_LIT(1e-3)

/* SERVO and pose streams: the closed loop's gain on the tool's error from the reference pose,
 * 1/s (the error decays as exp(-gain t); gain * dt << 1 at any tick up to 10 ms); the margin
 * kept from a joint limit, rad (m). */
#define FW_LINK_SERVO_GAIN CTRL_LIT(20.0)
#define FW_LINK_SERVO_LIMIT_MARGIN CTRL_LIT(1e-3)
/* SERVO's reference never lags the tool by more than this (m, rad): where the arm cannot follow
 * the twist (a singular pose, a joint limit) the reference waits for it. Within reach the twist
 * is fed forward and the lag is what the acceleration limit delays (micrometres on a 5 cm/s
 * trace; the twist scaled to a joint's speed does not add to it), so the bound acts only where
 * the arm is stuck. */
#define FW_LINK_SERVO_MAX_LAG_M CTRL_LIT(0.01)
#define FW_LINK_SERVO_MAX_LAG_RAD CTRL_LIT(0.02)
/* Their damping varies with sigma_min of J (the generated step_fault's rule, spec 30):
 * lambda^2 = (1 - (sigma_min / epsilon)^2) lambda_max^2 below epsilon, 0 above it, so the step
 * is the exact one away from singular poses and the joint speeds stay finite (at most
 * |x_dot| / (2 lambda_max)) at one; the limits then scale the step down. sigma_min in J's
 * units (m/rad on the position rows). */
#define FW_LINK_SERVO_EPSILON CTRL_LIT(0.02)
#define FW_LINK_SERVO_LAMBDA_MAX CTRL_LIT(0.02)
/* Their self-motion (SERVO_SETUP.criterion; a redundant arm's null space), ramped in linearly
 * over FW_LINK_SELF_MOTION_RAMP_S while the reference moves and out while it is still (a zero
 * twist or a stream's end comes to rest): switched on at once, the joint-limit criterion's
 * alpha at modular8's start asks for more than qddot_max in one tick, and the tool lagged its
 * pose stream by 0.14 mm (2e-5 m with the ramp). The default gains,
 * alpha = -gain grad H for the criteria minimised (joint limits, 1/s on H_L's gradient, the
 * planners' order of rho_L; rest, 1/s: q - q_start decays as exp(-t) in the null space) and
 * +gain grad H for those maximised (manipulability, joint manipulability: 1/s on their
 * gradients, which are of the order of w); the manipulabilities' smoothing delta. */
#define FW_LINK_GAIN_JOINT_LIMITS CTRL_LIT(0.1)
#define FW_LINK_GAIN_MANIPULABILITY CTRL_LIT(1.0)
#define FW_LINK_GAIN_JOINT_MANIPULABILITY CTRL_LIT(1.0)
#define FW_LINK_GAIN_REST CTRL_LIT(1.0)
#define FW_LINK_MANIPULABILITY_DELTA CTRL_LIT(1e-4)
#define FW_LINK_SELF_MOTION_RAMP_S CTRL_LIT(0.5)
/* A pose stream's first pose must lie this close to the held command's tool pose (m, rad): the
 * stream starts where the tool is, never with a jump. Consecutive poses of a stream differ by
 * less than a quarter turn (the interpolation's rotation vector is then unique). */
#define FW_LINK_POSE_START_TOL_M CTRL_LIT(1e-3)
#define FW_LINK_POSE_START_TOL_RAD CTRL_LIT(1e-3)
/* A pose's rotation must be orthonormal to this (|R^T R - I| entrywise): the wire's single
 * precision of a double rotation is ~1e-7. */
#define FW_LINK_POSE_ORTHO_TOL CTRL_LIT(1e-4)
/* A pose stream has arrived when the tool is this close to its last pose (m, rad) with every
 * joint slow enough to stop within a tick: then the command rests there. The closed loop
 * brings the error below it in ~0.5 s from a millimetre (exp(-20 t)); the float build's FK
 * rounds to ~1e-7 m. */
#define FW_LINK_POSE_ARRIVE_M CTRL_LIT(1e-5)
#define FW_LINK_POSE_ARRIVE_RAD CTRL_LIT(1e-4)

/* A frame: header, body, CRC-32 (FW_LINK_MAX_RAW); COBS adds one byte per 254 and the first. */
#define FW_LINK_MAX_RAW (FW_LINK_HEADER_SIZE + FW_LINK_MAX_BODY + FW_LINK_CRC_SIZE)
#define FW_LINK_MAX_ENCODED (FW_LINK_MAX_RAW + FW_LINK_MAX_RAW / 254u + 1u)

typedef struct {
  uint32_t rx_frames, bad_crc, malformed, oversized, out_of_order, wrong_version, no_session, rejected;
  uint32_t rx_overflow, seq_gaps, underruns, tx_overflow;
} fw_link_counts;

typedef struct {
  uint32_t t_us;
  uint8_t last;
  ctrl_real q[CTRL_NDOF], qd[CTRL_NDOF];
} fw_link_waypoint_slot;

/* A tool pose of a pose stream; phi: the rotation vector from the pose before to this one
 * (base frame), computed once on arrival. */
typedef struct {
  uint32_t t_us;
  uint8_t last;
  ctrl_real p[3], R[9], twist[6], phi[3];
} fw_link_pose_slot;

typedef struct {
  /* the controller's limits and start (copied from its configuration) */
  ctrl_real dt;
  ctrl_real q_min[CTRL_NDOF], q_max[CTRL_NDOF], qd_max[CTRL_NDOF], qdd_max[CTRL_NDOF], q_start[CTRL_NDOF];
  uint32_t watchdog_ticks;
  /* receive */
  uint8_t ring[FW_LINK_RX_RING];
  volatile uint32_t ring_head; /* written by the receiver (interrupt) only */
  volatile uint32_t ring_tail; /* written by fw_link_input only */
  uint8_t encoded[FW_LINK_MAX_ENCODED];
  size_t encoded_len;
  int encoded_overflow; /* the frame being received is longer than any message */
  /* session */
  int session;
  uint16_t rx_seq, tx_seq, ack_seq, telemetry_period;
  uint8_t result;
  int reply_telemetry, reply_ack, reply_hello, hello_accepted;
  uint8_t replies; /* HELLO.replies: FW_LINK_REPLY_TELEMETRY or FW_LINK_REPLY_ACK */
  uint32_t tick, last_frame_tick;
  fw_link_counts counts;
  /* this tick's command from a frame */
  ctrl_command command;
  ctrl_real target[16];
  ctrl_real q_target[CTRL_NDOF];
  uint32_t locked;
  /* stream: of joint waypoints or of tool poses (stream_poses says which), one ring; a stream
   * is of one kind, so the two share their memory */
  union {
    fw_link_waypoint_slot joints[FW_LINK_WAYPOINTS];
    fw_link_pose_slot poses[FW_LINK_WAYPOINTS];
  } wp;
  uint32_t wp_first, wp_count, stream_k;
  int streaming, stream_ended, stream_arrived; /* ended: its last waypoint received; arrived: the arm is there */
  int stream_poses;
  ctrl_real pose_t; /* a pose stream's clock, s: advanced by the step's scale each tick */
  /* servo */
  int servoing;
  uint32_t servo_k;
  ctrl_real twist[6];              /* the last TWIST, [v; w] in the base frame */
  ctrl_real p_ref[3], R_ref[9];    /* the tool pose of the twist as executed (scaled), integrated */
  ctrl_real servo_scale;           /* the scale of the last resolved-rate step, (0, 1] */
  ctrl_real sigma_min, damping;    /* of the last resolved-rate step (sigma_min NaN before one) */
  ctrl_real ref_err[6];            /* that step's reference minus the tool: position, orientation */
  ctrl_real null_ramp;             /* the self-motion's share, [0, 1] (FW_LINK_SELF_MOTION_RAMP_S) */
  int task_rows[CTRL_NTASK], servo_rows_known;
  uint8_t criterion, task_criterion; /* the self-motion (FW_LINK_CRITERION_*): chosen, the task's */
  ctrl_real null_gain, task_gain;
  ctrl_real hm_weights[CTRL_NDOF];   /* the joint manipulability's a_i: the task's, else 1 */
  /* the watchdog's stop */
  int stale, stopping;    /* stopping: the ramp to rest runs, then stop_end goes to the controller */
  ctrl_command stop_end;  /* CTRL_CMD_STALE (the watchdog) or CTRL_CMD_STOP (a STOP frame) */
  uint32_t stale_ticks, stop_k;
  ctrl_real stop_q0[CTRL_NDOF], stop_v0[CTRL_NDOF], stop_T;
  /* the controller's last output */
  ctrl_output last;
  /* transmit */
  uint8_t tx[FW_LINK_TX_BUFFER];
  size_t tx_len;
} fw_link;

/* Set up the link for a controller initialised with `config` (its limits, period and start). */
void fw_link_init(fw_link *l, const ctrl_config *config, uint32_t watchdog_ticks);
/* One received byte (from an interrupt or a poll): 1, or 0 when the ring is full (dropped, counted). */
int fw_link_receive(fw_link *l, uint8_t byte);
/* Free bytes in the receive ring: a driver with flow control (RTS, USB CDC's NAK, a pty left
 * unread) takes no more than this. */
uint32_t fw_link_receive_space(const fw_link *l);
/* Before ctrl_tick: decode the frames received, watch the watchdog, and write this tick's
 * command (or setpoint, or the stop) and the reported locks into `in`. */
void fw_link_input(fw_link *l, ctrl_input *in);
/* After ctrl_tick: remember the output, queue the replies and telemetry. */
void fw_link_output(fw_link *l, const ctrl_output *out);
/* Move up to `max` queued bytes to `dst`; returns how many. */
size_t fw_link_transmit(fw_link *l, uint8_t *dst, size_t max);

/* The framing, shared with the tests and tools. */
uint32_t fw_link_crc32(const uint8_t *data, size_t len);
/* COBS: encode len bytes (no delimiter written); returns the encoded length (at most len + len / 254 + 1). */
size_t fw_link_cobs_encode(const uint8_t *in, size_t len, uint8_t *out);
/* COBS: decode len bytes (no delimiter) into out (at most len - 1 bytes); returns the decoded
 * length, or 0 for bytes that are no COBS (a zero byte, a code past the end, an empty input). */
size_t fw_link_cobs_decode(const uint8_t *in, size_t len, uint8_t *out);
/* A whole frame of a body: header, CRC-32, COBS and the 0x00 delimiter; returns its length (out
 * holds FW_LINK_MAX_ENCODED + 1 bytes). */
size_t fw_link_frame(uint8_t version, uint8_t type, uint16_t seq, const uint8_t *body, size_t len, uint8_t *out);

#ifdef __cplusplus
}
#endif

#endif /* ARMGEN_FW_LINK_H */
