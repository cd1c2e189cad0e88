/* SPDX-License-Identifier: MIT -- part of gearctl, written for it. */
/* The test vectors' little-endian readers (the file's byte order, whatever the host's), for check.c and
 * bench.c; the controller library does not use them. */
#ifndef GEARCTL_VECTORS_H
#define GEARCTL_VECTORS_H
#include <stdint.h>
#include <string.h>

static int32_t rd_i32(const unsigned char *p) {
    uint32_t v = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
    int32_t out;
    memcpy(&out, &v, 4);
    return out;
}

static double rd_f64(const unsigned char *p) {
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--) v = v << 8 | p[i];
    double out;
    memcpy(&out, &v, 8);
    return out;
}

#endif
