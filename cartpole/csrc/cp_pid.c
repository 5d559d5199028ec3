/* cp_pid.c: controller "pid", cartpole.control.pid.CascadedPID (one pole on a cart), as the Python class does it:
 *
 *   cart loop (PD) -> tilt reference:  ref = clip(-(Kp_c e_cart + Kd_c de_cart), -tilt, tilt)
 *   angle loop (PID):                  e_i = e_hinge - ref
 *                                      u   = clip(u* - (Kp e_i + Ki z + Kd yf), lo, hi)
 *   rate filter (first order, tau):    yf += (1 - exp(-dt / tau)) (de_hinge - yf)     (yf = de_hinge for tau = 0)
 *   integrator:                        z  += dt e_i, skipped while u is saturated and the integral would push it
 *                                      further (anti-windup), and clamped to |z| <= ZMAX = (hi - lo) / (2 |Ki|)
 *
 * Constants PID_* are defined in cp_config.h; e = cp_error(x, PID_XEQ). */
#include <math.h>

#include "cp_common.h"
#include "cp_parts.h"

static struct {
    int started;
    double t;   /* time of the last update, s */
    cp_real z;  /* integral of the angle error */
    cp_real y;  /* filtered hinge rate */
} P;

void cp_ctrl_clear(void)
{
    P.started = 0;
    P.t = 0;
    P.z = 0;
    P.y = 0;
}

static cp_real pid_law(const cp_real* e, cp_real z, cp_real yf, cp_real* e_i)
{
    cp_real ref = cp_clip(-(PID_KPC * e[PID_SLIDE] + PID_KDC * e[NQ + PID_SLIDE]), -PID_TILT, PID_TILT);
    *e_i = e[PID_HINGE] - ref;
    return PID_UEQ - (PID_KP * *e_i + PID_KI * z + PID_KD * yf);
}

int cp_ctrl_eval(double t, const cp_real* x, cp_real* u)
{
    cp_real e[NX], rate, e_i, u_raw, push;
    double dt;
    cp_error(x, PID_XEQ, e);
    rate = e[NQ + PID_HINGE];
    if (!P.started) {
        P.started = 1;
        P.t = t;
        P.y = rate;
    } else if (t > P.t) {
        dt = t - P.t;
        P.t = t;
        if (PID_TAU > 0) {
            P.y += (cp_real)(1.0 - exp(-dt / PID_TAU)) * (rate - P.y);
        } else {
            P.y = rate;
        }
        if (PID_KI != 0) {
            u_raw = pid_law(e, P.z, P.y, &e_i);
            push = -PID_KI * e_i;
            if (!(PID_ANTI_WINDUP && ((u_raw > PID_HI && push > 0) || (u_raw < PID_LO && push < 0)))) {
                P.z += (cp_real)dt * e_i;
            }
            if (PID_ANTI_WINDUP) {
                P.z = cp_clip(P.z, -PID_ZMAX, PID_ZMAX);
            }
        }
    }
    u_raw = pid_law(e, P.z, P.y, &e_i);
    u[0] = cp_clip(u_raw, PID_LO, PID_HI);
    return CP_OK;
}
