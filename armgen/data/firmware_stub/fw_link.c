/*
 * The host link: framing (COBS, CRC-32), the receive ring and parser, the session and
 * sequence rules, the watchdog's controlled stop, the waypoint stream and the telemetry
 * (fw_link.h, docs/link.md). No heap, no globals: everything lives in the caller's fw_link.
 */
#include "fw_link.h"

#include <string.h>

#define N CTRL_NDOF
#define LINK_ATAN2 CTRL_M(ATAN2)

/* The generated step_fault and ft_index (spec 30) that SERVO's sigma_min damping and the
 * manipulability criteria use: a robot whose generated code lacks them is built with
 * -DCTRL_HAS_FAULT_TOLERANT=0 (armgen.firmware.sources), as the controller is; then the step is
 * step_gpm with a fixed damping (protocol version 1's) and those criteria are refused. */
#ifndef CTRL_HAS_FAULT_TOLERANT
#define CTRL_HAS_FAULT_TOLERANT 1
#endif

typedef char fw_link_ring_is_a_power_of_two[((FW_LINK_RX_RING & (FW_LINK_RX_RING - 1u)) == 0u) ? 1 : -1];

/* ------------------------------------------------------------------ framing */

/* CRC-32 (IEEE 802.3, reflected, polynomial 0xEDB88320, zlib's crc32): four bits a step from a
 * 16-entry table, 64 bytes of flash instead of the 1 KB byte table; a frame is < 300 bytes. */
uint32_t fw_link_crc32(const uint8_t *data, size_t len) {
  static const uint32_t nibble[16] = {
      0x00000000u, 0x1DB71064u, 0x3B6E20C8u, 0x26D930ACu, 0x76DC4190u, 0x6B6B51F4u, 0x4DB26158u, 0x5005713Cu,
      0xEDB88320u, 0xF00F9344u, 0xD6D6A3E8u, 0xCB61B38Cu, 0x9B64C2B0u, 0x86D3D2D4u, 0xA00AE278u, 0xBDBDF21Cu};
  uint32_t crc = 0xFFFFFFFFu;
  size_t i;
  for (i = 0; i < len; ++i) {
    crc ^= data[i];
    crc = (crc >> 4) ^ nibble[crc & 0x0Fu];
    crc = (crc >> 4) ^ nibble[crc & 0x0Fu];
  }
  return crc ^ 0xFFFFFFFFu;
}

size_t fw_link_cobs_encode(const uint8_t *in, size_t len, uint8_t *out) {
  size_t code_at = 0, o = 1, i;
  uint8_t code = 1;
  for (i = 0; i < len; ++i) {
    if (in[i] == 0u) {
      out[code_at] = code;
      code_at = o++;
      code = 1;
    } else {
      out[o++] = in[i];
      ++code;
      if (code == 0xFFu && i + 1u < len) { /* a full block of 254 non-zero bytes, more to come: no zero implied */
        out[code_at] = code;
        code_at = o++;
        code = 1;
      }
    }
  }
  out[code_at] = code;
  return o;
}

size_t fw_link_cobs_decode(const uint8_t *in, size_t len, uint8_t *out) {
  size_t i = 0, o = 0, j;
  if (len == 0u) return 0u;
  while (i < len) {
    uint8_t code = in[i];
    if (code == 0u || (size_t)code - 1u > len - i - 1u) return 0u; /* a zero, or a block past the end */
    ++i;
    for (j = 1; j < code; ++j) {
      if (in[i] == 0u) return 0u;
      out[o++] = in[i++];
    }
    if (code != 0xFFu && i < len) {
      out[o++] = 0u;
    }
  }
  return o;
}

size_t fw_link_frame(uint8_t version, uint8_t type, uint16_t seq, const uint8_t *body, size_t len, uint8_t *out) {
  uint8_t raw[FW_LINK_MAX_RAW];
  uint32_t crc;
  size_t n;
  raw[0] = version;
  raw[1] = type;
  raw[2] = (uint8_t)(seq & 0xFFu);
  raw[3] = (uint8_t)(seq >> 8);
  if (len > 0u) {
    (void)memcpy(raw + FW_LINK_HEADER_SIZE, body, len);
  }
  n = FW_LINK_HEADER_SIZE + len;
  crc = fw_link_crc32(raw, n);
  raw[n] = (uint8_t)(crc & 0xFFu);
  raw[n + 1u] = (uint8_t)((crc >> 8) & 0xFFu);
  raw[n + 2u] = (uint8_t)((crc >> 16) & 0xFFu);
  raw[n + 3u] = (uint8_t)(crc >> 24);
  n = fw_link_cobs_encode(raw, n + FW_LINK_CRC_SIZE, out);
  out[n] = 0u;
  return n + 1u;
}

/* ------------------------------------------------------------------ helpers */

static int finite_r(ctrl_real x) { return (x - x) == (x - x); } /* false for NaN and inf */

static ctrl_real clamp_r(ctrl_real x, ctrl_real lo, ctrl_real hi) { return x < lo ? lo : (x > hi ? hi : x); }

static int arm_moves(ctrl_state s) { return s == CTRL_STATE_RUNNING || s == CTRL_STATE_DEGRADED; }

/* Queue a frame for the transmitter; dropped (counted) when it does not fit. */
static void send(fw_link *l, uint8_t type, const uint8_t *body, size_t len) {
  uint8_t frame[FW_LINK_MAX_ENCODED + 1u];
  size_t n = fw_link_frame(FW_LINK_VERSION, type, l->tx_seq, body, len, frame);
  if (l->tx_len + n > sizeof l->tx) {
    ++l->counts.tx_overflow;
    return;
  }
  (void)memcpy(l->tx + l->tx_len, frame, n);
  l->tx_len += n;
  l->tx_seq = (uint16_t)(l->tx_seq + 1u);
}

/* ------------------------------------------------------------------ setup, receive, transmit */

/* The task's own null-space criterion for SERVO and pose streams: a resolved-rate task's
 * method (its Zghal gain rho_L, the same alpha = -rho_L grad H_L; the repetitive operator's
 * gain is tied to the task's end time, so REST takes its own), a fault-tolerant GPM task's
 * joint manipulability (its K and weights a_i); minimum norm where the task has none (PINV, WLN);
 * a joint-space task (playback, sampled) or a weighted-GPM one: the joint limits. */
static void init_task_criterion(fw_link *l, const ctrl_config *config) {
  int i, any_weight = 0;
  l->task_criterion = FW_LINK_CRITERION_JOINT_LIMITS;
  l->task_gain = FW_LINK_GAIN_JOINT_LIMITS;
  if (config->mode == CTRL_MODE_RESOLVED_RATE) {
    ctrl_method m = config->rr.method;
    if (m == CTRL_METHOD_PINV) {
      l->task_criterion = FW_LINK_CRITERION_NONE;
    } else if (m == CTRL_METHOD_REPETITIVE) {
      l->task_criterion = FW_LINK_CRITERION_REST;
      l->task_gain = FW_LINK_GAIN_REST;
    } else {
      l->task_gain = config->rr.rho_L; /* Zghal, windowed Zghal, combined */
    }
  } else if (config->mode == CTRL_MODE_FAULT_TOLERANT) {
    if (config->ft.method == CTRL_FT_GPM) {
      l->task_criterion = FW_LINK_CRITERION_JOINT_MANIPULABILITY;
      l->task_gain = config->ft.K;
      for (i = 0; i < N; ++i) {
        any_weight |= config->ft.a[i] != CTRL_LIT(0.0);
      }
      for (i = 0; i < N && any_weight; ++i) {
        l->hm_weights[i] = config->ft.a[i];
      }
    } else {
      l->task_criterion = FW_LINK_CRITERION_NONE;
    }
  } else {
    /* PLAYBACK, SAMPLED, WEIGHTED_GPM: away from the joint limits */
  }
  l->criterion = l->task_criterion;
  l->null_gain = l->task_gain;
}

