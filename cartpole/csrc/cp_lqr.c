/* cp_lqr.c: controller "lqr", cartpole.control.linear.LinearFeedback:
 *     u = clip(u* - K (x - x*), lo, hi)      (hinge errors wrapped to (-pi, pi])
 * with the tables LQR_K (CP_NU x NX), LQR_XEQ, LQR_UEQ, LQR_LO, LQR_HI of cp_data.c. */
#include "cp_common.h"
#include "cp_parts.h"

void cp_ctrl_clear(void)
{
}

int cp_ctrl_eval(double t, const cp_real* x, cp_real* u)
{
    (void)t;
    cp_linear_eval(LQR_K, LQR_XEQ, LQR_UEQ, LQR_LO, LQR_HI, x, u);
    return CP_OK;
}
