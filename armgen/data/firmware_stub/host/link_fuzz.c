/*
 * The link's codec and parser under test (tests/test_link_codec.py, benchmarks/bench_link.py),
 * built with ASan/UBSan:
 *
 *   link_fuzz cobs         stdin (up to 4 KB) COBS-encoded by fw_link_cobs_encode on stdout
 *   link_fuzz uncobs       stdin decoded by fw_link_cobs_decode on stdout (nothing: not COBS)
 *   link_fuzz echo         frames on stdin -> each decoded (COBS, CRC-32, header, body by its
 *                          type) and encoded again on stdout; a frame that does not decode
 *                          comes back as an empty frame (a lone 0x00)
 *   link_fuzz fuzz N SEED  N chunks fed a byte at a time to fw_link on a controller with the
 *                          compiled-in task, one tick after each: intact frames (fresh sequence
 *                          numbers), mutated copies of them (bytes flipped, inserted, deleted),
 *                          random bytes, over-long frames, frames with a valid CRC-32 but
 *                          another version, a replayed sequence number, a board's type or a wrong
 *                          length. Each chunk must change the count of frames acted on by exactly
 *                          1 if intact, else 0; prints "# key value" lines, "# violations 0" when
 *                          it held everywhere.
 *
 * Exit status 0 when the run completed (violations are data), 2 on bad arguments.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "controller.h"
#include "fw_link.h"
#include "fw_task.h"

#define CHUNK_MAX 4096u

static uint64_t next_random(uint64_t *s) { /* xorshift64*: seeded, reproducible */
  *s ^= *s >> 12;
  *s ^= *s << 25;
  *s ^= *s >> 27;
  return *s * 2685821657736338717ull;
}

static uint32_t below(uint64_t *s, uint32_t n) { return (uint32_t)(next_random(s) >> 33) % n; }

static int echo(void) {
  static const uint8_t empty = 0u;
  uint8_t enc[FW_LINK_MAX_ENCODED + 1u], raw[FW_LINK_MAX_ENCODED], body[FW_LINK_MAX_BODY],
      out[FW_LINK_MAX_ENCODED + 1u];
  size_t len = 0;
  int ch;
  while ((ch = getchar()) != EOF) {
    size_t n, body_len, out_len;
    fw_link_message m;
    uint32_t crc;
    if (ch != 0) {
      if (len < sizeof enc) enc[len++] = (uint8_t)ch;
      continue;
    }
    n = fw_link_cobs_decode(enc, len, raw);
    len = 0;
    if (n < FW_LINK_HEADER_SIZE + FW_LINK_CRC_SIZE) {
      (void)fwrite(&empty, 1, 1, stdout);
      continue;
    }
    n -= FW_LINK_CRC_SIZE;
    crc = (uint32_t)raw[n] | ((uint32_t)raw[n + 1u] << 8) | ((uint32_t)raw[n + 2u] << 16) | ((uint32_t)raw[n + 3u] << 24);
    if (crc != fw_link_crc32(raw, n) || !fw_link_unpack(raw[1], raw + FW_LINK_HEADER_SIZE, n - FW_LINK_HEADER_SIZE, &m)) {
      (void)fwrite(&empty, 1, 1, stdout);
      continue;
    }
    body_len = fw_link_pack(raw[1], &m, body);
    out_len = fw_link_frame(raw[0], raw[1], (uint16_t)(raw[2] | (raw[3] << 8)), body, body_len, out);
    (void)fwrite(out, 1, out_len, stdout);
  }
  return 0;
}

/* The size of a host message's body; 0 for a type without one. */
static size_t host_body_size(uint8_t type) {
  switch (type) {
    case FW_LINK_HELLO: return FW_LINK_HELLO_SIZE;
    case FW_LINK_MOVE_TO_POSE: return FW_LINK_MOVE_TO_POSE_SIZE;
    case FW_LINK_MOVE_TO_JOINTS: return FW_LINK_MOVE_TO_JOINTS_SIZE;
    case FW_LINK_WAYPOINT: return FW_LINK_WAYPOINT_SIZE;
    case FW_LINK_LOCK: return FW_LINK_LOCK_SIZE;
    case FW_LINK_TWIST: return FW_LINK_TWIST_SIZE;
    case FW_LINK_POSE_WAYPOINT: return FW_LINK_POSE_WAYPOINT_SIZE;
    case FW_LINK_SERVO_SETUP: return FW_LINK_SERVO_SETUP_SIZE;
    default: return 0u;
  }
}

