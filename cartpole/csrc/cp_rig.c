/* cartpole_controller.c (cartpole/csrc/cp_rig.c): the rig step of an exported controller.
 *
 * cp_step(t, y, u) does what cartpole.sim.rig.RigRun and cartpole.sim.rollout.simulate do around a controller,
 * in the same order and with the same arithmetic:
 *
 *   1. the first call starts the estimate from y (cp_est_start); later ones update it with the ctrl MuJoCo applied
 *      during each physics step since the last call (cp_est_update);
 *   2. with a delay of LAG physics steps and compensation on (CP_PREDICT_DELAY), the estimate is predicted over
 *      the delay through the exact discrete model with the ctrl already sent:
 *          x_pred = f_d^LAG(x_hat, u_{k}, ..., u_{k+LAG-1})      (CasADi-generated cp_predict)
 *   3. the controller gives u at t + CP_DELAY, the instant it takes effect (cp_ctrl_eval); u is clipped to the
 *      MJCF's ctrlrange [U_LOW, U_HIGH] and remembered: it acts on the CP_STEPS physics steps from LAG steps on.
 *
 * A measurement that is not finite repeats the last ctrl (CP_BAD_MEASUREMENT); a ctrl that is not finite becomes
 * zero clipped to ctrlrange (CP_BAD_STATE). Static memory only.
 */
#include <math.h>
#include <string.h>

#include "cartpole_controller.h"
#include "cp_common.h"
#include "cp_parts.h"
#if CP_PREDICT_DELAY
#include "cp_generated.h"
#endif

static struct cp_rig_state {
    int started;
    cp_real x_hat[NX];
    /* the ctrl of physics steps [k - CP_STEPS, k + LAG), column-major (CP_NU x (CP_STEPS + LAG)) */
    cp_real planned[(CP_STEPS + LAG) * CP_NU];
    cp_real last[CP_NU];
#if CP_PREDICT_DELAY
    cp_real w[CP_PREDICT_SZ_W];
    casadi_int iw[CP_PREDICT_SZ_IW];
#endif
} S;

void cp_reset(void)
{
    int i;
    memset(&S, 0, sizeof S);
    for (i = 0; i < (CP_STEPS + LAG) * CP_NU; ++i) {
        S.planned[i] = cp_clip(0, U_LOW[i % CP_NU], U_HIGH[i % CP_NU]);
    }
    for (i = 0; i < CP_NU; ++i) {
        S.last[i] = S.planned[i];
    }
    cp_est_clear();
    cp_ctrl_clear();
}

void cp_estimate(cp_real* x)
{
    int i;
    for (i = 0; i < NX; ++i) {
        x[i] = S.x_hat[i];
    }
}

int cp_step(double t, const cp_real y[CP_NY], cp_real u[CP_NU])
{
    int i, code;
    cp_real xu[NX];
    for (i = 0; i < CP_NY; ++i) {
        if (!isfinite(y[i])) {
            for (i = 0; i < CP_NU; ++i) {
                u[i] = S.last[i];
            }
            return CP_BAD_MEASUREMENT;
        }
    }
    if (!S.started) {
        cp_est_start(y, S.x_hat);
        S.started = 1;
    } else {
        cp_est_update(y, S.planned, S.x_hat);
    }
#if CP_PREDICT_DELAY
    {
        const cp_real* arg[CP_PREDICT_SZ_ARG] = {S.x_hat, S.planned + CP_STEPS * CP_NU};
        cp_real* res[CP_PREDICT_SZ_RES] = {xu};
        cp_predict(arg, res, S.iw, S.w, 0);
    }
#else
    for (i = 0; i < NX; ++i) {
        xu[i] = S.x_hat[i];
    }
#endif
    code = cp_ctrl_eval(t + CP_DELAY, xu, u);
    for (i = 0; i < CP_NU; ++i) {
        if (!isfinite(u[i])) {
            code = CP_BAD_STATE;
        }
    }
    for (i = 0; i < CP_NU; ++i) {
        u[i] = code == CP_BAD_STATE ? cp_clip(0, U_LOW[i], U_HIGH[i]) : cp_clip(u[i], U_LOW[i], U_HIGH[i]);
        S.last[i] = u[i];
    }
    /* the window of planned ctrl: steps [k - CP_STEPS, k + LAG) becomes [k, k + CP_STEPS + LAG) */
    for (i = 0; i < LAG * CP_NU; ++i) {
        S.planned[i] = S.planned[i + CP_STEPS * CP_NU];
    }
    for (i = LAG * CP_NU; i < (CP_STEPS + LAG) * CP_NU; ++i) {
        S.planned[i] = u[i % CP_NU];
    }
    return code;
}
