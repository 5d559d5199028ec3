/* cp_bench.c: the timing harness of cartpole.export.timing (not part of an export: POSIX clocks).
 * Linked with a compiled copy of an export; see the comment on main. */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "cartpole_controller.h"

/* stdin: rows of t and CP_NY measurements (text); argv[1]: repeats. stdout per row of the last repeat: the
   fastest step over the repeats (ns), the return code, the ctrl. */
int main(int argc, char** argv)
{
    int repeats = argc > 1 ? atoi(argv[1]) : 1, n = 0, cap = 1024, r, k, i, code = 0;
    double* rows = malloc(sizeof(double) * (size_t)cap * (1 + CP_NY));
    long* best;
    cp_real y[CP_NY], u[CP_NU];
    struct timespec a, b;
    while (rows && scanf("%lf", &rows[n * (1 + CP_NY)]) == 1) {
        for (i = 0; i < CP_NY; ++i) {
            if (scanf("%lf", &rows[n * (1 + CP_NY) + 1 + i]) != 1) {
                return 2;
            }
        }
        if (++n == cap) {
            cap *= 2;
            rows = realloc(rows, sizeof(double) * (size_t)cap * (1 + CP_NY));
        }
    }
    best = malloc(sizeof(long) * (size_t)(n + 1));
    for (k = 0; k < n; ++k) {
        best[k] = -1;
    }
    for (r = 0; r < repeats; ++r) {
        cp_reset();
        for (k = 0; k < n; ++k) {
            long ns;
            for (i = 0; i < CP_NY; ++i) {
                y[i] = (cp_real)rows[k * (1 + CP_NY) + 1 + i];
            }
            clock_gettime(CLOCK_MONOTONIC, &a);
            code = cp_step(rows[k * (1 + CP_NY)], y, u);
            clock_gettime(CLOCK_MONOTONIC, &b);
            ns = (long)(b.tv_sec - a.tv_sec) * 1000000000L + (b.tv_nsec - a.tv_nsec);
            if (best[k] < 0 || ns < best[k]) {
                best[k] = ns;
            }
            if (r == repeats - 1) {
                printf("%ld %d", best[k], code);
                for (i = 0; i < CP_NU; ++i) {
                    printf(" %.17g", (double)u[i]);
                }
                printf("\n");
            }
        }
    }
    free(rows);
    free(best);
    return 0;
}