typedef struct {
  ctrl c;
  fw_link l;
  uint64_t rng;
  uint16_t seq;
  uint32_t stream_t_us;
  uint8_t replay[FW_LINK_MAX_ENCODED + 1u];
  size_t replay_len;
  unsigned long commands, setpoints, pose_setpoints, dropped[5]; /* over the whole run: bad CRC, malformed, oversized, version, order */
} fuzz;

/* An intact host frame with the next sequence number: mostly STATUS and plausible joint and pose
 * waypoints (so streams of both kinds run), the other types with random bodies (finite or not,
 * in the limits or not). */
static size_t intact_frame(fuzz *z, uint8_t *out) {
  static const uint8_t types[] = {FW_LINK_STATUS, FW_LINK_STATUS, FW_LINK_WAYPOINT, FW_LINK_WAYPOINT, FW_LINK_START,
                                  FW_LINK_STOP,   FW_LINK_LOCK,   FW_LINK_MOVE_TO_JOINTS, FW_LINK_MOVE_TO_POSE,
                                  FW_LINK_TWIST,  FW_LINK_POSE_WAYPOINT, FW_LINK_SERVO_SETUP};
  uint8_t type = types[below(&z->rng, (uint32_t)sizeof types)], body[FW_LINK_MAX_BODY];
  size_t len = host_body_size(type), i;
  for (i = 0; i < len; ++i) body[i] = (uint8_t)next_random(&z->rng);
  if (type == FW_LINK_LOCK && below(&z->rng, 4u) != 0u) (void)memset(body, 0, len); /* mostly no lock */
  if (type == FW_LINK_WAYPOINT && below(&z->rng, 2u) == 0u) {
    fw_link_waypoint w;
    z->stream_t_us = z->l.streaming ? z->stream_t_us + 20000u : 0u;
    w.t_us = z->stream_t_us;
    w.last = (uint8_t)(below(&z->rng, 50u) == 0u);
    for (i = 0; i < (size_t)CTRL_NDOF; ++i) {
      w.q[i] = (float)z->l.last.q[i] + (float)below(&z->rng, 100u) * 1e-5f;
      w.qd[i] = 0.0f;
    }
    len = fw_link_pack_waypoint(&w, body);
  }
  if (type == FW_LINK_POSE_WAYPOINT && below(&z->rng, 2u) == 0u) { /* the tool's pose, nudged: pose streams run */
    fw_link_pose_waypoint w;
    ctrl_real T[16], J[6 * CTRL_NDOF];
    ctrl_gen_fk_jacobian(z->l.last.q, T, J);
    z->stream_t_us = z->l.streaming ? z->stream_t_us + 20000u : 0u;
    w.t_us = z->stream_t_us;
    w.last = (uint8_t)(below(&z->rng, 50u) == 0u);
    for (i = 0; i < 3u; ++i) {
      w.tool[i] = (float)T[12u + i] + (float)below(&z->rng, 100u) * 1e-5f;
      w.tool[3u + i] = (float)T[i];
      w.tool[6u + i] = (float)T[4u + i];
      w.tool[9u + i] = (float)T[8u + i];
      w.twist[i] = 0.0f;
      w.twist[3u + i] = 0.0f;
    }
    len = fw_link_pack_pose_waypoint(&w, body);
  }
  z->seq = (uint16_t)(z->seq + 1u);
  return fw_link_frame(FW_LINK_VERSION, type, z->seq, body, len, out);
}

/* 1 when a segment of the chunk between delimiters is the frame itself (an inserted 0x00 next to
 * it leaves it intact: acting on it is right). */
static int holds_frame(const uint8_t *chunk, size_t n, const uint8_t *frame, size_t len) {
  size_t start = 0, i;
  for (i = 0; i <= n; ++i) {
    if (i == n || chunk[i] == 0u) {
      if (i - start == len && memcmp(chunk + start, frame, len) == 0) return 1;
      start = i + 1u;
    }
  }
  return 0;
}

/* A copy of the frame with 1 to 4 bytes flipped, inserted or deleted (never the same bytes),
 * then a delimiter, so the next chunk starts on a frame boundary. */
