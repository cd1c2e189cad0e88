/* SPDX-License-Identifier: MIT -- part of gearctl, written for it. */
/* make check: replay the recorded test vectors (gearctl_vectors.bin: what the Python controller read and the
 * torque it gave, in gearctl's closed loop) through the exported controller; print the largest difference.
 * This program uses stdio and the heap; the controller library uses neither.
 * Exit status: 0 when the largest |du| is within 1e-9 of the largest |u| (relative; 0 is bit for bit, which the
 * ISO C flags of the Makefile give) and no torque is NaN where the recorded one is not, 1 otherwise, 2 on a bad
 * file. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearctl_ctrl.h"
#include "gearctl_vectors.h"

#define TOLERANCE 1e-9

static unsigned char *load(const char *path, long *size) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    *size = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *buf = malloc((size_t)*size + 1);
    if (buf && fread(buf, 1, (size_t)*size, f) != (size_t)*size) {
        free(buf);
        buf = NULL;
    }
    fclose(f);
    return buf;
}


int main(int argc, char **argv) {
    const char *path = argc > 1 ? argv[1] : "gearctl_vectors.bin";
    long size = 0;
    unsigned char *buf = load(path, &size);
    if (!buf || size < 16 || memcmp(buf, "GCXV", 4) != 0 || rd_i32(buf + 4) != 1) {
        fprintf(stderr, "check: %s is not a gearctl test-vector file\n", path);
        free(buf);
        return 2;
    }
    int preview = rd_i32(buf + 8), ncase = rd_i32(buf + 12);
    if (preview != GEARCTL_PREVIEW) {
        fprintf(stderr, "check: the vectors have preview %d, the controller %d\n", preview, GEARCTL_PREVIEW);
        free(buf);
        return 2;
    }
    long pos = 16, total = 0, differ = 0, nans = 0;
    long statuses[4] = {0, 0, 0, 0}; /* steps that returned each GEARCTL_STEP_ status */
    double max_du = 0.0, max_u = 0.0;
    static gearctl_ctrl_t ctrl; /* statically allocated, as on a target */
    double *rows = NULL;
    for (int c = 0; c < ncase; c++) {
        if (pos + 8 > size) {
            fprintf(stderr, "check: %s is truncated\n", path);
            goto bad;
        }
        long steps = rd_i32(buf + pos), nrows = rd_i32(buf + pos + 4);
        pos += 8;
        long need = nrows * 24 + steps * (4 + 16 + 8);
        if (steps < 0 || nrows < 0 || pos + need > size) {
            fprintf(stderr, "check: %s is truncated\n", path);
            goto bad;
        }
        double *grown = realloc(rows, sizeof(double) * (size_t)(3 * nrows + 3));
        if (!grown) {
            fprintf(stderr, "check: no memory for %ld reference rows\n", nrows);
            goto bad;
        }
        rows = grown;
        for (long i = 0; i < 3 * nrows; i++) rows[i] = rd_f64(buf + pos + 8 * i);
        const unsigned char *first = buf + pos + 24 * nrows;
        const unsigned char *ys = first + 4 * steps;
        const unsigned char *us = ys + 16 * steps;
        gearctl_ctrl_init(&ctrl);
        for (long k = 0; k < steps; k++) {
            long f = rd_i32(first + 4 * k);
            if (f < 0 || f + GEARCTL_PREVIEW > nrows) {
                fprintf(stderr, "check: step %ld reads rows beyond the table\n", k);
                goto bad;
            }
            double y[2] = {rd_f64(ys + 16 * k), rd_f64(ys + 16 * k + 8)};
            double u_ref = rd_f64(us + 8 * k), u = (double)NAN;
            int status = gearctl_ctrl_step(&ctrl, y, rows + 3 * f, &u);
            if (status > 0 && status < 4) statuses[status]++;
            if (isnan(u) != isnan(u_ref)) {
                nans++;
                continue;
            }
            double du = isnan(u) ? 0.0 : fabs(u - u_ref);
            if (du != 0.0) differ++;
            if (du > max_du) max_du = du;
            if (fabs(u_ref) > max_u) max_u = fabs(u_ref);
        }
        pos += need;
        total += steps;
    }
    free(rows);
    free(buf);
    double rel = max_u > 0.0 ? max_du / max_u : max_du;
    int ok = rel <= TOLERANCE && nans == 0;
    printf("gearctl check: %ld steps in %d cases, largest |du| %.3g N m, relative %.3g (of the largest |u|, "
           "%.3g N m; limit %g): %s\n", total, ncase, max_du, rel, max_u, TOLERANCE,
           !ok ? "FAILED" : differ ? "ok, within the limit" : "ok, bit for bit");
    if (differ) printf("gearctl check: %ld steps differ from the recorded torque\n", differ);
    if (nans) printf("gearctl check: %ld steps gave NaN where the recorded torque is a number, or the reverse\n", nans);
    if (statuses[1]) printf("gearctl check: %ld steps used the fallback (GEARCTL_STEP_FALLBACK)\n", statuses[1]);
    if (statuses[2]) printf("gearctl check: %ld steps had a bad input (GEARCTL_STEP_BAD_INPUT)\n", statuses[2]);
    if (statuses[3]) printf("gearctl check: %ld steps in the latched fault (GEARCTL_STEP_FAULT)\n", statuses[3]);
    return ok ? 0 : 1;
bad:
    free(rows);
    free(buf);
    return 2;
}
