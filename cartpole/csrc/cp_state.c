/* cp_state.c: estimator "none": the measurement is the state, y = x = [qpos, qvel]. */
#include "cp_parts.h"

void cp_est_clear(void)
{
}

void cp_est_start(const cp_real* y, cp_real* x)
{
    int i;
    for (i = 0; i < NX; ++i) {
        x[i] = y[i];
    }
}

void cp_est_update(const cp_real* y, const cp_real* U, cp_real* x)
{
    (void)U;
    cp_est_start(y, x);
}
