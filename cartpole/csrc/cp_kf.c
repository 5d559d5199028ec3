/* cp_kf.c: estimator "kf", the steady-state Kalman filter cartpole.estimation.kalman.KalmanFilter about the
 * operating point (x_op, u_op, y_op) of the design, over one control period of CP_STEPS held physics steps:
 *
 *   predict:  dx = x - x_op (hinges wrapped),  x_p = x_op' + A dx + B (U - u_op)
 *             (x_op' = x - dx: the operating point in the same turn as x; B acts on every physics step's ctrl)
 *   measure:  y_p = y_r + C dx_p + D (u_last - u_op),  dx_p = x_p - x_r,
 *             y_r = h(x_r, u_op) when x_r is x_op a whole turn away (CasADi-generated cp_h), else y_op
 *   correct:  x = x_p + L (y - y_p)
 *
 * Tables KF_A (NX x NX), KF_B (NX x CP_STEPS*CP_NU), KF_C (CP_NY x NX), KF_D (CP_NY x CP_NU), KF_L (NX x CP_NY),
 * KF_XOP, KF_UOP, KF_YOP; the first estimate from the encoders (EST_ROW, EST_BASE: cp_first_state). */
#include <math.h>

#include "cp_common.h"
#include "cp_generated.h"
#include "cp_parts.h"

static struct {
    cp_real w[CP_H_SZ_W];
    casadi_int iw[CP_H_SZ_IW];
} K;

void cp_est_clear(void)
{
}

void cp_est_start(const cp_real* y, cp_real* x)
{
    cp_first_state(EST_ROW, EST_BASE, y, x);
}

void cp_est_update(const cp_real* y, const cp_real* U, cp_real* x)
{
    cp_real dx[NX], xp[NX], dxp[NX], xr[NX], yr[CP_NY], yp[CP_NY], acc;
    int i, j, turned = 0;
    cp_error(x, KF_XOP, dx);
    for (i = 0; i < NX; ++i) {
        acc = 0;
        for (j = 0; j < NX; ++j) {
            acc += KF_A[i * NX + j] * dx[j];
        }
        xp[i] = (x[i] - dx[i]) + acc;
        acc = 0;
        for (j = 0; j < CP_STEPS * CP_NU; ++j) {
            acc += KF_B[i * CP_STEPS * CP_NU + j] * (U[j] - KF_UOP[j % CP_NU]);
        }
        xp[i] += acc;
    }
    cp_error(xp, KF_XOP, dxp);
    for (i = 0; i < NX; ++i) {
        xr[i] = xp[i] - dxp[i];
        if (WRAP[i] && CP_RINT((xr[i] - KF_XOP[i]) / (2 * CP_PI_)) != 0) {
            turned = 1;
        }
    }
    if (turned) {
        const cp_real* arg[CP_H_SZ_ARG] = {xr, KF_UOP};
        cp_real* res[CP_H_SZ_RES] = {yr};
        cp_h(arg, res, K.iw, K.w, 0);
    } else {
        for (i = 0; i < CP_NY; ++i) {
            yr[i] = KF_YOP[i];
        }
    }
    for (i = 0; i < CP_NY; ++i) {
        acc = 0;
        for (j = 0; j < NX; ++j) {
            acc += KF_C[i * NX + j] * dxp[j];
        }
        yp[i] = yr[i] + acc;
        acc = 0;
        for (j = 0; j < CP_NU; ++j) {
            acc += KF_D[i * CP_NU + j] * (U[(CP_STEPS - 1) * CP_NU + j] - KF_UOP[j]);
        }
        yp[i] += acc;
    }
    for (i = 0; i < NX; ++i) {
        acc = 0;
        for (j = 0; j < CP_NY; ++j) {
            acc += KF_L[i * CP_NY + j] * (y[j] - yp[j]);
        }
        x[i] = xp[i] + acc;
    }
}
