/* SPDX-License-Identifier: MIT -- part of gearctl, written for it. */
/* make bench: the wall time of gearctl_ctrl_step, replaying the recorded test vectors (real states: the
 * closed loop's encoder readings and references) several times; prints the median and the 99th percentile
 * per step, then the same as one JSON line. Uses POSIX clock_gettime; the controller library does not. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gearctl_ctrl.h"
#include "gearctl_vectors.h"

static int cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}
static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv) {
    const char *path = argc > 1 ? argv[1] : "gearctl_vectors.bin";
    double min_time = argc > 2 ? atof(argv[2]) : 1.0; /* seconds of replays at least */
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "bench: cannot open %s\n", path);
        return 2;
    }
    fseek(f, 0, SEEK_END);
    long size = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *buf = size > 0 ? malloc((size_t)size) : NULL;
    if (!buf || fread(buf, 1, (size_t)size, f) != (size_t)size || size < 16 || memcmp(buf, "GCXV", 4) ||
        rd_i32(buf + 4) != 1) {
        fprintf(stderr, "bench: %s is not a gearctl test-vector file\n", path);
        fclose(f);
        free(buf);
        return 2;
    }
    fclose(f);
    int preview = rd_i32(buf + 8), ncase = rd_i32(buf + 12);
    if (preview != GEARCTL_PREVIEW || ncase < 1 || ncase > 64) {
        fprintf(stderr, "bench: %s has preview %d and %d cases; the controller reads %d rows\n", path, preview, ncase,
                GEARCTL_PREVIEW);
        free(buf);
        return 2;
    }
    /* decode every case once, checking every count against the file's size */
    long pos = 16, total = 0;
    double **rows = calloc((size_t)ncase, sizeof *rows), **ys = calloc((size_t)ncase, sizeof *ys);
    int32_t **first = calloc((size_t)ncase, sizeof *first);
    long *steps = calloc((size_t)ncase, sizeof *steps);
    int bad = !rows || !ys || !first || !steps;
    for (int c = 0; c < ncase && !bad; c++) {
        long n = pos + 8 <= size ? rd_i32(buf + pos) : -1, nr = pos + 8 <= size ? rd_i32(buf + pos + 4) : -1;
        pos += 8;
        if (n < 1 || nr < GEARCTL_PREVIEW || pos + 24 * nr + 28 * n > size) {
            bad = 1;
            break;
        }
        steps[c] = n;
        rows[c] = malloc(sizeof(double) * (size_t)(3 * nr + 3));
        first[c] = malloc(sizeof(int32_t) * (size_t)(n + 1));
        ys[c] = malloc(sizeof(double) * (size_t)(2 * n + 2));
        if (!rows[c] || !first[c] || !ys[c]) {
            bad = 1;
            break;
        }
        for (long i = 0; i < 3 * nr; i++) rows[c][i] = rd_f64(buf + pos + 8 * i);
        pos += 24 * nr;
        for (long i = 0; i < n; i++) first[c][i] = rd_i32(buf + pos + 4 * i);
        pos += 4 * n;
        for (long i = 0; i < 2 * n; i++) ys[c][i] = rd_f64(buf + pos + 8 * i);
        pos += 16 * n + 8 * n;
        total += n;
        for (long i = 0; i < n; i++) bad = bad || first[c][i] < 0 || first[c][i] + GEARCTL_PREVIEW > nr;
    }
    if (bad) {
        fprintf(stderr, "bench: %s is truncated or inconsistent\n", path);
        for (int c = 0; c < ncase && rows; c++) free(rows[c]);
        for (int c = 0; c < ncase && ys; c++) free(ys[c]);
        for (int c = 0; c < ncase && first; c++) free(first[c]);
        free(rows), free(ys), free(first), free(steps), free(buf);
        return 2;
    }
    static gearctl_ctrl_t ctrl;
    long cap = total * 64, m = 0;
    double *dt = malloc(sizeof(double) * (size_t)cap);
    if (!dt) {
        fprintf(stderr, "bench: no memory for %ld step times\n", cap);
        return 2;
    }
    double start = now();
    volatile double sink = 0.0; /* keeps the calls */
    int passes = 0;
    while (m + total <= cap && (passes < 3 || now() - start < min_time)) {
        for (int c = 0; c < ncase; c++) {
            gearctl_ctrl_init(&ctrl);
            for (long k = 0; k < steps[c]; k++) {
                double u = 0.0;
                double t0 = now();
                gearctl_ctrl_step(&ctrl, ys[c] + 2 * k, rows[c] + 3 * first[c][k], &u);
                dt[m++] = now() - t0;
                sink += u;
            }
        }
        passes++;
    }
    qsort(dt, (size_t)m, sizeof(double), cmp);
    double med = dt[m / 2], p99 = dt[(long)(0.99 * (double)(m - 1))], mx = dt[m - 1];
    printf("gearctl bench: %ld steps (%d passes over %ld): median %.3g us, p99 %.3g us, max %.3g us per step "
           "(sample period %.3g us)\n", m, passes, total, med * 1e6, p99 * 1e6, mx * 1e6, GEARCTL_TS * 1e6);
    printf("{\"step_median\": %.6g, \"step_p99\": %.6g, \"step_max\": %.6g, \"steps\": %ld}\n", med, p99, mx, m);
    for (int c = 0; c < ncase; c++) free(rows[c]), free(ys[c]), free(first[c]);
    free(rows), free(ys), free(first), free(steps), free(dt), free(buf);
    (void)sink; /* read: clang's -Wunused-but-set-variable */
    return 0;
}
