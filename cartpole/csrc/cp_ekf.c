/* cp_ekf.c: estimator "ekf", cartpole.estimation.ekf.ExtendedKalmanFilter over one control period:
 *
 *   predict:  x_p = f(x, U),  A = df/dx(x, U)          (the exact discrete model held over CP_STEPS physics
 *             P_p = A P A' + W                           steps, CasADi-generated cp_ekf_predict)
 *             (a prediction that is not finite keeps x, with P_p = P + W)
 *   measure:  y_p = h(x_p, u_last),  H = dh/dx(x_p, u_last)              (CasADi-generated cp_ekf_measure)
 *   gain:     S = H P_p H' + V,  K = P_p H' S^-1        (LU with partial pivoting: la_right_solve)
 *   correct:  x = x_p + K (y - y_p)
 *             P = (I - K H) P_p (I - K H)' + K V K'     (Joseph form), then symmetrised (P + P') / 2
 *
 * Tables EKF_W, EKF_V, EKF_P0; the first estimate from the encoders (EST_ROW, EST_BASE: cp_first_state). */
#include <math.h>

#include "cp_common.h"
#include "cp_generated.h"
#include "cp_linalg.h"
#include "cp_parts.h"

#define EKF_SZ_W (CP_EKF_PREDICT_SZ_W > CP_EKF_MEASURE_SZ_W ? CP_EKF_PREDICT_SZ_W : CP_EKF_MEASURE_SZ_W)
#define EKF_SZ_IW (CP_EKF_PREDICT_SZ_IW > CP_EKF_MEASURE_SZ_IW ? CP_EKF_PREDICT_SZ_IW : CP_EKF_MEASURE_SZ_IW)

static struct {
    cp_real P[NX * NX];
    cp_real w[EKF_SZ_W];
    casadi_int iw[EKF_SZ_IW];
} E;

void cp_est_clear(void)
{
    int i;
    for (i = 0; i < NX * NX; ++i) {
        E.P[i] = EKF_P0[i];
    }
}

void cp_est_start(const cp_real* y, cp_real* x)
{
    cp_first_state(EST_ROW, EST_BASE, y, x);
}

void cp_est_update(const cp_real* y, const cp_real* U, cp_real* x)
{
    cp_real xp[NX], Acm[NX * NX], A[NX * NX], T1[NX * NX], P[NX * NX], yp[CP_NY], Hcm[CP_NY * NX], H[CP_NY * NX];
    cp_real PHt[NX * CP_NY], Sm[CP_NY * CP_NY], K[NX * CP_NY], IKH[NX * NX];
    cp_real KV[NX * CP_NY], T2[NX * NX];
    int i, j, ok = 1;
    {
        const cp_real* arg[CP_EKF_PREDICT_SZ_ARG] = {x, U};
        cp_real* res[CP_EKF_PREDICT_SZ_RES] = {xp, Acm};
        cp_ekf_predict(arg, res, E.iw, E.w, 0);
    }
    for (i = 0; i < NX; ++i) {
        ok = ok && isfinite(xp[i]);
    }
    for (i = 0; i < NX * NX; ++i) {
        ok = ok && isfinite(Acm[i]);
    }
    if (ok) {
        for (i = 0; i < NX; ++i) {
            for (j = 0; j < NX; ++j) {
                A[i * NX + j] = Acm[j * NX + i];
            }
        }
        la_mul(A, E.P, T1, NX, NX, NX);
        la_mul_t(T1, A, P, NX, NX, NX);
        for (i = 0; i < NX * NX; ++i) {
            P[i] += EKF_W[i];
        }
    } else {
        for (i = 0; i < NX; ++i) {
            xp[i] = x[i];
        }
        for (i = 0; i < NX * NX; ++i) {
            P[i] = E.P[i] + EKF_W[i];
        }
    }
    {
        const cp_real* arg[CP_EKF_MEASURE_SZ_ARG] = {xp, U + (CP_STEPS - 1) * CP_NU};
        cp_real* res[CP_EKF_MEASURE_SZ_RES] = {yp, Hcm};
        cp_ekf_measure(arg, res, E.iw, E.w, 0);
    }
    for (i = 0; i < CP_NY; ++i) {
        for (j = 0; j < NX; ++j) {
            H[i * NX + j] = Hcm[j * CP_NY + i];
        }
    }
    la_mul_t(P, H, PHt, NX, NX, CP_NY);
    la_mul(H, PHt, Sm, CP_NY, NX, CP_NY);
    for (i = 0; i < CP_NY * CP_NY; ++i) {
        Sm[i] += EKF_V[i];
    }
    /* K' = S^-1 PHt' (numpy: solve(S, PHt.T).T), i.e. rows of PHt right-divided by S (S symmetric) */
    la_right_solve(Sm, PHt, K, CP_NY, NX);
    for (i = 0; i < NX; ++i) {
        cp_real acc = 0;
        for (j = 0; j < CP_NY; ++j) {
            acc += K[i * CP_NY + j] * (y[j] - yp[j]);
        }
        x[i] = xp[i] + acc;
    }
    la_mul(K, H, IKH, NX, CP_NY, NX);
    for (i = 0; i < NX * NX; ++i) {
        IKH[i] = (i / NX == i % NX ? 1 : 0) - IKH[i];
    }
    la_mul(IKH, P, T1, NX, NX, NX);
    la_mul_t(T1, IKH, T2, NX, NX, NX);
    la_mul(K, EKF_V, KV, NX, CP_NY, CP_NY);
    la_mul_t(KV, K, T1, NX, CP_NY, NX);
    for (i = 0; i < NX; ++i) {
        for (j = 0; j < NX; ++j) {
            P[i * NX + j] = T2[i * NX + j] + T1[i * NX + j];
        }
    }
    for (i = 0; i < NX; ++i) {
        for (j = 0; j < NX; ++j) {
            E.P[i * NX + j] = 0.5 * (P[i * NX + j] + P[j * NX + i]);
        }
    }
}
