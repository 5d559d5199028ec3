/* cp_common.h: what every part of an exported controller shares (cartpole/csrc/cp_common.c).
 *
 * cp_real is the export's real type (double, or float with --float32); the maths below call the libm function of
 * that type (cosf... in a float build, so a Cortex-M4F never runs double-precision software maths). Times stay
 * double in every build.
 */
#ifndef CP_COMMON_H
#define CP_COMMON_H

#include <math.h>

#include "cp_config.h"

#if CP_REAL_IS_FLOAT
#define CP_FABS fabsf
#define CP_FMOD fmodf
#define CP_RINT rintf
#else
#define CP_FABS fabs
#define CP_FMOD fmod
#define CP_RINT rint
#endif

/* pi in cp_real */
#define CP_PI_ ((cp_real)3.14159265358979323846)

/* v clipped to [lo, hi] */
cp_real cp_clip(cp_real v, cp_real lo, cp_real hi);

/* a wrapped to (-pi, pi], as numpy's mod(a + pi, 2 pi) - pi with -pi mapped to pi */
cp_real cp_wrap(cp_real a);

/* e = x - ref (NX entries) with the hinge entries (WRAP[i] != 0) wrapped by cp_wrap */
void cp_error(const cp_real* x, const cp_real* ref, cp_real* e);

/* The linear law of cartpole.control.linear.LinearFeedback:
 *     u = clip(u* - K e, lo, hi),   e = cp_error(x, x*)
 * K (CP_NU x NX, row-major), x* (NX), u*, lo, hi (CP_NU). */
void cp_linear_eval(const cp_real* K, const cp_real* x_eq, const cp_real* u_eq, const cp_real* lo,
                    const cp_real* hi, const cp_real* x, cp_real* u);

/* The rig's first estimate (cartpole.estimation.initial_state): x = base, then each joint j with an encoder
 * (rows[j] >= 0) read from y[rows[j]]; base's rates are zero. */
void cp_first_state(const int* rows, const cp_real* base, const cp_real* y, cp_real* x);

#endif /* CP_COMMON_H */
