/* cp_clock.c: cp_clock_seconds() (cp_clock.h), a monotonic clock where the platform has one.
 *
 * POSIX hosts (Linux, the BSDs, macOS): clock_gettime(CLOCK_MONOTONIC), declared by <time.h> under -std=c99 once
 * _POSIX_C_SOURCE names POSIX.1b (hence the definition before any header). Any other target, or -DCP_NO_CLOCK:
 * 0, so the export compiles on a bare-metal toolchain unchanged.
 */
#if !defined(CP_NO_CLOCK) && (defined(__unix__) || defined(__APPLE__))
#define CP_HAS_CLOCK 1
#ifndef _POSIX_C_SOURCE
#define _POSIX_C_SOURCE 199309L
#endif
#include <time.h>
#else
#define CP_HAS_CLOCK 0
#endif

#include "cp_clock.h"

double cp_clock_seconds(void)
{
#if CP_HAS_CLOCK
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
#else
    return 0.0;
#endif
}