static size_t mutated(fuzz *z, const uint8_t *frame, size_t len, uint8_t *out) {
  size_t n, k, edits;
  do {
    (void)memcpy(out, frame, len);
    n = len;
    edits = 1u + below(&z->rng, 4u);
    for (k = 0; k < edits; ++k) {
      size_t at = below(&z->rng, (uint32_t)n);
      uint32_t op = below(&z->rng, 3u);
      if (op == 0u) {
        out[at] ^= (uint8_t)(1u + below(&z->rng, 255u));
      } else if (op == 1u && n + 1u < CHUNK_MAX) {
        (void)memmove(out + at + 1u, out + at, n - at);
        out[at] = (uint8_t)next_random(&z->rng);
        ++n;
      } else if (n > 1u) {
        (void)memmove(out + at, out + at + 1u, n - at - 1u);
        --n;
      }
    }
  } while (n == len && memcmp(out, frame, len) == 0);
  out[n] = 0u;
  return n + 1u;
}

static void tick(fuzz *z) {
  ctrl_input in;
  ctrl_output out;
  uint8_t sink[256];
  (void)memset(&in, 0, sizeof in);
  fw_link_input(&z->l, &in);
  z->setpoints += (unsigned long)(in.command == CTRL_CMD_SETPOINT);
  z->pose_setpoints += (unsigned long)(in.command == CTRL_CMD_SETPOINT && z->l.streaming && z->l.stream_poses);
  z->commands += (unsigned long)(in.command != CTRL_CMD_NONE && in.command != CTRL_CMD_SETPOINT);
  (void)ctrl_tick(&z->c, &in, &out);
  fw_link_output(&z->l, &out);
  while (fw_link_transmit(&z->l, sink, sizeof sink) > 0u) {
  }
}

/* Feed a chunk a byte at a time (a tick whenever the ring is full), then tick until it is read. */
static void feed(fuzz *z, const uint8_t *chunk, size_t len) {
  size_t i;
  for (i = 0; i < len; ++i) {
    while (!fw_link_receive(&z->l, chunk[i])) tick(z);
  }
  do {
    tick(z);
  } while (z->l.ring_tail != z->l.ring_head);
}

static void restart(fuzz *z) {
  uint8_t frame[FW_LINK_MAX_ENCODED + 1u], body[FW_LINK_HELLO_SIZE] = {0u};
  const fw_link_counts *n = &z->l.counts;
  z->dropped[0] += n->bad_crc;
  z->dropped[1] += n->malformed;
  z->dropped[2] += n->oversized;
  z->dropped[3] += n->wrong_version;
  z->dropped[4] += n->out_of_order;
  (void)ctrl_init(&z->c, &fw_task);
  fw_link_init(&z->l, &fw_task, 50u);
  z->seq = (uint16_t)next_random(&z->rng);
  feed(z, frame, fw_link_frame(FW_LINK_VERSION, FW_LINK_HELLO, z->seq, body, sizeof body, frame));
  z->replay_len = 0;
}

