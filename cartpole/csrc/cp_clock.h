/* cp_clock.h: a monotonic clock for timing a step on the host (cartpole/csrc/cp_clock.c).
 *
 * The NMPC (nmpc.c.jinja) times each solve with it, so that the MuJoCo loop reads the step's own time from the C
 * (cp_nmpc_state). On a POSIX host it is clock_gettime(CLOCK_MONOTONIC); elsewhere (a microcontroller), or when
 * compiled with -DCP_NO_CLOCK, it returns 0 and every time reads 0: replace cp_clock.c with the target's cycle
 * counter to time the step there.
 */
#ifndef CP_CLOCK_H
#define CP_CLOCK_H

/* Seconds since an arbitrary fixed origin, never decreasing; 0 without a clock. */
double cp_clock_seconds(void);

#endif /* CP_CLOCK_H */
