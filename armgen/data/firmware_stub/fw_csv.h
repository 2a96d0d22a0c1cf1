/*
 * CSV lines of the controller's output, shared by the host and the Cortex-M runners:
 *
 *   tick,t_s,q1_rad,...,dq1_rad_s,...,pos_err_m,ori_err_rad,window1_1,...,locked,state,fault
 *
 * and, for a robot with inertials (CTRL_HAS_DYNAMICS), the feed-forward torques after the
 * windows: ...,window<n>_1,tau_ff1_Nm,...,locked,state,fault (N m; N for a prismatic joint).
 * The last three columns stay last: readers take the state and the fault from the row's end.
 *
 * Reals are printed with %.17g (double) / %.9g (float) on the host, which round-trips, and
 * as C99 hexadecimal floating point ("0x1.8p+1", exact, no printf needed) when FW_CSV_HEX is
 * 1 (the bare-metal build). Python reads both (float() / float.fromhex()).
 */
#ifndef ARMGEN_FW_CSV_H
#define ARMGEN_FW_CSV_H

#include <stddef.h>

#include "controller.h"

#ifndef FW_CSV_HEX
#define FW_CSV_HEX 0
#endif

/* Longest line: a real takes at most 25 characters plus the comma (tau_ff with dynamics, the
 * clearance with a collision model). */
#if CTRL_HAS_DYNAMICS
#define FW_CSV_LINE_MAX (26 * (4 * CTRL_NDOF + 7 + CTRL_HAS_COLLISION) + 32)
#else
#define FW_CSV_LINE_MAX (26 * (3 * CTRL_NDOF + 7 + CTRL_HAS_COLLISION) + 32)
#endif

/* Write the header / one row, '\n'-terminated and NUL-terminated, into buf; return the
 * length (truncated to size - 1 if buf is too small). */
size_t fw_csv_header(char *buf, size_t size);
size_t fw_csv_row(char *buf, size_t size, const ctrl_output *out);

/* The text of one real as the rows print it (no comma). */
size_t fw_csv_real(char *buf, size_t size, ctrl_real x);
/* The text of an unsigned integer. */
size_t fw_csv_uint(char *buf, size_t size, unsigned long value);

#endif /* ARMGEN_FW_CSV_H */
