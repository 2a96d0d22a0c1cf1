/*
 * Host runner of the link (docs/link.md): the controller with the compiled-in task's
 * configuration (`fw_task`: period, limits, start) serves fw_link over a pseudo-terminal, in
 * real time (one tick per dt of CLOCK_MONOTONIC), so a host program talks to it as to a board
 * on a serial port.
 *
 *   fw_link_host [--port PATH | --tcp PORT] [--watchdog-ms MS] [--csv FILE] [--run-s S]
 *
 *   --port PATH      serve the link on this terminal device (default: a new pseudo-terminal,
 *                    its name printed on stdout as "# port /dev/pts/N")
 *   --tcp PORT       serve it on TCP, 127.0.0.1:PORT (0: any free port), one client at a time;
 *                    printed as "# port socket://127.0.0.1:N" (pyserial's URL)
 *   --watchdog-ms M  the watchdog's timeout (default 100 ms), rounded to whole ticks
 *   --csv FILE       one row per tick: tick, t, state, fault, link flags, valid frames so far,
 *                    the joint commands q<i> and velocities qd<i> (%.17g)
 *   --run-s S        stop after S seconds (default: run until killed)
 *
 * A simulation of a board, not a real-time controller: a tick that starts late (a busy host)
 * is run at once without reporting an overrun, so the run stays deterministic in ticks.
 * Exit status 0 after --run-s; 2 on bad arguments; 4 when the terminal cannot be opened.
 */
#define _XOPEN_SOURCE 600

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "controller.h"
#include "fw_link.h"
#include "fw_task.h"

typedef struct {
  const char *port, *csv;
  double watchdog_ms, run_s;
  long tcp; /* -1: no TCP */
} options;

static int parse_args(int argc, char **argv, options *o) {
  int i;
  o->port = NULL;
  o->csv = NULL;
  o->watchdog_ms = 100.0;
  o->run_s = -1.0;
  o->tcp = -1;
  for (i = 1; i + 1 < argc; i += 2) {
    char *end = NULL;
    if (strcmp(argv[i], "--tcp") == 0) {
      o->tcp = strtol(argv[i + 1], &end, 10);
      if (*end != '\0' || o->tcp < 0 || o->tcp > 65535) return 0;
    } else if (strcmp(argv[i], "--port") == 0) {
      o->port = argv[i + 1];
    } else if (strcmp(argv[i], "--csv") == 0) {
      o->csv = argv[i + 1];
    } else if (strcmp(argv[i], "--watchdog-ms") == 0) {
      o->watchdog_ms = strtod(argv[i + 1], &end);
      if (*end != '\0' || !(o->watchdog_ms > 0.0)) return 0;
    } else if (strcmp(argv[i], "--run-s") == 0) {
      o->run_s = strtod(argv[i + 1], &end);
      if (*end != '\0' || !(o->run_s > 0.0)) return 0;
    } else {
      return 0;
    }
  }
  return i == argc && !(o->tcp >= 0 && o->port != NULL);
}

/* A TCP listener on 127.0.0.1 (non-blocking), its port printed as pyserial's URL. */
static int open_tcp(long port) {
  struct sockaddr_in a;
  socklen_t len = sizeof a;
  int one = 1, fd = socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return -1;
  (void)setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  (void)memset(&a, 0, sizeof a);
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons((uint16_t)port);
  if (bind(fd, (struct sockaddr *)&a, sizeof a) != 0 || listen(fd, 1) != 0 ||
      getsockname(fd, (struct sockaddr *)&a, &len) != 0 || fcntl(fd, F_SETFL, O_NONBLOCK) != 0) {
    return -1;
  }
  printf("# port socket://127.0.0.1:%u\n", (unsigned)ntohs(a.sin_port));
  (void)fflush(stdout);
  return fd;
}

/* Raw bytes: no echo, no line editing, no translation of CR/LF, reads return at once. */
static int make_raw(int fd) {
  struct termios t;
  if (tcgetattr(fd, &t) != 0) return 0;
  t.c_iflag &= ~(tcflag_t)(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON);
  t.c_oflag &= ~(tcflag_t)OPOST;
  t.c_lflag &= ~(tcflag_t)(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
  t.c_cflag &= ~(tcflag_t)(CSIZE | PARENB);
  t.c_cflag |= (tcflag_t)CS8;
  t.c_cc[VMIN] = 0;
  t.c_cc[VTIME] = 0;
  return tcsetattr(fd, TCSANOW, &t) == 0;
}

/* The link's file descriptor: the master side of a new pseudo-terminal (its slave kept open
 * here in raw mode, so a client's open and close change nothing), or the given device. */
static int open_port(const options *o, int *keep) {
  int fd;
  *keep = -1;
  if (o->port != NULL) {
    fd = open(o->port, O_RDWR | O_NOCTTY | O_NONBLOCK);
    if (fd < 0 || !make_raw(fd)) return -1;
    return fd;
  }
  fd = posix_openpt(O_RDWR | O_NOCTTY);
  if (fd < 0 || grantpt(fd) != 0 || unlockpt(fd) != 0) return -1;
  *keep = open(ptsname(fd), O_RDWR | O_NOCTTY);
  if (*keep < 0 || !make_raw(*keep)) return -1;
  if (fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK) != 0) return -1;
  printf("# port %s\n", ptsname(fd));
  (void)fflush(stdout);
  return fd;
}

static void add_ns(struct timespec *t, long ns) {
  t->tv_nsec += ns;
  while (t->tv_nsec >= 1000000000L) {
    t->tv_nsec -= 1000000000L;
    ++t->tv_sec;
  }
}