void fw_link_init(fw_link *l, const ctrl_config *config, uint32_t watchdog_ticks) {
  int i;
  (void)memset(l, 0, sizeof *l);
  l->dt = config->dt;
  l->watchdog_ticks = watchdog_ticks;
  for (i = 0; i < N; ++i) {
    l->q_min[i] = config->q_min[i];
    l->q_max[i] = config->q_max[i];
    l->qd_max[i] = config->qdot_max[i];
    l->qdd_max[i] = config->qddot_max[i];
    l->q_start[i] = config->q_start[i];
    l->last.q[i] = config->q_start[i];
    l->hm_weights[i] = CTRL_LIT(1.0);
  }
  init_task_criterion(l, config);
  l->sigma_min = (ctrl_real)NAN;
  /* the robot's task rows: the resolved-rate modes' configuration names them; a robot that
   * controls all six rows needs no name; else (a planar arm's playback) SERVO is refused */
  l->servo_rows_known = config->mode == CTRL_MODE_RESOLVED_RATE || config->mode == CTRL_MODE_FAULT_TOLERANT ||
                        config->mode == CTRL_MODE_WEIGHTED_GPM || CTRL_NTASK == 6;
  for (i = 0; i < CTRL_NTASK; ++i) {
    l->task_rows[i] = CTRL_NTASK == 6 ? i : config->rr.task_rows[i];
  }
  l->last.state = CTRL_STATE_IDLE;
  l->command = CTRL_CMD_NONE;
}

int fw_link_receive(fw_link *l, uint8_t byte) {
  uint32_t head = l->ring_head;
  if (head - l->ring_tail >= FW_LINK_RX_RING) {
    ++l->counts.rx_overflow;
    return 0;
  }
  l->ring[head & (FW_LINK_RX_RING - 1u)] = byte;
  l->ring_head = head + 1u;
  return 1;
}

uint32_t fw_link_receive_space(const fw_link *l) { return FW_LINK_RX_RING - (l->ring_head - l->ring_tail); }

size_t fw_link_transmit(fw_link *l, uint8_t *dst, size_t max) {
  size_t n = l->tx_len < max ? l->tx_len : max;
  (void)memcpy(dst, l->tx, n);
  (void)memmove(l->tx, l->tx + n, l->tx_len - n);
  l->tx_len -= n;
  return n;
}

/* ------------------------------------------------------------------ messages */

/* R (3x3, column-major) of a 4x4 pose. */
static void rotation_of(const ctrl_real *T, ctrl_real *R) {
  int r, col;
  for (col = 0; col < 3; ++col) {
    for (r = 0; r < 3; ++r) {
      R[r + 3 * col] = T[r + 4 * col];
    }
  }
}

/* The orientation error of R from Rd: the vector part of Rd R^T (as the controller's). */
static void orientation_error(const ctrl_real *R, const ctrl_real *Rd, ctrl_real *e) {
  ctrl_real S[9];
  int r, col;
  for (col = 0; col < 3; ++col) {
    for (r = 0; r < 3; ++r) {
      S[r + 3 * col] = Rd[r] * R[col] + Rd[r + 3] * R[col + 3] + Rd[r + 6] * R[col + 6];
    }
  }
  e[0] = CTRL_LIT(0.5) * (S[5] - S[7]);
  e[1] = CTRL_LIT(0.5) * (S[6] - S[2]);
  e[2] = CTRL_LIT(0.5) * (S[1] - S[3]);
}

