/* CSV lines of the controller output, see fw_csv.h. */
#include "fw_csv.h"

#include <stdint.h>
#include <string.h>
#if !FW_CSV_HEX
#include <stdio.h>
#endif

typedef struct {
  char *buf;
  size_t size, len;
} line;

static void put(line *l, const char *s) {
  while (*s != '\0' && l->len + 1 < l->size) {
    l->buf[l->len++] = *s++;
  }
  if (l->size > 0) {
    l->buf[l->len] = '\0';
  }
}

size_t fw_csv_uint(char *buf, size_t size, unsigned long value) {
  char tmp[24];
  int i = 23;
  line l;
  tmp[i] = '\0';
  do {
    tmp[--i] = (char)('0' + (int)(value % 10ul));
    value /= 10ul;
  } while (value != 0ul && i > 0);
  l.buf = buf;
  l.size = size;
  l.len = 0;
  put(&l, &tmp[i]);
  return l.len;
}

#if FW_CSV_HEX
/* C99 %a-style text of an IEEE binary32/binary64 value, exact. */
size_t fw_csv_real(char *buf, size_t size, ctrl_real x) {
  static const char hex[] = "0123456789abcdef";
  char tmp[40];
  int n = 0, k, exp_bits, mant_bits, bias, digits;
  uint64_t bits, mant;
  long e;
  line l;
#if CTRL_USE_FLOAT
  {
    uint32_t b32;
    memcpy(&b32, &x, sizeof(b32));
    bits = b32;
    exp_bits = 8;
    mant_bits = 23;
  }
#else
  memcpy(&bits, &x, sizeof(bits));
  exp_bits = 11;
  mant_bits = 52;
#endif
  bias = (1 << (exp_bits - 1)) - 1;
  digits = (mant_bits + 3) / 4;
  mant = bits & ((((uint64_t)1) << mant_bits) - 1u);
  e = (long)((bits >> mant_bits) & ((1u << exp_bits) - 1u));
  if ((bits >> (mant_bits + exp_bits)) & 1u) {
    tmp[n++] = '-';
  }
  if (e == (long)((1u << exp_bits) - 1u)) {
    const char *s = mant != 0u ? "nan" : "inf";
    while (*s != '\0') tmp[n++] = *s++;
  } else if (e == 0 && mant == 0u) {
    memcpy(&tmp[n], "0x0p+0", 6);
    n += 6;
  } else {
    mant <<= (unsigned)(4 * digits - mant_bits); /* whole hex digits */
    tmp[n++] = '0';
    tmp[n++] = 'x';
    tmp[n++] = e == 0 ? '0' : '1';
    tmp[n++] = '.';
    for (k = digits - 1; k >= 0; --k) {
      tmp[n++] = hex[(mant >> (4 * k)) & 0xFu];
    }
    e = e == 0 ? 1 - bias : e - bias;
    tmp[n++] = 'p';
    tmp[n++] = e < 0 ? '-' : '+';
    n += (int)fw_csv_uint(&tmp[n], sizeof(tmp) - (size_t)n, (unsigned long)(e < 0 ? -e : e));
  }
  tmp[n] = '\0';
  l.buf = buf;
  l.size = size;
  l.len = 0;
  put(&l, tmp);
  return l.len;
}
#else
size_t fw_csv_real(char *buf, size_t size, ctrl_real x) {
#if CTRL_USE_FLOAT
  int n = snprintf(buf, size, "%.9g", (double)x);
#else
  int n = snprintf(buf, size, "%.17g", (double)x);
#endif
  if (n < 0) {
    n = 0;
  }
  return (size_t)n < size ? (size_t)n : (size > 0 ? size - 1 : 0);
}
#endif

static void put_real(line *l, ctrl_real x) {
  char tmp[40];
  (void)fw_csv_real(tmp, sizeof(tmp), x);
  put(l, tmp);
}

static void put_uint(line *l, unsigned long v) {
  char tmp[24];
  (void)fw_csv_uint(tmp, sizeof(tmp), v);
  put(l, tmp);
}

static void put_names(line *l, const char *stem, const char *unit) {
  int i;
  for (i = 0; i < CTRL_NDOF; ++i) {
    put(l, ",");
    put(l, stem);
    put_uint(l, (unsigned long)(i + 1));
    put(l, unit);
  }
}

size_t fw_csv_header(char *buf, size_t size) {
  line l;
  l.buf = buf;
  l.size = size;
  l.len = 0;
  put(&l, "tick,t_s");
  put_names(&l, "q", "_rad");
  put_names(&l, "dq", "_rad_s");
  put(&l, ",pos_err_m,ori_err_rad");
  put_names(&l, "window", "_1");
#if CTRL_HAS_DYNAMICS
  put_names(&l, "tau_ff", "_Nm");
#endif
#if CTRL_HAS_COLLISION
  put(&l, ",clearance_m");
#endif
  put(&l, ",locked,state,fault\n");
  return l.len;
}

size_t fw_csv_row(char *buf, size_t size, const ctrl_output *out) {
  line l;
  int i;
  l.buf = buf;
  l.size = size;
  l.len = 0;
  put_uint(&l, (unsigned long)out->tick);
  put(&l, ",");
  put_real(&l, out->t);
  for (i = 0; i < CTRL_NDOF; ++i) {
    put(&l, ",");
    put_real(&l, out->q[i]);
  }
  for (i = 0; i < CTRL_NDOF; ++i) {
    put(&l, ",");
    put_real(&l, out->qd[i]);
  }
  put(&l, ",");
  put_real(&l, out->pos_err);
  put(&l, ",");
  put_real(&l, out->ori_err);
  for (i = 0; i < CTRL_NDOF; ++i) {
    put(&l, ",");
    put_real(&l, out->window[i]);
  }
#if CTRL_HAS_DYNAMICS
  for (i = 0; i < CTRL_NDOF; ++i) {
    put(&l, ",");
    put_real(&l, out->tau_ff[i]);
  }
#endif
#if CTRL_HAS_COLLISION
  put(&l, ",");
  put_real(&l, out->clearance);
#endif
  put(&l, ",");
  put_uint(&l, (unsigned long)out->locked);
  put(&l, ",");
  put_uint(&l, (unsigned long)out->state);
  put(&l, ",");
  put_uint(&l, (unsigned long)out->fault);
  put(&l, "\n");
  return l.len;
}
