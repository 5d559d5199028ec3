/* cp_tvlqr.c: controller "tvlqr", cartpole.control.tvlqr.TVLQRController: a planned swing-up tracked by the
 * time-varying LQR, then the LQR catch from the end of the plan on (Drake's law u - u0(t) = -K(t) (x - x0(t))):
 *
 *   t >= TV_T_END:  u = clip(catch(x), TV_LO, TV_HI)                                     (cp_linear_eval, CATCH_*)
 *   otherwise:      u = clip(u0(t) - K(t) e, TV_LO, TV_HI),   e = cp_error(x, x0(t))
 *
 * With TV_EXACT the gains carry their own discrete reference (x0, u0 = TV_XREF, TV_UREF at the gain's step).
 * Otherwise x0(t) is the plan's cubic Hermite interpolation of its knots (TV_T, TV_X, TV_XD):
 *     x0 = h00 x_k + h10 h xd_k + h01 x_{k+1} + h11 h xd_{k+1},  s = (t - t_k) / h,
 *     h00 = 2s^3 - 3s^2 + 1, h10 = s^3 - 2s^2 + s, h01 = -2s^3 + 3s^2, h11 = s^3 - s^2,
 * u0 the first-order hold of TV_U at t + TV_SHIFT (half a step for discrete gains, held per step), and K(t) held
 * per step (TV_DISCRETE) or interpolated linearly in time between the gain times G_T (as numpy.interp).
 * cp_handover_state() gives the time of the first call that used the catch (the MuJoCo loop's hand-over time). */
#include <math.h>

#include "cp_common.h"
#include "cp_parts.h"
#include "cp_plan.h" /* the plan's switches, constants and tables */

/* the hand-over: whether the catch ran since the reset, and the time of its first call, s */
static struct {
    int done;
    double t;
} H;

void cp_ctrl_clear(void)
{
    H.done = 0;
    H.t = 0;
}

int cp_handover_state(double* t)
{
    *t = H.t;
    return H.done;
}

/* the gain step holding t: floor((t - G_T0) / G_DT), clamped to [0, G_N - 1] */
static int gain_index(double t)
{
    double f = floor((t - G_T0) / G_DT + 1e-9);
    return f < 0 ? 0 : (f > G_N - 1 ? G_N - 1 : (int)f);
}

static int catch_law(double t, const cp_real* x, cp_real* u)
{
    int i;
    if (!H.done) {
        H.done = 1;
        H.t = t;
    }
    cp_linear_eval(CATCH_K, CATCH_XEQ, CATCH_UEQ, CATCH_LO, CATCH_HI, x, u);
    for (i = 0; i < CP_NU; ++i) {
        u[i] = cp_clip(u[i], TV_LO[i], TV_HI[i]);
    }
    return CP_OK;
}

#if TV_EXACT

int cp_ctrl_eval(double t, const cp_real* x, cp_real* u)
{
    cp_real e[NX], acc;
    int i, j, k;
    if (t >= TV_T_END - 1e-12) {
        return catch_law(t, x, u);
    }
    k = gain_index(t);
    cp_error(x, TV_XREF + k * NX, e);
    for (i = 0; i < CP_NU; ++i) {
        acc = 0;
        for (j = 0; j < NX; ++j) {
            acc += TV_K[(k * CP_NU + i) * NX + j] * e[j];
        }
        u[i] = cp_clip(TV_UREF[k * CP_NU + i] - acc, TV_LO[i], TV_HI[i]);
    }
    return CP_OK;
}

#else

/* the interval k of the plan holding t (clamped) and s in [0, 1], as Trajectory._locate */
static int plan_locate(double t, double* h, double* s)
{
    int lo = 0, hi = TV_N + 1, mid, k;
    t = t < TV_T[0] ? TV_T[0] : (t > TV_T[TV_N] ? TV_T[TV_N] : t);
    while (lo < hi) { /* first index with TV_T[index] > t */
        mid = (lo + hi) / 2;
        if (TV_T[mid] <= t) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    k = lo - 1;
    k = k < 0 ? 0 : (k > TV_N - 1 ? TV_N - 1 : k);
    *h = TV_T[k + 1] - TV_T[k];
    *s = (t - TV_T[k]) / *h;
    return k;
}

#if !TV_DISCRETE
/* the (i, j) entry of the gain at t, linear in t between the gain times G_T (numpy.interp) */
static cp_real gain_at(double t, int i, int j)
{
    double w;
    int a;
    if (t <= G_T[0]) {
        return TV_K[i * NX + j];
    }
    if (t >= G_T[G_N - 1]) {
        return TV_K[((G_N - 1) * CP_NU + i) * NX + j];
    }
    a = gain_index(t);
    while (a + 1 < G_N && G_T[a + 1] <= t) {
        ++a;
    }
    while (a > 0 && G_T[a] > t) {
        --a;
    }
    w = (TV_K[((a + 1) * CP_NU + i) * NX + j] - TV_K[(a * CP_NU + i) * NX + j]) / (G_T[a + 1] - G_T[a]);
    return (cp_real)(w * (t - G_T[a]) + TV_K[(a * CP_NU + i) * NX + j]);
}
#endif

int cp_ctrl_eval(double t, const cp_real* x, cp_real* u)
{
    cp_real xr[NX], e[NX], acc, kij;
    double h, s, h00, h10, h01, h11, tu;
    int i, j, k;
#if TV_DISCRETE
    int gk;
#endif
    if (t >= TV_T_END - 1e-12) {
        return catch_law(t, x, u);
    }
    k = plan_locate(t, &h, &s);
    h00 = 2 * pow(s, 3) - 3 * pow(s, 2) + 1;
    h10 = pow(s, 3) - 2 * pow(s, 2) + s;
    h01 = -2 * pow(s, 3) + 3 * pow(s, 2);
    h11 = pow(s, 3) - pow(s, 2);
    for (i = 0; i < NX; ++i) {
        xr[i] = (cp_real)(h00 * TV_X[k * NX + i] + h10 * h * TV_XD[k * NX + i] + h01 * TV_X[(k + 1) * NX + i]
                          + h11 * h * TV_XD[(k + 1) * NX + i]);
    }
    cp_error(x, xr, e);
    tu = t + TV_SHIFT < TV_T_END ? t + TV_SHIFT : TV_T_END;
    k = plan_locate(tu, &h, &s);
#if TV_DISCRETE
    gk = gain_index(t);
#endif
    for (i = 0; i < CP_NU; ++i) {
        acc = 0;
        for (j = 0; j < NX; ++j) {
#if TV_DISCRETE
            kij = TV_K[(gk * CP_NU + i) * NX + j];
#else
            kij = gain_at(t, i, j);
#endif
            acc += kij * e[j];
        }
        u[i] = cp_clip((cp_real)((1 - s) * TV_U[k * CP_NU + i] + s * TV_U[(k + 1) * CP_NU + i]) - acc,
                       TV_LO[i], TV_HI[i]);
    }
    return CP_OK;
}

#endif /* TV_EXACT */
