/* example/main.c: the exported controller on stdin/stdout.
 * Each input line: t followed by the CP_NY measurements (manifest.json's "y" order), separated by spaces.
 * Each output line: the return code, then the CP_NU ctrl values. */
#include <stdio.h>

#include "cartpole_controller.h"

int main(void)
{
    double t, v;
    cp_real y[CP_NY], u[CP_NU];
    int i, code;
    cp_reset();
    while (scanf("%lf", &t) == 1) {
        for (i = 0; i < CP_NY; ++i) {
            if (scanf("%lf", &v) != 1) {
                fprintf(stderr, "expected %d measurements after t\n", CP_NY);
                return 2;
            }
            y[i] = (cp_real)v;
        }
        code = cp_step(t, y, u);
        printf("%d", code);
        for (i = 0; i < CP_NU; ++i) {
            printf(" %.17g", (double)u[i]);
        }
        printf("\n");
        fflush(stdout);
    }
    return 0;
}
