/* cp_energy.c: controller "energy", cartpole.control.switching.SwitchingController around
 * cartpole.control.energy.EnergyShapingController, with the LQR catch:
 *
 *   cost = e' S e,  e = cp_error(x, x*)          (S: the catch's Riccati matrix SW_S)
 *   the catch takes over when cost < SW_RHO (the verified basin's level) and lets go above SW_RELEASE
 *   (release_factor * rho); while caught  u = cp_linear_eval(CATCH_*) (clip(u* - K e)),
 *   otherwise u = the energy-shaping law, its expression graph CasADi-generated (cp_energy(x, ENERGY_PRM)).
 *
 * cp_switch_state() gives the mode (1: caught), the time and the cost of the last evaluation: the MuJoCo loop reads
 * the switch log of the swing-up from it (cartpole.export.inloop).
 */
#include "cp_common.h"
#include "cp_generated.h"
#include "cp_parts.h"
#include "cp_plan.h" /* the plan's switches, constants and tables */

static struct {
    int caught;
    double t;     /* the time of the last evaluation, s */
    cp_real cost; /* e' S e at the last evaluation */
    cp_real w[CP_ENERGY_SZ_W];
    casadi_int iw[CP_ENERGY_SZ_IW];
} E;

void cp_ctrl_clear(void)
{
    E.caught = 0;
    E.t = 0;
    E.cost = 0;
}

int cp_switch_state(double* t, cp_real* cost)
{
    *t = E.t;
    *cost = E.cost;
    return E.caught;
}

/* e' S e of the catch */
static cp_real sw_cost(const cp_real* x)
{
    cp_real e[NX], es[NX], c = 0;
    int i, j;
    cp_error(x, CATCH_XEQ, e);
    for (j = 0; j < NX; ++j) {
        es[j] = 0;
        for (i = 0; i < NX; ++i) {
            es[j] += e[i] * SW_S[i * NX + j];
        }
    }
    for (j = 0; j < NX; ++j) {
        c += es[j] * e[j];
    }
    return c;
}

int cp_ctrl_eval(double t, const cp_real* x, cp_real* u)
{
    cp_real cost = sw_cost(x);
    E.t = t;
    E.cost = cost;
    if (!E.caught && cost < SW_RHO) {
        E.caught = 1;
    } else if (E.caught && cost > SW_RELEASE) {
        E.caught = 0;
    }
    if (E.caught) {
        cp_linear_eval(CATCH_K, CATCH_XEQ, CATCH_UEQ, CATCH_LO, CATCH_HI, x, u);
    } else {
        const cp_real* arg[CP_ENERGY_SZ_ARG] = {x, ENERGY_PRM};
        cp_real* res[CP_ENERGY_SZ_RES] = {u};
        cp_energy(arg, res, E.iw, E.w, 0);
    }
    return CP_OK;
}