static int later(const struct timespec *a, const struct timespec *b) {
  return a->tv_sec > b->tv_sec || (a->tv_sec == b->tv_sec && a->tv_nsec > b->tv_nsec);
}

static void csv_row(FILE *f, const fw_link *l, const ctrl_output *out) {
  int i;
  fprintf(f, "%lu,%.17g,%d,%d,%d,%lu", (unsigned long)l->tick, (double)out->t, (int)out->state,
          (int)(l->stale ? CTRL_FAULT_STALE : out->fault),
          (l->session ? 1 : 0) | (l->streaming ? 2 : 0) | (l->stale ? 4 : 0) | (l->servoing ? 8 : 0),
          (unsigned long)l->counts.rx_frames);
  for (i = 0; i < CTRL_NDOF; ++i) fprintf(f, ",%.17g", (double)out->q[i]);
  for (i = 0; i < CTRL_NDOF; ++i) fprintf(f, ",%.17g", (double)out->qd[i]);
  fputc('\n', f);
  (void)fflush(f);
}

int main(int argc, char **argv) {
  options o;
  ctrl c;
  fw_link l;
  int fd, keep, i;
  long period_ns;
  unsigned long ticks_max;
  FILE *csv = NULL;
  struct timespec next, now;
  if (!parse_args(argc, argv, &o)) {
    fprintf(stderr, "usage: fw_link_host [--port PATH | --tcp PORT] [--watchdog-ms MS] [--csv FILE] [--run-s S]\n");
    return 2;
  }
  if (ctrl_init(&c, &fw_task) != CTRL_FAULT_NONE) {
    fprintf(stderr, "fw_link_host: the compiled-in task's configuration is refused (BAD_CONFIG)\n");
    return 2;
  }
  fw_link_init(&l, &fw_task, (uint32_t)(o.watchdog_ms * 1e-3 / (double)fw_task.dt + 0.5));
  if (o.tcp >= 0) {
    keep = open_tcp(o.tcp); /* the listener; fd is the client's connection, -1 while none */
    fd = -1;
    if (keep < 0) {
      fprintf(stderr, "fw_link_host: cannot listen on TCP port %ld: %s\n", o.tcp, strerror(errno));
      return 4;
    }
  } else {
    fd = open_port(&o, &keep);
  }
  if (fd < 0 && o.tcp < 0) {
    fprintf(stderr, "fw_link_host: cannot open the terminal: %s\n", strerror(errno));
    return 4;
  }
  if (o.csv != NULL) {
    csv = fopen(o.csv, "w");
    if (csv == NULL) {
      fprintf(stderr, "fw_link_host: cannot write %s: %s\n", o.csv, strerror(errno));
      return 4;
    }
    fprintf(csv, "tick,t_s,state,fault,link_flags,rx_frames");
    for (i = 0; i < CTRL_NDOF; ++i) fprintf(csv, ",q%d", i + 1);
    for (i = 0; i < CTRL_NDOF; ++i) fprintf(csv, ",qd%d", i + 1);
    fputc('\n', csv);
  }
  period_ns = (long)((double)fw_task.dt * 1e9 + 0.5);
  ticks_max = o.run_s > 0.0 ? (unsigned long)(o.run_s * 1e9 / (double)period_ns) : 0ul;
  (void)clock_gettime(CLOCK_MONOTONIC, &next);
  for (;;) {
    uint8_t buf[512];
    ssize_t n = -1;
    size_t m;
    ctrl_input in;
    ctrl_output out;
    if (o.tcp >= 0 && fd < 0) { /* TCP: take a client when one connects */
      fd = accept(keep, NULL, NULL);
      if (fd >= 0 && fcntl(fd, F_SETFL, O_NONBLOCK) != 0) {
        (void)close(fd);
        fd = -1;
      }
    }
    /* no more than the ring takes: the rest waits in the terminal's or socket's buffer (flow control) */
    while (fd >= 0 && fw_link_receive_space(&l) > 0u &&
           (n = read(fd, buf, fw_link_receive_space(&l) < sizeof buf ? fw_link_receive_space(&l) : sizeof buf)) > 0) {
      for (i = 0; i < (int)n; ++i) (void)fw_link_receive(&l, buf[i]);
    }
    if (o.tcp >= 0 && fd >= 0 && n == 0) { /* the client closed its end: wait for the next */
      (void)close(fd);
      fd = -1;
    }
    (void)memset(&in, 0, sizeof in);
    fw_link_input(&l, &in);
    (void)ctrl_tick(&c, &in, &out);
    if (csv != NULL) csv_row(csv, &l, &out); /* before fw_link_output: the row's tick is this tick */
    fw_link_output(&l, &out);
    while ((m = fw_link_transmit(&l, buf, sizeof buf)) > 0u) {
      /* no reader, or a slow one: the rest is dropped (a closed TCP peer raises no SIGPIPE) */
      if (fd < 0 || (o.tcp >= 0 ? send(fd, buf, m, MSG_NOSIGNAL) : write(fd, buf, m)) != (ssize_t)m) break;
    }
    if (ticks_max > 0ul && (unsigned long)l.tick >= ticks_max) break;
    add_ns(&next, period_ns);
    (void)clock_gettime(CLOCK_MONOTONIC, &now);
    if (later(&next, &now)) {
      (void)clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL);
    }
  }
  if (csv != NULL) (void)fclose(csv);
  if (keep >= 0) (void)close(keep);
  if (fd >= 0) (void)close(fd);
  return 0;
}
