/* A test harness that is not gearctl's: a plain C program that knows nothing but the exported API
 * (gearctl_ctrl.h) and links the exported static library. It reads the inputs from a text file and writes
 * the torques, one per line.
 *
 *   harness IN OUT
 *   IN:  first line the number of steps; then one line per step:
 *        y0 y1 r_0 r'_0 r''_0 ... r_(P-1) r'_(P-1) r''_(P-1)      (P = GEARCTL_PREVIEW; y1 may be nan)
 *   OUT: the torque of each step (%.17g)
 *
 * It runs two controllers side by side on the same inputs (two gearctl_ctrl_t, stepped alternately) and
 * fails (exit 3) if their torques ever differ: any state kept outside gearctl_ctrl_t would show there. */
#include <stdio.h>
#include <stdlib.h>

#include "gearctl_ctrl.h"

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: harness IN OUT\n");
        return 2;
    }
    FILE *in = fopen(argv[1], "r"), *out = fopen(argv[2], "w");
    if (!in || !out) {
        fprintf(stderr, "harness: cannot open the files\n");
        return 2;
    }
    long steps = 0;
    if (fscanf(in, "%ld", &steps) != 1 || steps < 0) return 2;
    gearctl_ctrl_t a, b;
    gearctl_ctrl_init(&a);
    gearctl_ctrl_init(&b);
    double y[2], ref[3 * GEARCTL_PREVIEW];
    char tok[64];
    for (long k = 0; k < steps; k++) {
        for (int i = 0; i < 2 + 3 * GEARCTL_PREVIEW; i++) {
            if (fscanf(in, "%63s", tok) != 1) return 2;
            double v = strtod(tok, NULL);
            if (i < 2)
                y[i] = v;
            else
                ref[i - 2] = v;
        }
        double ua = 0.0, ub = 0.0;
        gearctl_ctrl_step(&a, y, ref, &ua);
        gearctl_ctrl_step(&b, y, ref, &ub);
        if (!(ua == ub)) {
            fprintf(stderr, "harness: two instances disagree at step %ld\n", k);
            return 3;
        }
        fprintf(out, "%.17g\n", ua);
    }
    fclose(in);
    fclose(out);
    return 0;
}