static int run_fuzz(unsigned long chunks, uint64_t seed) {
  static fuzz z; /* large: not on the stack */
  static uint8_t frame[CHUNK_MAX], chunk[CHUNK_MAX];
  unsigned long i, intact = 0, violations = 0, kinds[8] = {0}, mutated_intact = 0;
  z.rng = seed * 0x9E3779B97F4A7C15ull + 1u;
  restart(&z);
  for (i = 0; i < chunks; ++i) {
    uint32_t kind = below(&z.rng, 100u), before;
    size_t n = 0, k, len;
    int valid = 0;
    if (i % 20000ul == 19999ul) restart(&z); /* a latched fault (STALE, a random LOCK) ends coverage */
    before = z.l.counts.rx_frames;
    if (kind < 30u) {
      n = intact_frame(&z, chunk);
      (void)memcpy(z.replay, chunk, n);
      z.replay_len = n;
      valid = 1;
      kinds[0]++;
    } else if (kind < 65u) {
      len = intact_frame(&z, frame);
      n = mutated(&z, frame, len - 1u, chunk); /* the frame without its delimiter */
      valid = holds_frame(chunk, n, frame, len - 1u);
      kinds[1]++;
    } else if (kind < 75u) {
      n = 1u + below(&z.rng, 600u);
      for (k = 0; k < n; ++k) chunk[k] = (uint8_t)next_random(&z.rng);
      chunk[n++] = 0u;
      kinds[2]++;
    } else if (kind < 80u) {
      n = FW_LINK_MAX_ENCODED + 1u + below(&z.rng, 2000u);
      for (k = 0; k < n; ++k) chunk[k] = (uint8_t)(1u + below(&z.rng, 255u));
      chunk[n++] = 0u;
      kinds[3]++;
    } else if (kind < 85u) { /* a valid CRC, another version */
      uint8_t body[FW_LINK_HELLO_SIZE] = {0u};
      z.seq = (uint16_t)(z.seq + 1u);
      n = fw_link_frame((uint8_t)(FW_LINK_VERSION + 1u + below(&z.rng, 254u)), FW_LINK_HELLO, z.seq, body,
                        sizeof body, chunk);
      kinds[4]++;
    } else if (kind < 90u && z.replay_len > 0u) { /* the last intact frame again: an old seq */
      (void)memcpy(chunk, z.replay, z.replay_len);
      n = z.replay_len;
      kinds[5]++;
    } else if (kind < 95u) { /* a valid CRC, a board's message type */
      uint8_t body[FW_LINK_TELEMETRY_SIZE];
      for (k = 0; k < sizeof body; ++k) body[k] = (uint8_t)next_random(&z.rng);
      z.seq = (uint16_t)(z.seq + 1u);
      n = fw_link_frame(FW_LINK_VERSION, below(&z.rng, 2u) == 0u ? FW_LINK_TELEMETRY : FW_LINK_HELLO_REPLY, z.seq,
                        body, FW_LINK_TELEMETRY_SIZE, chunk);
      kinds[6]++;
    } else { /* a valid CRC, a body one byte too long */
      uint8_t body[FW_LINK_WAYPOINT_SIZE + 1u];
      for (k = 0; k < sizeof body; ++k) body[k] = (uint8_t)next_random(&z.rng);
      z.seq = (uint16_t)(z.seq + 1u);
      n = fw_link_frame(FW_LINK_VERSION, FW_LINK_WAYPOINT, z.seq, body, sizeof body, chunk);
      kinds[7]++;
    }
    feed(&z, chunk, n);
    intact += (unsigned long)valid;
    mutated_intact += (unsigned long)(valid && kind >= 30u);
    if (z.l.counts.rx_frames - before != (uint32_t)valid) ++violations;
  }
  printf("# chunks %lu\n# intact %lu\n# mutated %lu\n# random %lu\n# oversized_sent %lu\n# other_version %lu\n"
         "# replayed %lu\n# board_type %lu\n# wrong_length %lu\n",
         chunks, intact, kinds[1], kinds[2], kinds[3], kinds[4], kinds[5], kinds[6], kinds[7]);
  restart(&z); /* adds the last counts */
  printf("# bad_crc %lu\n# malformed %lu\n# oversized %lu\n# wrong_version %lu\n# out_of_order %lu\n",
         z.dropped[0], z.dropped[1], z.dropped[2], z.dropped[3], z.dropped[4]);
  printf("# commands %lu\n# setpoints %lu\n# pose_setpoints %lu\n", z.commands, z.setpoints, z.pose_setpoints);
  printf("# mutated_but_intact %lu\n", mutated_intact); /* a 0x00 inserted beside the frame */
  printf("# violations %lu\n", violations);
  return 0;
}

static int cobs(int decode) {
  static uint8_t in[CHUNK_MAX], out[CHUNK_MAX + CHUNK_MAX / 254u + 1u];
  size_t n = fread(in, 1, sizeof in, stdin);
  size_t m = decode ? fw_link_cobs_decode(in, n, out) : fw_link_cobs_encode(in, n, out);
  (void)fwrite(out, 1, m, stdout);
  return 0;
}

int main(int argc, char **argv) {
  if (argc == 2 && strcmp(argv[1], "echo") == 0) return echo();
  if (argc == 2 && strcmp(argv[1], "cobs") == 0) return cobs(0);
  if (argc == 2 && strcmp(argv[1], "uncobs") == 0) return cobs(1);
  if (argc == 4 && strcmp(argv[1], "fuzz") == 0) {
    char *end1 = NULL, *end2 = NULL;
    unsigned long n = strtoul(argv[2], &end1, 10);
    unsigned long long seed = strtoull(argv[3], &end2, 10);
    if (*end1 == '\0' && *end2 == '\0' && n > 0ul) return run_fuzz(n, (uint64_t)seed);
  }
  fprintf(stderr, "usage: link_fuzz echo | cobs | uncobs | fuzz N SEED\n");
  return 2;
}
