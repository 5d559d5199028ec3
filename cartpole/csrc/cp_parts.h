/* cp_parts.h: the two parts the rig step (cp_rig.c) calls: one estimator, one controller.
 *
 * Estimators (cp_state.c, cp_kf.c, cp_ekf.c; the MHE): x_hat from y.
 * Controllers (cp_lqr.c, cp_pid.c, cp_tvlqr.c, cp_switching.c; the NMPC): u from x_hat.
 */
#ifndef CP_PARTS_H
#define CP_PARTS_H

#include "cp_config.h"

/* Forget everything (called by cp_reset). */
void cp_est_clear(void);
/* The first estimate x (NX) from the first measurement y (CP_NY). */
void cp_est_start(const cp_real* y, cp_real* x);
/* One period: the estimate x updated in place with y and U, the ctrl MuJoCo applied during each of the CP_STEPS
 * physics steps since the last sample (CP_NU x CP_STEPS, column-major: U[k * CP_NU + i]). */
void cp_est_update(const cp_real* y, const cp_real* U, cp_real* x);

/* Forget everything (called by cp_reset). */
void cp_ctrl_clear(void);
/* The ctrl u (CP_NU) at time t (s) from the state x (NX); returns CP_OK or CP_FALLBACK. */
int cp_ctrl_eval(double t, const cp_real* x, cp_real* u);

/* The rig's current estimate x_hat (NX), before the delay prediction (cp_rig.c; for the MuJoCo loop's log, not
 * part of the exported interface). */
void cp_estimate(cp_real* x);

/* The controller's state, for the MuJoCo loop's log (not part of the exported interface; defined only by the part
 * that has it). cp_energy.c: the mode (1: the catch, 0: the swing-up law), and the time t (s) and cost e' S e of
 * the last evaluation. cp_tvlqr.c: 1 once the catch has run since the reset, and the time t (s) of its first call. */
int cp_switch_state(double* t, cp_real* cost);
int cp_handover_state(double* t);
/* The NMPC (nmpc.c.jinja): the solves since the reset, and the time t (s), wall time (s, cp_clock.c), status
 * (0 solved, 1-3 the QP's failure, 4 not finite, 5 a state not finite) and QP active-set changes of the last;
 * returns its safe action (0 none, 1 the previous plan's input, 2 the upright LQR). */
int cp_nmpc_state(long* solves, double* t, double* seconds, int* status, int* qp_iterations);

#endif /* CP_PARTS_H */