/* R <- Rot(w h) R (Rodrigues), w in the base frame. */
static void rotate(ctrl_real *R, const ctrl_real *w, ctrl_real h) {
  ctrl_real th = CTRL_SQRT(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * h, k[3], K[9], KK[9], A[9], out[9];
  int r, col, j;
  if (!(th > CTRL_LIT(0.0))) return;
  for (j = 0; j < 3; ++j) {
    k[j] = w[j] * h / th;
  }
  K[0] = CTRL_LIT(0.0); K[3] = -k[2]; K[6] = k[1];
  K[1] = k[2]; K[4] = CTRL_LIT(0.0); K[7] = -k[0];
  K[2] = -k[1]; K[5] = k[0]; K[8] = CTRL_LIT(0.0);
  for (col = 0; col < 3; ++col) {
    for (r = 0; r < 3; ++r) {
      KK[r + 3 * col] = K[r] * K[3 * col] + K[r + 3] * K[1 + 3 * col] + K[r + 6] * K[2 + 3 * col];
    }
  }
  for (j = 0; j < 9; ++j) {
    A[j] = CTRL_SIN(th) * K[j] + (CTRL_LIT(1.0) - CTRL_COS(th)) * KK[j] + ((j % 4) == 0 ? CTRL_LIT(1.0) : CTRL_LIT(0.0));
  }
  for (col = 0; col < 3; ++col) {
    for (r = 0; r < 3; ++r) {
      out[r + 3 * col] = A[r] * R[3 * col] + A[r + 3] * R[1 + 3 * col] + A[r + 6] * R[2 + 3 * col];
    }
  }
  (void)memcpy(R, out, sizeof out);
}

static uint8_t accept_twist(fw_link *l, const fw_link_twist *m) {
  int i;
  ctrl_real T[16], J[6 * N];
  for (i = 0; i < 6; ++i) {
    l->twist[i] = (ctrl_real)m->xdot[i];
    if (!finite_r(l->twist[i])) return FW_LINK_RESULT_BAD_VALUE;
  }
  if (!l->servo_rows_known || l->streaming || (arm_moves(l->last.state) && !l->servoing) ||
      l->last.state == CTRL_STATE_FAULT) {
    return FW_LINK_RESULT_REFUSED_STATE;
  }
  if (!l->servoing) { /* the reference starts at the held command's tool pose */
    ctrl_gen_fk_jacobian(l->last.q, T, J);
    rotation_of(T, l->R_ref);
    for (i = 0; i < 3; ++i) {
      l->p_ref[i] = T[12 + i];
    }
    l->servoing = 1;
    l->servo_k = 0;
    l->null_ramp = CTRL_LIT(0.0);
  }
  return FW_LINK_RESULT_OK;
}

static uint8_t accept_move_to_pose(fw_link *l, const fw_link_move_to_pose *m) {
  int i;
  for (i = 0; i < 16; ++i) {
    l->target[i] = (ctrl_real)m->pose[i];
    if (!finite_r(l->target[i])) return FW_LINK_RESULT_BAD_VALUE;
  }
  if (arm_moves(l->last.state) || l->streaming || l->servoing) return FW_LINK_RESULT_REFUSED_STATE;
  l->command = CTRL_CMD_MOVE_TO;
  return FW_LINK_RESULT_OK;
}

static int inside_limits(const fw_link *l, const ctrl_real *q) {
  int i, inside = 1;
  for (i = 0; i < N; ++i) {
    inside &= finite_r(q[i]) && q[i] >= l->q_min[i] && q[i] <= l->q_max[i];
  }
  return inside;
}

static uint8_t accept_move_to_joints(fw_link *l, const fw_link_move_to_joints *m) {
  int i;
  for (i = 0; i < N; ++i) {
    l->q_target[i] = (ctrl_real)m->q[i];
  }
  if (!inside_limits(l, l->q_target)) return FW_LINK_RESULT_BAD_VALUE;
  if (arm_moves(l->last.state) || l->streaming || l->servoing) return FW_LINK_RESULT_REFUSED_STATE;
  l->command = CTRL_CMD_MOVE_TO_JOINTS;
  return FW_LINK_RESULT_OK;
}

/* A waypoint: inside the limits, within the speed limits, later than the one before; the first
 * of a stream at t = 0 at the held command, with the arm at rest. */
static uint8_t accept_waypoint(fw_link *l, const fw_link_waypoint *m) {
  fw_link_waypoint_slot w;
  int i;
  w.t_us = m->t_us;
  w.last = m->last;
  for (i = 0; i < N; ++i) {
    w.q[i] = (ctrl_real)m->q[i];
    w.qd[i] = (ctrl_real)m->qd[i];
    if (!finite_r(w.qd[i]) || w.qd[i] > l->qd_max[i] || w.qd[i] < -l->qd_max[i]) return FW_LINK_RESULT_BAD_VALUE;
  }
  if (!inside_limits(l, w.q)) return FW_LINK_RESULT_BAD_VALUE;
  if (!l->streaming) {
    if (arm_moves(l->last.state) || l->servoing || l->last.state == CTRL_STATE_FAULT) {
      return FW_LINK_RESULT_REFUSED_STATE;
    }
    if (w.t_us != 0u) return FW_LINK_RESULT_STREAM_START;
    for (i = 0; i < N; ++i) {
      ctrl_real d = w.q[i] - l->last.q[i];
      if (d > FW_LINK_STREAM_START_TOL || d < -FW_LINK_STREAM_START_TOL) return FW_LINK_RESULT_STREAM_START;
    }
    l->streaming = 1;
    l->stream_poses = 0;
    l->stream_ended = 0;
    l->stream_arrived = 0;
    l->stream_k = 0;
    l->wp_first = 0;
    l->wp_count = 0;
  } else {
    const fw_link_waypoint_slot *prev = &l->wp.joints[(l->wp_first + l->wp_count - 1u) % FW_LINK_WAYPOINTS];
    if (l->stream_poses) return FW_LINK_RESULT_REFUSED_STATE; /* a pose stream runs */
    if (l->stream_ended || w.t_us <= prev->t_us) return FW_LINK_RESULT_STREAM_ORDER;
    if (l->wp_count >= FW_LINK_WAYPOINTS) return FW_LINK_RESULT_STREAM_FULL;
  }
  l->wp.joints[(l->wp_first + l->wp_count) % FW_LINK_WAYPOINTS] = w;
  ++l->wp_count;
  l->stream_ended = w.last != 0u;
  return FW_LINK_RESULT_OK;
}

/* The rotation vector phi of Rb Ra^T (base frame): Rb = Rot(phi) Ra; 0 when the rotation is a
 * quarter turn or more (refused by the caller). Returns cos of the angle. */
static ctrl_real rotation_vector(const ctrl_real *Ra, const ctrl_real *Rb, ctrl_real *phi) {
  ctrl_real S[9], u[3], c, sn, th;
  int r, col;
  for (col = 0; col < 3; ++col) {
    for (r = 0; r < 3; ++r) {
      S[r + 3 * col] = Rb[r] * Ra[col] + Rb[r + 3] * Ra[col + 3] + Rb[r + 6] * Ra[col + 6];
    }
  }
  u[0] = CTRL_LIT(0.5) * (S[5] - S[7]);
  u[1] = CTRL_LIT(0.5) * (S[6] - S[2]);
  u[2] = CTRL_LIT(0.5) * (S[1] - S[3]);
  c = CTRL_LIT(0.5) * (S[0] + S[4] + S[8] - CTRL_LIT(1.0));
  sn = CTRL_SQRT(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
  th = LINK_ATAN2(sn, c);
  for (r = 0; r < 3; ++r) {
    phi[r] = sn > CTRL_LIT(0.0) ? u[r] * (th / sn) : CTRL_LIT(0.0);
  }
  return c;
}

/* A pose waypoint: finite, its rotation orthonormal, later than the one before and less than a
 * quarter turn from it; the first of a stream at t = 0 at the held command's tool pose, with
 * the arm at rest. */
static uint8_t accept_pose_waypoint(fw_link *l, const fw_link_pose_waypoint *m) {
  fw_link_pose_slot w;
  ctrl_real T[16], J[6 * N], R[9], e[3];
  int i, r, col;
  w.t_us = m->t_us;
  w.last = m->last;
  for (i = 0; i < 3; ++i) {
    w.p[i] = (ctrl_real)m->tool[i];
  }
  for (i = 0; i < 9; ++i) {
    w.R[i] = (ctrl_real)m->tool[3 + i];
  }
  for (i = 0; i < 6; ++i) {
    w.twist[i] = (ctrl_real)m->twist[i];
  }
  for (i = 0; i < 12; ++i) {
    if (!finite_r(i < 3 ? w.p[i] : w.R[i - 3]) || (i < 6 && !finite_r(w.twist[i]))) return FW_LINK_RESULT_BAD_VALUE;
  }
  for (col = 0; col < 3; ++col) { /* R^T R = I */
    for (r = 0; r < 3; ++r) {
      ctrl_real d = w.R[3 * r] * w.R[3 * col] + w.R[3 * r + 1] * w.R[3 * col + 1] + w.R[3 * r + 2] * w.R[3 * col + 2] -
                    (r == col ? CTRL_LIT(1.0) : CTRL_LIT(0.0));
      if (d > FW_LINK_POSE_ORTHO_TOL || d < -FW_LINK_POSE_ORTHO_TOL) return FW_LINK_RESULT_BAD_VALUE;
    }
  }
  if (!l->streaming) {
    if (arm_moves(l->last.state) || l->servoing || l->last.state == CTRL_STATE_FAULT || !l->servo_rows_known) {
      return FW_LINK_RESULT_REFUSED_STATE;
    }
    if (w.t_us != 0u) return FW_LINK_RESULT_STREAM_START;
    ctrl_gen_fk_jacobian(l->last.q, T, J);
    rotation_of(T, R);
    orientation_error(R, w.R, e);
    for (i = 0; i < 3; ++i) {
      ctrl_real d = w.p[i] - T[12 + i];
      if (d > FW_LINK_POSE_START_TOL_M || d < -FW_LINK_POSE_START_TOL_M || e[i] > FW_LINK_POSE_START_TOL_RAD ||
          e[i] < -FW_LINK_POSE_START_TOL_RAD) {
        return FW_LINK_RESULT_STREAM_START;
      }
    }
    for (i = 0; i < 3; ++i) {
      w.phi[i] = CTRL_LIT(0.0);
    }
    l->streaming = 1;
    l->stream_poses = 1;
    l->stream_ended = 0;
    l->stream_arrived = 0;
    l->stream_k = 0;
    l->pose_t = CTRL_LIT(0.0);
    l->null_ramp = CTRL_LIT(0.0);
    l->wp_first = 0;
    l->wp_count = 0;
  } else {
    const fw_link_pose_slot *prev = &l->wp.poses[(l->wp_first + l->wp_count - 1u) % FW_LINK_WAYPOINTS];
    if (!l->stream_poses) return FW_LINK_RESULT_REFUSED_STATE; /* a joint stream runs */
    if (l->stream_ended || w.t_us <= prev->t_us) return FW_LINK_RESULT_STREAM_ORDER;
    if (l->wp_count >= FW_LINK_WAYPOINTS) return FW_LINK_RESULT_STREAM_FULL;
    if (!(rotation_vector(prev->R, w.R, w.phi) > CTRL_LIT(0.0))) return FW_LINK_RESULT_BAD_VALUE;
  }
  l->wp.poses[(l->wp_first + l->wp_count) % FW_LINK_WAYPOINTS] = w;
  ++l->wp_count;
  l->stream_ended = w.last != 0u;
  return FW_LINK_RESULT_OK;
}

static uint8_t accept_servo_setup(fw_link *l, const fw_link_servo_setup *m) {
  ctrl_real gain = (ctrl_real)m->gain;
  if (m->criterion > FW_LINK_CRITERION_REST || !finite_r(gain) || gain < CTRL_LIT(0.0)) return FW_LINK_RESULT_BAD_VALUE;
  if (!CTRL_HAS_FAULT_TOLERANT && (m->criterion == FW_LINK_CRITERION_MANIPULABILITY ||
                                   m->criterion == FW_LINK_CRITERION_JOINT_MANIPULABILITY)) {
    return FW_LINK_RESULT_BAD_VALUE; /* no generated ft_index */
  }
  if (m->criterion == FW_LINK_CRITERION_TASK) {
    l->criterion = l->task_criterion;
    l->null_gain = gain > CTRL_LIT(0.0) ? gain : l->task_gain;
    return FW_LINK_RESULT_OK;
  }
  l->criterion = m->criterion;
  if (gain > CTRL_LIT(0.0)) {
    l->null_gain = gain;
  } else if (m->criterion == FW_LINK_CRITERION_JOINT_LIMITS) {
    l->null_gain = FW_LINK_GAIN_JOINT_LIMITS;
  } else if (m->criterion == FW_LINK_CRITERION_MANIPULABILITY) {
    l->null_gain = FW_LINK_GAIN_MANIPULABILITY;
  } else if (m->criterion == FW_LINK_CRITERION_JOINT_MANIPULABILITY) {
    l->null_gain = FW_LINK_GAIN_JOINT_MANIPULABILITY;
  } else {
    l->null_gain = FW_LINK_GAIN_REST; /* REST; NONE has no gain */
  }
  return FW_LINK_RESULT_OK;
}

static void start_stop(fw_link *l, ctrl_command end);

/* A valid frame of the session: act on it (or refuse it) and reply. */
static uint8_t dispatch(fw_link *l, uint8_t type, const fw_link_message *m) {
  if (type == FW_LINK_HELLO) {
    l->telemetry_period = m->hello.telemetry_period;
    l->replies = m->hello.replies == FW_LINK_REPLY_ACK ? FW_LINK_REPLY_ACK : FW_LINK_REPLY_TELEMETRY;
    l->reply_hello = 1;
    l->hello_accepted = 1;
    return FW_LINK_RESULT_OK;
  }
  if (type == FW_LINK_STATUS || l->replies == FW_LINK_REPLY_TELEMETRY) {
    l->reply_telemetry = 1;
  } else {
    l->reply_ack = 1;
  }
  if (type == FW_LINK_STATUS) return FW_LINK_RESULT_OK;
  if (l->stale) return FW_LINK_RESULT_STALE;
  if (l->stopping && type != FW_LINK_LOCK) return FW_LINK_RESULT_REFUSED_STATE; /* until at rest */
  switch (type) {
    case FW_LINK_START:
      if (l->last.state != CTRL_STATE_IDLE || l->streaming || l->servoing) return FW_LINK_RESULT_REFUSED_STATE;
      l->command = CTRL_CMD_START;
      return FW_LINK_RESULT_OK;
    case FW_LINK_STOP:
      if (arm_moves(l->last.state)) {
        start_stop(l, CTRL_CMD_STOP); /* to rest within the acceleration limits, then DONE */
      } else {
        l->command = CTRL_CMD_STOP;
      }
      return FW_LINK_RESULT_OK;
    case FW_LINK_MOVE_TO_POSE: return accept_move_to_pose(l, &m->move_to_pose);
    case FW_LINK_MOVE_TO_JOINTS: return accept_move_to_joints(l, &m->move_to_joints);
    case FW_LINK_WAYPOINT: return accept_waypoint(l, &m->waypoint);
    case FW_LINK_TWIST: return accept_twist(l, &m->twist);
    case FW_LINK_POSE_WAYPOINT: return accept_pose_waypoint(l, &m->pose_waypoint);
    case FW_LINK_SERVO_SETUP: return accept_servo_setup(l, &m->servo_setup);
    case FW_LINK_LOCK:
      l->locked = m->lock.locked;
      return FW_LINK_RESULT_OK;
    default: return FW_LINK_RESULT_BAD_VALUE; /* not reached: fw_link_unpack knows only the types above */
  }
}

/* One received frame (its COBS bytes, without the delimiter): checked, then acted on or counted. */
static void frame_received(fw_link *l, const uint8_t *encoded, size_t len) {
  uint8_t raw[FW_LINK_MAX_ENCODED];
  fw_link_message m;
  size_t n = fw_link_cobs_decode(encoded, len, raw);
  uint32_t crc;
  uint16_t seq;
  uint8_t type;
  if (n < FW_LINK_HEADER_SIZE + FW_LINK_CRC_SIZE) {
    ++l->counts.malformed;
    return;
  }
  n -= FW_LINK_CRC_SIZE;
  crc = (uint32_t)raw[n] | ((uint32_t)raw[n + 1u] << 8) | ((uint32_t)raw[n + 2u] << 16) | ((uint32_t)raw[n + 3u] << 24);
  if (fw_link_crc32(raw, n) != crc) {
    ++l->counts.bad_crc;
    return;
  }
  type = raw[1];
  seq = (uint16_t)(raw[2] | (uint16_t)((uint16_t)raw[3] << 8));
  if (raw[0] != FW_LINK_VERSION) {
    ++l->counts.wrong_version;
    if (type == FW_LINK_HELLO) { /* say which version this board speaks; nothing else happens */
      l->reply_hello = 1;
      l->hello_accepted = 0;
    }
    return;
  }
  /* host messages only: a board message (HELLO_REPLY, TELEMETRY) from the host is malformed */
  if ((type & 0x80u) != 0u || !fw_link_unpack(type, raw + FW_LINK_HEADER_SIZE, n - FW_LINK_HEADER_SIZE, &m)) {
    ++l->counts.malformed;
    return;
  }
  if (type == FW_LINK_HELLO) {
    l->session = 1;
  } else if (!l->session) {
    ++l->counts.no_session;
    return;
  } else {
    /* serial-number arithmetic (RFC 1982): newer when 1 ... 32767 ahead */
    uint16_t ahead = (uint16_t)(seq - l->rx_seq);
    if (ahead == 0u || ahead >= 0x8000u) {
      ++l->counts.out_of_order;
      return;
    }
    l->counts.seq_gaps += (uint32_t)ahead - 1u;
  }
  l->rx_seq = seq;
  ++l->counts.rx_frames;
  l->last_frame_tick = l->tick;
  l->ack_seq = seq;
  l->result = dispatch(l, type, &m);
  if (l->result != FW_LINK_RESULT_OK) {
    ++l->counts.rejected;
  }
}

/* Decode the received bytes up to the first valid frame: one frame is acted on (and answered)
 * per tick, the rest wait in the ring (at 1 kHz, a thousand frames a second). */
static void receive_frames(fw_link *l) {
  uint32_t before = l->counts.rx_frames;
  while (l->counts.rx_frames == before && l->ring_tail != l->ring_head) {
    uint32_t tail = l->ring_tail;
    uint8_t b = l->ring[tail & (FW_LINK_RX_RING - 1u)];
    l->ring_tail = tail + 1u;
    if (b != 0u) {
      if (l->encoded_len < sizeof l->encoded) {
        l->encoded[l->encoded_len++] = b;
      } else {
        l->encoded_overflow = 1;
      }
      continue;
    }
    if (l->encoded_overflow) {
      ++l->counts.oversized;
    } else if (l->encoded_len > 0u) {
      frame_received(l, l->encoded, l->encoded_len);
    } else {
      /* an empty frame (two delimiters) only resynchronises */
    }
    l->encoded_len = 0;
    l->encoded_overflow = 0;
  }
}

/* ------------------------------------------------------------------ the watchdog's stop */

/* A controlled stop: the velocities of the last command ramp down together over the shortest
 * duration in which every joint decelerates within its qddot_max; then `end` (STALE or STOP). */
static void start_stop(fw_link *l, ctrl_command end) {
  int i;
  l->stopping = 1;
  l->stop_end = end;
  l->streaming = 0;
  l->servoing = 0;
  l->command = CTRL_CMD_NONE;
  l->stop_T = CTRL_LIT(0.0);
  l->stop_k = 0;
  for (i = 0; i < N; ++i) {
    ctrl_real v = l->last.qd[i], t = (v < CTRL_LIT(0.0) ? -v : v) / l->qdd_max[i];
    l->stop_q0[i] = l->last.q[i];
    l->stop_v0[i] = v;
    l->stop_T = t > l->stop_T ? t : l->stop_T;
  }
}

/* The stop's command of this tick: q0 + v0 tau - v0 tau^2 / (2 T), then at rest; then its end. */
static void stop_tick(fw_link *l, ctrl_input *in) {
  ctrl_real tau;
  int i;
  ++l->stop_k;
  tau = (ctrl_real)l->stop_k * l->dt;
  if (tau > l->stop_T + l->dt || !arm_moves(l->last.state)) {
    in->command = l->stop_end; /* at rest since the tick before */
    l->stopping = 0;
    return;
  }
  tau = tau < l->stop_T ? tau : l->stop_T;
  in->command = CTRL_CMD_SETPOINT;
  for (i = 0; i < N; ++i) {
    ctrl_real a = l->stop_T > CTRL_LIT(0.0) ? l->stop_v0[i] / l->stop_T : CTRL_LIT(0.0);
    in->q_ref[i] = l->stop_q0[i] + l->stop_v0[i] * tau - CTRL_LIT(0.5) * a * tau * tau;
    in->qd_ref[i] = l->stop_v0[i] - a * tau;
  }
}

/* ------------------------------------------------------------------ the stream */

/* The cubic Hermite between waypoints a and b at time t (s): position. */
static ctrl_real hermite(const fw_link_waypoint_slot *a, const fw_link_waypoint_slot *b, int i, ctrl_real t) {
  ctrl_real h = (ctrl_real)(b->t_us - a->t_us) * CTRL_LIT(1e-6);
  ctrl_real s = (t - (ctrl_real)a->t_us * CTRL_LIT(1e-6)) / h;
  ctrl_real s2 = s * s, s3 = s2 * s;
  return (CTRL_LIT(2.0) * s3 - CTRL_LIT(3.0) * s2 + CTRL_LIT(1.0)) * a->q[i] + (s3 - CTRL_LIT(2.0) * s2 + s) * h * a->qd[i] +
         (CTRL_LIT(3.0) * s2 - CTRL_LIT(2.0) * s3) * b->q[i] + (s3 - s2) * h * b->qd[i];
}

/* The stream's command of this tick: the interpolated point, reached from the last command with
 * each joint's step limited to qdot_max * dt and its change of velocity to qddot_max * dt. */
static void stream_tick(fw_link *l, ctrl_input *in) {
  const fw_link_waypoint_slot *a, *b;
  ctrl_real t = (ctrl_real)l->stream_k * l->dt, ref[N];
  int i, arriving = 1;
  if (l->stream_k > 0u && !arm_moves(l->last.state)) { /* the controller stopped it (a fault) */
    l->streaming = 0;
    return;
  }
  if (l->stream_k == 0u && l->wp_count < 2u && !l->stream_ended) {
    return; /* the stream starts once its first segment is known: the arm holds until then */
  }
  if (l->stream_arrived) { /* at the last waypoint, at rest, since the tick before: the controller holds (DONE) */
    in->command = CTRL_CMD_STOP;
    l->streaming = 0;
    return;
  }
  while (l->wp_count >= 2u && (ctrl_real)l->wp.joints[(l->wp_first + 1u) % FW_LINK_WAYPOINTS].t_us * CTRL_LIT(1e-6) <= t) {
    l->wp_first = (l->wp_first + 1u) % FW_LINK_WAYPOINTS;
    --l->wp_count;
  }
  a = &l->wp.joints[l->wp_first];
  if (l->wp_count >= 2u) {
    b = &l->wp.joints[(l->wp_first + 1u) % FW_LINK_WAYPOINTS];
    for (i = 0; i < N; ++i) {
      ref[i] = clamp_r(hermite(a, b, i, t), l->q_min[i], l->q_max[i]);
    }
  } else {
    if (!l->stream_ended) {
      ++l->counts.underruns; /* the host is late: hold the last waypoint */
    }
    for (i = 0; i < N; ++i) {
      ref[i] = a->q[i];
    }
  }
  in->command = CTRL_CMD_SETPOINT;
  for (i = 0; i < N; ++i) {
    ctrl_real q = l->last.q[i], v_prev = l->stream_k > 0u ? l->last.qd[i] : CTRL_LIT(0.0);
    ctrl_real dv = l->qdd_max[i] * l->dt, e = ref[i] - q;
    ctrl_real v = clamp_r(e / l->dt, -l->qd_max[i], l->qd_max[i]);
    v = clamp_r(v, v_prev - dv, v_prev + dv);
    in->q_ref[i] = v * l->dt + q;
    in->qd_ref[i] = v;
    /* one step from the end, slow enough to stop within qddot_max in it */
    arriving &= (v_prev <= dv) && (v_prev >= -dv) && (e <= dv * l->dt) && (e >= -dv * l->dt);
  }
  ++l->stream_k;
  if (l->wp_count == 1u && l->stream_ended && arriving) { /* the last waypoint exactly, at rest */
    for (i = 0; i < N; ++i) {
      in->q_ref[i] = ref[i];
      in->qd_ref[i] = CTRL_LIT(0.0);
    }
    l->stream_arrived = 1;
  }
}

/* ------------------------------------------------------------------ servo */

/* The largest s in [0, s_max] with |s qd_i - v_i| <= dv_i for every joint, or -1 when none. */
static ctrl_real acceleration_scale(const ctrl_real *qd, const ctrl_real *v, const ctrl_real *dv, ctrl_real s_max) {
  ctrl_real lo = CTRL_LIT(0.0), hi = s_max;
  int i;
  for (i = 0; i < N; ++i) {
    if (qd[i] != CTRL_LIT(0.0)) {
      ctrl_real a = (v[i] - dv[i]) / qd[i], b = (v[i] + dv[i]) / qd[i];
      lo = a < b ? (a > lo ? a : lo) : (b > lo ? b : lo);
      hi = a < b ? (b < hi ? b : hi) : (a < hi ? a : hi);
    } else if (v[i] > dv[i] || v[i] < -dv[i]) {
      return CTRL_LIT(-1.0); /* a joint the step leaves still cannot stop within the tick */
    } else {
      /* a joint the step leaves still, and can: no bound on s */
    }
  }
  return lo <= hi ? hi : CTRL_LIT(-1.0);
}

/* The chosen criterion's self-motion alpha at the last command (J its Jacobian). */
static void self_motion(const fw_link *l, const ctrl_real *J, ctrl_real *alpha) {
  ctrl_real H, grad[N], sign = -CTRL_LIT(1.0);
#if CTRL_HAS_FAULT_TOLERANT
  ctrl_real ones[N], omega[N], grad_w[N], w;
#endif
  int i;
#if CTRL_HAS_FAULT_TOLERANT
  for (i = 0; i < N; ++i) {
    ones[i] = CTRL_LIT(1.0);
  }
#else
  (void)J;
#endif
  switch (l->criterion) {
    case FW_LINK_CRITERION_JOINT_LIMITS:
      ctrl_gen_zghal(l->last.q, &H, grad);
      break;
    case FW_LINK_CRITERION_REST:
      ctrl_gen_repetitive(l->last.q, l->q_start, &H, grad);
      break;
#if CTRL_HAS_FAULT_TOLERANT
    case FW_LINK_CRITERION_MANIPULABILITY:
    case FW_LINK_CRITERION_JOINT_MANIPULABILITY: /* both from one call: w and H_M, maximised */
      ctrl_gen_ft_index(J, ones, l->hm_weights, FW_LINK_MANIPULABILITY_DELTA, omega, &H, grad, &w, grad_w);
      if (l->criterion == FW_LINK_CRITERION_MANIPULABILITY) {
        (void)memcpy(grad, grad_w, sizeof grad);
      }
      sign = CTRL_LIT(1.0);
      break;
#endif
    default: /* NONE: minimum norm */
      sign = CTRL_LIT(0.0);
      for (i = 0; i < N; ++i) {
        grad[i] = CTRL_LIT(0.0);
      }
      break;
  }
  for (i = 0; i < N; ++i) {
    alpha[i] = sign * l->null_gain * grad[i];
    alpha[i] = finite_r(alpha[i]) ? alpha[i] : CTRL_LIT(0.0);
  }
}

/* One resolved-rate tick of SERVO or a pose stream: the step toward the reference pose
 * (p_ref, R_ref) moving at twist (the closed loop on the tool's error from it), the criterion's
 * self-motion while the reference moves, solved by the generated step_fault (the damping from
 * sigma_min; a locked joint's column masked), scaled into the limits (speed, braking distance
 * to a limit, acceleration), written to `in`. Returns the scale of the twist, (0, 1]. */
static ctrl_real rate_step(fw_link *l, ctrl_input *in, const ctrl_real *twist, const ctrl_real *p_ref,
                           const ctrl_real *R_ref, int first) {
  ctrl_real T[16], J[6 * N], R[9], e[6], xd[CTRL_NTASK], alpha[N], qd[N], v[N], dv[N];
  ctrl_real s = CTRL_LIT(1.0), lam, sigma;
  ctrl_gen_status status;
#if CTRL_HAS_FAULT_TOLERANT
  ctrl_real mask[N], W[N];
#endif
  int i, moving = 0;
  ctrl_gen_fk_jacobian(l->last.q, T, J);
  rotation_of(T, R);
  for (i = 0; i < 3; ++i) {
    e[i] = p_ref[i] - T[12 + i];
  }
  orientation_error(R, R_ref, e + 3);
  for (i = 0; i < CTRL_NTASK; ++i) {
    xd[i] = twist[l->task_rows[i]] + FW_LINK_SERVO_GAIN * e[l->task_rows[i]];
  }
  for (i = 0; i < 6; ++i) {
    moving |= twist[i] != CTRL_LIT(0.0);
  }
  /* the self-motion ramps in while the reference moves and out while it is still (a zero twist,
   * a stream's end: rest), so that it never asks for a jump of velocity */
  l->null_ramp = clamp_r(l->null_ramp + (moving ? l->dt : -l->dt) / FW_LINK_SELF_MOTION_RAMP_S, CTRL_LIT(0.0),
                         CTRL_LIT(1.0));
  if (l->null_ramp > CTRL_LIT(0.0)) {
    self_motion(l, J, alpha);
  }
  for (i = 0; i < N; ++i) {
    int locked = ((l->locked >> (uint32_t)i) & 1u) != 0u;
    alpha[i] = l->null_ramp > CTRL_LIT(0.0) && !locked ? l->null_ramp * alpha[i] : CTRL_LIT(0.0);
#if CTRL_HAS_FAULT_TOLERANT
    mask[i] = locked ? CTRL_LIT(0.0) : CTRL_LIT(1.0);
    W[i] = CTRL_LIT(1.0);
#endif
    v[i] = first ? CTRL_LIT(0.0) : l->last.qd[i];
    dv[i] = l->qdd_max[i] * l->dt;
  }
#if CTRL_HAS_FAULT_TOLERANT
  status = ctrl_gen_step_fault(J, xd, mask, W, alpha, FW_LINK_SERVO_EPSILON, FW_LINK_SERVO_LAMBDA_MAX, qd, &lam, &sigma);
#else
  lam = CTRL_LIT(0.005); /* step_gpm's fixed damping, m: finite joint speeds at a singular pose, 5 um off the path elsewhere */
  sigma = (ctrl_real)NAN; /* not computed */
  status = ctrl_gen_step_gpm(J, xd, alpha, lam, qd);
#endif
  if (status != CTRL_GEN_OK) {
    for (i = 0; i < N; ++i) {
      qd[i] = CTRL_LIT(0.0); /* a non-finite step: come to rest */
    }
  }
  l->sigma_min = sigma;
  (void)memcpy(l->ref_err, e, sizeof l->ref_err);
  l->damping = lam;
  for (i = 0; i < N; ++i) { /* each joint's speed cap: its limit, and stopping before its joint limit */
    ctrl_real room = (qd[i] > CTRL_LIT(0.0) ? l->q_max[i] - l->last.q[i] : l->last.q[i] - l->q_min[i]) -
                     FW_LINK_SERVO_LIMIT_MARGIN;
    ctrl_real cap = CTRL_SQRT(CTRL_LIT(2.0) * l->qdd_max[i] * (room > CTRL_LIT(0.0) ? room : CTRL_LIT(0.0)));
    ctrl_real speed = qd[i] < CTRL_LIT(0.0) ? -qd[i] : qd[i];
    cap = cap < l->qd_max[i] ? cap : l->qd_max[i];
    if (speed > cap) s = s < cap / speed ? s : cap / speed;
  }
  /* the reference moves by the twist scaled to the speeds the joints may reach; the change of
   * velocity this tick is limited on top, and the closed loop makes up the lag */
  l->servo_scale = s;
  s = acceleration_scale(qd, v, dv, s);
  for (i = 0; i < N; ++i) { /* no common scale fits the acceleration: each joint as close as it can */
    v[i] = s >= CTRL_LIT(0.0) ? s * qd[i] : clamp_r(l->servo_scale * qd[i], v[i] - dv[i], v[i] + dv[i]);
    in->q_ref[i] = clamp_r(l->last.q[i] + v[i] * l->dt, l->q_min[i], l->q_max[i]);
    in->qd_ref[i] = v[i];
  }
  in->command = CTRL_CMD_SETPOINT;
  return l->servo_scale;
}

/* The servo's command of this tick; the reference then moves by the twist as executed. */
static void servo_tick(fw_link *l, ctrl_input *in) {
  ctrl_real s, lag, back[3];
  int i;
  if (l->servo_k > 0u && !arm_moves(l->last.state)) { /* the controller stopped it (a fault) */
    l->servoing = 0;
    return;
  }
  s = rate_step(l, in, l->twist, l->p_ref, l->R_ref, l->servo_k == 0u);
  /* where the arm cannot follow (a singular pose, a joint limit), the reference waits for the
   * tool instead of running away: drawn back to FW_LINK_SERVO_MAX_LAG of it, so that the arm
   * answers a reversed twist at once rather than after unwinding the lag */
  lag = CTRL_SQRT(l->ref_err[0] * l->ref_err[0] + l->ref_err[1] * l->ref_err[1] + l->ref_err[2] * l->ref_err[2]);
  if (lag > FW_LINK_SERVO_MAX_LAG_M) {
    for (i = 0; i < 3; ++i) {
      l->p_ref[i] -= l->ref_err[i] * (CTRL_LIT(1.0) - FW_LINK_SERVO_MAX_LAG_M / lag);
    }
  }
  lag = CTRL_SQRT(l->ref_err[3] * l->ref_err[3] + l->ref_err[4] * l->ref_err[4] + l->ref_err[5] * l->ref_err[5]);
  if (lag > FW_LINK_SERVO_MAX_LAG_RAD) {
    for (i = 0; i < 3; ++i) {
      back[i] = -l->ref_err[3 + i] * (CTRL_LIT(1.0) - FW_LINK_SERVO_MAX_LAG_RAD / lag);
    }
    rotate(l->R_ref, back, CTRL_LIT(1.0));
  }
  for (i = 0; i < 3; ++i) {
    l->p_ref[i] += s * l->twist[i] * l->dt;
  }
  rotate(l->R_ref, l->twist + 3, s * l->dt);
  ++l->servo_k;
}

/* The pose between stream poses a and b at time t (s): position and rotation vector by cubic
 * Hermites (the rotation vector from a's rotation: 0 to b->phi, its rates the poses' angular
 * velocities, exact at the ends), and the reference's twist, their derivatives. */
static void pose_between(const fw_link_pose_slot *a, const fw_link_pose_slot *b, ctrl_real t, ctrl_real *p,
                         ctrl_real *R, ctrl_real *twist) {
  ctrl_real h = (ctrl_real)(b->t_us - a->t_us) * CTRL_LIT(1e-6);
  ctrl_real s = (t - (ctrl_real)a->t_us * CTRL_LIT(1e-6)) / h, s2 = s * s, s3 = s2 * s, phi[3];
  ctrl_real h00 = CTRL_LIT(2.0) * s3 - CTRL_LIT(3.0) * s2 + CTRL_LIT(1.0), h10 = s3 - CTRL_LIT(2.0) * s2 + s;
  ctrl_real h01 = CTRL_LIT(3.0) * s2 - CTRL_LIT(2.0) * s3, h11 = s3 - s2;
  ctrl_real d00 = (CTRL_LIT(6.0) * s2 - CTRL_LIT(6.0) * s) / h, d10 = CTRL_LIT(3.0) * s2 - CTRL_LIT(4.0) * s + CTRL_LIT(1.0);
  ctrl_real d01 = -d00, d11 = CTRL_LIT(3.0) * s2 - CTRL_LIT(2.0) * s;
  int i;
  for (i = 0; i < 3; ++i) {
    p[i] = h00 * a->p[i] + h10 * h * a->twist[i] + h01 * b->p[i] + h11 * h * b->twist[i];
    twist[i] = d00 * a->p[i] + d10 * a->twist[i] + d01 * b->p[i] + d11 * b->twist[i];
    phi[i] = h10 * h * a->twist[3 + i] + h01 * b->phi[i] + h11 * h * b->twist[3 + i];
    twist[3 + i] = d10 * a->twist[3 + i] + d01 * b->phi[i] + d11 * b->twist[3 + i];
  }
  (void)memcpy(R, a->R, 9u * sizeof *R);
  rotate(R, phi, CTRL_LIT(1.0));
}

/* The pose stream's command of this tick: the interpolated pose at the stream's clock, followed
 * by the resolved-rate step; the clock advances by the step's scale (slower where the limits
 * slow the tool). After the last pose, the step closes on it at rest; there, the command rests. */
static void pose_stream_tick(fw_link *l, ctrl_input *in) {
  const fw_link_pose_slot *a;
  ctrl_real p[3], R[9], twist[6], s, T[16], J[6 * N], Rt[9], e[3];
  int i, arrived = 1;
  if (l->stream_k > 0u && !arm_moves(l->last.state)) { /* the controller stopped it (a fault) */
    l->streaming = 0;
    return;
  }
  if (l->stream_k == 0u && l->wp_count < 2u && !l->stream_ended) {
    return; /* the stream starts once its first segment is known: the arm holds until then */
  }
  if (l->stream_arrived) { /* at the last pose, at rest, since the tick before: the controller holds (DONE) */
    in->command = CTRL_CMD_STOP;
    l->streaming = 0;
    return;
  }
  while (l->wp_count >= 2u &&
         (ctrl_real)l->wp.poses[(l->wp_first + 1u) % FW_LINK_WAYPOINTS].t_us * CTRL_LIT(1e-6) <= l->pose_t) {
    l->wp_first = (l->wp_first + 1u) % FW_LINK_WAYPOINTS;
    --l->wp_count;
  }
  a = &l->wp.poses[l->wp_first];
  if (l->wp_count >= 2u) {
    pose_between(a, &l->wp.poses[(l->wp_first + 1u) % FW_LINK_WAYPOINTS], l->pose_t, p, R, twist);
  } else {
    if (!l->stream_ended) {
      ++l->counts.underruns; /* the host is late: hold the last pose */
    }
    (void)memcpy(p, a->p, sizeof p);
    (void)memcpy(R, a->R, sizeof R);
    (void)memset(twist, 0, sizeof twist);
  }
  if (l->wp_count == 1u && l->stream_ended) { /* past the end: arrived when there and slow */
    ctrl_gen_fk_jacobian(l->last.q, T, J);
    rotation_of(T, Rt);
    orientation_error(Rt, R, e);
    for (i = 0; i < 3; ++i) {
      ctrl_real d = p[i] - T[12 + i];
      arrived &= d <= FW_LINK_POSE_ARRIVE_M && d >= -FW_LINK_POSE_ARRIVE_M && e[i] <= FW_LINK_POSE_ARRIVE_RAD &&
                 e[i] >= -FW_LINK_POSE_ARRIVE_RAD;
    }
    for (i = 0; i < N; ++i) {
      ctrl_real dv = l->qdd_max[i] * l->dt;
      arrived &= l->last.qd[i] <= dv && l->last.qd[i] >= -dv;
    }
    if (arrived) { /* rest where the command is */
      for (i = 0; i < N; ++i) {
        in->q_ref[i] = l->last.q[i];
        in->qd_ref[i] = CTRL_LIT(0.0);
      }
      in->command = CTRL_CMD_SETPOINT;
      l->stream_arrived = 1;
      ++l->stream_k;
      return;
    }
  }
  s = rate_step(l, in, twist, p, R, l->stream_k == 0u);
  l->pose_t += s * l->dt;
  ++l->stream_k;
}

/* ------------------------------------------------------------------ per tick */

void fw_link_input(fw_link *l, ctrl_input *in) {
  in->locked = l->locked;
  receive_frames(l);
  if (!l->stale && l->session && arm_moves(l->last.state) && l->tick - l->last_frame_tick > l->watchdog_ticks) {
    l->stale = 1;
    l->stale_ticks = l->tick - l->last_frame_tick;
    start_stop(l, CTRL_CMD_STALE);
  }
  if (l->stopping) {
    stop_tick(l, in);
    return;
  }
  if (l->stale) {
    return; /* latched: the controller holds */
  }
  if (l->command != CTRL_CMD_NONE) {
    in->command = l->command;
    if (l->command == CTRL_CMD_MOVE_TO) {
      (void)memcpy(in->target, l->target, sizeof in->target);
    } else if (l->command == CTRL_CMD_MOVE_TO_JOINTS) {
      (void)memcpy(in->q_ref, l->q_target, sizeof in->q_ref);
    } else {
      /* START, STOP: the command alone */
    }
    l->command = CTRL_CMD_NONE;
    return;
  }
  if (l->streaming && l->stream_poses) {
    pose_stream_tick(l, in);
  } else if (l->streaming) {
    stream_tick(l, in);
  } else if (l->servoing) {
    servo_tick(l, in);
  } else {
    /* nothing to command: the controller goes on with its mode or holds */
  }
}

static void send_hello_reply(fw_link *l) {
  fw_link_hello_reply r;
  uint8_t body[FW_LINK_HELLO_REPLY_SIZE];
  r.accepted = (uint8_t)l->hello_accepted;
  r.version = FW_LINK_VERSION;
  r.ndof = (uint8_t)N;
  r.dt_us = (uint32_t)(l->dt * CTRL_LIT(1e6) + CTRL_LIT(0.5));
  r.watchdog_ticks = l->watchdog_ticks;
  r.waypoint_capacity = (uint16_t)FW_LINK_WAYPOINTS;
  send(l, FW_LINK_HELLO_REPLY, body, fw_link_pack_hello_reply(&r, body));
}

static uint8_t link_flags(const fw_link *l) {
  return (uint8_t)((l->session ? FW_LINK_FLAG_SESSION : 0u) | (l->streaming ? FW_LINK_FLAG_STREAMING : 0u) |
                   (l->stale ? FW_LINK_FLAG_STALE : 0u) | (l->servoing ? FW_LINK_FLAG_SERVOING : 0u) |
                   (l->streaming && l->stream_poses ? FW_LINK_FLAG_POSES : 0u));
}

static uint16_t waypoints_free(const fw_link *l) {
  return (uint16_t)(l->streaming ? FW_LINK_WAYPOINTS - l->wp_count : FW_LINK_WAYPOINTS);
}

/* The light reply: what became of the frame, and the state; no joint values, no FK. */
static void send_ack(fw_link *l) {
  fw_link_ack m;
  uint8_t body[FW_LINK_ACK_SIZE];
  m.tick = l->tick;
  m.motion_tick = l->last.tick;
  m.ack_seq = l->ack_seq;
  m.result = l->result;
  m.state = (uint8_t)l->last.state;
  m.fault = (uint8_t)(l->stale ? CTRL_FAULT_STALE : l->last.fault);
  m.link_flags = link_flags(l);
  m.waypoints_free = waypoints_free(l);
  send(l, FW_LINK_ACK, body, fw_link_pack_ack(&m, body));
}

static void send_telemetry(fw_link *l) {
  const ctrl_output *o = &l->last;
  fw_link_telemetry m;
  uint8_t body[FW_LINK_TELEMETRY_SIZE];
  ctrl_real T[16], J[6 * N];
  int i;
  ctrl_gen_fk_jacobian(o->q, T, J);
  m.tick = l->tick;
  m.motion_tick = o->tick;
  m.state = (uint8_t)o->state;
  m.fault = (uint8_t)(l->stale ? CTRL_FAULT_STALE : o->fault);
  m.link_flags = link_flags(l);
  m.result = l->result;
  m.ack_seq = l->ack_seq;
  m.waypoints_free = waypoints_free(l);
  for (i = 0; i < N; ++i) {
    m.q[i] = (float)o->q[i];
    m.qd[i] = (float)o->qd[i];
  }
  for (i = 0; i < 3; ++i) {
    m.tool[i] = (float)T[12 + i];
    m.tool[3 + i] = (float)T[i];
    m.tool[6 + i] = (float)T[4 + i];
    m.tool[9 + i] = (float)T[8 + i];
  }
  m.pos_err = (float)o->pos_err;
  m.ori_err = (float)o->ori_err;
  m.locked = o->locked;
  m.rx_frames = l->counts.rx_frames;
  m.bad_crc = l->counts.bad_crc;
  m.malformed = l->counts.malformed;
  m.oversized = l->counts.oversized;
  m.out_of_order = l->counts.out_of_order;
  m.wrong_version = l->counts.wrong_version;
  m.no_session = l->counts.no_session;
  m.rejected = l->counts.rejected;
  m.rx_overflow = l->counts.rx_overflow;
  m.seq_gaps = l->counts.seq_gaps;
  m.underruns = l->counts.underruns;
  m.stale_ticks = l->stale_ticks;
  m.sigma_min = (float)l->sigma_min;
  m.damping = (float)l->damping;
  m.servo_scale = (float)l->servo_scale;
#if CTRL_HAS_COLLISION
  m.clearance = o->clearance == CTRL_CLEARANCE_UNCHECKED ? (float)NAN : (float)o->clearance;
#else
  m.clearance = (float)NAN; /* a robot without a collision model: nothing computed */
#endif
  send(l, FW_LINK_TELEMETRY, body, fw_link_pack_telemetry(&m, body));
}

void fw_link_output(fw_link *l, const ctrl_output *out) {
  l->last = *out;
  if (l->reply_hello) {
    send_hello_reply(l);
    l->reply_hello = 0;
  }
  if (l->reply_ack) {
    send_ack(l);
    l->reply_ack = 0;
  }
  if (l->reply_telemetry || (l->session && l->telemetry_period > 0u && l->tick % l->telemetry_period == 0u)) {
    send_telemetry(l);
    l->reply_telemetry = 0;
  }
  ++l->tick;
}
