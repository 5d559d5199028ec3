/* cp_common.c: clip, angle wrap, wrapped state error, the linear law and the first estimate, shared by the parts
 * of an exported controller (declared in cp_common.h). */
#include "cp_common.h"

cp_real cp_clip(cp_real v, cp_real lo, cp_real hi)
{
    return v < lo ? lo : (v > hi ? hi : v);
}

cp_real cp_wrap(cp_real a)
{
    cp_real w = CP_FMOD(a + CP_PI_, 2 * CP_PI_);
    if (w != 0 && w < 0) {
        w += 2 * CP_PI_;
    }
    w -= CP_PI_;
    return w == -CP_PI_ ? CP_PI_ : w;
}

void cp_error(const cp_real* x, const cp_real* ref, cp_real* e)
{
    int i;
    for (i = 0; i < NX; ++i) {
        e[i] = x[i] - ref[i];
        if (WRAP[i]) {
            e[i] = cp_wrap(e[i]);
        }
    }
}

void cp_linear_eval(const cp_real* K, const cp_real* x_eq, const cp_real* u_eq, const cp_real* lo,
                    const cp_real* hi, const cp_real* x, cp_real* u)
{
    cp_real e[NX], acc;
    int i, j;
    cp_error(x, x_eq, e);
    for (i = 0; i < CP_NU; ++i) {
        acc = 0;
        for (j = 0; j < NX; ++j) {
            acc += K[i * NX + j] * e[j];
        }
        u[i] = cp_clip(u_eq[i] - acc, lo[i], hi[i]);
    }
}

void cp_first_state(const int* rows, const cp_real* base, const cp_real* y, cp_real* x)
{
    int j;
    for (j = 0; j < NX; ++j) {
        x[j] = base[j];
    }
    for (j = 0; j < NQ; ++j) {
        if (rows[j] >= 0) {
            x[j] = y[rows[j]];
        }
    }
}
